"""A short soak (benchmarks.soak): recording with rollover and 2 clients at 1x; no error, every part verifies."""

from __future__ import annotations

from pathlib import Path

from benchmarks.soak import report, run_soak

MINUTES = 0.35  # the full hour is `python -m benchmarks.soak`; this keeps the test under a minute


def test_short_soak_has_no_errors_and_every_part_verifies(tmp_path: Path) -> None:
    r = run_soak(MINUTES, tmp_path, warmup_min=MINUTES / 3, rrd_max_min=0.1, sample_s=1.0)
    print("\n" + report(r))  # memory growth is printed, not asserted: half a minute says little
    assert r["server_errors"] == 0 and r["server_log"] == [], r["server_log"]
    assert r["client_errors"] == [], r["client_errors"]
    assert r["loop_alive"] and r["steps"] > 0.5 * MINUTES * 60 * 1000 * 0.5  # at least half speed
    assert len(r["parts"]) >= 3, "0.1 min parts over half a minute: rollover did not happen"
    assert all(good for _, _, good, _ in r["parts"]), r["parts"]
    assert len(r["updates_per_s"]) == 2 and min(r["updates_per_s"]) > 5, r["updates_per_s"]
