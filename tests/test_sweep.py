"""`hopper-sim sweep`: specs, workers that reuse one model, the Parquet contract, and a resumed sweep on Ray."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import random
import signal
import subprocess
import sys
import threading
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.dataset as ds
import pytest
from in_process import cli, tree
from net import free_port, wait_until
from sweep_data import FLAKY

from hopper.config import GRAVITY_PRESETS, SimConfig
from hopper.control.phases import Phase
from hopper.experiments.executor import InProcess, chunks, unreachable
from hopper.experiments.runner import run_sweep
from hopper.experiments.spec import SpecError, parse_spec
from hopper.experiments.store import RESULT_COLUMNS, SETTING_COLUMNS, SweepStore
from hopper.experiments.stress import Case, Schedule, run_case
from hopper.experiments.worker import Worker
from hopper.metrics import HopMetrics
from hopper.model import build_model, set_terrain, terrain_window
from hopper.sim import Simulation

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)


def hopper_sim(*args: str, cwd: Path | None = None, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=timeout, cwd=cwd
    )


def test_a_spec_expands_its_axes_and_reads_back_resolved() -> None:
    spec = parse_spec({
        "kp": {"start": 300, "stop": 800, "num": 3}, "seeds": {"start": 4, "stop": 6}, "gravity": ["moon", 3.72],
        "wheel": [True, "off"], "gait": {"apex_height": [0.2, 0.25]},
        "disturbance": [{"kind": "none"}, {"kind": "pitch_kick", "size": [1.0, -1.0], "phase": "stance", "delay": 0.1}],
    })  # fmt: skip
    assert spec.kp == (300.0, 550.0, 800.0) and spec.seeds == (4, 5) and spec.gravity == (1.625, 3.72)
    assert spec.wheel == (True, False) and spec.gait == (("apex_height", (0.2, 0.25)),)
    assert spec.disturbance == (None, Schedule("pitch_kick", 1.0, Phase.STANCE, 0.1, 2), Schedule("pitch_kick", -1.0,
                                Phase.STANCE, 0.1, 2))  # fmt: skip
    episodes = list(spec.episodes())
    assert len(episodes) == spec.size == 3 * 2 * 2 * 2 * 2 * 3
    assert len({e.episode_id for e in episodes}) == len(episodes), "ids must tell every episode apart"
    assert parse_spec(tomllib.loads(spec.to_toml())) == spec
    kicked = next(e for e in episodes if e.disturbance is not None)
    assert kicked.settings()["disturbance"] == "pitch_kick +1 N m s at stance +0.1 s of hop 2"
    assert kicked.settings()["disturbance_size"] == 1.0 and kicked.config().gait.apex_height in (0.2, 0.25)
    # the id depends on the settings only, never on the spec's order or size
    a, b = parse_spec({"seeds": [5], "kp": 300}), parse_spec({"kp": [300], "seeds": 6})
    assert next(a.episodes()).episode_id == next(e for e in b.episodes() if e.seed == 5).episode_id


@pytest.mark.parametrize(
    "data, message",
    [
        ({"kpp": 3}, "unknown key 'kpp'"),
        ({"kp": 5000}, "kp must be a finite number in [0, 2000] N m/rad"),
        ({"kp": {"start": 1, "stop": 2}}, "a range is {start, stop, num}"),
        ({"gravity": "pluto"}, "neither m/s^2 nor one of moon"),
        ({"seeds": -2}, "seeds: expected an integer"),
        ({"gait": {"crouch_height": 0.9}}, "crouch_height must be"),
        ({"gait": {"leg": 1.0}}, "unknown parameter 'leg'"),
        ({"disturbance": [{"kind": "shove", "size": 1, "phase": "stance", "delay": 0}]}, "kind 'shove' is not one of"),
        ({"disturbance": [{"kind": "pitch_kick", "size": 9.0, "phase": "stance", "delay": 0}]}, "size must be"),
        ({"disturbance": [{"kind": "pitch_kick", "size": 1.0, "phase": "nap", "delay": 0}]}, "phase 'nap'"),
        ({"kd": [20, 20]}, "kd: a value is repeated"),
        (
            {
                "hops": [2, 5],
                "disturbance": [{"kind": "pitch_kick", "size": 1.0, "phase": "flight", "delay": 0.1, "hop": 5}],
            },
            "hop 5 never comes in an episode of 2 hops",
        ),  # fmt: skip
    ],
)
def test_bad_specs_are_refused_with_the_reason(data: dict, message: str) -> None:
    with pytest.raises(SpecError) as caught:
        parse_spec(data)
    assert message in str(caught.value)


@pytest.mark.parametrize(
    "args, message",
    [
        (["spec.toml", "--out", "o"], "spec.toml is not valid TOML"),
        (["--out", "o", "--kp", "1:2"], "a range is {start, stop, num}"),
        (["--out", "file.txt", "--seeds", "1"], "is not a folder"),
        (["--out", "file.txt/quick", "--seeds", "1"], "file.txt is not a folder"),
        (["--out", "missing/runs/quick", "--seeds", "1"], "--out: folder missing/runs does not exist"),  # not made
        (["--out", "/proc/runs", "--seeds", "1"], "cannot write to /proc/runs"),  # even as root
        (["--out", "o", "--hops", "2", "--disturbance", "pitch_kick:5:flight:0.1:5"], "hop 5 never comes"),
    ],
)
def test_the_cli_refuses_a_bad_spec_in_one_line_before_any_work(tmp_path: Path, args: list[str], message: str) -> None:
    (tmp_path / "spec.toml").write_text("kp = [300,\n")
    (tmp_path / "file.txt").write_text("")
    result = hopper_sim("sweep", *args, cwd=tmp_path)
    assert result.returncode == 2, result
    assert result.stderr.count("\n") == 1 and message in result.stderr, result.stderr
    assert result.stderr.startswith("hopper-sim: error: ") and result.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt", "spec.toml"], "work started"


def test_swapping_the_terrain_gives_the_model_a_fresh_compile_gives() -> None:
    cases = ((SimConfig(seed=0), SimConfig(seed=5), 0), (SimConfig(seed=3), SimConfig(terrain="flat"), 0),
             (SimConfig(seed=4), SimConfig(seed=4), 1234))  # the last: the window moved 61.7 m along  # fmt: skip
    for before, after, moved in cases:
        model = build_model(before)
        window = terrain_window(after)
        window.place(window.start + moved)
        set_terrain(model, window)
        fresh = build_model(after, window)
        differ = [
            name for name in dir(fresh)
            if isinstance(getattr(fresh, name), np.ndarray) and not np.array_equal(getattr(fresh, name),
                                                                                   getattr(model, name))
        ]  # fmt: skip
        assert differ == [], f"{before.seed} -> {after.terrain} {after.seed}: {differ}"


def test_a_reused_worker_gives_exactly_the_episodes_of_fresh_simulations() -> None:
    spec = parse_spec({
        "seeds": [0, 1], "hops": 2, "kp": [300, 450], "wheel": ["on", "off"], "sensing": ["ideal", "realistic"],
        "gravity": ["moon", "mars"], "gait": {"apex_height": [0.25, 0.2]},
        "disturbance": [{"kind": "none"}, {"kind": "pitch_kick", "size": 1.0, "phase": "flight", "delay": 0.2}],
    })  # fmt: skip
    episodes = list(spec.episodes())
    random.Random(3).shuffle(episodes)
    episodes = episodes[:14]  # every setting changes from one to the next, in no helpful order
    worker = Worker()
    reused = [worker.run(e) for e in episodes]
    assert worker.built == 1, "the worker must build its model once"
    for episode, result in zip(episodes, reused, strict=True):
        fresh = Worker().run(episode)
        assert (fresh.hops, fresh.fell, fresh.sim_time_s, fresh.saturation_s, fresh.momentum_used_pct) == (
            result.hops, result.fell, result.sim_time_s, result.saturation_s, result.momentum_used_pct
        ), episode  # fmt: skip


def test_a_disturbed_episode_is_the_stress_battery_case() -> None:
    from hopper.experiments.spec import Episode

    push = Schedule("push_forward", 6.0, Phase.CROUCH, 0.1)
    episode = Episode(kp=450.0, ki=50.0, kd=30.0, gravity=GRAVITY_PRESETS["moon"], seed=0, hops_target=4,
                      terrain="flat", wheel=True, sensing="ideal", disturbance=push)  # fmt: skip
    worker = Worker()
    worker.run(dataclasses.replace(episode, terrain="crater", seed=9, disturbance=None))  # a worker with a past
    result = worker.run(episode)
    outcome = run_case(Case("ground", "push", episode.config(), 4, push))
    assert result.applied and outcome.applied
    row = result.row()
    assert (row["hops_completed"], row["fell"]) == (outcome.hops, outcome.fell)
    assert row["worst_landing_deg"] == outcome.worst_landing_deg and row["peak_pitch_deg"] == outcome.worst_peak_deg


def test_an_episodes_momentum_is_the_most_a_flight_used_and_tells_gain_sets_apart() -> None:
    """It was the peak wheel speed over whole hops, the first stance from standing included: 59.089608 %
    for every gain set (the stance's, which the flight gains do not touch), the flights' ~19 % hidden."""
    spec = parse_spec({"seeds": [0], "hops": 2, "kp": [200, 1200], "kd": [15, 60]})
    worker = Worker()
    results = [worker.run(e) for e in spec.episodes()]
    used = [r.momentum_used_pct for r in results]
    for r in results:
        assert r.row()["momentum_used_pct"] == r.momentum_used_pct == max(h.peak_momentum_pct for h in r.hops)
        stance = max(h.peak_wheel_rpm for h in r.hops) / 60 * 2 * np.pi / worker.sim.robot.wheel_no_load_speed
        assert r.momentum_used_pct < 40 < 100 * stance, "the flights use a third of what the stance spins up"
    assert len(set(used)) == 4 and max(used) - min(used) > 0.5, used
    # A flight in progress counts too: the first one, before its hop is done.
    sim = Simulation(SimConfig(terrain="flat"))
    while sim.phase is not Phase.FLIGHT:
        sim.step()
    sim.advance(200)
    in_flight = sim.metrics.momentum_pct(float(sim.controller.mem["acc_resp_wheel"][0]))
    assert sim.hops == [] and sim.metrics.flight_momentum_pct() == in_flight > 1.0


def test_the_parquet_datasets_follow_the_contract(tmp_path: Path) -> None:
    spec = parse_spec({"seeds": 2, "hops": 2, "wheel": ["on", "off"], "gait": {"apex_height": [0.25]}})
    run = run_sweep(spec, tmp_path / "out", lambda todo: InProcess(), progress=False, announce=lambda _: None)
    assert (run.ran, run.skipped) == (4, 0)
    episodes = ds.dataset(tmp_path / "out" / "episodes", format="parquet").to_table()
    hops = ds.dataset(tmp_path / "out" / "hops", format="parquet").to_table()
    settings = [name for name, _ in SETTING_COLUMNS] + ["apex_height", "controller"]
    assert episodes.column_names == settings + [name for name, _ in RESULT_COLUMNS]
    hop_fields = list(HopMetrics.__dataclass_fields__)
    assert hops.column_names == settings + ["hop"] + hop_fields
    assert episodes.schema.field("seed").type == pa.int64() and episodes.schema.field("wheel").type == pa.bool_()
    assert episodes.schema.field("fell").type == pa.bool_() and hops.schema.field("completed").type == pa.bool_()
    rows = episodes.to_pylist()
    assert len({r["episode_id"] for r in rows}) == 4
    for r in rows:
        own = [h for h in hops.to_pylist() if h["episode_id"] == r["episode_id"]]
        assert [h["hop"] for h in own] == list(range(1, len(own) + 1))
        assert all(h["seed"] == r["seed"] and h["wheel"] == r["wheel"] for h in own)
        assert r["hops_completed"] == sum(h["completed"] for h in own)
        assert r["disturbance"] == "" and r["disturbance_size"] == 0.0 and r["terrain"] == "crater"
        assert r["controller"] == "pid" and r["controller_fault"] == ""
        if r["wheel"]:
            assert not r["fell"] and r["hops_completed"] == 2 and 0 < r["momentum_used_pct"] < 100
        else:  # wheel off: the robot tumbles in its first flight (README)
            assert r["fell"] and r["peak_pitch_deg"] > 30
    assert tomllib.loads((tmp_path / "out" / "spec.toml").read_text())["seeds"] == [0, 1]


def test_a_killed_runs_leftovers_are_cleaned_and_another_spec_is_refused(tmp_path: Path) -> None:
    spec, out = parse_spec({"seeds": 1, "hops": 1}), tmp_path / "out"
    run_sweep(spec, out, lambda todo: InProcess(), progress=False, announce=lambda _: None)
    orphan = out / "hops" / "part-killed-00001.parquet"  # its episodes part never came
    orphan.write_bytes((next((out / "hops").glob("*.parquet"))).read_bytes())
    (out / "episodes" / ".tmp-part-x.parquet").write_bytes(b"half a file")
    again = run_sweep(spec, out, lambda todo: InProcess(), progress=False, announce=lambda _: None)
    assert (again.ran, again.skipped) == (0, 1)
    assert not orphan.exists() and not (out / "episodes" / ".tmp-part-x.parquet").exists()
    result = hopper_sim("sweep", "--out", str(out), "--seeds", "2", "--hops", "1")
    assert result.returncode == 2 and "holds another sweep" in result.stderr, result.stderr


ONE_EPISODE = ["--seeds", "1", "--hops", "1", "--workers", "1"]


@pytest.fixture
def grid(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """TMP/runs/grid: a one-episode sweep, as hopper-sim sweep writes it."""
    grid = tmp_path / "runs" / "grid"
    grid.parent.mkdir()
    assert cli(capsys, "sweep", "--out", str(grid), *ONE_EPISODE)[0] == 0
    return grid


@pytest.mark.parametrize(
    "make, message",
    [
        (
            lambda grid: grid / "episodes",
            "is the episodes/ dataset of the sweep in {grid}: give --out {grid} to resume",
        ),
        (lambda grid: grid / "hops", "is the hops/ dataset of the sweep in {grid}"),
        (lambda grid: grid.parent, "holds grid/, and is not a sweep's folder (no spec.toml)"),
        (
            lambda grid: _figures(grid.parent / "fig_grid"),
            "holds a.pdf, a.png and report.html, and is not a sweep's folder (no spec.toml): give a new or empty",
        ),
    ],
)
def test_an_out_that_holds_something_else_than_a_sweep_is_refused_before_any_work(
    grid: Path, capsys: pytest.CaptureFixture[str], make: Callable[[Path], Path], message: str
) -> None:
    """`sweep --out runs/grid/episodes` wrote a new sweep into the old one's dataset (exit 0): its report
    and its resume then failed on a spec.toml among the Parquet parts. A report's folder was taken too."""
    out = make(grid)
    before = tree(grid.parent)
    code, printed, err = cli(capsys, "sweep", "--out", str(out), *ONE_EPISODE)
    assert code == 2 and printed == "" and err.count("\n") == 1, err
    assert err.startswith(f"hopper-sim: error: --out: {out} ") and message.format(grid=grid) in err, err
    assert tree(grid.parent) == before, "a refused --out was written to"
    code, printed, _ = cli(capsys, "sweep", "--out", str(grid), *ONE_EPISODE)  # the sweep itself resumes as before
    assert code == 0 and "nothing left to run" in printed


def _figures(folder: Path) -> Path:
    folder.mkdir()
    for name in ("report.html", "a.png", "a.pdf"):
        (folder / name).write_text("")
    return folder


def _cut(episodes: Path) -> None:
    """A Parquet part cut short: its first 300 bytes."""
    (episodes / "cut.parquet").write_bytes(next(episodes.glob("*.parquet")).read_bytes()[:300])


@pytest.mark.parametrize(
    "damage, message",
    [
        (
            lambda episodes: [(episodes / "spec.toml").write_text("x"), (episodes / "hops").mkdir()],
            "episodes holds hops/, spec.toml, which are not its Parquet parts: move them out of it and run again",
        ),
        (_cut, "cannot read {grid}/episodes (Error creating dataset"),
    ],
)
def test_resuming_a_damaged_sweep_is_one_line_not_a_traceback(
    grid: Path, capsys: pytest.CaptureFixture[str], damage: Callable[[Path], object], message: str
) -> None:
    """A stray file in a dataset (what the bug above wrote) or a part cut short ended the resume in
    pyarrow's ArrowInvalid traceback, exit 1."""
    damage(grid / "episodes")
    code, printed, err = cli(capsys, "sweep", "--out", str(grid), *ONE_EPISODE)
    assert code == 2 and printed == "" and err.count("\n") == 1, err
    assert err.startswith(f"hopper-sim: error: {grid} is a damaged sweep: ") and message.format(grid=grid) in err, err


def test_two_stores_of_one_process_within_a_second_keep_each_others_parts(tmp_path: Path) -> None:
    """Parts were named by the second and the pid: a second store of one process within the same
    second (a resume right after a first run, in one Python session) overwrote the first's part 1."""
    spec = parse_spec({"kp": [300, 600], "seeds": 1, "hops": 1})
    first, second = spec.episodes()
    for episode in (first, second):
        store = SweepStore(tmp_path, spec)
        store.open()
        store.add([Worker().run(episode)])
        store.flush()
    assert sorted(SweepStore(tmp_path, spec).read_episodes().column("episode_id").to_pylist()) == sorted(
        [first.episode_id, second.episode_id]
    )


def test_a_mixed_sweep_written_before_the_gain_axes_were_the_pids_counts_each_episode_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, --controller pid,lqr --kp 300,600 flew the LQR at each kp; resumed now, the LQR flies once at
    the default gains (its fallback PID's) beside those rows, and the summary counted all three."""
    from hopper.app.sim_cli import main

    out = tmp_path / "out"
    spec = parse_spec({"controller": ["pid", "lqr"], "kp": [300, 600], "seeds": 2, "hops": 1})
    pid = [e for e in spec.episodes() if e.controller == "pid"]
    old = pid + [dataclasses.replace(e, controller="lqr") for e in pid]  # the old product, as its code wrote it
    store = SweepStore(out, spec)
    store.open()
    store.add([Worker().run(e) for e in old])
    store.flush()
    args = ["sweep", "--out", str(out), "--controller", "pid,lqr", "--kp", "300,600", "--seeds", "2", "--hops", "1"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert f"{out}: 6 episodes, 0 fell" in text, text
    assert f"{out} also holds 4 rows of episodes this spec does not fly" in text
    assert "seed: 0: 0/3 fell" in text and "controller: pid: 0/4 fell" in text and "; lqr: 0/2 fell" in text, text
    assert "this run: 2 episodes on in-process" in text  # the LQR at the default gains, for each seed


def test_chunks_keep_the_order_and_cover_every_episode() -> None:
    episodes = list(parse_spec({"seeds": 5, "kp": [300, 400, 500], "hops": 2}).episodes())
    parts = chunks(episodes, workers=2)
    assert [e for part in parts for e in part] == episodes and len(parts) >= 8


# A user's law that flies until its 100th call (the probe's are done), then hangs there deaf to SIGTERM.
WEDGED = """
import os, signal, threading
from pathlib import Path


class Wedged:
    calls = 0

    def __call__(self, obs):
        self.calls += 1
        if self.calls == 100:
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            Path(MARK + ".tmp").write_text(str(os.getpid()))
            os.replace(MARK + ".tmp", MARK)
            threading.Event().wait()
        return 450.0 * obs.pitch + 30.0 * obs.rate
"""


def test_closing_a_pool_ends_a_worker_that_ignores_sigterm_in_bounded_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Pool.terminate joins its workers without a timeout: a wedged one hung close(), a Ctrl-C included."""
    import psutil

    from hopper.experiments import executor

    mark = tmp_path / "wedged.pid"
    (tmp_path / "wedged.py").write_text(WEDGED.replace("MARK", repr(str(mark))))
    chunk = list(parse_spec({"controller": [f"{tmp_path / 'wedged.py'}:Wedged"], "seeds": 1, "hops": 1}).episodes())
    monkeypatch.setattr(executor, "STOP_S", 1.0, raising=False)
    pool = executor.LocalPool(1)
    pid = None
    try:
        pool.pool.apply_async(executor._run_in_process_worker, (chunk,))  # noqa: SLF001
        assert wait_until(mark.exists, timeout=120), "the worker never reached the wedge"
        pid = int(mark.read_text())
        closed = threading.Event()
        threading.Thread(target=lambda: (pool.close(), closed.set()), daemon=True).start()
        assert closed.wait(30), "close() still waits on the worker after 30 s"
    finally:
        if pid is not None and psutil.pid_exists(pid) and psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
            os.kill(pid, signal.SIGKILL)  # the old close() left it wedged
    assert not psutil.pid_exists(pid), "the worker was not reaped"
    err = capsys.readouterr().err
    assert f"local pool: worker {pid} did not stop within 1 s of SIGTERM: killed" in err, err


def test_a_sweep_on_a_local_ray_interrupted_half_way_resumes_without_redoing_episodes(tmp_path: Path) -> None:
    out = tmp_path / "out"
    flags = ["sweep", "--out", str(out), "--seeds", "10", "--kp", "300,450,600,750", "--wheel", "on,off", "--hops",
             "2", "--executor", "ray", "--workers", "2"]  # fmt: skip
    total = 10 * 4 * 2
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}  # a local Ray, started by the CLI
    process = subprocess.Popen([sys.executable, "-m", "hopper.app.sim_cli", *flags], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=env)  # fmt: skip
    try:
        assert wait_until(lambda: any((out / "episodes").glob("part-*.parquet")), timeout=90), "no episode written"
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "hopper-sim: interrupted" and "Traceback" not in err, err
    first = {p.name: p.stat().st_mtime_ns for p in (out / "episodes").glob("*.parquet")}
    done = ds.dataset(out / "episodes", format="parquet").to_table().column("episode_id").to_pylist()
    assert 0 < len(done) < total, f"interrupted after {len(done)} of {total}: not half way"

    result = subprocess.run([sys.executable, "-m", "hopper.app.sim_cli", *flags], capture_output=True, text=True,
                            timeout=180, env=env)  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert f"{len(done)} of {total} episodes already done, {total - len(done)} to run" in result.stderr
    kept = {p.name: p.stat().st_mtime_ns for p in (out / "episodes").glob("*.parquet") if p.name in first}
    assert kept == first, "the first run's parts were rewritten"
    table = ds.dataset(out / "episodes", format="parquet").to_table()
    ids = table.column("episode_id").to_pylist()
    assert len(ids) == total and len(set(ids)) == total, "an episode is missing or was run twice"
    new = [i for name in set(p.name for p in (out / "episodes").glob("*.parquet")) - set(first)
           for i in ds.dataset(out / "episodes" / name).to_table().column("episode_id").to_pylist()]  # fmt: skip
    assert not set(new) & set(done) and len(new) == total - len(done)
    hops = ds.dataset(out / "hops", format="parquet").to_table()
    assert hops.num_rows == sum(r["hops_completed"] + (1 if r["fell"] else 0) for r in table.to_pylist())
    assert "wheel: on: 0/40 fell" in result.stdout and "off: 40/40 fell" in result.stdout, result.stdout
    # What the Ray actors computed is what a fresh simulation gives.
    spec = parse_spec(tomllib.loads((out / "spec.toml").read_text()))
    rows = {r["episode_id"]: r for r in table.to_pylist()}
    for episode in list(spec.episodes())[::23]:
        mine = Worker().run(episode).row()
        theirs = rows[episode.episode_id]
        assert {k: v for k, v in mine.items() if k != "wall_s"} == {k: v for k, v in theirs.items() if k != "wall_s"}
    assert SweepStore(out, spec).done_ids() == set(ids)


@pytest.mark.parametrize(
    "failure, words",
    [
        ("auth", "RPC error: InvalidAuthToken: Authentication token is missing"),
        ("connection", "Failed to connect to Ray cluster at 127.0.0.1:1"),  # its cause says why
    ],
)
def test_an_executor_that_cannot_start_leaves_no_sweep_folder_and_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], failure: str, words: str
) -> None:
    """ray.init raising past the address probe (here in this process, as Ray 2.60 raises it: an
    AuthenticationError, a RayError, escaped as a traceback; a ConnectionError whose cause says why) left
    OUT holding a spec.toml and no episodes, a sweep the next command resumed. A resumed OUT is left as it was."""
    import ray
    import ray.exceptions
    from hopper.app.sim_cli import main

    def refuse(*args: object, **kwargs: object) -> None:
        if failure == "auth":
            raise ray.exceptions.AuthenticationError("RPC error: InvalidAuthToken: Authentication token is missing")
        try:
            raise RuntimeError("Failed to connect to GCS: Authentication token is missing or incorrect")
        except RuntimeError as exc:
            raise ConnectionError("Failed to connect to Ray cluster at 127.0.0.1:1") from exc

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setattr(ray, "init", refuse)
    flags = ["--seeds", "2", "--hops", "1", "--executor", "ray"]
    with pytest.raises(SystemExit) as exit:
        main(["sweep", "--out", str(tmp_path / "new"), *flags])
    err = capsys.readouterr().err
    hint = "(token authentication? see the README)"
    assert exit.value.code == 2 and err == f"hopper-sim: error: cannot start or reach a local Ray {hint}: {words}\n"
    assert not (tmp_path / "new").exists(), "the folder made for the sweep was left behind"

    resumed = tmp_path / "resumed"
    spec = parse_spec({"seeds": 2, "hops": 1})
    run_sweep(spec, resumed, lambda todo: InProcess(), progress=False, announce=lambda _: None)
    for part in [*(resumed / "episodes").glob("*.parquet"), *(resumed / "hops").glob("*.parquet")]:
        part.unlink()  # its episodes to run again, in a folder this command did not make
    before = sorted(p.relative_to(resumed) for p in resumed.rglob("*"))
    with pytest.raises(SystemExit):
        main(["sweep", "--out", str(resumed), *flags])
    assert sorted(p.relative_to(resumed) for p in resumed.rglob("*")) == before


# hopper-sim, with a thread that signals its main thread (as the kernel may pick any thread) once that
# runs the function FUNCTION of Ray's FILE (ray/_private/...) at the line holding TEXT or after.
STOPPED_IN_RAY_INIT = """
import inspect, importlib, os, signal, sys, threading, time

module = importlib.import_module(os.environ["MODULE"])
function, text = os.environ["FUNCTION"], os.environ["TEXT"]
code = inspect.unwrap(getattr(module, function.split(".")[0]))
if "." in function:
    code = getattr(code, function.split(".")[1])
lines, first = inspect.getsourcelines(code)
at = first + next(i for i, line in enumerate(lines) if text in line)


def watch():
    main = threading.main_thread().ident
    while True:
        frame = sys._current_frames().get(main)
        while frame is not None:
            if frame.f_code is code.__code__ and frame.f_lineno >= at:
                signal.pthread_kill(main, getattr(signal, os.environ["STOP_SIGNAL"]))
                return
            frame = frame.f_back
        time.sleep(0.0005)


threading.Thread(target=watch, daemon=True).start()
from hopper.app.sim_cli import main

sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize(
    "signum, where",
    [
        # Ctrl-C as ray.init makes its core worker: that worker was out of ray.shutdown's reach, and
        # the exit crashed in Ray's C++ (SIGSEGV) in about two runs of three.
        ("SIGINT", ("ray._private.worker", "connect", "ray._raylet.CoreWorker(")),
        # SIGTERM while ray.init starts the local Ray: its own handler then, it exited 15 (or 1), not 130.
        ("SIGTERM", ("ray._private.node", "Node.start_ray_processes", "start_raylet")),
    ],
    ids=["sigint-making-the-core-worker", "sigterm-starting-ray"],
)
def test_a_stop_while_ray_starts_exits_130_in_one_line_and_leaves_nothing(
    tmp_path: Path, signum: str, where: tuple[str, str, str]
) -> None:
    import psutil

    module, function, text = where
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}  # a local Ray, started by the CLI
    env |= {"MODULE": module, "FUNCTION": function, "TEXT": text, "STOP_SIGNAL": signum}
    out = tmp_path / "out"
    flags = ["sweep", "--out", str(out), "--seeds", "4", "--hops", "400", "--terrain", "flat", "--executor", "ray",
             "--workers", "2"]  # fmt: skip
    process = subprocess.Popen([sys.executable, "-c", STOPPED_IN_RAY_INIT, *flags], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)  # fmt: skip
    try:
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    lines = [line for line in err.splitlines() if line.strip() and "episodes:" not in line]
    assert process.returncode == 130 and lines == ["hopper-sim: interrupted"], (process.returncode, err[-3000:])
    assert not out.exists(), "a sweep folder was made before Ray had started"

    def session() -> list[psutil.Process]:  # what the CLI started and is still running, Ray's daemons included
        alive = []
        for p in psutil.process_iter():
            with contextlib.suppress(psutil.Error, OSError):
                if os.getsid(p.pid) == process.pid and p.status() != psutil.STATUS_ZOMBIE:
                    alive.append(p)
        return alive

    assert wait_until(lambda: not session(), timeout=30), [p.cmdline() for p in session()]


def test_unreachable_tells_a_closed_loopback_port_from_a_silent_one_and_from_a_grpc_server() -> None:
    import socket
    import threading

    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen(2)
        address = f"127.0.0.1:{listening.getsockname()[1]}"
        silent = "it accepts TCP but gave no gRPC handshake within 0.5 s: not a Ray head"
        assert unreachable(address, timeout_s=0.5) == silent
        listening.accept()[0].close()  # that one, then a gRPC server's first frame: SETTINGS (RFC 9113)

        def answer() -> None:
            peer = listening.accept()[0]
            with peer:
                peer.settimeout(5.0)
                peer.sendall(bytes([0, 0, 0, 0x4, 0, 0, 0, 0, 0]))
                while peer.recv(64):  # the probe's preface, until it closes (no reset of unread bytes)
                    pass

        server = threading.Thread(target=answer)
        server.start()
        assert unreachable(address, timeout_s=5.0) is None
        server.join(timeout=5.0)
        assert not server.is_alive()
    assert unreachable(f"127.0.0.1:{free_port()}", timeout_s=2.0) == "connection refused"
    assert unreachable(f"ray://127.0.0.1:{free_port()}", timeout_s=2.0) == "connection refused"
    assert unreachable("auto") is None  # Ray finds the cluster `ray start` runs here itself
    for port in ("99999", "0"):  # the socket said "connection refused" for a port that cannot exist
        assert unreachable(f"127.0.0.1:{port}") == f"port {port} is not a TCP port (1 to 65535)"


@pytest.mark.integration  # a process (Ray is never started: the probe fails first)
def test_a_ray_address_where_nothing_listens_fails_in_one_line_not_minutes_of_retries(tmp_path: Path) -> None:
    port = free_port()  # 127.0.0.1 only, nothing listening
    result = hopper_sim("sweep", "--out", str(tmp_path / "t"), "--seeds", "1", "--hops", "1", "--executor", "ray",
                        "--address", f"127.0.0.1:{port}", timeout=60)  # fmt: skip
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert f"cannot reach the Ray cluster at 127.0.0.1:{port}: connection refused" in result.stderr


def test_a_sweep_counts_a_controller_fault_as_a_failure_and_says_why(tmp_path: Path) -> None:
    (tmp_path / "flaky.py").write_text(FLAKY)
    out = tmp_path / "runs"
    flags = ["--controller", "pid,flaky.py:Flaky", "--seeds", "1", "--hops", "2", "--executor", "local"]
    result = hopper_sim("sweep", "--out", str(out), *flags, "--workers", "1", cwd=tmp_path)
    assert result.returncode == 4, result  # as run's: the PID flew the rest of the faulted episode
    cause = "Flaky returned nan N m"
    assert "2 episodes, 0 fell (0.0 %), 1 controller fault," in result.stdout, result.stdout
    assert "Flaky: 0/1 fell, 1 controller fault" in result.stdout and cause in result.stdout, result.stdout
    assert result.stderr.strip().splitlines()[-1].startswith("hopper-sim: error: controller ")
    assert f"Flaky failed in 1 of 1 episodes: {cause}" in result.stderr, result.stderr
    again = hopper_sim("sweep", "--out", str(out), *flags, cwd=tmp_path)  # nothing left to run: the same verdict
    assert again.returncode == 4 and "nothing left to run" in again.stdout, again


def test_a_disturbance_that_never_came_is_recorded_and_not_counted_a_survivor(tmp_path: Path) -> None:
    out = tmp_path / "late"  # a kick 5 s into the flight of hop 2: the flight is over long before
    flags = ["--seeds", "1", "--hops", "2", "--disturbance", "none", "--disturbance", "pitch_kick:1:flight:5.0:2"]
    result = hopper_sim("sweep", "--out", str(out), *flags, "--executor", "local", "--workers", "1")
    assert result.returncode == 0, result
    rows = ds.dataset(out / "episodes").to_table().to_pylist()
    applied = {row["disturbance_size"]: row["disturbance_applied"] for row in rows}
    assert applied == {0.0: True, 1.0: False}
    assert "1 of 2 episodes' disturbance was not applied" in result.stdout, result.stdout
    assert "1 not disturbed" in result.stdout.splitlines()[0], result.stdout
