"""Per-hop metrics from the kernel's accumulators: what counts toward a hop and what does not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hopper.config import TOTAL_MASS
from hopper.control.memory import MEMORY
from hopper.metrics import TRAP_HOPS, TRAP_M, MetricsTracker, trapped_at


def _fly(mem: np.ndarray, pitches: list[float], rate: float) -> None:
    """What the kernel adds in flight, tick by tick."""
    for pitch in pitches:
        mem["acc_peak_pitch"] = max(mem["acc_peak_pitch"][0], abs(pitch))
        mem["acc_rate_sq"] += rate * rate
        mem["acc_flight_ticks"] += 1


def test_a_rejected_skip_leaves_nothing_in_the_next_hops_flight_metrics() -> None:
    mem = np.zeros(1, dtype=MEMORY)
    tracker = MetricsTracker(mem)
    tracker.liftoff(1.0, z=1.0, momentum=0.0)
    _fly(mem, [0.3] * 20, rate=4.0)  # a 20 ms skip off a rim, tumbling
    assert tracker.touchdown(1.02, x=0.1, pitch=0.0) is None  # too short to be a hop
    tracker.liftoff(2.0, z=1.0, momentum=0.0)
    _fly(mem, [0.01] * 1000, rate=0.2)  # the real, quiet flight
    hop = tracker.touchdown(3.0, x=0.9, pitch=0.0)
    assert hop is not None and hop.flight_time_s == pytest.approx(1.0)
    assert hop.peak_pitch_deg == pytest.approx(math.degrees(0.01))
    assert hop.rms_pitch_rate_deg_s == pytest.approx(math.degrees(0.2))


def test_saturation_before_the_liftoff_belongs_to_the_hop() -> None:
    mem = np.zeros(1, dtype=MEMORY)
    tracker = MetricsTracker(mem)
    mem["acc_saturation"] = 0.05  # on the ground, before the push
    tracker.liftoff(0.5, z=1.0, momentum=0.1)
    _fly(mem, [0.02] * 10, rate=0.1)
    hop = tracker.touchdown(1.5, x=0.8, pitch=0.01)
    assert hop.saturation_time_s == pytest.approx(0.05) and hop.stance_time_s == pytest.approx(0.5)
    assert hop.landing_pitch_deg == pytest.approx(math.degrees(0.01)) and hop.liftoff_momentum == 0.1
    assert mem["acc_saturation"][0] == 0.0  # the next hop starts from nothing


def test_the_energy_of_the_ground_phase_belongs_to_the_hop_and_sets_its_cost_of_transport() -> None:
    mem = np.zeros(1, dtype=MEMORY)
    mem["gravity"] = 1.625
    tracker = MetricsTracker(mem)
    mem["acc_wheel_energy"], mem["acc_leg_energy"] = 4.0, 20.0  # J, standing and pushing
    tracker.liftoff(0.5, z=1.0, momentum=0.0)
    mem["acc_wheel_energy"] += 1.0  # J
    assert tracker.touchdown(0.52, x=0.0, pitch=0.0) is None  # a skip: its flight metrics go, not its energy
    tracker.liftoff(0.6, z=1.0, momentum=0.0)
    mem["acc_wheel_energy"] += 5.0  # J, in flight
    hop = tracker.touchdown(1.5, x=0.8, pitch=0.0)
    assert hop.wheel_energy_j == 10.0 and hop.leg_energy_j == 20.0
    assert hop.cost_of_transport == pytest.approx(30.0 / (TOTAL_MASS * 1.625 * 0.8))
    assert mem["acc_wheel_energy"][0] == mem["acc_leg_energy"][0] == 0.0  # the next hop starts from nothing
    mem["acc_leg_energy"] = 25.0
    tracker.liftoff(2.0, z=1.0, momentum=0.0)
    in_place = tracker.touchdown(3.0, x=0.805, pitch=0.0)  # 5 mm: it went nowhere
    assert in_place.leg_energy_j == 25.0 and math.isnan(in_place.cost_of_transport)


def test_a_run_that_hops_back_and_forth_is_trapped_where_it_started_to() -> None:
    """Mars seed 0 hopped 800 times in one crater, back and forth, without falling or stopping."""
    hops = [0.8] * 200 + [0.3, -0.25] * 400
    # From hop 200 on, a window of 50 gains 25 x 0.05 = 1.25 m; the one from hop 199, 0.8 + 1.5 m.
    assert trapped_at(hops) == 200
    assert trapped_at([0.8] * 1000) is None
    assert trapped_at([TRAP_M / TRAP_HOPS * 1.01] * 200) is None  # slow, but on its way
    assert trapped_at([0.8] * 10) is None  # fewer hops than a window
