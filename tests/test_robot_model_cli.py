"""`--model` on hopper-sim: a variant runs and is stressed on its own wheel; a misnamed model exits 2 in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import variants

from hopper.config import SimConfig
from hopper.layout import NAMES
from hopper.model import robot_of

pytestmark = pytest.mark.integration  # processes and pools (conftest: the suite in parts)


def hopper_sim(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


@pytest.mark.parametrize("command", ["run", "compare", "stress", "league", "envelope", "sweep", "tune"])
def test_a_renamed_actuator_exits_2_in_one_line_naming_it(tmp_path: Path, command: str) -> None:
    path = variants.renamed_actuator(tmp_path)
    extra = ["--out", str(tmp_path / "out")] if command == "sweep" else []
    done = hopper_sim(command, "--model", str(path), *extra)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hopper-sim: error: argument --model: "), done.stderr
    assert "no actuator 'wheel'" in lines[0] and f"expected {', '.join(NAMES['actuator'])}" in lines[0]
    assert not (tmp_path / "out").exists()  # refused before any work


def test_a_missing_model_file_exits_2_in_one_line(tmp_path: Path) -> None:
    done = hopper_sim("run", "--model", str(tmp_path / "nowhere.xml"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "no such file" in done.stderr


@pytest.mark.parametrize("name", ["robot.mjcf", "robot.XML", "robot"])
def test_a_model_whose_name_mujoco_will_not_read_exits_2_saying_so(tmp_path: Path, name: str) -> None:
    """MjSpec.from_file picks its decoder by the name: a valid MJCF named otherwise read as 'not a
    valid MJCF file (could not find decoder ...)', with MuJoCo's own warning lines before it."""
    path = tmp_path / name
    path.write_bytes(variants.variant(tmp_path).read_bytes())
    done = hopper_sim("run", "--model", str(path))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.strip().endswith(
        f"model {path}: MuJoCo reads an MJCF file only if its name ends in .xml: rename it"
    )


@pytest.mark.parametrize("command", [["size", "--gravity", "earth"], ["identify", "log.csv"]])
def test_a_model_written_under_a_name_mujoco_will_not_read_back_is_refused_first(
    tmp_path: Path, command: list[str]
) -> None:
    done = hopper_sim(*command, "--out", str(tmp_path / "earth.mjcf"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "earth.mjcf: an MJCF file is read back (--model) only if its name ends in .xml" in done.stderr
    assert not (tmp_path / "earth.mjcf").exists()


def test_run_flies_a_variant_from_a_relative_path(tmp_path: Path) -> None:
    variants.variant(tmp_path)
    out = tmp_path / "run.json"
    done = hopper_sim("run", "--model", "variant.xml", "--hops", "5", "--seed", "2", "--json", str(out), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    result = json.loads(out.read_text())
    assert result["settings"]["model"] == str(tmp_path / "variant.xml")  # absolute: workers find it too
    hops = [h for h in result["hops"] if h["completed"]]
    assert len(hops) == 5 and not result["fell"]
    assert max(abs(h["landing_pitch_deg"]) for h in hops) < 1.0
    assert f"model {tmp_path / 'variant.xml'}, terrain crater" in done.stdout


def test_stress_kicks_a_variant_by_its_own_wheel(tmp_path: Path) -> None:
    path = variants.variant(tmp_path)
    out = tmp_path / "stress.json"
    done = hopper_sim(
        "stress", "--quick", "--groups", "flight", "--workers", "2", "--model", str(path), "--json", str(out)
    )
    assert done.returncode == 0, done.stdout + done.stderr
    cases = json.loads(out.read_text())["cases"]
    assert len(cases) == 8 and all(c["passed"] for c in cases)
    assert {c["settings"]["model"] for c in cases} == {str(path)}
    kick = 0.7 * robot_of(SimConfig(model=str(path), terrain="flat")).momentum_capacity
    assert any(f"pitch kick {kick:+.2f} N m s" in c["case"] for c in cases)
    assert kick > 0.7 * robot_of(SimConfig(terrain="flat")).momentum_capacity * 1.2  # the variant's wheel holds more
