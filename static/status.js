// The status strip's values, written into its cells (hopper.app.dashboard.panels.status): the server
// re-sends the strip's table only when its layout changes, and its values five times a second in a
// hidden <template data-hd-status='[...]'>. Each cell marked data-v="i" shows value i; the phase
// badge takes its colour class from its value, the gauge's fill "level left width" (%). Run as the
// page connects (again on a reconnect, which may be to another server version: the last one run
// replaces the one before); it watches the page, so a value arriving or a strip drawn again (a new
// layout, a re-render) is written at once.
(() => {
  window.hopperStatus?.observer?.disconnect(); // an older copy may have none
  const apply = () => {
    const carrier = document.querySelector("template[data-hd-status]");
    const strip = document.querySelector(".hd-status");
    if (!carrier || !strip) return;
    const text = carrier.getAttribute("data-hd-status");
    if (strip.dataset.shown === text) return; // written already (also ends the observer's own echo)
    const values = JSON.parse(text);
    for (const cell of strip.querySelectorAll("[data-v]")) {
      const v = values[Number(cell.dataset.v)];
      if (cell.classList.contains("hd-gauge-fill")) {
        const [level, left, width] = v.split(" ");
        cell.className = `hd-gauge-fill ${level}`;
        cell.style.left = `${left}%`;
        cell.style.width = `${width}%`;
      } else {
        if (cell.classList.contains("hd-phase")) cell.className = `hd-phase hd-${v}`;
        cell.textContent = v;
      }
    }
    strip.dataset.shown = text;
  };
  const observer = new MutationObserver(apply);
  observer.observe(document.body, { childList: true, subtree: true });
  window.hopperStatus = { apply, observer };
  const strip = document.querySelector(".hd-status");
  if (strip) delete strip.dataset.shown; // written by the script before this one: write it again
  apply();
})();
