"""Crater heightfields: seeded, validated, exported as PNG in MuJoCo's orientation."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hopper.terrain import CraterParams, crater_profile, flat, generate, read_png, to_hfield, write_png


def test_same_seed_same_terrain_and_seeds_differ() -> None:
    params = CraterParams()
    a = generate(params, np.random.default_rng(3))
    b = generate(params, np.random.default_rng(3))
    c = generate(params, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.01


def test_strip_holds_twenty_hops_with_a_level_start() -> None:
    params = CraterParams()
    heights = generate(params, np.random.default_rng(0))
    assert heights.shape == params.shape
    assert params.length >= 20 * 0.8 + abs(params.x0)
    start = slice(
        round((0.0 - params.x0 - params.clear_radius) / params.cell),
        round((params.clear_radius - params.x0) / params.cell),
    )
    assert np.abs(heights[:, start]).max() < 1e-9  # the robot starts on level ground
    assert heights.min() < -0.03  # and there are real craters further on


def test_crater_profile_has_bowl_and_rim() -> None:
    rho = np.array([0.0, 1.0, 1.5, 2.5])
    h = crater_profile(rho, depth=0.2, rim=0.04)
    assert h[0] == pytest.approx(-0.2)
    assert h[1] == pytest.approx(0.04)
    assert 0 < h[2] < 0.04
    assert h[3] == 0.0


def test_size_frequency_follows_inverse_square() -> None:
    from hopper.terrain.craters import sample_diameters

    d = sample_diameters(np.random.default_rng(0), 200_000, 0.3, 3.0)
    # Cumulative count above D ~ D^-2 (truncated): N(>0.6) / N(>0.3) = (0.6^-2 - 3^-2) / (0.3^-2 - 3^-2)
    expected = (0.6**-2 - 3.0**-2) / (0.3**-2 - 3.0**-2)
    assert (d > 0.6).mean() == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"cell": 0.0},
        {"density": -1.0},
        {"diameter_range": (2.0, 1.0)},
        {"length": float("nan")},
        {"depth_ratio_range": (0.1, 0.9)},
    ],
)
def test_invalid_parameters_raise_clear_errors(kwargs: dict) -> None:
    with pytest.raises(ValueError, match="invalid crater parameter"):
        CraterParams(**kwargs)


def test_flat_is_flat() -> None:
    assert not flat(CraterParams()).any()


def test_png_round_trip_and_mujoco_reads_it_the_right_way_up(tmp_path) -> None:
    params = CraterParams()
    heights = generate(params, np.random.default_rng(1))
    path = write_png(heights, tmp_path / "craters.png")
    relief = heights.max() - heights.min()
    assert np.abs(read_png(path) - heights).max() <= relief / 65535  # 16-bit keeps the relief
    # MuJoCo loads the same image as a heightfield: row 0 must be the -y edge, as in our data.
    xml = f"""<mujoco><asset><hfield name="t" file="{path}" size="15 1 1 0.1"/></asset>
              <worldbody><geom type="hfield" hfield="t"/></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    loaded = model.hfield_data.reshape(model.hfield_nrow[0], model.hfield_ncol[0])
    data, _, _ = to_hfield(heights)
    assert np.abs(loaded - data).max() <= 1 / 255  # MuJoCo quantises PNGs to 8 bits
    assert np.abs(loaded - np.flipud(data)).max() > 10 / 255  # and the flip is not a no-op
