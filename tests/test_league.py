"""`hopper-sim league` with a controller that faults in some episodes, or in all: the flight figures are its own."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_sim_cli import PICKY

from hopper.report.league import league_report

pytestmark = pytest.mark.integration  # subprocesses

SOME, EVERY = "some.py:Picky", "every.py:Picky"


def hopper_sim(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=600, cwd=cwd
    )


def flight_figures(runs: list[dict]) -> dict[str, float]:
    """The league's flight figures over `runs` (the JSON's), computed here from their hops."""
    hops = [h for r in runs for h in r["hops"]]
    landing = [abs(h["landing_pitch_deg"]) for h in hops if h["completed"]]
    return {
        "landing_p50_deg": float(np.percentile(landing, 50)),
        "landing_max_deg": max(landing),
        "peak_pitch_deg": max(h["peak_pitch_deg"] for h in hops),
        "rms_rate_deg_s": float(np.mean([h["rms_pitch_rate_deg_s"] for h in hops])),
        "energy_j": float(np.mean([h["wheel_energy_j"] + h["leg_energy_j"] for h in hops if h["completed"]])),
    }


def test_the_flight_figures_leave_out_the_episodes_whose_controller_faulted(tmp_path: Path) -> None:
    """The landing, peak pitch, RMS rate, energy and saturation took every episode's hops, the faulted ones
    too, whose flights after the fault are the PID's (and here the faulting law's 5 deg tip): a
    controller's row was mostly the PID's. Picky faults from seed 1 (the battery's seed 0 alone flies
    to the end) or, in every.py, from seed 0 (every episode)."""
    (tmp_path / "some.py").write_text(PICKY)
    (tmp_path / "every.py").write_text(PICKY.replace('Param("bad", 1.0', 'Param("bad", 0.0'))
    out = tmp_path / "league.json"
    result = hopper_sim("league", "--quick", "--controllers", f"{SOME},{EVERY}", "--workers", "2", "--json",
                        str(out), cwd=tmp_path)  # fmt: skip
    assert result.returncode == 4, result.stderr  # finished, but a controller faulted: as compare and sweep
    document = json.loads(out.read_text())
    rows = {r["controller"].rpartition("/")[2]: r for r in document["rows"]}
    runs = [r for r in document["runs"] if r["settings"]["controller"].endswith(SOME)]
    flown = [r for r in runs if not r["fault"]]
    assert [r["settings"]["seed"] for r in flown] == [0] and len(runs) == rows[SOME]["episodes"] > 10

    some, every = rows[SOME], rows[EVERY]
    said = ", ".join(f"{r['controller']} in {r['faults']} of {r['episodes']}" for r in (some, every))
    assert result.stderr.splitlines()[-1] == f"hopper-sim: error: a controller failed mid-episode and the PID flew " \
        f"on from there: {said}", result.stderr  # fmt: skip
    for key, value in flight_figures(flown).items():
        assert some[key] == pytest.approx(value), key
    assert flight_figures(runs)["peak_pitch_deg"] > some["peak_pitch_deg"] + 2  # the faulted ones' would move it
    figures = ("landing_p50_deg", "landing_p95_deg", "landing_max_deg", "peak_pitch_deg", "rms_rate_deg_s",
               "energy_j", "saturation_s")  # fmt: skip
    assert all(every[key] is None for key in figures)  # JSON null, not NaN nor the PID's figures
    assert (some["faults"], some["flown"], some["success_pct"]) == (len(runs) - 1, 1, pytest.approx(100 / len(runs)))
    assert every["flown"] == 0 and every["faults"] == every["episodes"]

    lines = {line.split()[0].rpartition("/")[2]: line for line in result.stdout.splitlines()}
    assert lines[EVERY].split()[1:9] == ["0.00"] + ["faulted"] * 7, lines[EVERY]
    assert f"{some['peak_pitch_deg']:.2f}" in lines[SOME].split()
    assert f"{SOME}: 0 fell, {some['faults']} controller faults (left out of the figures from land p50 to sat s: " \
           "the PID flew on from each fault); e.g. " in result.stdout  # fmt: skip
    assert f"{EVERY}: 0 fell, {every['faults']} controller faults (every episode, so no figure from land p50 to " \
           "sat s is its own: the PID flew on from each fault); e.g. " in result.stdout  # fmt: skip

    report = league_report(document, "league")
    (section,) = report.tables
    cells = {r[0]: r for r in section.rows}
    assert cells[EVERY][4:11] == ["every episode faulted"] * 7 and cells[SOME][7] == some["peak_pitch_deg"]
    assert (f"leave out the episodes with a controller fault (the PID flew on from each; they count as failed): "
            f"{SOME} {some['faults']} of {some['episodes']}, {EVERY} {every['faults']} of {every['episodes']}.") \
        in section.note  # fmt: skip
    for row in document["rows"]:  # a league JSON from before: its figures took the faulted episodes in
        del row["flown"]
    (older,) = league_report(document, "league").tables
    assert "include their faulted episodes" in older.note and "leave out" not in older.note
