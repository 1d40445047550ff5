// Live charts fed with what is new: the page keeps each chart's window and hands it to uPlot.
// Installed with a page's first push by hopper.app.dashboard.chart_feed (again after a reconnect, which
// may be to another server version: the last one run replaces the one before, and its first push
// brings whole windows); each push then brings, per chart, the
// samples since the last one ("c": one array per column, or one number for a constant column such as
// a limit line), the window's first time ("f": older samples are dropped) and "r" when the window was
// replaced (a reset or a restore). The uPlot instances are viser's own, found by CHART_INSTANCE
// (hopper.app.dashboard.viser_compat.CHART_INSTANCE_JS); a chart created or re-created after the
// last push (a page still loading, a theme switch) is drawn within WATCH_MS.
(() => {
  if (window.hopperCharts) clearInterval(window.hopperCharts.watch);
  const WATCH_MS = 250;
  const chartOf = CHART_INSTANCE;
  const windows = {};
  const drawn = {};
  const draw = (uuid) => {
    const w = windows[uuid];
    const chart = chartOf(uuid);
    const n = w.find((c) => typeof c !== "number").length;
    if (!chart || !n) return;
    chart.setData(w.map((c) => (typeof c === "number" ? new Array(n).fill(c) : c)));
    // Its expand dialog would draw the element's own data, one sample: the stylesheet hides the button.
    chart.root.closest(".uplot-container")?.classList.add("hd-fed");
    drawn[uuid] = chart;
  };
  const watch = setInterval(() => {
    for (const uuid of Object.keys(windows)) if (chartOf(uuid) !== drawn[uuid]) draw(uuid);
  }, WATCH_MS);
  window.hopperCharts = {
    windows,
    watch,
    push(update) {
      for (const [uuid, u] of Object.entries(update)) {
        let w = windows[uuid];
        if (!w || u.r) w = windows[uuid] = u.c.map((c) => (typeof c === "number" ? c : []));
        u.c.forEach((c, i) => {
          if (typeof c === "number") w[i] = c;
          else for (const v of c) w[i].push(v);
        });
        const t = w.find((c) => typeof c !== "number");
        let old = 0;
        while (old < t.length && t[old] < u.f) old++;
        if (old) for (const c of w) if (typeof c !== "number") c.splice(0, old);
        draw(uuid);
      }
    },
  };
})();
