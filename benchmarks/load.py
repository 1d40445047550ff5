"""Dashboard load: 16 clients connecting and leaving at random for N minutes at 1x.

Run: python -m benchmarks.load [--minutes 10] [--clients 16] [--stay 4] [--speed 1] [--seed 0]

The server runs in this process; `--stay` of the client slots keep one connection for the whole
run, the others connect, stay 2 to 20 s and leave, again and again (benchmarks.harness), from two
child processes. Printed, all measured in this one run: the real-time factor (overall and the worst
10 s window), errors logged by the server (log records at ERROR, thread exceptions, tracebacks on
stderr) and on the clients' side, and scene updates per second per client that stays (and per
session of those that come and go). Targets: RTF >= 0.99, no error, >= 29 updates/s per staying client.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from benchmarks.harness import ErrorLog, RtfSampler, collect, free_port, spawn_clients  # noqa: E402

SETTLE_S = 5.0  # s after the start before staying clients are measured (initial scenes, warm-up)
PROCESSES = 2  # client processes (decoding 16 streams in one Python process would measure the GIL)


def run_load(minutes: float, clients: int = 16, stay: int = 4, speed: float = 1.0, seed: int = 0) -> dict[str, Any]:
    from hopper.app.dashboard.config import DashboardConfig
    from hopper.app.dashboard.server import Dashboard

    errors = ErrorLog().install()
    seconds = minutes * 60.0
    dashboard = Dashboard(DashboardConfig(port=free_port(), speed=speed), verbose=False).start()
    try:
        slots = [{"index": i, "stay": i < stay} for i in range(clients)]
        children = [
            spawn_clients(dashboard.url, slots[k::PROCESSES], seconds, SETTLE_S, seed) for k in range(PROCESSES)
        ]
        time.sleep(SETTLE_S)
        sampler = RtfSampler(dashboard).start()
        frames0, t0 = dashboard.frames, time.perf_counter()
        result = collect(children, timeout=seconds + 120)
        frames_per_s = (dashboard.frames - frames0) / (time.perf_counter() - t0)
        sampler.stop()
        alive = dashboard._thread.is_alive()
    finally:
        dashboard.stop()
        errors.uninstall()
    rtf, worst = sampler.rtf(window_s=10.0)
    stayers = [s["updates_per_s"] for s in result["sessions"] if s["stay"]]
    churn = [s["updates_per_s"] for s in result["sessions"] if not s["stay"]]
    return {
        "minutes": minutes,
        "clients": clients,
        "stay": stay,
        "speed": speed,
        "rtf": rtf,
        "rtf_worst_10s": worst,
        "loop_alive": alive,
        "server_frames_per_s": frames_per_s,
        "server_errors": errors.errors + errors.tracebacks,
        "server_log": errors.records,
        "client_errors": result["errors"],
        "stayer_updates_per_s": stayers,
        "churn_sessions": len(churn),
        "churn_updates_per_s_median": statistics.median(churn) if churn else float("nan"),
        "churn_updates_per_s_min": min(churn) if churn else float("nan"),
    }


def report(r: dict[str, Any]) -> str:
    stay = r["stayer_updates_per_s"]
    lines = [
        f"hopper-dashboard load: {r['clients']} clients ({r['stay']} staying, the rest coming and going) "
        f"for {r['minutes']:g} min at {r['speed']:g}x",
        f"RTF {r['rtf']:.3f} overall, worst 10 s window {r['rtf_worst_10s']:.3f} (target >= 0.99); "
        f"scene frames published {r['server_frames_per_s']:.1f}/s; loop alive: {r['loop_alive']}",
        f"errors: server {r['server_errors']}, clients {len(r['client_errors'])} (target 0); "
        f"server log lines at WARNING+: {len(r['server_log'])}",
        "scene updates/s per staying client: "
        + (f"min {min(stay):.1f}, mean {statistics.fmean(stay):.1f} (target >= 29)" if stay else "none measured"),
        f"sessions of leaving clients: {r['churn_sessions']}, updates/s median {r['churn_updates_per_s_median']:.1f}, "
        f"min {r['churn_updates_per_s_min']:.1f}",
    ]
    lines += [f"  server: {line}" for line in r["server_log"][:5]]
    lines += [f"  client: {line}" for line in r["client_errors"][:5]]
    met = r["rtf"] >= 0.99 and not r["server_errors"] and not r["client_errors"] and stay and min(stay) >= 29
    lines.append(f"targets met: {'yes' if met else 'NO'}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="duration (min)")
    parser.add_argument("--clients", type=int, default=16, help="client slots")
    parser.add_argument("--stay", type=int, default=4, help="slots that stay connected the whole run")
    parser.add_argument("--speed", type=float, default=1.0, help="simulation speed (x real time)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the comings and goings")
    args = parser.parse_args()
    print(report(run_load(args.minutes, args.clients, args.stay, args.speed, args.seed)))


if __name__ == "__main__":
    main()
