"""The endless crater field: seeded by tile, the same ground at the same x whatever the path, today's
statistics, a level start, validated parameters, PNG export in MuJoCo's orientation."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hopper.terrain import CraterField, CraterParams, FlatField, Window, crater_profile, read_png, to_hfield, write_png
from hopper.terrain.field import CACHE_TILES
from hopper.terrain.window import AHEAD_M, LEFT_M

PARAMS = CraterParams()
START = round(PARAMS.x0 / PARAMS.cell)  # the start window's first column
NCOL = PARAMS.shape[1]


def start_window(seed: int) -> np.ndarray:
    return CraterField(PARAMS, seed).columns(START, NCOL)


def test_same_seed_same_terrain_and_seeds_differ() -> None:
    a, b, c = start_window(3), start_window(3), start_window(4)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.01


def test_the_same_world_x_has_the_same_heights_to_the_bit_whatever_the_path() -> None:
    """Columns 4000-4600 (x = 200-230 m) reached three ways: straight there, walking a window forward
    37 columns at a time from the start, and after the cache forgot them on a trip to x < -500 m."""
    first, count = 4000, 601
    straight = CraterField(PARAMS, 9).columns(first, count)
    walked_field = CraterField(PARAMS, 9)
    window = Window(walked_field, PARAMS)
    while window.first < first:
        window.place(window.first + 37)  # steps that are no divisor of a tile: every offset in a tile
    walked = walked_field.columns(first, count)
    for k in range(40):  # far back, 40 windows: the tiles of x = 200 m leave the cache
        window.place(-10_000 - k * NCOL)
    tile = first // round(PARAMS.tile / PARAMS.cell)
    assert tile not in walked_field._tiles and len(walked_field._tiles) <= CACHE_TILES
    again = walked_field.columns(first, count)
    for other in (walked, again):
        assert np.array_equal(straight, other)  # bit for bit, not approximately
    # and every window holding a column holds the field's heights of it
    moved = window.place(first - 250) and window.heights[:, 250:]
    assert np.array_equal(moved, straight[:, : NCOL - 250])


def test_a_window_moves_by_whole_columns_and_its_overlap_is_unchanged() -> None:
    window = Window(CraterField(PARAMS, 2), PARAMS)
    before, x0 = window.heights, window.x0
    assert window.follow(x0 + 1.5) is False and window.heights is before  # the robot at the start
    x = window.x1 - AHEAD_M + 0.01
    assert window.follow(x) is True and window.heights is not before
    assert window.x0 == pytest.approx(x - LEFT_M, abs=PARAMS.cell)
    shift = window.first - round(x0 / PARAMS.cell)
    assert np.array_equal(window.heights[:, : NCOL - shift], before[:, shift:])
    assert window.follow(window.x0 + 0.8, urgent=True) is False  # 0.8 m behind: due at the next apex only
    assert window.due(window.x0 + 0.8) == -1


def test_the_start_window_holds_twenty_hops_with_a_level_start() -> None:
    heights = start_window(0)
    assert heights.shape == PARAMS.shape
    assert PARAMS.length >= 20 * 0.8 + abs(PARAMS.x0)
    pad = slice(round((0.0 - PARAMS.x0 - PARAMS.clear_radius) / PARAMS.cell),
                round((PARAMS.clear_radius - PARAMS.x0) / PARAMS.cell))  # fmt: skip
    assert np.abs(heights[:, pad]).max() == 0.0  # the robot starts on level ground
    assert heights.min() < -0.03  # and there are real craters further on


def test_the_field_keeps_the_strips_statistics() -> None:
    """Figures of the 30 m strip this field replaced (60 seeds, |x| > 2 m): 8.7 % of the ground
    below -3 cm, height RMS 3.2 cm, the 1 % quantile -15.5 cm, cell-to-cell slope RMS 0.146."""
    xs = (START + np.arange(NCOL)) * PARAMS.cell
    away = np.abs(xs) > 2 * PARAMS.clear_radius
    far = [CraterField(PARAMS, s).columns(100_000 + 601 * s, NCOL) for s in range(30)]
    near = [start_window(s)[:, away] for s in range(30)]
    for windows in (near, far):
        h = np.concatenate([w.ravel() for w in windows])
        assert (h < -0.03).mean() == pytest.approx(0.087, rel=0.12)
        assert h.std() == pytest.approx(0.032, rel=0.12)
        assert np.quantile(h, 0.01) == pytest.approx(-0.155, rel=0.12)
        slope = np.concatenate([np.diff(w, axis=1).ravel() for w in windows]) / PARAMS.cell
        assert slope.std() == pytest.approx(0.146, rel=0.1)


def test_the_base_noise_has_its_rms_and_correlation_length_across_tile_edges() -> None:
    h = CraterField(CraterParams(density=0.0), 5).columns(-3000, 6000)  # 300 m, 75 tile edges
    assert h.std() == pytest.approx(PARAMS.roughness, rel=0.05)
    sigma = PARAMS.roughness_scale / PARAMS.cell  # cells; Gaussian-filtered noise: exp(-lag^2 / 4 sigma^2)
    lag = 6
    assert np.corrcoef(h[:, :-lag].ravel(), h[:, lag:].ravel())[0, 1] == pytest.approx(
        np.exp(-(lag**2) / (4 * sigma**2)), abs=0.03
    )
    # no seam: the steps across tile edges are as small as anywhere else
    step = np.abs(np.diff(h, axis=1))
    n = round(PARAMS.tile / PARAMS.cell)
    edges = [c for c in range(step.shape[1]) if (-3000 + c + 1) % n == 0]
    assert step[:, edges].mean() == pytest.approx(step.mean(), rel=0.15)


def test_craters_cross_tile_edges_and_the_range_holds_every_height() -> None:
    field = CraterField(PARAMS, 1)
    low, high = PARAMS.vertical_range
    heights = field.columns(40, 20_000)  # 1 km
    assert low < heights.min() < -0.3 and 0.05 < heights.max() < high  # deep craters, never clipped
    per_metre = sum(len(field._draw(k).craters) for k in range(1, 251)) / (250 * PARAMS.tile)
    assert per_metre == pytest.approx(PARAMS.density * PARAMS.width, rel=0.1)
    straddling = [c for k in range(1, 251) for c in field._draw(k).craters
                  if int((c[0] - c[2]) // PARAMS.tile) != int((c[0] + c[2]) // PARAMS.tile)]  # fmt: skip
    assert len(straddling) > 50


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
        {"tile": 1.5},  # shorter than the widest crater's reach (2 m)
        {"x0": -2.01},  # off the grid
    ],
)
def test_invalid_parameters_raise_clear_errors(kwargs: dict) -> None:
    with pytest.raises(ValueError, match="invalid crater parameter"):
        CraterParams(**kwargs)


def test_flat_is_flat() -> None:
    assert not FlatField(PARAMS).columns(-123_456, NCOL).any()


def test_png_round_trip_and_mujoco_reads_it_the_right_way_up(tmp_path) -> None:
    heights = start_window(1)
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
