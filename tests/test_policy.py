"""The learned controller: the shipped weights fly through the API; other layouts and damaged files are refused."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from hopper.config import SimConfig
from hopper.controllers import ControllerError, build, with_controller
from hopper.controllers.features import LAYOUT
from hopper.laws.policy import Policy, Weights, load_weights
from hopper.sim import Simulation

SHIPPED = Path(__file__).resolve().parent.parent / "hopper" / "laws" / "policy_weights.json"


@pytest.mark.parametrize("seed", [0, 5])
def test_the_policy_flies_seven_hops_without_a_fall(seed: int) -> None:
    sim = Simulation(with_controller(SimConfig(seed=seed), "policy"))
    hops = sim.run(7)
    assert not sim.fallen and len(hops) == 7 and sim.controller_fault is None
    assert max(abs(h.landing_error_deg) for h in hops) < 2.0
    assert type(sim.law.controller) is Policy


def test_the_policy_is_a_controller_like_any_other() -> None:
    policy = build("policy")
    assert isinstance(policy, Policy) and callable(policy)


LAWS = """
from hopper.config import Gains
from hopper.laws.pid import PaperPID
from hopper.laws.policy import Policy, Weights

class StartPolicy(Policy):  # the training's start: the paper's PID on the skip path
    def __init__(self):
        g = Gains()
        super().__init__(Weights.pid(g.kp, g.kd, g.ki, seed=2))

class PythonPID(PaperPID):
    compiled = None  # through the API, as the policy flies
"""


@pytest.mark.parametrize("sensing", ["ideal", "realistic"])
def test_the_trainings_start_is_the_papers_pid_integral_and_all(tmp_path: Path, sensing: str) -> None:
    (tmp_path / "laws.py").write_text(LAWS)
    landings = []
    for name, values in (("StartPolicy", {}), ("PythonPID", {}), ("PythonPID", {"ki": 0.0})):
        sim = Simulation(with_controller(SimConfig(seed=3, sensing=sensing), f"{tmp_path}/laws.py:{name}", values))
        landings.append([h.landing_error_deg for h in sim.run(3)])
    assert landings[0] == pytest.approx(landings[1], abs=1e-9)
    assert landings[0] != pytest.approx(landings[2], abs=1e-6)  # the integral is there and it matters


def test_the_weights_round_trip(tmp_path: Path) -> None:
    w = Weights.pid(450.0, 30.0, 50.0, hidden=4, seed=1)
    w.save(tmp_path / "w.json")
    back = load_weights(tmp_path / "w.json")
    assert (back.flat() == w.flat()).all() and back.hidden == 4
    assert (Weights.unflat(w.flat(), 4).flat() == w.flat()).all()


def _refused(path: Path) -> str:
    with pytest.raises(ControllerError) as info:
        load_weights(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    return message


def test_weights_for_another_observation_layout_are_refused_in_one_line(tmp_path: Path) -> None:
    doc = json.loads(SHIPPED.read_text())
    doc["layout"] = {**LAYOUT, "version": 0, "fields": ["pitch", "rate"], "hash": "0123456789ab"}
    (tmp_path / "old.json").write_text(json.dumps(doc))
    assert "layout '0123456789ab'" in _refused(tmp_path / "old.json")


def test_weights_for_layout_1_without_the_integral_are_refused_in_one_line(tmp_path: Path) -> None:
    doc = json.loads(SHIPPED.read_text())
    fields = ["pitch", "rate", "wheel_speed", "time_to_touchdown", "time_since_liftoff", "headroom_up",
              "headroom_down", "gravity"]  # fmt: skip
    doc["layout"] = {"version": 1, "fields": fields, "hash": "8034a004e976"}  # the first shipped file's
    (tmp_path / "v1.json").write_text(json.dumps(doc))
    assert "layout '8034a004e976', this build reads" in _refused(tmp_path / "v1.json")


@pytest.mark.parametrize(
    ("damage", "cause"),
    [
        (lambda text: text[: len(text) // 2], "unreadable"),
        (lambda text: text.replace('"w2"', '"w3"'), "damaged"),
        (lambda text: json.dumps({**json.loads(text), "b2": "nan"}), "damaged"),
        (lambda text: "[]", "not a hopper-policy"),
    ],
)
def test_a_damaged_weights_file_is_refused_in_one_line(tmp_path: Path, damage, cause: str) -> None:
    (tmp_path / "bad.json").write_text(damage(SHIPPED.read_text()))
    assert cause in _refused(tmp_path / "bad.json")


def test_a_missing_weights_file_is_refused(tmp_path: Path) -> None:
    assert _refused(tmp_path / "none.json").endswith("none.json: no such file")


@pytest.mark.integration
def test_a_short_training_runs_and_one_seed_gives_the_same_weights(tmp_path: Path) -> None:
    if os.environ.get("CI") != "true":  # under CI the [test] extra installs cma: never skip there
        pytest.importorskip("cma", reason="the [rl] extra (cma) is not installed")
    from hopper.app.train_policy import main

    runs = []
    for name in ("a.json", "b.json"):
        out = tmp_path / name
        small = ["--generations", "2", "--episodes", "1", "--popsize", "3", "--validation", "2", "--test", "2"]
        assert main(["--seed", "3", *small, "--every", "1", "--out", str(out)]) == 0
        runs.append(load_weights(out))
    meta = json.loads(out.read_text())["meta"]
    assert meta["generations"] == 2 and runs[0].hidden == 16 and meta["test"]["episodes"] == 2
    assert (runs[0].flat() == runs[1].flat()).all()


@pytest.mark.integration
def test_ctrl_c_during_training_exits_130_in_one_line_and_writes_nothing(tmp_path: Path) -> None:
    """A terminal's Ctrl-C reaches the workers too: they printed KeyboardInterrupt tracebacks, and so
    did the trainer itself."""
    if os.environ.get("CI") != "true":  # under CI the [test] extra installs cma: never skip there
        pytest.importorskip("cma", reason="the [rl] extra (cma) is not installed")
    out = tmp_path / "w.json"
    small = ["--generations", "1000", "--episodes", "2", "--popsize", "4", "--validation", "2", "--test", "2"]
    process = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.train_policy", *small, "--workers", "2", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's Ctrl-C reaches every process of it
    )
    try:
        first = process.stdout.readline()  # the start's validation: the workers are up, the search begins
        assert first.startswith("PID start"), first + process.stderr.read()
        os.killpg(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 130, err
    assert err == "train_policy: interrupted\n", err
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--sig", "0.1"], "unrecognized arguments: --sig 0.1"),  # was taken for --sigma
        (["--seed", "-1"], "argument --seed: seed must be a non-negative integer below 2^64, got -1"),
        (["--seed", str(2**32 - 1)], "argument --seed: must be at most 4294967294 (CMA-ES takes seed + 1 < 2^32)"),
        (["--every", "0"], "argument --every: must be at least 1, got 0"),  # ZeroDivisionError, mid-training
        (["--popsize", "1"], "argument --popsize: must be at least 2, got 1"),
        (["--test", "1"], "argument --test: must be at least 2, got 1"),  # a NaN interval
        (["--sigma", "nan"], "argument --sigma: nan is not a finite number"),
        (["--sigma", "0"], "argument --sigma: must be above 0, got 0"),
        (["--out", "/proc/weights.json"], "argument --out: cannot write /proc/weights.json"),  # after the training
    ],
)
def test_the_training_refuses_bad_arguments_in_one_line_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    """hopper-sim's parser and number checks: one line, exit 2, no abbreviation; nothing trained, nothing written."""
    from hopper.app.train_policy import main

    small = ["--generations", "1", "--episodes", "1", "--popsize", "2", "--validation", "1", "--test", "2"]
    with pytest.raises(SystemExit) as exit:
        main([*small, "--out", str(tmp_path / "w.json"), *args])
    captured = capsys.readouterr()
    assert exit.value.code == 2 and captured.out == "", captured.out
    assert captured.err.startswith(f"train_policy: error: {message}") and captured.err.count("\n") == 1, captured.err
    assert not any(tmp_path.iterdir())
