"""Import time and peak memory of a 1-hour hopper log (3.6 M samples at 1 kHz) in each format.

Run: python -m benchmarks.log_import [--seconds 3600] [--rounds 3] [--dir DIR]

Writes one synthetic log (hopper.logs.synthetic, every column of the schema: 22 float64 columns)
as CSV and as MCAP, then imports each with hopper.logs.io.read_log in a fresh child process, so
every import starts with an empty heap: the child reports its wall time and its peak RSS
(VmHWM), beside the size of the Log's own arrays (the floor any reader must reach).
Formats alternate (CSV, MCAP, CSV, MCAP, ...) over the rounds; the median and spread are printed.
The target (issue 21): under 30 s each. On a shared machine the times are upper bounds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Peak RSS is the child's VmHWM: getrusage's ru_maxrss survives exec, so a child would report the
# parent's high-water mark from before it forked (the 634 MB log it wrote) when that is higher.
HWM = "int(next(l for l in open('/proc/self/status') if l.startswith('VmHWM')).split()[1]) * 1024"
CHILD = """
import json, sys, time
t0 = time.perf_counter()
from hopper.logs.io import read_log
log = read_log(sys.argv[1])
seconds = time.perf_counter() - t0
peak = HWM
data = log.time.nbytes + sum(v.nbytes for v in log.signals.values())
print(json.dumps({"s": seconds, "peak": peak, "data": data, "n": len(log.time), "columns": 1 + len(log.signals)}))
""".replace("HWM", HWM)
BASELINE = f"import hopper.logs.io; print({HWM})"


def _child(code: str, *args: str) -> str:
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, check=False)
    if done.returncode:
        raise SystemExit(f"log_import: the child failed: {done.stderr.strip().splitlines()[-1:]}")
    return done.stdout.strip()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.log_import", description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3600.0, help="log length at 1 kHz (default 3600)")
    parser.add_argument("--rounds", type=int, default=3, help="imports of each format, alternated (default 3)")
    parser.add_argument("--dir", type=Path, help="where to write the logs (default: a temporary folder)")
    parser.add_argument("--formats", default=".csv,.mcap", help="suffixes to measure (default .csv,.mcap)")
    args = parser.parse_args(argv)
    from hopper.logs.io import write_log
    from hopper.logs.synthetic import synthetic_log

    with tempfile.TemporaryDirectory(dir=args.dir) as folder:
        log = synthetic_log(args.seconds, seed=0)
        paths = {}
        for suffix in args.formats.split(","):
            t0 = time.perf_counter()
            paths[suffix] = write_log(log, Path(folder) / f"log{suffix}")
            size = paths[suffix].stat().st_size / 1e6
            print(f"wrote {suffix}: {size:.0f} MB in {time.perf_counter() - t0:.1f} s", flush=True)
        del log
        baseline = int(_child(BASELINE))
        runs: dict[str, list[dict]] = {s: [] for s in paths}
        for r in range(args.rounds):
            for suffix, path in paths.items():
                runs[suffix].append(json.loads(_child(CHILD, str(path))))
                last = runs[suffix][-1]
                print(f"round {r + 1} {suffix}: {last['s']:.2f} s, peak RSS {last['peak'] / 1e6:.0f} MB", flush=True)
    print(f"python + hopper.logs imported: peak RSS {baseline / 1e6:.0f} MB")
    for suffix, rows in runs.items():
        seconds = [row["s"] for row in rows]
        peaks = [row["peak"] / 1e6 for row in rows]
        data = rows[0]["data"] / 1e6
        print(
            f"{suffix}: {rows[0]['n']:,} samples x {rows[0]['columns']} columns;"
            f" import median {statistics.median(seconds):.2f} s"
            f" (min {min(seconds):.2f}, max {max(seconds):.2f}); peak RSS median {statistics.median(peaks):.0f} MB"
            f" (max {max(peaks):.0f}) for {data:.0f} MB of arrays: {statistics.median(peaks) / data:.2f}x the data"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
