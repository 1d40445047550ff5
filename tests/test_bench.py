"""Measuring the loop as a lab would (hopper.analysis.bench): on the stand, in flight over many
flights, and for a controller that is not linear, on the real MuJoCo model."""

from __future__ import annotations

import math
import re

import pytest

from hopper.analysis.bench import flight_window, measure_flight, measure_stand, stand, step_response
from hopper.analysis.frequency import ChirpSpec
from hopper.config import Gains, SimConfig
from hopper.controllers import with_controller

pytestmark = pytest.mark.unit

FLIGHT_CHIRP = ChirpSpec(f_min=5.0, f_max=200.0, amplitude=1.0, length=0.4, kind="linear")


def test_short_chirps_over_many_flights_measure_the_flight_loop():
    result = measure_flight(SimConfig(gains=Gains(kp=450.0, ki=50.0, kd=30.0)), FLIGHT_CHIRP, 30)
    assert result.records == 30
    assert result.measured is not None and result.predicted is not None
    assert result.measured.crossover_hz == pytest.approx(result.predicted.margins.crossover_hz, rel=0.2)
    assert result.measured.phase_margin_deg == pytest.approx(result.predicted.margins.phase_margin_deg, abs=10.0)
    assert result.saturated_ticks == 0
    text = "\n".join(result.lines())
    assert "crossover Hz" in text and "flight, PaperPID" in text


def test_a_flight_crossover_too_low_for_a_flights_chirp_is_said_so():
    result = measure_flight(SimConfig(gains=Gains(kp=300.0, ki=30.0, kd=20.0)), FLIGHT_CHIRP, 8)
    assert result.measured is None
    assert re.search("cannot resolve|stays below 1", result.note), result.note
    assert result.predicted is not None and result.predicted.margins.crossover_hz < 8.0


def test_a_controller_that_is_not_linear_is_measured_without_a_prediction():
    sim = stand(with_controller(SimConfig(terrain="flat"), "mpc"), "locked", settle_s=0.2)
    result = measure_stand(sim, ChirpSpec(f_min=1.0, f_max=100.0, length=6.0))
    assert result.predicted is None
    assert "MPC is not a linear law" in result.note
    assert result.measured is not None and result.measured.crossover_hz > 0.0  # what it measured


def test_the_step_response_is_printed_measured_against_predicted():
    sim = stand(SimConfig(terrain="flat"), "locked")
    result = step_response(sim, math.radians(2.0))
    assert result.predicted_metrics is not None
    assert result.measured_metrics.rise_s == pytest.approx(result.predicted_metrics.rise_s, abs=1e-3)
    assert sim.reference == pytest.approx(math.radians(2.0))  # the step stays
    assert "rise ms" in "\n".join(result.lines())


def test_a_flight_chirp_fits_what_is_left_of_the_flight_after_the_apex():
    moon, mars = flight_window(SimConfig()), flight_window(SimConfig(gravity=3.72))
    assert 0.3 < moon < 0.5  # ~1 s lunar flights: half of it after the apex, less the settling
    assert 0.1 < mars < 0.7 * moon
