"""Loop analysis and gain design (hopper.analysis: loop, linearize, design), checked against
closed forms on the reduced model and against the full simulation's response to a kick in flight."""

from __future__ import annotations

import math

import pytest

from hopper.analysis.design import lqr_bryson, place_poles, reduced_placement
from hopper.analysis.identify import fit_modes, kick_in_flight
from hopper.analysis.linearize import flight_plant, settled_flight
from hopper.analysis.loop import analyse, dominant_pair, pitch_inertia, reduced_plant
from hopper.config import WHEEL_TORQUE_LIMIT, Gains, SimConfig
from hopper.sim import Simulation

WHEEL_ARMATURE = 0.0045  # kg m^2, models/hopper.xml


@pytest.fixture(scope="module")
def plant():
    """The flight plant of the default robot on the Moon, early in its first descent."""
    return flight_plant(settled_flight(SimConfig()))


def test_effective_inertia_is_the_textbook_formula_with_the_armature():
    sim = Simulation(SimConfig())
    inertia = pitch_inertia(sim.model, sim.data)
    assert 0.45 <= inertia.locked <= 0.6  # PHYSICS.md's range over leg poses
    assert inertia.wheel == pytest.approx(0.03375)  # m r^2 / 2 of the 3 kg, 0.15 m disc
    textbook = inertia.locked * (1.0 + WHEEL_ARMATURE / inertia.wheel) - inertia.wheel
    assert inertia.effective == pytest.approx(textbook, rel=1e-9)
    assert inertia.torso < 0.5 * inertia.effective  # the torso alone is far lighter


def test_reduced_placement_puts_the_sampled_loops_pair_where_asked():
    for wn, zeta in ((20.0, 0.4), (25.0, 0.7), (30.0, 0.9)):
        kp, ki, kd = reduced_placement(0.5, wn, zeta)
        result = analyse(reduced_plant(0.5), Gains(kp=kp, ki=ki, kd=kd))
        assert result.stable
        # The 1 kHz hold shifts a 30 rad/s pair by about 1.5 %.
        assert result.wn == pytest.approx(wn, rel=0.03) and result.zeta == pytest.approx(zeta, rel=0.03)


def test_phase_margin_matches_the_continuous_pd_loop_less_the_hold_and_the_delay():
    inertia, gains = 0.5, Gains(kp=450.0, ki=0.0, kd=30.0)
    # Continuous PD on J s^2: |kp + j kd w| = J w^2 at crossover, phase margin = atan(kd w / kp).
    wc = math.sqrt((gains.kd**2 + math.sqrt(gains.kd**4 + 4 * inertia**2 * gains.kp**2)) / (2 * inertia**2))
    ideal = math.degrees(math.atan2(gains.kd * wc, gains.kp))
    for delay in (0, 3):
        result = analyse(reduced_plant(inertia), gains, delay=delay)
        lag = math.degrees(wc * 1e-3 * (delay + 0.5))  # the hold's half tick plus the delay
        assert result.crossover_rad_s == pytest.approx(wc, rel=0.02)
        assert result.phase_margin_deg == pytest.approx(ideal - lag, abs=1.0)
    assert analyse(reduced_plant(inertia), Gains(kp=450.0, ki=0.0, kd=0.0)).phase_margin_deg < 1.0


def test_an_unstable_loop_is_reported_unstable(plant):
    result = analyse(reduced_plant(0.5), Gains(kp=2000.0, ki=0.0, kd=0.0), delay=3)
    assert not result.stable and math.isnan(result.wn)
    assert analyse(plant, Gains()).stable


def test_rate_disturbance_needs_scale_with_the_rate_and_the_gains():
    slow = analyse(reduced_plant(0.5), Gains(), rate_disturbance_deg_s=30.0)
    fast = analyse(reduced_plant(0.5), Gains(), rate_disturbance_deg_s=60.0)
    assert fast.peak_torque == pytest.approx(2.0 * slow.peak_torque, rel=1e-6)
    # The D term's first command: kd * rate.
    assert fast.peak_torque >= Gains().kd * math.radians(60.0) - 1e-9
    # Stopping the robot's turn moves its momentum, J * rate, into the wheel; the transient's
    # overshoot takes a little more on the way.
    assert 1.0 <= fast.peak_momentum / (0.5 * math.radians(60.0)) < 1.3
    assert fast.torque_fraction == pytest.approx(fast.peak_torque / WHEEL_TORQUE_LIMIT)


def test_lqr_with_brysons_weights_gives_physics_md_range():
    for max_pitch, kp_expected in ((2.0, 845.0), (5.0, 338.0)):
        gains = lqr_bryson(0.5, max_pitch, WHEEL_TORQUE_LIMIT, ki=40.0)
        # Q = 1/theta_max^2 on pitch only: kp = tau_max / theta_max, kd = sqrt(2 kp J).
        assert gains.kp == pytest.approx(WHEEL_TORQUE_LIMIT / math.radians(max_pitch), rel=1e-6)
        assert gains.kp == pytest.approx(kp_expected, rel=0.01)
        assert gains.kd == pytest.approx(math.sqrt(2.0 * gains.kp * 0.5), rel=1e-6)
        assert gains.ki == 40.0


def test_designs_out_of_range_are_refused_with_the_reason(plant):
    with pytest.raises(ValueError, match="ki = .* outside"):
        place_poles(plant, 80.0, 0.7)
    with pytest.raises(ValueError, match="damping ratio"):
        place_poles(plant, 20.0, 0.0)
    with pytest.raises(ValueError, match="max pitch"):
        lqr_bryson(0.5, 0.0, 29.5)


def test_the_analysis_predicts_the_simulated_kick_response():
    """For three gain sets: the flight plant's dominant pair is within 10 % of the pair fitted to
    the full simulation's response to a small kick in flight; the reduced model's is not."""
    plant = flight_plant(settled_flight(SimConfig()))
    reduced_errors = []
    for wn, zeta in ((20.0, 0.4), (25.0, 0.7), (30.0, 0.9)):
        gains = place_poles(plant, wn, zeta)
        response = kick_in_flight(SimConfig(gains=gains))
        predicted = analyse(response.plant, gains)
        fitted_wn, fitted_zeta = dominant_pair([m for m in fit_modes(response) if m.share > 1e-4])
        print(
            f"\nwn {wn:g} zeta {zeta:g}: {gains}; predicted {predicted.wn:.1f} rad/s, {predicted.zeta:.3f};"
            f" fitted {fitted_wn:.1f} rad/s, {fitted_zeta:.3f}"
        )
        assert fitted_wn == pytest.approx(predicted.wn, rel=0.10)
        assert fitted_zeta == pytest.approx(predicted.zeta, rel=0.10)
        # Pole placement put the simulated pair where it was asked, too.
        assert fitted_wn == pytest.approx(wn, rel=0.10) and fitted_zeta == pytest.approx(zeta, rel=0.10)
        reduced = analyse(reduced_plant(response.plant.inertia.effective), gains)
        reduced_errors.append(max(abs(reduced.wn / fitted_wn - 1.0), abs(reduced.zeta / fitted_zeta - 1.0)))
    assert max(reduced_errors) > 0.2  # why the flight plant: the rigid-legs model misses the legs' servos
