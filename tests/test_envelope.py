"""The flight envelope: the physical limit from the model, and flown kicks on either side of it."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from hopper.analysis import envelope
from hopper.config import (
    LEG_TORQUE_LIMIT,
    WHEEL_ARMATURE,
    WHEEL_INERTIA,
    WHEEL_NO_LOAD_SPEED,
    WHEEL_TORQUE_LIMIT,
    SimConfig,
)
from hopper.control import Phase
from hopper.control.gait import LEG_SHARE, momentum_capacity
from hopper.experiments.stress import LANDING_LIMIT_DEG, run_case
from hopper.model import build_model
from hopper.sim import Simulation

FLAT = SimConfig(terrain="flat")


@pytest.fixture(scope="module")
def moments() -> list[envelope.Moment]:
    return envelope.flight_moments(FLAT, every_s=0.05)


def test_the_flight_is_sampled_from_liftoff_to_touchdown(moments: list[envelope.Moment]) -> None:
    flight = moments[0].to_go
    assert 0.8 < flight < 1.2  # a lunar hop of 0.25 m: about 1 s
    assert all(math.isclose(m.t + m.to_go, flight, abs_tol=1e-9) for m in moments)
    assert all(0.4 < m.locked < 0.6 and 0.1 < m.torso < 0.13 for m in moments)  # kg m^2, PHYSICS.md


def test_the_wheel_takes_the_torsos_momentum_through_its_own_inertia_not_the_armature() -> None:
    # MuJoCo couples pitch and wheel by the wheel body's spin inertia alone; the armature is the
    # wheel joint's own. So a kick saturates the wheel at I_w w_max (1.41 N m s), not 1.60.
    model = build_model(FLAT)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    inertia = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, inertia)
    pitch, wheel = (model.jnt_dofadr[model.joint(name).id] for name in ("pitch", "wheel"))
    assert inertia[pitch, wheel] == pytest.approx(WHEEL_INERTIA)
    assert inertia[wheel, wheel] == pytest.approx(WHEEL_INERTIA + WHEEL_ARMATURE)
    still = envelope.Moment(t=0.0, to_go=10.0, wheel_speed=0.0, momentum=0.0, locked=0.5, torso=0.12)
    assert envelope.wheel_reach(still, 1.0) == pytest.approx(WHEEL_INERTIA * WHEEL_NO_LOAD_SPEED, rel=1e-6)
    assert envelope.wheel_reach(still, 1.0) < 0.9 * momentum_capacity()


def test_the_limit_is_the_wheels_headroom_early_and_grows_as_the_touchdown_nears(moments) -> None:  # noqa: ANN001
    early, late = moments[2], moments[-3]
    for sign in (1.0, -1.0):
        assert envelope.wheel_reach(early, sign) <= envelope.physical_limit(early, sign)
        assert envelope.physical_limit(early, sign) < 1.3 * momentum_capacity()  # the wheel sets it
        assert envelope.physical_limit(late, sign) > envelope.physical_limit(early, sign)


def test_the_torque_bound_is_an_impulses_swing_before_the_actuators_stop_it(moments) -> None:  # noqa: ANN001
    # 0.05 s before the touchdown a kick of 4 N m s swings the torso out by about 20 deg before
    # 90 N m stop it, and a torso that turns at 35 rad/s cannot be brought back in 0.05 s.
    late = min(moments, key=lambda m: abs(m.to_go - 0.05))
    assert not envelope.torque_allows(late, 1.0, 4.0)
    assert envelope.torque_allows(late, 1.0, 0.1)
    assert envelope.physical_limit(late, 1.0) < envelope.momentum_limit(late, 1.0)


def test_kicks_under_the_limit_land_and_over_it_do_not(moments) -> None:  # noqa: ANN001
    flight = moments[0].to_go
    moment = min(moments, key=lambda m: abs(m.t - 0.3 * flight))
    limit = envelope.physical_limit(moment, 1.0)
    cases = envelope.envelope_cases(FLAT, [0.5 * limit, 1.4 * limit], [0.3], flight)
    under, over = (run_case(c) for c in cases)
    assert not under.fell and under.worst_landing_deg <= LANDING_LIMIT_DEG, under
    assert over.fell or over.worst_landing_deg > LANDING_LIMIT_DEG, over
    rows = envelope.rows([under, over], moments, [0.3], flight)
    plus = next(r for r in rows if r.sign > 0)
    assert plus.recovered == pytest.approx(0.5 * limit) and plus.falls_below_limit == 0
    assert plus.stood == (plus.recovered if over.fell else pytest.approx(1.4 * limit))


def test_hopper_sim_envelope_writes_its_table_figure_and_json(tmp_path: Path) -> None:
    out = tmp_path / "env"
    result = subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", "envelope", "--sizes", "0.5,3", "--moments", "0.5",
         "--out", str(out), "--workers", "2"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert result.returncode in (0, 1), result.stderr
    lines = result.stdout.splitlines()
    assert (
        lines[1].split()[:6] == ["kick", "moment", "t", "limit", "landed", "ratio"]
        and len([x for x in lines if "50%" in x]) == 2
    )
    data = json.loads((out / "envelope.json").read_text())
    assert len(data["cases"]) == 4 and len(data["rows"]) == 2
    assert (out / "envelope.png").stat().st_size > 10_000 and (out / "envelope.pdf").exists()


@pytest.mark.parametrize("flags", [["--sizes", "0,1"], ["--sizes", "x"], ["--moments", "1.5"], ["--sizes", "9"]])
def test_hopper_sim_envelope_refuses_bad_input_in_one_line(flags: list[str]) -> None:
    result = subprocess.run([sys.executable, "-m", "hopper.app.sim_cli", "envelope", *flags], capture_output=True,
                            text=True, timeout=120)  # fmt: skip
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) <= 2, result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("out", ["file", "/proc/no-such/env"])
def test_hopper_sim_envelope_refuses_an_unwritable_out_before_flying(tmp_path: Path, out: str) -> None:
    if out == "file":
        out = str(tmp_path / "run.out")
        Path(out).write_text("kept")
    result = subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", "envelope", "--sizes", "1", "--moments", "0.5",
         "--workers", "1", "--out", out],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "--out" in result.stderr and "kicks" not in result.stderr  # refused before any kick flew
    assert out.startswith("/proc") or Path(out).read_text() == "kept"


ENVELOPE = ("envelope", "--sizes", "0.5", "--moments", "0.5", "--workers", "1")  # 2 kicks, a few seconds


def _earlier_envelope(out: Path) -> None:
    """What an earlier `envelope --out OUT` left (its three files; their bytes do not matter)."""
    out.mkdir()
    for name in ("envelope.png", "envelope.pdf", "envelope.json"):
        (out / name).write_text(f"the earlier {name}")


def test_an_interrupted_envelope_leaves_out_as_it_was_and_a_finished_one_replaces_it_whole(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    handlers: None,
) -> None:
    """It wrote its three files in place: stopped between the figure and the JSON, OUT held the new
    figures beside the earlier JSON (or, new, the figures without their JSON). Stopped before its
    last kick now, OUT is as it was."""
    from in_process import cli, tree
    from stops import pool_stopping_after

    old = tmp_path / "old"
    _earlier_envelope(old)
    before = tree(tmp_path)
    pool_stopping_after(monkeypatch, 0)  # of 2
    for out in (old, tmp_path / "new"):
        code, _, err = cli(capsys, *ENVELOPE, "--out", str(out))
        assert code == 130 and err.endswith("hopper-sim: interrupted\n"), err
        assert tree(tmp_path) == before, f"{out}: an interrupted envelope changed what was there"
    monkeypatch.undo()
    old.chmod(0o750)
    code, printed, err = cli(capsys, *ENVELOPE, "--out", str(old))
    assert code in (0, 1) and printed.endswith(f"wrote {old / 'envelope.png'}, .pdf and .json\n"), err
    assert sorted(p.name for p in old.iterdir()) == ["envelope.json", "envelope.pdf", "envelope.png"]
    assert len(json.loads((old / "envelope.json").read_text())["cases"]) == 2, "the new envelope, whole"
    assert old.stat().st_mode & 0o777 == 0o750, "the folder keeps who may read it"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"], "a partial or old folder was left beside it"


@pytest.mark.parametrize("moment", ["last kick", "figure"])
def test_a_stop_once_every_kick_has_flown_ends_the_envelope_complete(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, handlers: None, moment: str
) -> None:
    """A Ctrl-C once the last kick was in (or as the figure was drawn) exited 130 `interrupted`, OUT
    unwritten, though every kick had flown: it cuts nothing short, and the envelope is written whole."""
    from in_process import cli
    from stops import ctrl_c, pool_stopping_after

    from hopper.report import envelope as envelope_report

    if moment == "last kick":
        pool_stopping_after(monkeypatch, 1)  # of 2
    else:
        figure = envelope_report.figure
        monkeypatch.setattr(envelope_report, "figure", lambda *args: (ctrl_c(), figure(*args))[1])
    out = tmp_path / "out"
    code, printed, err = cli(capsys, *ENVELOPE, "--out", str(out))
    assert code in (0, 1) and "interrupted" not in err, (code, err)
    assert "hopper-sim: the stop came after every kick was done: envelope is complete" in err, err
    assert printed.endswith(f"wrote {out / 'envelope.png'}, .pdf and .json\n"), printed
    assert len(json.loads((out / "envelope.json").read_text())["cases"]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"], "a partial folder was left beside it"


@pytest.mark.parametrize(
    "files, message",
    [
        (["envelope.json", "notes.txt"], "holds envelope.json and notes.txt, and is not an envelope's folder"),
        (["envelope.png", "envelope.pdf"], "holds envelope.pdf and envelope.png, and is not an envelope's folder"),
        (["envelope.json", "data/"], "holds data/ and envelope.json, and is not an envelope's folder"),
    ],
)
def test_an_out_that_holds_more_than_an_envelope_is_refused_before_flying(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], files: list[str], message: str
) -> None:
    """The envelope replaces its folder whole: one holding anything else would lose it (it was
    written into, mixed, before)."""
    from in_process import cli, tree

    out = tmp_path / "out"
    out.mkdir()
    for name in files:
        (out / name).mkdir() if name.endswith("/") else (out / name).write_text("mine")
    before = tree(tmp_path)
    code, printed, err = cli(capsys, *ENVELOPE, "--out", str(out))
    assert code == 2 and printed == "" and err.count("\n") == 1, err
    assert err.startswith(f"hopper-sim: error: --out: {out} ") and message in err and "kicks" not in err, err
    assert tree(tmp_path) == before


def test_the_folder_the_command_runs_in_is_refused_as_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from in_process import cli

    monkeypatch.chdir(tmp_path)
    code, _, err = cli(capsys, *ENVELOPE, "--out", ".")
    assert code == 2 and err == ("hopper-sim: error: --out: . is the folder this command runs in, which an "
                                 "envelope replaces whole: give another\n"), err  # fmt: skip
    assert not any(tmp_path.iterdir())


def _kicked_peak(share: float, kick: float, delay: float) -> float:
    """Peak |pitch| (deg) of the second flight after `kick` N m s `delay` s into it, legs' share `share`."""
    sim = Simulation(FLAT)
    sim.controller.mem["leg_share"] = share
    while len(sim.hops) < 1 or sim.phase is not Phase.FLIGHT:
        sim.step()
    start = sim.time
    while sim.time - start < delay:
        sim.step()
    sim.disturb("pitch_kick", kick)
    peak = 0.0
    while sim.phase is Phase.FLIGHT:
        sim.step()
        peak = max(peak, abs(sim.state().pitch))
    return math.degrees(peak)


def test_the_legs_take_a_kick_down_to_near_the_floor_the_actuators_set(moments) -> None:  # noqa: ANN001
    """A 0.7-capacity kick: its swing, against h^2 / (2 I_torso tau) with the wheel and both hips at
    their torque limits, and against the wheel alone. That estimate takes the torso alone; its
    hips sit 0.18 m below its CoM, so a kicked torso drags the legs along and can swing a little
    less (3.34 against 3.47 deg, with the hips braking at their limit and rigid legs)."""
    kick, delay = 0.7 * momentum_capacity(), 0.3
    moment = min(moments, key=lambda m: abs(m.t - delay))
    stall = WHEEL_TORQUE_LIMIT * (1.0 - abs(moment.wheel_speed) / WHEEL_NO_LOAD_SPEED)
    floor = math.degrees(kick**2 / (2.0 * moment.torso * (stall + 2.0 * LEG_TORQUE_LIMIT)))
    shared = _kicked_peak(LEG_SHARE, kick, delay)
    alone = _kicked_peak(0.0, kick, delay)
    assert 0.9 * floor < shared < 1.1 * floor, (floor, shared)
    assert alone > 2.5 * shared, (alone, shared)  # the wheel alone: about 13 deg
