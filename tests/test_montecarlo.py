"""Monte Carlo over model uncertainty: distributions, seeded robots, the model read back, Wilson intervals, the CLI."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
import tomllib
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow.dataset as ds
import pytest

from hopper.config import MOTOR_TORQUE_CONSTANT, STANDARD_GRAVITY, SimConfig
from hopper.experiments.montecarlo import group_stats, percent, success, wilson
from hopper.experiments.spec import SpecError, parse_spec
from hopper.experiments.uncertainty import TRUNCATE_SD, Distribution, UncertaintyError, params, parse_model
from hopper.mismatch import quantities
from hopper.model import build_model
from hopper.sim import Simulation

AROUND_DEFAULT = {  # the acceptance's tolerances (benchmarks/montecarlo.toml), every parameter
    "mass_torso": {"uniform": [0.9, 1.1], "relative": True},
    "mass_wheel": {"uniform": [0.9, 1.1], "relative": True},
    "mass_thigh": {"uniform": [0.9, 1.1], "relative": True},
    "mass_shank": {"uniform": [0.9, 1.1], "relative": True},
    "inertia_torso": {"uniform": [0.85, 1.15], "relative": True},
    "inertia_thigh": {"normal": [1.0, 0.05], "relative": True},
    "inertia_shank": {"uniform": [0.85, 1.15], "relative": True},
    "wheel_inertia": {"uniform": [0.85, 1.15], "relative": True},
    "motor_torque": {"uniform": [0.038, 0.044]},
    "friction": {"uniform": [0.5, 1.0]},
    "com_x": {"normal": [0.0, 0.005]},
    "com_z": {"uniform": [-0.01, 0.01]},
    "delay": {"uniform": [0, 5]},
    "gyro_noise": {"uniform": [0.01, 0.02]},
    "accel_noise": {"normal": [175.0, 20.0]},
    "gyro_bias": {"uniform": [-1, 1]},
    "accel_bias_x": {"uniform": [-1, 1]},
    "accel_bias_z": {"normal": [0.0, 0.3]},
}


def hopper_sim(*args: str, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=timeout, cwd=cwd
    )


def test_distributions_parse_into_their_shape_and_read_back_from_the_resolved_spec() -> None:
    model = parse_model({"samples": 4, "seed": 7, **AROUND_DEFAULT})
    dists = dict(model.distributions)
    assert model.names() == tuple(n for n in params() if n in AROUND_DEFAULT), "the canonical order, not the table's"
    assert dists["mass_torso"] == Distribution("uniform", 0.9, 1.1, relative=True)
    assert dists["com_x"] == Distribution("normal", 0.0, 0.005)
    assert dists["mass_torso"].support(4.0) == pytest.approx((3.6, 4.4))
    assert dists["com_x"].support(0.0) == pytest.approx((-TRUNCATE_SD * 0.005, TRUNCATE_SD * 0.005))
    edges = parse_model({"samples": 1, "seed": 0, "friction": {"uniform": [0.16, 4.0]}})  # 0.2 and 5 x 0.8, rounded
    assert dict(edges.distributions)["friction"].support(0.8) == (0.16, 4.0)
    spec = parse_spec({"sensing": "realistic", "hops": 1, "model": {"samples": 4, "seed": 7, **AROUND_DEFAULT}})
    assert spec.size == 4 and parse_spec(tomllib.loads(spec.to_toml())) == spec


def test_every_draw_lies_in_its_distributions_range() -> None:
    model = parse_model({"samples": 300, "seed": 3, **AROUND_DEFAULT})
    table = params()
    draws = np.array([[v for _, v in model.sample(i)] for i in range(model.samples)])
    for column, (name, dist) in enumerate(model.distributions):
        low, high = dist.support(table[name].nominal)
        assert (draws[:, column] >= low - 1e-12).all() and (draws[:, column] <= high + 1e-12).all(), name
    delays = draws[:, model.names().index("delay")]
    assert set(delays) == {0.0, 1.0, 2.0, 3.0, 4.0, 5.0}, "the delay is flown in whole 1 ms ticks"
    friction = draws[:, model.names().index("friction")]
    assert abs(friction.mean() - 0.75) < 0.03 and abs(friction.std() - 0.5 / math.sqrt(12)) < 0.02


def test_a_uniform_delay_gives_each_whole_tick_equally_often() -> None:
    """It rounded a continuous draw to the tick: 0 and 5 ms came half as often (526, 994, 1033, 964, 1001,
    482 in 5000)."""
    model = parse_model({"samples": 6000, "seed": 1, "delay": {"uniform": [0, 5]}})
    counts = Counter(model.sample(i)[0][1] for i in range(model.samples))
    assert sorted(counts) == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert all(850 < n < 1150 for n in counts.values()), counts  # 1000 each, +-5 standard deviations
    normal = parse_model({"samples": 200, "seed": 1, "delay": {"normal": [3, 1]}})
    assert {normal.sample(i)[0][1] for i in range(200)} <= {float(t) for t in range(7)}, "a normal: the nearest tick"
    with pytest.raises(UncertaintyError, match=r"model.delay: uniform \[0.5, 5\] ms: it takes whole steps of 1 ms"):
        parse_model({"samples": 2, "seed": 0, "delay": {"uniform": [0.5, 5]}})


def test_a_fixed_seed_reproduces_every_sample_exactly() -> None:
    table = {"samples": 20, "seed": 11, **AROUND_DEFAULT}
    first, again = parse_model(table), parse_model(dict(table))
    assert [first.sample(i) for i in range(20)] == [again.sample(i) for i in range(20)]
    other = parse_model({**table, "seed": 12})
    assert all(first.sample(i) != other.sample(i) for i in range(20)), "another seed, other robots"
    # sample k does not depend on how many are drawn nor on which other parameters are sampled
    fewer = parse_model({"samples": 3, "seed": 11, "friction": AROUND_DEFAULT["friction"]})
    assert [fewer.sample(i) for i in range(3)] == [(("friction", dict(first.sample(i))["friction"]),) for i in range(3)]
    # and the same spec twice gives the same episodes, ids included
    spec = {"sensing": "realistic", "hops": 1, "model": table}
    assert list(parse_spec(spec).episodes()) == list(parse_spec(spec).episodes())


def test_the_simulated_model_holds_the_samples_values() -> None:
    nominal = quantities(build_model(SimConfig(terrain="flat")))
    spec = parse_spec({"sensing": "realistic", "terrain": "flat", "hops": 1,
                       "model": {"samples": 3, "seed": 5, **AROUND_DEFAULT}})  # fmt: skip
    for episode in spec.episodes():
        sample = dict(episode.model)
        sim = Simulation(episode.config())
        q = quantities(sim.model)
        for part in ("torso", "wheel", "thigh", "shank"):
            assert q[f"mass_{part}"] == pytest.approx(sample[f"mass_{part}"], rel=1e-12), part
        for part in ("torso", "thigh", "shank"):
            assert q[f"inertia_{part}"] == pytest.approx(sample[f"inertia_{part}"], rel=1e-12), part
        assert q["wheel_spin"] == pytest.approx(sample["wheel_inertia"], rel=1e-12)
        torso = sim.model.body("torso").id
        assert tuple(sim.model.body_ipos[torso]) == pytest.approx((sample["com_x"], 0.0, sample["com_z"]), abs=1e-15)
        assert sim.model.geom_friction[:, 0] == pytest.approx(sample["friction"], rel=1e-12), "ground and feet"
        kt = sample["motor_torque"] / MOTOR_TORQUE_CONSTANT  # torque x k_t, back-EMF damping x k_t^2 (a DC motor)
        assert q["stall_torque"] == pytest.approx(nominal["stall_torque"] * kt, rel=1e-12)
        assert q["back_emf_damping"] == pytest.approx(nominal["back_emf_damping"] * kt**2, rel=1e-12)
        assert float(sim.controller.mem["wheel_kt"][0]) == pytest.approx(sample["motor_torque"], rel=1e-12)
        # the IMU and the delay: the kernel's memory after the first realistic tick powered the IMU on
        sim.step()
        mem = sim.controller.mem
        assert int(mem["motor_delay"][0]) == round(sample["delay"])
        assert float(mem["gyro_bias"][0]) == pytest.approx(math.radians(sample["gyro_bias"]), abs=1e-6), "+ 1 tick walk"
        assert float(mem["accel_bias_x"][0]) == pytest.approx(sample["accel_bias_x"] * 1e-3 * STANDARD_GRAVITY)
        assert float(mem["accel_bias_z"][0]) == pytest.approx(sample["accel_bias_z"] * 1e-3 * STANDARD_GRAVITY)
        dt = sim.model.opt.timestep
        assert float(mem["gyro_noise"][0]) == pytest.approx(math.radians(sample["gyro_noise"]) / math.sqrt(dt))
        assert float(mem["accel_noise"][0]) == pytest.approx(sample["accel_noise"] * 1e-6 * STANDARD_GRAVITY / dt**0.5)
    # and back to the nominal robot, on the same model
    sim.start_over(next(parse_spec({"terrain": "flat"}).episodes()).config())
    assert quantities(sim.model) == nominal


@pytest.mark.parametrize(
    "successes, n, low, high",
    [  # Newcombe, "Two-sided confidence intervals for the single proportion", Stat. Med. 17 (1998), Table I
        (81, 263, 0.2553, 0.3662),
        (15, 148, 0.0624, 0.1605),
        (0, 20, 0.0, 0.1611),
        (1, 29, 0.0061, 0.1718),
    ],
)
def test_the_wilson_interval_is_the_published_one(successes: int, n: int, low: float, high: float) -> None:
    assert wilson(successes, n) == pytest.approx((low, high), abs=5e-5)


def test_an_interval_short_of_100_percent_never_prints_as_100() -> None:
    low, high = wilson(8000, 8000)
    assert (percent(low), percent(high)) == ("99.95", "100.0")
    assert percent(wilson(500, 500)[0]) == "99.2" and percent(wilson(0, 8000)[1]) == "0.05"
    assert percent(0.0) == "0.0" and percent(0.5) == "50.0"


def test_the_wilson_interval_is_exact_at_the_ends() -> None:
    assert wilson(10, 10)[1] == 1.0 and wilson(0, 10)[0] == 0.0
    assert wilson(500, 500)[0] == pytest.approx(0.99238, abs=1e-5)  # the rule of three's cousin: 1 - 3.84/504


@pytest.mark.parametrize(
    "model, message",
    [
        ({"mass_arm": {"uniform": [1, 2]}}, "model: unknown parameter 'mass_arm' (known: mass_torso"),
        ({"com_x": {"normal": [0.0, -0.01]}}, "model.com_x: negative spread (SD -0.01)"),
        ({"mass_torso": {"normal": [4.0, 2.0]}}, "model.mass_torso: mean +- 3 SD [-2, 10] kg leaves the physical"),
        ({"friction": {"uniform": [0.5, 0.1]}}, "model.friction: uniform LOW 0.5 is above HIGH 0.1"),
        ({"friction": {"uniform": [-0.5, 1.0]}}, "leaves the physical range [0.16, 4]"),
        ({"gyro_bias": {"uniform": [-1, 1], "relative": True}}, "its nominal value is 0, so relative means nothing"),
        ({"delay": {"uniform": [0, 50]}}, "model.delay: its range [0, 50] ms leaves the physical range [0, 16] ms"),
        ({"friction": {"beta": [1, 2]}}, "model.friction: unknown key 'beta'"),
        ({"friction": {"uniform": [0.5]}}, "uniform = [LOW, HIGH], two finite numbers"),
        ({"friction": 0.7}, "model.friction: expected {uniform = [LOW, HIGH]} or {normal = [MEAN, SD]}"),
    ],
)
def test_bad_distributions_are_refused_with_the_reason(model: dict, message: str) -> None:
    with pytest.raises(SpecError) as caught:
        parse_spec({"sensing": "realistic", "model": {"samples": 2, "seed": 0, **model}})
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_sensing_parameters_need_realistic_sensing_and_a_table_needs_its_count() -> None:
    with pytest.raises(SpecError, match='delay act in realistic sensing only: set sensing = "realistic"'):
        parse_spec({"model": {"samples": 2, "seed": 0, "delay": {"uniform": [0, 5]}}})
    with pytest.raises(SpecError, match="model: missing samples"):
        parse_spec({"model": {"seed": 0, "friction": {"uniform": [0.5, 1.0]}}})


@pytest.mark.integration
@pytest.mark.parametrize(
    "args, message",
    [
        (["--vary", "mass_arm=uniform:1:2"], "unknown parameter 'mass_arm'"),
        (["--vary", "com_x=normal:0:-0.01"], "negative spread"),
        (["--vary", "mass_torso=normal:4:2"], "leaves the physical range"),
        (["--vary", "friction=uniform:0.5"], "expected uniform|normal:A:B[:relative]"),
    ],
)
def test_the_cli_refuses_a_bad_model_in_one_line_with_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    result = hopper_sim("sweep", "--out", "o", "--samples", "2", "--model-seed", "0", *args, cwd=tmp_path)
    assert result.returncode == 2 and result.stdout == "", result
    assert result.stderr.count("\n") == 1 and message in result.stderr, result.stderr
    assert list(tmp_path.iterdir()) == [], "work started"


@pytest.mark.integration
def test_a_sweep_over_sampled_robots_reports_success_with_its_interval_and_draws_it(tmp_path: Path) -> None:
    spec = tmp_path / "mc.toml"
    spec.write_text('sensing = "realistic"\nterrain = "flat"\nhops = 1\n[model]\nsamples = 3\nseed = 4\n'
                    'friction = {uniform = [0.5, 1.0]}\ndelay = {uniform = [0, 5]}\n')  # fmt: skip
    out = tmp_path / "mc"  # as the README's `--out mc`
    result = hopper_sim("sweep", str(spec), "--out", str(out), "--kp", "300,450", "--vary",
                        "mass_torso=uniform:0.9:1.1:relative", "--workers", "1")  # fmt: skip
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert any(line.startswith("model uncertainty: 3 robots drawn (seed 4)") for line in lines), lines
    rows = [line for line in lines if line.startswith("pid kp ")]
    assert [r.split(":")[0] for r in rows] == ["pid kp 300 ki 50 kd 30", "pid kp 450 ki 50 kd 30"]
    episodes = ds.dataset(out / "episodes", format="parquet").to_table()
    assert episodes.num_rows == 6 and sorted(set(episodes.column("sample").to_pylist())) == [0, 1, 2]
    for g in group_stats(episodes):  # what it printed is what the table says
        low, high = wilson(g.successes, g.episodes)
        assert f"success {g.successes}/3 = {100 * g.successes / 3:.1f} % [{100 * low:.1f}, {100 * high:.1f}] %" in (
            next(r for r in rows if r.startswith(g.label))
        )  # fmt: skip
    assert success(episodes).sum() == sum(g.successes for g in group_stats(episodes))
    assert set(episodes.column_names) >= {"model_mass_torso", "model_friction", "model_delay", "energy_j_per_hop"}
    report = hopper_sim("report", str(out), "--out", str(tmp_path / "report"))
    assert report.returncode == 0, report.stderr
    for name in ("mc_success", "mc_distributions", "mc_parameters"):
        assert (tmp_path / "report" / f"{name}.png").stat().st_size > 10_000, name
    assert "Monte Carlo over the sampled robots" in (tmp_path / "report" / "report.html").read_text()


@pytest.mark.integration
def test_tune_robust_scores_a_quantile_over_robots_and_judges_on_fresh_ones(tmp_path: Path) -> None:
    spec = tmp_path / "mc.toml"
    spec.write_text("[model]\nsamples = 3\nseed = 0\nmass_torso = {uniform = [0.9, 1.1], relative = true}\n")
    flags = ["tune", "--robust", str(spec), "--trials", "2", "--seeds", "0:1", "--heldout", "0:1", "--gravity", "moon",
             "--hops", "1", "--terrain", "flat", "--judge-samples", "2", "--workers", "1"]  # fmt: skip
    runs = [hopper_sim(*flags, "--json", str(tmp_path / f"{i}.json")) for i in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
        assert "judging: 100%" in r.stderr, "the judging (with 500 robots half an hour) counts its episodes"
    assert runs[0].stdout == runs[1].stdout, "seeded: the same search, the same robots"
    report = json.loads((tmp_path / "0.json").read_text())
    assert report["tuning"]["best"]["episodes"] == 3 and report["heldout"]["best"]["episodes"] == 2
    assert report["setup"]["judge"]["seed"] == 1 and report["setup"]["model"]["seed"] == 0
    assert report["tuning"]["best"]["value"] <= report["tuning"]["defaults"]["value"]
    lines = runs[0].stdout.splitlines()
    assert any(line.startswith("score = the 90th percentile of the worst landing error") for line in lines)
    assert any(line.startswith("judging: 2 robots (model seed 1) x seeds 0") for line in lines)
    assert lines[-1].startswith("best: --kp ")
    bad = hopper_sim(*flags, "--judge-seed", "0")
    assert bad.returncode == 2 and "another seed" in bad.stderr and bad.stderr.count("\n") == 1, bad.stderr


@pytest.mark.integration
@pytest.mark.parametrize(
    "file_samples, args, message",
    [
        (3, ["--samples", "0", "--judge-samples", "3"], "error: --samples: expected an integer in [1, 1000000], got 0"),
        (3, ["--judge-samples", "0"], "error: --judge-samples must be at least 1, got 0"),  # was: the file's 3
        (3, ["--judge-samples", "2000000"], "error: --judge-samples: expected an integer in [1, 1000000]"),
        (0, ["--samples", "2"], "error: mc.toml: model.samples: expected an integer in [1, 1000000], got 0"),
    ],
)
def test_tune_robust_names_the_flag_or_file_whose_count_is_wrong(
    tmp_path: Path, file_samples: int, args: list[str], message: str
) -> None:
    (tmp_path / "mc.toml").write_text(
        f"[model]\nsamples = {file_samples}\nseed = 0\nmass_torso = {{uniform = [0.9, 1.1]}}\n"
    )
    result = hopper_sim("tune", "--robust", "mc.toml", "--trials", "1", *args, cwd=tmp_path, timeout=60)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert message in result.stderr and result.stdout == "", result.stderr


def test_a_robust_score_is_a_quantile_where_a_failure_counts_90_deg_and_energy_its_weight() -> None:
    from hopper.experiments.robust import FAILED_LANDING_DEG, robust_score
    from hopper.experiments.worker import Worker, energy_per_hop

    episode = next(parse_spec({"terrain": "flat", "hops": 1}).episodes())
    worker = Worker()
    landed = worker.run(episode)
    fell = worker.run(dataclasses.replace(episode, wheel=False))  # the wheel-off robot tumbles in its first flight
    assert landed.row()["hops_completed"] == 1 and fell.fell
    s = robust_score([landed] * 9 + [fell], "landing", 0.5)
    assert (s.successes, s.failures) == (9, 1) and s.value == pytest.approx(landed.row()["worst_landing_deg"])
    worst = robust_score([landed] * 5 + [fell] * 5, "landing", 0.9)
    assert worst.value == FAILED_LANDING_DEG and worst.landing_deg[-1] == math.inf, "failures beyond any landing"
    failure = robust_score([landed] * 9 + [fell], "failure", 0.9)
    assert 0.1 < failure.value < 0.1 + 1 / 11, "the failure probability, the landing only breaking ties"
    weighted = robust_score([landed] * 3, "landing", 0.5, energy_weight=100.0)
    assert weighted.value == pytest.approx(landed.row()["worst_landing_deg"] + 3.5 * energy_per_hop(landed) / 100.0)
