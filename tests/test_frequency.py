"""Frequency response by injection (hopper.analysis.frequency): a chirp injected into a known linear
loop recovers its response, and bad chirp specs are refused with one line."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from hopper.analysis.frequency import (
    ChirpSpec,
    InvalidChirp,
    NotMeasured,
    excitation,
    margins,
    measure,
    measured_margins,
)
from hopper.errors import HopperError

pytestmark = pytest.mark.unit

INERTIA = 0.5  # kg m^2: a pitch plant J theta'' = -tau, as the wheel turns the torso
KP, KD = 450.0, 30.0  # N m/rad, N m s/rad


def known_loop(dt: float = 0.001, inertia: float = INERTIA):
    """A sampled double integrator under PD on a one-tick-late rate, as the kernel sees its gyro:
    returns step(d) -> (u, uc, pitch) records and the exact L(z) broken at the plant input."""
    plant = ct.c2d(ct.ss([[0, 1], [0, 0]], [[0], [-1 / inertia]], np.eye(2), np.zeros((2, 1))), dt)
    a = np.zeros((3, 3))
    a[:2, :2] = plant.A
    a[2, 1] = 1.0  # the lagged rate register
    b = np.vstack([plant.B, [[0.0]]])
    k = np.array([[KP, 0.0, KD]])  # u_c = kp theta + kd rate_{k-1}
    exact = ct.ss(a, b, -k, np.zeros((1, 1)), dt)  # L = -K (zI - A)^-1 B

    def run(d: np.ndarray) -> dict[str, np.ndarray]:
        x = np.zeros(3)
        out = {name: np.empty(len(d)) for name in ("u", "uc", "pitch")}
        for i, di in enumerate(d):
            uc = float(k[0] @ x)
            u = uc + di
            out["u"][i], out["uc"][i], out["pitch"][i] = u, uc, x[0]
            x = a @ x + b[:, 0] * u
        out["d"] = d
        return out

    return run, exact


def exact_response(system: ct.StateSpace, f: np.ndarray) -> np.ndarray:
    return np.asarray(ct.frequency_response(system, 2 * math.pi * f).complex).ravel()


@pytest.mark.parametrize(
    ("kind", "f_min", "length"),
    # A linear chirp over 2-80 Hz sweeps 4 Hz/s: at 3 Hz that is 30 % a settling time of the loop,
    # too fast for a steady response there (2 dB off). It is for narrower bands; log is the default.
    [("log", 2.0, 20.0), ("linear", 5.0, 20.0), ("stepped", 2.0, 30.0)],
)
def test_a_chirp_on_a_known_loop_recovers_its_response(kind: str, f_min: float, length: float):
    spec = ChirpSpec(f_min=f_min, f_max=80.0, amplitude=1.0, length=length, kind=kind, steps=12)
    run, exact = known_loop()
    response = measure([run(excitation(spec))], spec)
    good = response.coherence >= 0.9
    assert good.mean() > 0.9, "most of the band should be coherent on a noise-free linear loop"
    truth = exact_response(exact, response.f[good])
    measured = response.loop[good]
    gain_db = 20 * np.log10(np.abs(measured) / np.abs(truth))
    phase = np.degrees(np.angle(measured / truth))
    assert np.abs(gain_db).max() < 1.0
    assert np.abs(phase).max() < 5.0
    # S and T follow from L: S = 1 / (1 + L), T = L / (1 + L)
    s_truth = 1 / (1 + truth)
    assert np.abs(20 * np.log10(np.abs(response.sensitivity[good] / s_truth))).max() < 1.0
    assert np.allclose(response.sensitivity + response.complementary, 1.0, atol=0.05)


def test_measured_margins_match_the_model_margins():
    spec = ChirpSpec(f_min=2.0, f_max=80.0, amplitude=1.0, length=20.0)
    run, exact = known_loop()
    measured = measured_margins(measure([run(excitation(spec))], spec))
    f = np.geomspace(1.0, 400.0, 4000)
    model = margins(f, exact_response(exact, f))
    assert measured.crossover_hz == pytest.approx(model.crossover_hz, rel=0.02)
    assert measured.phase_margin_deg == pytest.approx(model.phase_margin_deg, abs=1.0)
    assert measured.coherence > 0.99
    # wc of |kd s + kp| = J w^2: the crossover of the continuous loop, the sampled one is close
    w = np.roots([INERTIA**2, 0, -(KD**2), 0, -(KP**2)])
    wc = max(r.real for r in w if abs(r.imag) < 1e-9 and r.real > 0)
    assert model.crossover_hz == pytest.approx(wc / (2 * math.pi), rel=0.02)


@pytest.mark.parametrize(("length", "segments"), [(3.0, 1), (5.1, 4)])
def test_a_short_chirp_is_estimated_over_its_whole_band(length: float, segments: int):
    """A record under two 2.048 s segments (f_min 1 Hz) is one segment, the whole record; a longer one
    takes in its end too. The segment used to stop at 2.048 s, where a 3 s log chirp to 200 Hz had
    reached 43 Hz (5.1 s: the end's 0.98 s, above 88 Hz, in no segment): above, |L| read flat."""
    spec = ChirpSpec(f_min=1.0, f_max=200.0, amplitude=1.0, length=length)
    run, exact = known_loop()
    response = measure([run(excitation(spec))], spec)
    assert response.f[-1] >= 0.99 * spec.f_max and response.segments == segments
    truth = exact_response(exact, response.f)
    up = response.f >= 2.0  # (5.1 s: the first Hann segment tapers off the chirp's first hertz: 1.9 dB at 1.5 Hz)
    assert np.abs(20 * np.log10(np.abs(response.loop / truth)))[up].max() < 1.0
    assert np.abs(np.degrees(np.angle(response.loop / truth)))[up].max() < 5.0
    found = measured_margins(response)
    model = margins(response.f, truth)
    assert found.gain_margin_db == pytest.approx(model.gain_margin_db, abs=0.5)
    # One segment's coherence is 1 whatever the noise: it is not reported as one
    assert response.coherent == (segments > 1) and math.isnan(found.coherence) == (segments == 1)


def test_short_records_stitched_together_estimate_the_loop():
    """Many 0.4 s records (flights), each a short chirp, average into one estimate (a light torso:
    a crossover near 30 Hz, as in flight)."""
    spec = ChirpSpec(f_min=5.0, f_max=150.0, amplitude=1.0, length=0.4, kind="linear")
    run, exact = known_loop(inertia=0.17)
    flights = run(np.tile(excitation(spec), 12))  # one run, a chirp each 0.4 s: each starts where the last left
    records = [{k: v[i * spec.ticks : (i + 1) * spec.ticks] for k, v in flights.items()} for i in range(12)]
    response = measure(records, spec)
    found = measured_margins(response)
    f = np.geomspace(1.0, 400.0, 4000)
    model = margins(f, exact_response(exact, f))
    assert 20.0 < model.crossover_hz < 40.0
    assert found.crossover_hz == pytest.approx(model.crossover_hz, rel=0.05)
    assert found.phase_margin_deg == pytest.approx(model.phase_margin_deg, abs=3.0)


def test_a_crossover_below_the_resolution_is_not_measured():
    spec = ChirpSpec(f_min=5.0, f_max=80.0, amplitude=1.0, length=0.4, kind="linear")
    run, _ = known_loop()
    soft = dict(run(excitation(spec)))
    soft["uc"] = soft["uc"] * 0.02  # a loop 34 dB lower: its crossover falls under 8 Hz
    with pytest.raises(NotMeasured, match="cannot resolve|stays below"):
        measured_margins(measure([soft], spec))


@pytest.mark.parametrize(
    ("settings", "said"),
    [
        ({"length": 0.0}, r"chirp length must be in \(0, 600\] s, got 0"),
        ({"length": 1e9}, r"chirp length must be in \(0, 600\] s, got 1e\+09"),
        ({"f_max": 600.0}, "must be under the Nyquist frequency of the 1000 Hz loop"),
        ({"f_max": 500.0}, "Nyquist"),
        ({"amplitude": 40.0}, "the motor's torque limit"),
        ({"amplitude": 0.5, "at": "reference"}, r"\(0, 0\.261799\] rad \(a quarter of the fall pitch\)"),
        ({"f_min": 50.0, "f_max": 20.0}, "f_min < f_max"),
        ({"length": float("nan")}, "length"),
        ({"kind": "square"}, "linear, log, stepped"),
    ],
)
def test_a_bad_chirp_is_refused_in_one_line(settings: dict, said: str):
    with pytest.raises(InvalidChirp, match=said) as caught:
        ChirpSpec(**settings)
    assert "\n" not in str(caught.value)
    assert isinstance(caught.value, HopperError) and isinstance(caught.value, ValueError)


def test_the_excitation_has_the_asked_amplitude_and_length():
    spec = ChirpSpec(f_min=1.0, f_max=50.0, amplitude=2.5, length=4.0)
    d = excitation(spec)
    assert d.shape == (4000,)
    assert np.abs(d).max() == pytest.approx(2.5, rel=1e-3)
    assert abs(d[0]) < 1e-9 and abs(d[-1]) < 1e-9  # tapered: no step into or out of the chirp
