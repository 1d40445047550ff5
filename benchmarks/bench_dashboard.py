"""Dashboard load: real-time factor, scene updates, chart refreshes and bandwidth with 0 to 16 clients.

Run: python -m benchmarks.bench_dashboard [--seconds 10] [--speed 1] [--clients 0,1,4,16]
         [--workbench] [--speeds 4,16,32,64] [--speed-clients 1] [--controller SPEC]

The server runs in this process at the asked speed; the clients run in a child process (browsers
are separate processes too) and speak viser's real protocol: subprotocol handshake, a camera
report, then they receive and decode the full stream (zstd + msgpack + binary buffers) as a
browser would, without rendering it. Everything is measured in this one run.

Per client it reports the bytes received per second split into charts (uPlot data), poses (the
scene nodes' transforms) and other (status, trail, tables, ...), as app/dashboard/probe.py attributes
them, the scene updates per second (frames that moved the robot) and the chart refreshes per
second (data updates of the least refreshed chart).

--workbench turns on what a tuning session runs besides the scene and charts: a repeatable kick
after every liftoff (per-hop response metrics), the physics overlays (on by default) and the
replay history (always on). --speeds then asks the loop for each speed in turn, with
--speed-clients clients connected, and reports what it delivered: the highest speed it sustains
is the largest whose delivered speed is at least 0.95 of the asked one (the status strip's
"behind" threshold).
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from benchmarks.bench_sim import ControlRecorder, closed_loop, raw_replay  # noqa: E402
from benchmarks.harness import MIN_ROUNDS, interleaved, ratio, spread  # noqa: E402
from hopper.config import TIMESTEP  # noqa: E402


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def probe_main(url: str, clients: int, settle: float, seconds: float) -> None:
    """Child process: connect `clients`, wait out the initial scene, measure, print JSON."""
    from hopper.app.dashboard.probe import ProbeClient

    probes = [ProbeClient(url) for _ in range(clients)]
    for p in probes:
        if not p.wait_for(lambda c: c.pose_frames > 0, timeout=30):
            raise SystemExit("a client never received a pose")
    time.sleep(settle)
    initial = [(p.snapshot(), p.traffic_snapshot()) for p in probes]
    print(json.dumps({"event": "measuring"}), flush=True)
    start = time.perf_counter()
    time.sleep(seconds)
    wall = time.perf_counter() - start
    final = [(p.snapshot(), p.traffic_snapshot()) for p in probes]
    stats = []
    for ((b0, f0, _), t0), ((b1, f1, _), t1) in zip(initial, final, strict=True):
        d = t1.minus(t0)
        stats.append(
            {
                "initial_bytes": b0,
                "bytes_per_s": (b1 - b0) / wall,
                "frames_per_s": (f1 - f0) / wall,
                "pose_updates_per_s": d.scene_updates / wall,
                "chart_refreshes_per_s": min(d.chart_refreshes.values(), default=0) / wall,
                "breakdown_bytes_per_s": {k: v / wall for k, v in d.bytes.items()},
                "messages_per_s": {k: v / wall for k, v in d.messages.items()},
            }
        )
    print(json.dumps({"event": "done", "clients": stats}), flush=True)
    for p in probes:
        p.close()


def measure(dashboard, clients: int, settle: float, seconds: float) -> dict:
    """Real-time factor over the measuring window, with `clients` connected from a child process."""
    child = None
    if clients:
        child = subprocess.Popen(
            [sys.executable, "-m", "benchmarks.bench_dashboard", "--probe", dashboard.url,
             "--clients", str(clients), "--seconds", str(seconds), "--settle", str(settle)],
            stdout=subprocess.PIPE, text=True, cwd=ROOT,
        )  # fmt: skip
        line = child.stdout.readline()
        if '"measuring"' not in line:
            raise SystemExit(f"probe failed to start: {line!r}")
    else:
        time.sleep(settle)
    pacer, recorder = dashboard.pacer, dashboard.recorder
    steps0, frames0, t0, cpu0 = pacer._steps, dashboard.frames, time.perf_counter(), time.process_time()
    written0 = recorder.progress()[1]
    time.sleep(seconds)
    steps1, frames1, t1, cpu1 = pacer._steps, dashboard.frames, time.perf_counter(), time.process_time()
    written1 = recorder.progress()[1]
    delivered = (steps1 - steps0) * pacer.timestep / (t1 - t0)  # simulated s per wall s
    result = {
        "clients": clients,
        "delivered": delivered,
        "rtf": delivered / pacer.speed,  # 0 at Max: there the delivered speed is the figure
        "server_frames_per_s": (frames1 - frames0) / (t1 - t0),
        "cpu": (cpu1 - cpu0) / (t1 - t0),  # cores of this process (loop, viser, rerun, the file's writer)
        "recorded_kb_per_s": (written1 - written0) / (t1 - t0) / 1e3,
        "per_client": [],
    }
    if child is not None:
        out, _ = child.communicate(timeout=seconds + 60)
        result["per_client"] = json.loads(out.strip().splitlines()[-1])["clients"]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="measuring window per case and round (s)")
    parser.add_argument("--settle", type=float, default=2.0, help="wait after connecting, before measuring (s)")
    parser.add_argument("--rounds", type=int, default=MIN_ROUNDS, help="interleaved rounds: every case in each")
    parser.add_argument("--speed", type=float, default=1.0, help="simulation speed (x real time)")
    parser.add_argument("--clients", default="0,1,4,16", help="comma-separated client counts, one case each")
    parser.add_argument("--workbench", action="store_true", help="a kick schedule on every hop, overlays on")
    parser.add_argument(
        "--speeds", default="", help="comma-separated speeds (or max) to measure the delivered speed at"
    )
    parser.add_argument("--speed-clients", type=int, default=1, help="clients connected while --speeds runs")
    parser.add_argument("--record", action="store_true", help="--speeds also with a recording on (data rate, CPU)")
    parser.add_argument("--controller", default="pid", help="the flight's controller (hopper-dashboard --controller)")
    parser.add_argument("--probe", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.rounds < MIN_ROUNDS:
        parser.error(f"--rounds must be at least {MIN_ROUNDS}: a median of fewer rounds says little")
    if args.probe:
        probe_main(args.probe, int(args.clients), args.settle, args.seconds)
        return
    cases = [int(c) for c in args.clients.split(",") if c]

    from hopper.app.dashboard.config import DashboardConfig
    from hopper.app.dashboard.pacing import MAX
    from hopper.app.dashboard.server import Dashboard

    speeds = [MAX if v.strip().lower() == "max" else float(v) for v in args.speeds.split(",") if v]
    with tempfile.TemporaryDirectory() as sessions:
        config = DashboardConfig(port=free_port(), speed=args.speed, controller=args.controller,
                                 sessions_dir=Path(sessions))  # fmt: skip
        controls = bare_controls(config.sim_config()) if speeds else None
        dashboard = Dashboard(config, verbose=False).start()
        try:
            if args.workbench:
                enable_workbench(dashboard)
            sides: dict[str, object] = {}
            for n in cases:
                sides[f"clients {n}"] = lambda n=n: measure(dashboard, n, args.settle, args.seconds)
            for speed in speeds:
                sides[f"speed {speed}"] = lambda v=speed: at_speed(dashboard, v, args, record=False)
                if args.record:
                    sides[f"speed {speed} rec"] = lambda v=speed: at_speed(dashboard, v, args, record=True)
            if speeds:
                sides["bare"] = lambda: bare_round(dashboard, config.sim_config(), controls, args.seconds)
            start = (dashboard.sim.state().x, time.perf_counter())
            rounds = interleaved(sides, args.rounds)
            end = (dashboard.sim.state().x, time.perf_counter(), dashboard.terrain.sent, dashboard.terrain.sent_bytes)
            kicked = sum(h.kicked for h in dashboard.sim.hops) if args.workbench else 0
        finally:
            dashboard.stop()

    print(f"{args.rounds} rounds, each case in turn in every round (medians; range in brackets); machine shared")
    if cases:
        report([merged(rounds[f"clients {n}"]) for n in cases], args.seconds, args.speed)
        if speeds:  # the robot's travel over the run includes the fast-forwarded rounds
            print("\nterrain over the long run: not measured with --speeds (run the client cases alone)")
        else:
            long_run(start, end, dashboard.sim.config.craters.tile, [merged(rounds[f"clients {n}"]) for n in cases])
        base = [r["rtf"] for r in rounds[f"clients {cases[0]}"]]
        for n in cases[1:]:
            print(f"RTF {n} clients / {cases[0]} clients: {ratio([r['rtf'] for r in rounds[f'clients {n}']], base)}")
    if args.workbench:
        print(f"workbench on: {kicked} hops kicked by the schedule since the last reset, overlays and history on")
    if speeds:
        report_speeds(rounds, speeds, args.speed_clients, args.record)


def bare_controls(config) -> np.ndarray:
    """The controls of a 3-hop closed loop of the dashboard's configuration, to replay with bare mj_step."""
    recorder = ControlRecorder()
    closed_loop(config, 3, (recorder,))
    return np.array(recorder.ctrl)


def bare_round(dashboard, config, controls: np.ndarray, seconds: float) -> dict:
    """Bare mj_step's rate (steps/s) on the same model in this process over about `seconds` of stepping
    (as long as the other sides' windows, or a moment's load weighs more on it), the dashboard paused."""
    dashboard.set_paused(True)
    while not dashboard.pacer.paused:
        time.sleep(0.01)
    steps, stepping = 0, 0.0
    try:
        while stepping < seconds:
            rate, _ = raw_replay(config, controls)
            steps, stepping = steps + len(controls), stepping + len(controls) / rate
    finally:
        dashboard.set_paused(False)
    return {"rate": steps / stepping}


def at_speed(dashboard, speed: float, args: argparse.Namespace, record: bool) -> dict:
    """The delivered speed at `speed` (MAX: as fast as it goes), with a recording on if `record`.

    The speed goes back to --speed after: the client cases of the next round are measured at it.
    """
    dashboard.set_speed(speed)
    if record:
        dashboard.recorder.start()
        while not dashboard.recorder.progress()[1]:  # its first bytes on disk
            time.sleep(0.05)
    try:
        return measure(dashboard, args.speed_clients, args.settle, args.seconds)
    finally:
        if record:
            dashboard.recorder.stop()
            while dashboard.recorder.active:
                time.sleep(0.05)
        dashboard.set_speed(args.speed)


def merged(results: list[dict]) -> dict:
    """One case's rounds as one: median figures, every round's clients."""
    out = {k: statistics.median(r[k] for r in results) for k in ("rtf", "server_frames_per_s", "delivered", "cpu")}
    return {**out, "clients": results[0]["clients"], "per_client": [c for r in results for c in r["per_client"]]}


def enable_workbench(dashboard) -> None:
    """A repeatable test on every hop (a small pitch kick 0.2 s after liftoff); overlays and history are on."""
    from hopper.commands import SetSchedule
    from hopper.schedule import KickSchedule

    dashboard.sim.submit(SetSchedule(KickSchedule("pitch_kick", 0.3, delay_s=0.2, every=1)))
    assert dashboard.physics.visible


def report_speeds(rounds: dict[str, list], speeds: list[float], clients: int, record: bool) -> None:
    """Per speed: delivered (x real time), its ratio to the asked one or, at Max, in steps/s against bare
    mj_step's rate of the same round; with a recording, its data rate and what it costs in CPU."""
    bare = [r["rate"] for r in rounds["bare"]]
    print(f"\nfast-forward with {clients} client(s); bare mj_step in this process: {spread(bare)} steps/s")
    print(f"{'asked':>6}  {'delivered':>24}  {'of asked / of bare':>30}  {'frames/s':>8}  {'CPU cores':>9}  "
          f"{'kB/s':>6}")  # fmt: skip
    for speed in speeds:
        for rec in (False, True) if record else (False,):
            runs = rounds[f"speed {speed}" + (" rec" if rec else "")]
            delivered = [r["delivered"] for r in runs]
            if speed == float("inf"):
                of = ratio([d / TIMESTEP for d in delivered], bare)  # steps/s over bare steps/s, round by round
                name, against = "max", f"{of} of bare"
            else:
                name, against = f"{speed:g}", f"{statistics.median(d / speed for d in delivered):.3f} of asked"
            per = [c for r in runs for c in r["per_client"]]
            kb = _mean(per, "bytes_per_s") / 1e3 if per else float("nan")
            print(f"{name + (' rec' if rec else ''):>6}  {spread(delivered, 1)}x  {against:>30}  "
                  f"{statistics.median(r['server_frames_per_s'] for r in runs):8.1f}  "
                  f"{statistics.median(r['cpu'] for r in runs):9.2f}  {kb:6.1f}")  # fmt: skip
            if rec:
                cpu = ratio([r["cpu"] for r in runs], [r["cpu"] for r in rounds[f"speed {speed}"]])
                on_disk = spread([r["recorded_kb_per_s"] for r in runs], 1)
                print(f"{'':>6}  recording: {on_disk} kB/s on disk; CPU with / without: {cpu}")


def long_run(start: tuple, end: tuple, tile_m: float, results: list[dict]) -> None:
    """The terrain's share of the stream over a long run, which the windows cannot show: a tile is
    sent as the window moves, 15 m at a time (its first move 18 m out), so a run sends none for a
    minute or more and a window sends four or none. Each client receives every tile once: their
    bytes per metre of travel at the robot's speed over this run is what a long session averages."""
    (x0, t0), (x1, t1, sent, sent_bytes) = start, end
    speed = (x1 - x0) / (t1 - t0)  # m per wall s
    tile_kb = sent_bytes / max(sent, 1) / 1e3  # the mean tile, the start's included
    rate = tile_kb / tile_m * speed
    print(f"\nterrain over the long run: {tile_kb:.0f} kB a {tile_m:g} m tile, the robot at {speed:.3f} m/s: "
          f"{rate:.1f} kB/s a client")  # fmt: skip
    for r in results:
        if r["per_client"]:
            per = r["per_client"]
            rest = (_mean(per, "bytes_per_s") - _mean(per, "breakdown_bytes_per_s", "terrain")) / 1e3
            print(f"  {r['clients']} client(s): {rest:.1f} kB/s without tiles + {rate:.1f} = {rest + rate:.1f} kB/s")


def _mean(per: list[dict], key: str, sub: str | None = None) -> float:
    return sum(c[key][sub] if sub else c[key] for c in per) / len(per)


KINDS = ("charts", "poses", "other", "terrain")  # the probe's categories (app/dashboard/probe.py), in the table


def report(results: list[dict], seconds: float, speed: float) -> None:
    print(f"\nhopper-dashboard load, {seconds:g} s windows at {speed:g}x real time (target RTF >= 0.98)")
    print("RTF = simulated s per wall s over the asked speed (medians of the rounds); per client: means over")
    print("the clients and rounds")
    print(f"{'clients':>7}  {'RTF':>6}  {'server frames/s':>15}  {'updates/s':>9}  {'charts/s':>8}  {'kB/s':>6}  "
          f"{'charts':>6}  {'poses':>6}  {'other':>6}  {'tiles':>6}  {'initial kB':>10}")  # fmt: skip
    for r in results:
        per = r["per_client"]
        if per:
            kb = {k: _mean(per, "breakdown_bytes_per_s", k) / 1e3 for k in KINDS}
            cells = (
                f"{_mean(per, 'pose_updates_per_s'):9.1f}  {_mean(per, 'chart_refreshes_per_s'):8.1f}  "
                f"{_mean(per, 'bytes_per_s') / 1e3:6.1f}  "
                + "".join(f"{kb[k]:6.1f}  " for k in KINDS)
                + f"{_mean(per, 'initial_bytes') / 1e3:10.0f}"
            )
        else:
            cells = "  ".join(f"{'-':>{w}}" for w in (9, 8, 6, 6, 6, 6, 6, 10))
        print(f"{r['clients']:7d}  {r['rtf']:6.3f}  {r['server_frames_per_s']:15.1f}  {cells}")
    for r in results:
        if r["per_client"]:
            rates = {
                k: round(_mean(r["per_client"], "messages_per_s", k)) for k in ("charts", "poses", "other", "terrain")
            }
            print(f"messages/s per client with {r['clients']} clients: {rates}")
    base = results[0]["rtf"]
    ratios = ", ".join(f"{r['clients']} clients {r['rtf'] / base:.3f}" for r in results[1:])
    print(f"RTF ratio vs {results[0]['clients']} clients: {ratios}")


if __name__ == "__main__":
    main()
