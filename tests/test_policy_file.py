"""Trained weights flown by spec, `policy:FILE`: in run and the league, from other folders, in the
dashboard; a missing, damaged or other-layout file refused in one line before any work."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hopper.app.dashboard.probe import ProbeClient
from net import free_port, wait_until

from hopper.config import SimConfig
from hopper.controllers import ControllerError, load_class, with_controller
from hopper.controllers.features import LAYOUT
from hopper.laws.policy import Policy, Weights, load_weights
from hopper.sim import Simulation

pytestmark = pytest.mark.integration  # subprocesses and a served dashboard


def hopper_sim(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=600, cwd=cwd
    )


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A user's folder holding weights trained elsewhere: the shipped ones, perturbed (Weights.save),
    and a damaged file and one for another observation layout."""
    folder = tmp_path_factory.mktemp("trained")
    shipped = load_weights()
    theta = shipped.flat() + 0.05 * np.random.default_rng(0).standard_normal(shipped.flat().shape)
    Weights.unflat(theta, shipped.hidden).save(folder / "weights.json", meta={"note": "perturbed"})
    text = (folder / "weights.json").read_text()
    (folder / "damaged.json").write_text(text[: len(text) // 2])  # cut off mid-write
    doc = json.loads(text)
    doc["layout"] = {**LAYOUT, "version": 0, "hash": "0123456789ab"}
    (folder / "old.json").write_text(json.dumps(doc))
    return folder


def test_the_spec_names_its_file_by_absolute_path_and_flies_those_weights(
    folder: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(folder)
    config = with_controller(SimConfig(seed=2), "policy:weights.json")
    assert config.controller == f"policy:{folder / 'weights.json'}"
    assert load_class(config.controller) is Policy
    landings = {}
    for name, flown in (("shipped", with_controller(SimConfig(seed=2), "policy")), ("file", config)):
        sim = Simulation(flown)
        landings[name] = [h.landing_error_deg for h in sim.run(3)]
        assert not sim.fallen and sim.controller_fault is None
    assert (sim.law.controller.weights.flat() == load_weights(folder / "weights.json").flat()).all()
    assert landings["file"] != pytest.approx(landings["shipped"], abs=1e-3)  # not the shipped weights


def test_run_and_the_league_fly_the_file_from_a_relative_spec(folder: Path) -> None:
    spec, absolute = "policy:weights.json", f"policy:{folder / 'weights.json'}"
    runs = {}
    for controller in ("policy", spec):
        out = folder / f"run-{len(runs)}.json"
        result = hopper_sim("run", "--hops", "3", "--controller", controller, "--json", str(out), cwd=folder)
        assert result.returncode == 0, result.stderr
        runs[controller] = json.loads(out.read_text())
    assert runs[spec]["settings"]["controller"] == absolute and f"controller {absolute} (Policy;" in result.stdout
    peaks = [[h["peak_pitch_deg"] for h in runs[c]["hops"]] for c in ("policy", spec)]
    assert peaks[0] != pytest.approx(peaks[1], rel=0.05)  # the perturbed weights fly measurably otherwise

    league = hopper_sim("league", "--quick", "--controllers", f"policy,{spec}", "--workers", "2",
                        "--json", str(folder / "league.json"), cwd=folder)  # fmt: skip
    assert league.returncode == 0, league.stderr
    rows = {r["controller"]: r for r in json.loads((folder / "league.json").read_text())["rows"]}
    assert set(rows) == {"policy", absolute} and rows[absolute]["episodes"] == rows["policy"]["episodes"] > 10
    assert rows[absolute]["faults"] == 0 and rows[absolute]["landing_p50_deg"] != rows["policy"]["landing_p50_deg"]


def test_a_worker_started_in_another_folder_finds_the_file(folder: Path, tmp_path: Path) -> None:
    """The spec travels as a string (pools, Ray, saved settings): parsed once, it names the file wherever read."""
    spec = _canonical_in(folder, "policy:weights.json")
    code = (
        "import sys; from hopper.config import SimConfig; from hopper.sim import Simulation;"
        f"sim = Simulation(SimConfig(controller={spec!r})); print(type(sim.law.controller).__name__)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "Policy", result.stderr


def _canonical_in(folder: Path, spec: str) -> str:
    result = subprocess.run(
        [sys.executable, "-c", f"from hopper.controllers.loading import canonical; print(canonical({spec!r}))"],
        capture_output=True, text=True, timeout=60, cwd=folder,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


@pytest.mark.parametrize(
    ("file", "message"),
    [
        ("missing.json", "policy weights {folder}/missing.json: no such file"),
        ("damaged.json", "policy weights {folder}/damaged.json: unreadable (JSONDecodeError"),
        ("old.json", "policy weights {folder}/old.json: trained for observation layout '0123456789ab'"),
        ("", "'policy:' names no file: give policy:FILE"),
    ],
)
@pytest.mark.parametrize("command", ["run", "league", "dashboard"])
def test_a_bad_weights_file_is_one_line_and_exit_2_before_any_work(
    folder: Path, file: str, message: str, command: str
) -> None:
    spec = f"policy:{file}"
    if command == "dashboard":
        args = [
            sys.executable,
            "-m",
            "hopper.app.dashboard.cli",
            "--port",
            str(free_port()),
            "--controller-choice",
            spec,
        ]
        prefix = "hopper-dashboard: error: "
    else:
        flag = ["--controller", spec] if command == "run" else ["--quick", "--controllers", f"pid,{spec}"]
        args = [sys.executable, "-m", "hopper.app.sim_cli", command, *flag, "--json", str(folder / "never.json")]
        prefix = "hopper-sim: error: "
    result = subprocess.run(args, capture_output=True, text=True, timeout=300, cwd=folder)
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix + message.format(folder=folder)), lines
    assert result.stdout == "" and not (folder / "never.json").exists()


def test_a_built_in_that_takes_no_file_says_which_does() -> None:
    with pytest.raises(ControllerError, match=r"^lqr takes no file after a colon \(policy:FILE does"):
        load_class("lqr:weights.json")


def test_the_dashboard_offers_the_file_and_its_panel_names_it(folder: Path, start: Any) -> None:
    spec = f"policy:{folder / 'weights.json'}"
    d = start(controller_choice=("policy:" + str(folder / "." / "weights.json"),))
    assert d.config.controller_choice == (spec,)
    probe = ProbeClient(d.url)
    try:
        assert wait_until(lambda: d.roles.operator is not None)
        assert spec in d.layout.controller.choice.options
        probe.set_gui_value("Controller", spec)
        assert wait_until(lambda: d.sim.law.spec == spec, timeout=60), d.sim.law.spec
        assert wait_until(lambda: "(weights.json)" in d.layout.controller.info.content), (
            d.layout.controller.info.content
        )
        assert f"title='{spec}'" in d.layout.controller.info.content  # the whole path on hover
        assert isinstance(d.sim.law.controller, Policy)
    finally:
        probe.close()
