"""Soak: the dashboard at 1x for an hour, recording with rollover, 2 clients: memory growth and every file verified.

Run: python -m benchmarks.soak [--minutes 60] [--warmup 5] [--rrd-max-min 5] [--clients 2] [--out DIR]

The server runs in this process, recording to DIR/soak.rrd in numbered parts (rollover on); the
clients stay connected from a child process (benchmarks.harness). Printed, all measured in this
one run: resident memory (RSS) of this process after the warm-up and at the end, and its growth
(target < 5 %), the RTF, errors logged, scene updates per second per client, and `rerun rrd
verify` of every part (target: all verify).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from benchmarks.harness import ErrorLog, RtfSampler, collect, free_port, spawn_clients  # noqa: E402


def verify(path: Path) -> tuple[bool, str]:
    """`rerun rrd verify` with the CLI binary itself (`python -m rerun_cli` always exits 0)."""
    import rerun_cli

    binary = os.path.join(os.path.dirname(rerun_cli.__file__), "rerun")
    done = subprocess.run([binary, "rrd", "verify", str(path)], capture_output=True, text=True, timeout=600)
    out = (done.stdout + done.stderr).strip()
    # The summary names the count: a file it could not read at all gives "0 files verified" and exit 0.
    ok = done.returncode == 0 and "1 file verified without error" in out
    return ok, out.splitlines()[-1] if out else ""


def run_soak(
    minutes: float,
    out: Path,
    *,
    warmup_min: float | None = None,
    rrd_max_min: float | None = 5.0,
    rrd_max_mb: float | None = None,
    clients: int = 2,
    speed: float = 1.0,
    sample_s: float = 5.0,
) -> dict[str, Any]:
    import psutil
    from hopper.app.dashboard.config import DashboardConfig
    from hopper.app.dashboard.server import Dashboard

    warmup_s = (warmup_min if warmup_min is not None else min(5.0, minutes / 3)) * 60.0
    seconds = minutes * 60.0
    errors = ErrorLog().install()
    process = psutil.Process()
    rss: list[tuple[float, int]] = []
    config = DashboardConfig(
        port=free_port(), speed=speed, rrd=out / "soak.rrd", rrd_max_min=rrd_max_min, rrd_max_mb=rrd_max_mb,
        sessions_dir=out / "sessions",
    )  # fmt: skip
    dashboard = Dashboard(config, verbose=False).start()
    start = time.perf_counter()
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            rss.append((time.perf_counter() - start, process.memory_info().rss))
            stop.wait(sample_s)

    sampler_thread = threading.Thread(target=sample, name="rss", daemon=True)
    sampler_thread.start()
    try:
        slots = [{"index": i, "stay": True} for i in range(clients)]
        child = spawn_clients(dashboard.url, slots, seconds, min(warmup_s, 5.0), seed=0)
        rtf = RtfSampler(dashboard).start()
        result = collect([child], timeout=seconds + 120)
        rtf.stop()
        alive = dashboard._thread.is_alive()
        steps = dashboard.pacer._steps
        telemetry = dashboard.recorder._telemetry
        parts = list(telemetry.parts) if telemetry else []
        switches = list(telemetry.switch_s) if telemetry else []
    finally:
        stop.set()
        sampler_thread.join()
        rss.append((time.perf_counter() - start, process.memory_info().rss))
        dashboard.stop()
        errors.uninstall()
    parts = parts or sorted(out.glob("soak*.rrd"))
    verified = [(p.name, p.stat().st_size, *verify(p)) for p in parts]
    after_warmup = next((r for t, r in rss if t >= warmup_s), rss[-1][1])
    overall, worst = rtf.rtf(window_s=10.0)
    return {
        "minutes": minutes,
        "warmup_min": warmup_s / 60,
        "speed": speed,
        "rss_after_warmup_mb": after_warmup / 1e6,
        "rss_end_mb": rss[-1][1] / 1e6,
        "rss_max_mb": max(r for _, r in rss) / 1e6,
        "rss_growth_pct": 100.0 * (rss[-1][1] - after_warmup) / after_warmup,
        "rtf": overall,
        "rtf_worst_10s": worst,
        "loop_alive": alive,
        "steps": steps,
        "server_errors": errors.errors + errors.tracebacks,
        "server_log": errors.records,
        "client_errors": result["errors"],
        "updates_per_s": [s["updates_per_s"] for s in result["sessions"]],
        "parts": verified,
        "rollover_ms_max": 1e3 * max(switches, default=0.0),
        "rollover_ms_mean": 1e3 * sum(switches) / len(switches) if switches else 0.0,
        "rss_by_minute_mb": [r / 1e6 for t, r in rss if int(t / 60) != int((t - sample_s) / 60)],
    }


def report(r: dict[str, Any]) -> str:
    ok = [p for p in r["parts"] if p[2]]
    lines = [
        f"hopper-dashboard soak: {r['minutes']:g} min at {r['speed']:g}x, recording with rollover, "
        f"{len(r['updates_per_s'])} clients",
        f"RSS {r['rss_after_warmup_mb']:.1f} MB after the {r['warmup_min']:g} min warm-up, {r['rss_end_mb']:.1f} MB "
        f"at the end (max {r['rss_max_mb']:.1f}): growth {r['rss_growth_pct']:+.2f} % (target < 5 %)",
        "RSS at each minute (MB): " + " ".join(f"{m:.0f}" for m in r["rss_by_minute_mb"]),
        f"RTF {r['rtf']:.3f} overall, worst 10 s window {r['rtf_worst_10s']:.3f}; loop alive: {r['loop_alive']}",
        f"errors: server {r['server_errors']}, clients {len(r['client_errors'])} (target 0)",
        "scene updates/s per client: " + ", ".join(f"{u:.1f}" for u in r["updates_per_s"]),
        f"recorded parts: {len(r['parts'])}, verified with `rerun rrd verify`: {len(ok)} (target: all), "
        f"{sum(p[1] for p in r['parts']) / 1e6:.1f} MB in all; each rollover held the loop "
        f"{r['rollover_ms_mean']:.0f} ms on average, {r['rollover_ms_max']:.0f} ms at most",
    ]
    lines += [
        f"  {name}: {size / 1e6:.2f} MB: {'ok' if good else 'FAILED ' + msg}" for name, size, good, msg in r["parts"]
    ]
    lines += [f"  server: {line}" for line in r["server_log"][:5]]
    lines += [f"  client: {line}" for line in r["client_errors"][:5]]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="duration (min)")
    parser.add_argument("--warmup", type=float, help="minutes before memory is compared (default 5, or a third)")
    parser.add_argument("--rrd-max-min", type=float, default=5.0, help="minutes of simulation per recorded part")
    parser.add_argument("--rrd-max-mb", type=float, help="MB per recorded part (instead of, or with, minutes)")
    parser.add_argument("--clients", type=int, default=2, help="clients connected the whole run")
    parser.add_argument("--speed", type=float, default=1.0, help="simulation speed (x real time)")
    parser.add_argument("--out", type=Path, help="folder for the recordings (default: a new temporary one)")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="hopper-soak-"))
    out.mkdir(parents=True, exist_ok=True)
    r = run_soak(
        args.minutes, out, warmup_min=args.warmup, rrd_max_min=args.rrd_max_min, rrd_max_mb=args.rrd_max_mb,
        clients=args.clients, speed=args.speed,
    )  # fmt: skip
    print(report(r))
    print(f"recordings in {out}")
    if r["server_errors"] or r["client_errors"] or not all(p[2] for p in r["parts"]):
        sys.exit(1)


if __name__ == "__main__":
    main()
