"""`hopper-sim report`: the paper's figures from a run's JSON, a comparison, a .rrd and a sweep's Parquet,
all from real simulated episodes; PNG, PDF and one self-contained HTML page."""

from __future__ import annotations

import argparse
import base64
import dataclasses
import io
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pyarrow.dataset as ds
import pytest
from hopper.app import report_cli
from hopper.app.sim_cli import simulate
from in_process import cli, tree
from PIL import Image
from sweep_data import write_sweep

from hopper.config import SimConfig
from hopper.report import build, page
from hopper.report.rrd import read_run
from hopper.report.runs import run_from_result
from hopper.report.sweep import LANDING_LIMIT_DEG, Sweep, gain_map, load, sweep_report
from hopper.sim import Simulation
from hopper.telemetry import Telemetry
from hopper.trace import TRACE_COLUMNS, TraceRecorder

RUN_FIGURES = ("translation", "pitch_wheel", "wheel_torque", "hop_metrics", "saturation")
UNIT = re.compile(r"\(.+\)")  # an axis label names its unit in parentheses


def hopper_sim(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


def args(**overrides: object) -> argparse.Namespace:
    return argparse.Namespace(**{"seed": None, "no_simulate": False, **overrides})


@pytest.fixture(scope="module")
def run_json(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real 2-hop run on crater seed 0, as `hopper-sim run --json` writes it."""
    path = tmp_path_factory.mktemp("run") / "run.json"
    path.write_text(json.dumps(simulate(SimConfig(seed=0), 2)))
    return path


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real 2 x 2 Kp x Kd sweep at two gravities, with and without a 1.8 N m s flight kick."""
    return write_sweep(tmp_path_factory.mktemp("sweep") / "out", kps=(100.0, 900.0), kds=(5.0, 40.0),
                       gravities=(1.625, 3.72), kicks=(0.0, 1.8))  # fmt: skip


def test_the_trace_is_the_run_the_hop_table_describes(run_json: Path) -> None:
    result = json.loads(run_json.read_text())
    trace = result["trace"]
    assert list(trace) == ["hz", *TRACE_COLUMNS] and trace["hz"] == 100.0
    t = np.array(trace["t_s"])
    assert np.allclose(np.diff(t), 0.01) and abs(t[-1] - result["sim_time_s"]) <= 0.01
    pitch, x = np.array(trace["pitch_deg"]), np.array(trace["x_m"])
    for hop in result["hops"]:
        up, down = hop["touchdown_time_s"] - hop["flight_time_s"], hop["touchdown_time_s"]
        flight = (t > up) & (t <= down)
        inside = (t > up + 0.015) & (t < down - 0.015)  # a sample is the state after its tick
        assert set(np.array(trace["phase"])[inside]) == {"flight"}
        # The 1 kHz peak bounds the 100 Hz samples, which come within a sample's motion of it.
        sampled = np.abs(pitch[flight]).max()
        assert sampled <= hop["peak_pitch_deg"] + 1e-3 and sampled >= 0.7 * hop["peak_pitch_deg"]
    first, second = result["hops"]
    travelled = np.interp(second["touchdown_time_s"], t, x) - np.interp(first["touchdown_time_s"], t, x)
    assert travelled == pytest.approx(second["distance_m"], abs=0.01)


def test_report_of_a_run_json_writes_png_pdf_and_one_self_contained_page(run_json: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    result = hopper_sim("report", str(run_json), "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert "simulating seed 0, wheel off" in result.stderr  # the paper's comparison needs the wheel-off twin
    for name in RUN_FIGURES:
        with Image.open(out / f"{name}.png") as image:
            assert image.width >= 1000 and image.height >= 300
        assert (out / f"{name}.pdf").read_bytes().startswith(b"%PDF")
    html = (out / "report.html").read_text()
    assert not re.search(r"""(src|href)=["']?(https?:|//|file:)""", html), "the page must need nothing else"
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    assert len(images) == len(RUN_FIGURES)
    for data in images:
        with Image.open(io.BytesIO(base64.b64decode(data))) as image:
            image.verify()
    for setting in ("gains.kp", "gains.kd", "gravity", "terrain", "seed", "gait.sweep_angle", "scenario"):
        assert f">{setting}<" in html, setting


def test_the_run_report_compares_wheel_on_with_the_simulated_wheel_off_twin(run_json: Path) -> None:
    report = report_cli._json_report(run_json, args())
    try:
        assert [n.name for n in report.figures] == list(RUN_FIGURES)
        # Every axis that holds data names its quantity and unit.
        for named in report.figures:
            for ax in named.figure.axes:
                if ax.lines or ax.patches or ax.images:
                    assert UNIT.search(ax.get_ylabel()), (named.name, ax.get_ylabel())
                    if ax.get_xlabel():
                        assert UNIT.search(ax.get_xlabel()) or ax.get_xlabel() == "hop", ax.get_xlabel()
        pitch = report.figures[1].figure.axes[1]  # wheel on vs off, below the pitch and rpm plot
        on, off = (np.abs(line.get_ydata()).max() for line in pitch.lines[:2])
        assert off > 45.0 and on < 2.0  # with the wheel off the torso tumbles to the fall limit
    finally:
        for named in report.figures:
            build.style.close(named.figure)


def test_a_compare_json_gets_a_per_seed_table_with_the_reduction(run_json: Path, tmp_path: Path) -> None:
    on = json.loads(run_json.read_text())
    off = simulate(SimConfig(seed=0, wheel=False), 2)
    path = tmp_path / "compare.json"
    path.write_text(json.dumps({"median_peak_reduction_pct": 0.0, "seeds": [], "runs": [on, off]}))
    report = report_cli._json_report(path, args())
    for named in report.figures:
        build.style.close(named.figure)
    table = next(t for t in report.tables if t.title.startswith("Per seed"))
    (row,) = table.rows
    peak_on = max(h["peak_pitch_deg"] for h in on["hops"])
    peak_off = max(h["peak_pitch_deg"] for h in off["hops"])
    assert row[0] == 0 and row[2] == peak_on and row[7] == peak_off
    assert row[8] == pytest.approx(100 * (peak_off - peak_on) / peak_off) and row[8] > 65.0


def test_a_json_without_a_trace_is_simulated_again_for_it(run_json: Path, tmp_path: Path) -> None:
    old = json.loads(run_json.read_text())
    del old["trace"]  # as hopper-sim wrote it before the report existed
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old))
    report = report_cli._json_report(path, args())
    for named in report.figures:
        build.style.close(named.figure)
    assert report.subtitle.startswith("run JSON, re-simulated for its trace")
    fresh = run_from_result(json.loads(run_json.read_text()), "run JSON")
    assert [r[4] for r in report.tables[0].rows] == [h["peak_pitch_deg"] for h in fresh.hops]  # deterministic


def test_a_recording_read_back_with_rerun_gives_the_same_series(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    sim = Simulation(SimConfig(terrain="flat"))
    direct = TraceRecorder(sim.config.timestep)
    sim.listeners.append(direct)
    with Telemetry(sim, path=tmp_path / "run.rrd"):
        sim.run(2)
    run = read_run(tmp_path / "run.rrd")
    assert run.wheel and not run.fell and run.settings["terrain"] == "flat" and run.settings["gains"]["kp"] == 450.0
    assert [h["index"] for h in run.hops] == [1, 2]
    for mine, hop in zip(run.hops, sim.hops, strict=True):
        assert mine["peak_pitch_deg"] == pytest.approx(hop.peak_pitch_deg, abs=0.005)  # the table rounds
    # The recording's rows are the state at the start of each tick, the trace's the state after it:
    # compare at the same times.
    t = np.array(direct.columns["t_s"])
    for name in ("pitch_deg", "wheel_rpm", "x_m", "z_m"):
        mine = np.interp(t, run.trace["t_s"], run.trace[name])
        theirs = np.array(direct.columns[name])
        inside = t <= run.trace["t_s"][-1]
        scale = max(np.abs(theirs).max(), 1e-6)
        assert np.abs(mine[inside] - theirs[inside]).max() < 0.02 * scale, name
    assert set(run.trace["phase"]) >= {"stance", "crouch", "push", "flight", "landing"}
    out = tmp_path / "rrd-report"
    code, _, err = cli(capsys, "report", str(tmp_path / "run.rrd"), "--out", str(out))
    assert code == 0, err
    assert all((out / f"{name}.png").is_file() for name in RUN_FIGURES)


def test_a_sweep_report_maps_the_gains_and_the_success_rates(sweep_dir: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    sweep = load(sweep_dir)
    episodes = ds.dataset(sweep_dir / "episodes").to_table().to_pylist()
    assert sweep.episodes.num_rows == len(episodes) == 16 and sweep.hops is not None and "kp" in sweep.spec
    ok = [e for e in episodes if not e["fell"] and e["hops_completed"] >= e["hops_target"]
          and e["worst_landing_deg"] <= LANDING_LIMIT_DEG]  # fmt: skip
    assert int(sweep.success().sum()) == len(ok)
    assert 0 < len(ok) < len(episodes), "the test sweep must hold both outcomes"
    fig = gain_map(sweep)
    ax = fig.axes[0]
    cells = np.ma.filled(ax.images[0].get_array(), np.nan)
    for e in episodes:  # each cell holds the worst landing over its episodes
        j, i = [100.0, 900.0].index(e["kp"]), [5.0, 40.0].index(e["kd"])
        same = [x["worst_landing_deg"] for x in episodes if x["kp"] == e["kp"] and x["kd"] == e["kd"]]
        assert cells[i, j] == pytest.approx(np.nanmax(same))
    marked = sum("fell" in t.get_text() for t in ax.texts)
    assert marked == len({(e["kp"], e["kd"]) for e in episodes if e["fell"]})
    build.style.close(fig)
    report = sweep_report(sweep, "t")
    names = [n.name for n in report.figures]
    assert names == ["gain_map_wheel_on", "success_vs_gravity", "success_vs_disturbance_size"]
    for named in report.figures:
        build.style.close(named.figure)
    rates = {(r[0], r[1]): r[3] for r in report.tables[0].rows}
    for size in (0.0, 1.8):
        chosen = [e for e in episodes if e["disturbance_size"] == size]
        assert rates[("disturbance_size", size)] == pytest.approx(100 * sum(e in ok for e in chosen) / len(chosen))
    out = tmp_path / "sweep-report"
    code, _, err = cli(capsys, "report", str(sweep_dir), "--out", str(out))
    assert code == 0, err
    assert {p.name for p in out.glob("*.png")} == {f"{n}.png" for n in names}
    assert "spec.toml" in (out / "report.html").read_text()
    part = sorted((sweep_dir / "episodes").glob("*.parquet"))[0]  # one part file is a sweep too
    assert load(part).episodes.num_rows == len(ds.dataset(part).to_table())


def test_success_against_disturbance_gives_each_kind_its_own_panel_and_unit(tmp_path: Path) -> None:
    """A push (N s) and a kick (N m s) share no axis: one panel each, labelled in its unit, the
    undisturbed episodes the size 0 of both; a kind not recorded says so instead of guessing a unit."""
    import pyarrow as pa

    when = " at stance +0.1 s of hop 2"
    texts = ["", f"push_forward +4 N s{when}", f"push_forward +8 N s{when}", f"pitch_kick +0.5 N m s{when}",
             f"pitch_kick +3 N m s{when}"]  # fmt: skip
    sizes, fell = [0.0, 4.0, 8.0, 0.5, 3.0], [False, False, True, False, True]
    n = len(texts)
    table = pa.table({
        "kp": [450.0] * n, "kd": [40.0] * n, "gravity": [1.625] * n, "wheel": [True] * n, "disturbance": texts,
        "disturbance_size": sizes, "hops_target": [3] * n, "hops_completed": [2 if f else 3 for f in fell],
        "fell": fell, "worst_landing_deg": [1.0] * n,
    })  # fmt: skip
    report = sweep_report(Sweep(table, None, None, tmp_path), "t")
    (named,) = [f for f in report.figures if f.name == "success_vs_disturbance_size"]
    axes = named.figure.axes
    assert [ax.get_xlabel() for ax in axes] == ["pitch_kick size (N m s); 0: undisturbed",
                                                "push_forward size (N s); 0: undisturbed"]  # fmt: skip
    kick, push = (ax.lines[0].get_xydata().tolist() for ax in axes)
    assert kick == [[0.0, 100.0], [0.5, 100.0], [3.0, 0.0]] and push == [[0.0, 100.0], [4.0, 100.0], [8.0, 0.0]]
    for f in report.figures:
        build.style.close(f.figure)
    unknown = Sweep(table.set_column(4, "disturbance", pa.array(["", "a kick", "a kick", "a kick", "a kick"])),
                    None, None, tmp_path)  # fmt: skip
    (named,) = [f for f in sweep_report(unknown, "t").figures if f.name == "success_vs_disturbance_size"]
    assert [ax.get_xlabel() for ax in named.figure.axes] == ["disturbance size (kind and unit not recorded)"]
    build.style.close(named.figure)


def drawn_episodes(fault: list[str], applied: list[bool] | None = None, size: list[float] | None = None):  # noqa: ANN201
    """Episodes of two robots drawn (friction, mass_torso) per controller, every hop done and landed well:
    only `fault` (a controller fault's cause, "" for none) and `applied` (the disturbance happened) differ."""
    import pyarrow as pa

    n = len(fault)
    size = size or [0.0] * n
    return pa.table({
        "episode_id": [f"e{i}" for i in range(n)], "kp": [450.0] * n, "ki": [50.0] * n, "kd": [30.0] * n,
        "gravity": [1.625] * n, "wheel": [True] * n,
        "disturbance": [f"pitch_kick {s:+g} N m s at flight +5 s of hop 2" if s else "" for s in size],
        "disturbance_size": size, "controller": ["pid" if i % 2 == 0 else "flaky.py:Flaky" for i in range(n)],
        "sample": [i // 2 % 2 for i in range(n)], "model_friction": [0.6 + 0.1 * (i // 2 % 2) for i in range(n)],
        "model_mass_torso": [1.9 + 0.1 * (i // 2 % 2) for i in range(n)], "hops_target": [3] * n,
        "hops_completed": [3] * n, "fell": [False] * n, "worst_landing_deg": [0.5 + 0.1 * i for i in range(n)],
        "peak_pitch_deg": [1.0] * n, "momentum_used_pct": [50.0] * n, "energy_j_per_hop": [60.0] * n,
        "controller_fault": fault, **({"disturbance_applied": applied} if applied is not None else {}),
    })  # fmt: skip


def test_a_faulted_episode_fails_in_every_part_of_the_sweep_report_saying_why(tmp_path: Path) -> None:
    """The Monte Carlo table counted a controller fault as a failure, the per-value table as a success,
    the landing quantiles took the PID's landings after the fault, and the heading said nothing varied."""
    from hopper.experiments.montecarlo import group_stats, success

    cause = "Flaky returned nan N m, not a finite torque"
    table = drawn_episodes(["", cause, "", cause])
    sweep = Sweep(table, None, None, tmp_path)
    assert sweep.success().tolist() == success(table).tolist() == [True, False, True, False]  # one rule
    flaky = next(g for g in group_stats(table) if g.label.startswith("flaky"))
    assert flaky.successes == 0 and all(math.isinf(q) for q in flaky.quantiles["worst_landing_deg"])
    report = sweep_report(sweep, "t")
    for named in report.figures:
        build.style.close(named.figure)
    assert report.subtitle.startswith("4 episodes, 0 fell, 2 with a controller fault (failed); varied: controller, ")
    assert "2 model parameters drawn for 2 robots (friction, mass_torso)" in report.subtitle
    (values,) = [t for t in report.tables if t.title == "Per setting value"]
    rows = {r[1]: r for r in values.rows if r[0] == "controller"}
    assert rows["flaky.py:Flaky"][3] == 0.0 and rows["flaky.py:Flaky"][6] == 2 and rows["pid"][3] == 100.0
    # The worst landing is the controller's: the PID's after a fault (0.6 and 0.8 deg here) are left out.
    assert rows["flaky.py:Flaky"][5] == "every one faulted" and rows["pid"][5] == pytest.approx(0.7)
    assert "The worst landing leaves out the episodes with a controller fault" in values.note
    assert "4 episodes, 2 successful" in values.note and cause in values.note
    (mc,) = [t for t in report.tables if t.title.startswith("Monte Carlo")]
    assert [r[2] for r in mc.rows] == [2, 0]


def test_episodes_whose_disturbance_never_came_are_left_out_of_success_against_it(tmp_path: Path) -> None:
    """A kick due after its flight ended never touched the robot: it is no survivor of that kick size."""
    table = drawn_episodes(["", "", "", ""], applied=[True, True, False, True], size=[0.0, 0.0, 1.0, 2.0])
    report = sweep_report(Sweep(table, None, None, tmp_path), "t")
    (named,) = [f for f in report.figures if f.name == "success_vs_disturbance_size"]
    points = named.figure.axes[0].lines[0].get_xydata().tolist()
    assert points == [[0.0, 100.0], [2.0, 100.0]], "the 1 N m s kick never happened: no point for it"
    assert "Left out: 1 episodes whose disturbance was not applied" in named.caption
    for f in report.figures:
        build.style.close(f.figure)
    older = Sweep(drawn_episodes(["", "", "", ""], size=[0.0, 0.0, 1.0, 2.0]), None, None, tmp_path)
    (named,) = [f for f in sweep_report(older, "t").figures if f.name == "success_vs_disturbance_size"]
    assert [x for x, _ in named.figure.axes[0].lines[0].get_xydata().tolist()] == [0.0, 1.0, 2.0]  # as applied
    build.style.close(named.figure)


def test_a_gain_cell_whose_robots_never_landed_says_so_instead_of_a_perfect_zero(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """With the wheel off the robot falls in its first flight: the store writes 0 deg for an episode
    without a landing, which the map drew as the best colour ("0.00°") and the table as 0."""
    out = tmp_path / "sweep"
    code, printed, err = cli(capsys, "sweep", "--out", str(out), "--seeds", "2", "--wheel", "on,off", "--hops", "1",
                             "--terrain", "flat", "--executor", "local", "--workers", "1")  # fmt: skip
    assert code == 0, err
    off = [e for e in ds.dataset(out / "episodes").to_table().to_pylist() if not e["wheel"]]
    assert off and all(e["fell"] and e["hops_completed"] == 0 and e["worst_landing_deg"] == 0.0 for e in off)
    assert "off: 2/2 fell, land none (no hop completed)" in printed
    sweep = load(out)
    fig = gain_map(sweep, wheel=False)
    ax = fig.axes[0]
    assert np.ma.getmaskarray(ax.images[0].get_array()).all()  # grey, not coloured as 0 deg
    assert [t.get_text() for t in ax.texts] == ["no landing\n2/2 fell"]
    build.style.close(fig)
    report = sweep_report(sweep, "t")
    for named in report.figures:
        build.style.close(named.figure)
    assert "gain_map_wheel_off" not in [n.name for n in report.figures]  # the gains act on nothing there
    assert any("wheel off: no Kp x Kd map" in t.note for t in report.tables)
    rows = {(r[0], r[1]): r for r in report.tables[0].rows}
    on = [e["worst_landing_deg"] for e in ds.dataset(out / "episodes").to_table().to_pylist() if e["wheel"]]
    assert rows[("wheel", False)][5] == "no landing"
    assert rows[("wheel", True)][5] == pytest.approx(max(on))


def test_a_compare_json_carries_the_drawn_seeds_trace_so_report_simulates_nothing(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """compare --json keeps the first seed's 100 Hz traces (the time series report draws by default) as
    run --json does (the same samples), and no other seed's: a 100-seed file stays small. report draws
    the file as it is (--no-simulate works); another seed drawn is simulated, its two runs alone."""
    path = tmp_path / "cmp.json"
    code, _, err = cli(capsys, "compare", "--seeds", "3", "--hops", "2", "--workers", "1", "--json", str(path))
    assert code == 0, err
    runs = json.loads(path.read_text())["runs"]
    assert [(r["seed"], r["wheel"]) for r in runs] == [(s, w) for s in range(3) for w in (True, False)]
    assert ["trace" in r for r in runs] == [True, True, False, False, False, False]
    alone = simulate(SimConfig(seed=0, wheel=False), 2)  # as `hopper-sim run` flies it
    assert runs[1]["trace"] == json.loads(json.dumps(alone["trace"]))  # a reused simulation's second episode
    for flags in ([], ["--no-simulate"]):
        code, out, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "r"), *flags)
        assert code == 0 and "simulating" not in err, (out, err)
        assert out.startswith("11 files in "), out
    code, out, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "r2"), "--seed", "2")
    assert code == 0, err
    assert err.splitlines() == ["simulating seed 2, wheel on, 2 hops", "simulating seed 2, wheel off, 2 hops"], err
    code, out, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "r3"), "--seed", "1", "--no-simulate")
    assert code == 2 and err == (
        f"hopper-sim: error: run 3 of 6 in {path} holds no trace (compare keeps its first seed's only): "
        "drop --no-simulate to simulate it again for one\n"
    )


def test_a_seed_not_in_the_file_is_refused_before_any_simulation(run_json: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    old = json.loads(run_json.read_text())
    del old["trace"]  # an older compare's run: report would simulate it again for its trace
    path = _write(tmp_path / "old.json", json.dumps({"median_peak_reduction_pct": 0.0, "seeds": [], "runs": [old]}))
    code, out, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "r"), "--seed", "5")
    assert code == 2 and out == "", out
    assert err == f"hopper-sim: error: --seed 5: no wheel-on run of that seed in {path} (its wheel-on seeds: 0)\n"
    code, _, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "r"), "--no-simulate")
    assert code == 2 and err == (
        f"hopper-sim: error: run 1 of 1 in {path} holds no trace (compare keeps its first seed's only): "
        "drop --no-simulate to simulate it again for one\n"
    )


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda d: d / "missing.json", "does not exist"),
        (lambda d: _write(d / "x.txt", "hello"), "expected a .json, .rrd, .parquet or a sweep directory"),
        (
            lambda d: _write(d / "x.json", '{"a": 1}'),
            "a run or compare result (no 'settings' and 'hops', nor 'runs'), a league or a stand document",
        ),
        (lambda d: _write(d / "x.json", "{not json"), "x.json: Expecting property name"),
        (
            lambda d: _write(d / "x.json", '{"settings": {}, "hops": "abc", "fell": false}'),
            "x.json: hops must be a list of hops, got a string",
        ),  # hand-edited: was a TypeError
        (
            lambda d: _write(d / "x.json", '{"settings": {}, "hops": [{"index": "1"}], "fell": false}'),
            'x.json: hops[0].index must be a number, got "1"',
        ),
        (
            lambda d: _write(d / "x.json", '{"runs": [{"settings": 3, "hops": []}]}'),
            "x.json: a result must be an object with a settings object",
        ),
        (lambda d: _write(d / "x.rrd", "not a recording"), "cannot read it as a rerun recording"),
        (lambda d: _write(d / "x.parquet", "not parquet"), "cannot read it as Parquet"),
        (lambda d: d, "is a folder without an episodes/ dataset or Parquet files"),
    ],
)
def test_bad_inputs_fail_in_one_line(tmp_path: Path, capsys, make, message: str) -> None:  # noqa: ANN001
    path = make(tmp_path)
    code, out, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "out"))
    assert code == 2, (out, err)
    assert err.startswith("hopper-sim: error: ") and err.count("\n") == 1, err
    assert message in err and out == ""
    assert not (tmp_path / "out").exists(), "a refused input left the --out folder it made"


def test_bad_input_in_a_real_process_is_one_line_too(tmp_path: Path) -> None:
    result = hopper_sim("report", str(tmp_path / "nothing.rrd"), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "does not exist" in result.stderr
    assert "Traceback" not in result.stderr


def test_a_truncated_recording_is_one_line_without_rerun_warning_first(tmp_path: Path) -> None:
    sim = Simulation(SimConfig(terrain="flat"))
    with Telemetry(sim, path=tmp_path / "run.rrd"):
        sim.run(1)
    whole = (tmp_path / "run.rrd").read_bytes()
    (tmp_path / "cut.rrd").write_bytes(whole[: len(whole) // 2])  # no footer, a frame past the end
    result = hopper_sim("report", str(tmp_path / "cut.rrd"), "--out", str(tmp_path / "out"))
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr  # was: a RerunWarning's 2 lines
    assert result.stderr.startswith("hopper-sim: error: ") and "cannot read it as a rerun recording" in result.stderr


def test_a_hops_dataset_or_an_unwritable_out_is_refused(sweep_dir: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    code, _, err = cli(capsys, "report", str(sweep_dir / "hops"), "--out", str(tmp_path / "o"))
    assert code == 2 and "holds a sweep's hops" in err, err
    blocker = _write(tmp_path / "file", "")
    code, _, err = cli(capsys, "report", str(sweep_dir), "--out", str(blocker / "sub"))
    assert code == 2 and err == f"hopper-sim: error: --out: {blocker} is not a folder\n", err
    code, _, err = cli(capsys, "report", str(sweep_dir), "--out", "/proc/report")
    assert code == 2 and err.startswith("hopper-sim: error: --out: cannot write to /proc/report: "), err


def _stop_after_figures(monkeypatch: pytest.MonkeyPatch, figures: int) -> None:
    """Ctrl-C as each report writes: KeyboardInterrupt once its `figures`-th figure is on disk."""
    from hopper.report import style

    save, saved = style.save, []

    def save_then_stop(fig, folder: Path, name: str) -> list[Path]:  # noqa: ANN001 (Figure)
        paths = save(fig, folder, name)
        saved.append(name)
        if len(saved) % figures == 0:
            raise KeyboardInterrupt
        return paths

    monkeypatch.setattr(style, "save", save_then_stop)


def test_an_interrupted_report_leaves_out_as_it_was(run_json: Path, tmp_path: Path, capsys, monkeypatch) -> None:  # noqa: ANN001
    """Stopped mid-write, report left new figures beside an earlier report's page and figures (a mixed
    folder), or, in a new folder, a few figures and no report.html."""
    old = tmp_path / "old"
    assert cli(capsys, "report", str(run_json), "--out", str(old), "--no-simulate")[0] == 0
    (old / "stale.png").write_bytes(b"a figure only the earlier report drew")
    before = tree(tmp_path)
    _stop_after_figures(monkeypatch, 2)
    for out in (old, tmp_path / "new"):
        code, printed, err = cli(capsys, "report", str(run_json), "--out", str(out), "--no-simulate")
        assert code == 130 and err == "hopper-sim: interrupted\n", err
        assert tree(tmp_path) == before, f"{out}: an interrupted report changed what was there"
    monkeypatch.undo()
    (old / "stale.pdf").write_bytes(b"")
    old.chmod(0o750)
    code, printed, _ = cli(capsys, "report", str(run_json), "--out", str(old), "--no-simulate")
    assert code == 0 and printed.startswith(f"{len(RUN_FIGURES) * 2 + 1} files in {old}: ")
    assert sorted(p.name for p in old.iterdir()) == sorted(
        ["report.html", *(f"{name}.{kind}" for name in RUN_FIGURES for kind in ("png", "pdf"))]
    ), "the earlier report is replaced whole: its own figures go with it"
    assert old.stat().st_mode & 0o777 == 0o750, "the folder keeps who may read it"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"], "a partial or old folder was left beside it"


def test_a_stop_signal_during_the_swap_waits_for_it(run_json: Path, tmp_path: Path, capsys, monkeypatch) -> None:  # noqa: ANN001
    """The new report takes the folder's place in two renames; Ctrl-C between them would leave no
    folder at all (or the earlier report aside, hidden): it is delivered after the second."""
    from hopper import interrupts
    from hopper.report import folder

    out = tmp_path / "out"
    assert cli(capsys, "report", str(run_json), "--out", str(out), "--no-simulate")[0] == 0
    (out / "stale.png").write_bytes(b"")
    rename, renames = os.rename, []

    def rename_then_ctrl_c(src: Path, dst: Path) -> None:
        rename(src, dst)
        renames.append(dst)
        if len(renames) == 1:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(folder.os, "rename", rename_then_ctrl_c)
    try:
        code, _, err = cli(capsys, "report", str(run_json), "--out", str(out), "--no-simulate")
    finally:
        interrupts.clear()
    assert code == 130 and len(renames) == 2 and renames[1] == out, renames
    assert (out / "report.html").is_file() and not (out / "stale.png").exists(), "the new report, whole"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


# hopper-sim report in a child process that stops mid-write (one figure in its staging folder), says
# where on stdout and waits there until it is killed.
STOPPED_MID_WRITE = """
import sys
from hopper.report import build

def write_then_wait(report, folder):
    (folder / "half-written.png").write_bytes(b"")
    print(folder, flush=True)
    sys.stdin.read()  # until killed

build.write = write_then_wait
from hopper.app.sim_cli import main
sys.exit(main(sys.argv[1:]))
"""


def _writing(run_json: Path, out: Path) -> tuple[subprocess.Popen[str], Path]:
    """A report to `out` running in a child, stopped mid-write, and its staging folder."""
    child = subprocess.Popen(
        [sys.executable, "-c", STOPPED_MID_WRITE, "report", str(run_json), "--out", str(out), "--no-simulate"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    guard = threading.Timer(120, child.kill)  # a bound for a loaded machine, not a pace
    guard.start()
    line = child.stdout.readline()  # '' if the child ended first
    guard.cancel()
    if not line:
        child.kill()
        raise AssertionError(f"the report never wrote: {child.communicate()[1][-2000:]}")
    return child, Path(line.strip())


def _kill(child: subprocess.Popen[str]) -> None:
    child.kill()  # SIGKILL: no handler, no finally, nothing cleans up
    assert child.wait(timeout=60) == -signal.SIGKILL
    child.stdout.close()
    child.stdin.close()
    child.stderr.close()


def test_a_killed_reports_staging_folder_is_removed_by_the_next_run_and_a_live_writers_kept(
    run_json: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """kill -9 mid-write left its hidden .OUT.partial-* folder beside OUT for good: the next report to
    OUT now removes it, once its writer is gone; a report still writing to OUT keeps its own."""
    out = tmp_path / "fig"
    children = []
    try:
        live, live_partial = _writing(run_json, out)
        children.append(live)
        killed, killed_partial = _writing(run_json, out)  # its own start keeps the live writer's folder
        children.append(killed)
        _kill(killed)
        assert (killed_partial / "half-written.png").is_file() and live_partial.is_dir()
        code, printed, err = cli(capsys, "report", str(run_json), "--out", str(out), "--no-simulate")
        assert code == 0 and (out / "report.html").is_file(), err
        assert not killed_partial.exists(), "the killed writer's staging folder is left beside OUT"
        assert (live_partial / "half-written.png").is_file(), "a live writer's staging folder was removed"
        _kill(live)
        assert cli(capsys, "report", str(run_json), "--out", str(out), "--no-simulate")[0] == 0
        assert sorted(p.name for p in tmp_path.iterdir()) == ["fig"]
    finally:
        for child in children:
            if child.poll() is None:
                child.kill()
                child.wait(timeout=60)


def test_only_staging_folders_of_writers_gone_from_this_host_are_removed(tmp_path: Path) -> None:
    """Another host's (a shared disk: its pids mean nothing here), an unknown writer's (named before
    writers were) and a live one's are kept, as are other folders' staging folders."""
    from hopper.report.folder import remove_stale

    gone = subprocess.Popen([sys.executable, "-c", ""])
    assert gone.wait(timeout=60) == 0  # reaped: its pid names no process now
    here = socket.gethostname()
    stale = tmp_path / f".fig.partial-0123abcd-{gone.pid}@{here}"
    kept = [f".fig.partial-0123abcd-{gone.pid}@not-{here}", ".fig.partial-0123abcd",
            f".fig.partial-0123abcd-{os.getpid()}@{here}", f".other.partial-0123abcd-{gone.pid}@{here}"]  # fmt: skip
    for path in [stale, *(tmp_path / name for name in kept)]:
        path.mkdir()
        (path / "a.png").write_bytes(b"")
    assert remove_stale(tmp_path / "fig") == [stale]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(kept)


def test_an_earlier_report_moved_aside_by_a_killed_swap_is_put_back_or_removed(
    run_json: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A kill -9 between a swap's two renames left OUT missing and the earlier report in .OUT.old-*:
    the next run puts it back, also where it made OUT empty first, and keeps it there if that run is
    stopped; once a report is in OUT the copy is removed; beside anything else it is kept (it may be
    the only copy). A live writer's moved-aside report is its own to finish with, and kept."""
    from hopper.report.folder import remove_stale

    gone = subprocess.Popen([sys.executable, "-c", ""])
    assert gone.wait(timeout=60) == 0  # reaped: its pid names no process now
    here, out = socket.gethostname(), tmp_path / "fig"
    earlier = tmp_path / f".fig.old-0123abcd-{gone.pid}@{here}"
    live = tmp_path / f".fig.old-4567abcd-{os.getpid()}@{here}"

    def aside(path: Path) -> None:
        path.mkdir()
        (path / "report.html").write_text(path.name)

    aside(earlier)
    aside(live)
    assert remove_stale(out) == [earlier]
    assert (out / "report.html").read_text() == earlier.name and live.is_dir()
    shutil.rmtree(out)
    aside(earlier)  # and a report run that is refused: it made OUT empty, put the copy back, and stopped
    bad = tmp_path / "bad.json"
    bad.write_text("{}")  # read once OUT is made: refused then
    code, _, err = cli(capsys, "report", str(bad), "--out", str(out), "--no-simulate")
    assert code == 2 and (out / "report.html").read_text() == earlier.name and not earlier.exists(), err
    aside(earlier)  # beside a report in place: a stale copy
    assert remove_stale(out) == [earlier] and (out / "report.html").read_text() == earlier.name
    shutil.rmtree(out)
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    aside(earlier)  # beside something else: kept
    assert remove_stale(out) == [] and earlier.is_dir() and (out / "notes.txt").is_file()
    shutil.rmtree(out)
    code, _, err = cli(capsys, "report", str(run_json), "--out", str(out), "--no-simulate")
    assert code == 0 and not earlier.exists(), err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["fig", live.name, bad.name])


@pytest.mark.parametrize(
    "files, message",
    [
        (["report.html", "a.png", "notes.txt"], "holds a.png, notes.txt and report.html, and is not a report's folder"),
        (["a.png", "a.pdf"], "holds a.pdf and a.png, and is not a report's folder (report.html with its PNG and PDF"),
        (["report.html", "data/"], "holds data/ and report.html, and is not a report's folder"),
    ],
)
def test_an_out_that_holds_more_than_a_report_is_refused_before_any_work(
    run_json: Path,
    tmp_path: Path,
    capsys,
    files: list[str],
    message: str,  # noqa: ANN001
) -> None:
    """A report replaces its folder whole: one holding anything else (a note, data, loose figures not
    known to be a report's) would lose it, and was written into, mixed, before."""
    out = tmp_path / "out"
    out.mkdir()
    for name in files:
        (out / name).mkdir() if name.endswith("/") else (out / name).write_text("mine")
    before = tree(tmp_path)
    code, printed, err = cli(capsys, "report", str(run_json), "--out", str(out))
    assert code == 2 and printed == "" and err.count("\n") == 1, err
    assert err.startswith(f"hopper-sim: error: --out: {out} ") and message in err and "simulating" not in err, err
    assert tree(tmp_path) == before


def test_the_folder_the_command_runs_in_is_refused_as_out(run_json: Path, tmp_path: Path, capsys, monkeypatch) -> None:  # noqa: ANN001
    """Replaced whole, it would leave the shell that ran the command in a removed folder."""
    monkeypatch.chdir(tmp_path)
    code, _, err = cli(capsys, "report", str(run_json), "--out", ".", "--no-simulate")
    assert code == 2 and err == ("hopper-sim: error: --out: . is the folder this command runs in, which a report "
                                 "replaces whole: give another\n"), err  # fmt: skip
    assert not any(tmp_path.iterdir())


def test_the_page_escapes_and_flattens_settings() -> None:
    html = page.render("t <x>", "s", {"gains": {"kp": 1.5}, "name": "<b>"}, [page.Section("n", note="a & b")])
    assert ">gains.kp<" in html and "&lt;b&gt;" in html and "a &amp; b" in html and "<b>" not in html
    assert math.isclose(float(re.search(r"<td>([\d.]+)</td>", html).group(1)), 1.5)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("make", "flags", "what"),
    [
        (lambda d: _write(d / "run.rrd", "not read: refused first"), ["--seed", "1"], "a recording"),
        (lambda d: (d / "sweep" / "episodes").mkdir(parents=True) or d / "sweep", ["--no-simulate"], "a sweep"),
        (lambda d: _write(d / "l.json", '{"kind": "league"}'), ["--controller", "lqr"], "a league JSON"),
        (lambda d: _write(d / "f.json", '{"kind": "frequency"}'), ["--seed", "0"], "a stand JSON"),
    ],
)
def test_a_flag_only_runs_use_is_refused_where_it_would_be_ignored(make, flags, what, tmp_path, capsys) -> None:  # noqa: ANN001
    """--seed, --controller and --no-simulate were silently ignored for these inputs."""
    path = make(tmp_path)
    code, out, err = cli(capsys, "report", str(path), "--out", str(tmp_path / "r"), *flags)
    assert code == 2 and out == "" and not (tmp_path / "r").exists()
    said = f"{flags[0]} is for a run or compare JSON; {what} has no runs to draw or simulate: drop it"
    assert err == f"hopper-sim: error: {said}\n", err


def test_a_stand_documents_kick_is_drawn_and_tabled_and_an_older_one_without_its_trace_is_tabled():
    """`report stand.json` showed no trace of a --kick: neither its figure nor its numbers."""
    from hopper.report import style
    from hopper.report.frequency import frequency_report

    t = np.arange(0, 1001) * 1e-3
    pitch = 0.8 * (t / 0.034) * np.exp(1 - t / 0.034)  # deg: a peak of 0.8 deg at 34 ms
    kick = {"magnitude_nms": 0.5, "peak_pitch_deg": 0.8, "peak_s": 0.034, "back_within_10pct_s": 0.16,
            "watched_s": 1.0, "t": t.tolist(), "pitch_deg": pitch.tolist()}  # fmt: skip
    for document, figures in (({"kick": kick}, ["kick"]), ({"kick": {k: kick[k] for k in list(kick)[:5]}}, [])):
        report = frequency_report(document, "stand")
        assert [f.name for f in report.figures] == figures
        (table,) = report.tables
        assert [row[2:4] for row in table.rows] == [["peak pitch (deg)", 0.8], ["peak at (ms)", 34.0],
                                                    ["back within 10 % from (ms)", 160.0]]  # fmt: skip
        for named in report.figures:
            (ax,) = named.figure.axes
            assert ax.lines[0].get_ydata().max() == pytest.approx(0.8) and ax.get_xlabel() == "time since the kick (ms)"
            style.close(named.figure)


def test_every_number_of_a_config_has_its_unit_in_the_reports_settings_table():
    """The settings table gave 1.625 and 450 with no unit."""
    import dataclasses

    from hopper.config import SETTING_UNITS, SimConfig, unit_of
    from hopper.report import page

    numbers = [k for k, v in page.flatten(dataclasses.asdict(SimConfig())) if isinstance(v, int | float | tuple | list)]
    numbers = [k for k in numbers if k not in ("seed", "wheel", "controller_params", "mismatch")]  # no units
    assert sorted(numbers) == sorted(SETTING_UNITS), "a number of SimConfig without a unit, or a unit of none"
    # By its last part where that names one setting: a sweep's axes, a recording's gains.
    assert (unit_of("values.kp"), unit_of("kp"), unit_of("values.gravity"), unit_of("hops")) == (
        "N m/rad", "N m/rad", "m/s^2", ""
    )  # fmt: skip
    html = page.render("t", "s", {"gravity": 1.625, "gains": {"kp": 450.0}, "seed": 3}, [])
    assert "<td>1.625</td><td>m/s^2</td>" in html and "<td>450</td><td>N m/rad</td>" in html


def test_the_papers_bands_are_drawn_for_the_papers_scenario_only(run_json: Path) -> None:
    """A default-scenario run at 0.23 deg was drawn under the paper's 15-20 deg band: its scale, not the run's."""
    from hopper.scenarios import scenario

    run = run_from_result(json.loads(run_json.read_text()), "run JSON")
    as_paper = dataclasses.replace(run, settings={**run.settings, "gait": dataclasses.asdict(scenario("paper").gait)})
    for shown, bands in ((run, 0), (as_paper, 2)):
        report = build.run_report([shown], [], "t", "s")
        (named,) = [n for n in report.figures if n.name == "hop_metrics"]
        drawn = [p for ax in named.figure.axes for p in ax.patches if p.get_label().startswith("paper, wheel on")]
        assert len(drawn) == bands, named.name
        assert ("drawn for its own scenario only" in named.caption) == (bands == 0)
        for n in report.figures:
            build.style.close(n.figure)


def _faulted_compare(run_json: Path, tmp_path: Path, faulted: set[int]) -> Path:
    """A compare JSON of seeds 0 to 2 (copies of the real run, wheel on and off), whose wheel-on runs of
    `faulted` seeds had a controller fault and flew to 40 deg on the PID after it."""
    on = json.loads(run_json.read_text())
    runs = []
    for seed in range(3):
        for wheel in (True, False):
            run = {**on, "settings": {**on["settings"], "seed": seed, "wheel": wheel}, "seed": seed, "wheel": wheel}
            if seed:
                del run["trace"]  # as compare keeps the first seed's only
            if wheel and seed in faulted:
                run["fault"] = "Picky returned nan N m, not a finite torque"
                run["hops"] = [{**h, "peak_pitch_deg": 40.0, "saturation_time_s": 0.5} for h in on["hops"]]
            runs.append(run)
    path = tmp_path / "compare.json"
    path.write_text(json.dumps({"median_peak_reduction_pct": None, "seeds": [], "runs": runs}))
    return path


def _bar_heights(figure, label: str) -> list[list[float]]:  # noqa: ANN001 (Figure)
    """Per axes, the heights of the bars labelled `label`."""
    return [[p.get_height() for c in ax.containers if c.get_label() == label for p in c] for ax in figure.axes]


def test_the_per_hop_medians_leave_out_the_runs_whose_controller_faulted(run_json: Path, tmp_path: Path) -> None:
    """The bars were medians over every run, the faulted ones' too: two of three seeds flown on by the
    PID from the fault at 40 deg made the wheel-on medians 40 deg, the PID's figure, not the controller's."""
    real = json.loads(run_json.read_text())["hops"]
    report = report_cli._json_report(_faulted_compare(run_json, tmp_path, {1, 2}), args())
    try:
        figures = {n.name: n for n in report.figures}
        metrics, saturation = figures["hop_metrics"], figures["saturation"]
        peaks, rates = _bar_heights(metrics.figure, "wheel on")
        assert peaks == pytest.approx([h["peak_pitch_deg"] for h in real])  # seed 0's alone
        assert rates == pytest.approx([h["rms_pitch_rate_deg_s"] for h in real])
        assert _bar_heights(saturation.figure, "wheel on")[0] == pytest.approx([h["saturation_time_s"] for h in real])
        assert metrics.figure._suptitle.get_text().endswith("(over 3 seeds, 2 runs that faulted left out)")  # noqa: SLF001
        left = ("Left out of the medians: 2 runs whose controller faulted (seed 1 wheel on, seed 2 wheel on), as the "
                "PID flew on from the fault: their figures are not the controller's.")  # fmt: skip
        assert left in metrics.caption and left in saturation.caption and "no bars" not in metrics.caption
        faults, *_, seeds = report.tables
        assert faults.title == "Controller faults" and "left out of the per-hop medians" in faults.note
        assert seeds.note.startswith("Median reduction of the peak mid-air pitch deviation, wheel on vs off: 0.0% "
                                     "(over 1 seed of 3; 2 faulted runs left out (seeds 1, 2);")  # fmt: skip
    finally:
        for named in report.figures:
            build.style.close(named.figure)


def test_a_group_whose_every_run_faulted_is_said_so_instead_of_bars(run_json: Path, tmp_path: Path) -> None:
    report = report_cli._json_report(_faulted_compare(run_json, tmp_path, {0, 1, 2}), args())
    try:
        figures = {n.name: n for n in report.figures}
        for name in ("hop_metrics", "saturation"):
            figure = figures[name].figure
            assert all(not heights for heights in _bar_heights(figure, "wheel on")), name
            said = [t.get_text() for ax in figure.axes for t in ax.texts]
            line = "wheel on: no bars, the controller faulted in every run (3) and the PID flew on"
            assert said.count(line) == len(figure.axes), (name, said)
            assert figures[name].caption.endswith("Wheel on: every run faulted, so no bars."), figures[name].caption
        assert all(_bar_heights(figures["hop_metrics"].figure, "wheel off (zero torque, free to spin)"))  # still drawn
        none = "wheel on vs off: none, every seed has a faulted run (3 faulted runs of 6)"
        assert report.tables[-1].note.startswith(f"Median reduction of the peak mid-air pitch deviation, {none}")
        assert "its controller faulted and the PID flew on" in report.tables[1].note  # the hop table of seed 0
    finally:
        for named in report.figures:
            build.style.close(named.figure)
