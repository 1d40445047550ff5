"""Per-hop metrics from the kernel's accumulators: what counts toward a hop and what does not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hopper.control.memory import MEMORY
from hopper.metrics import MetricsTracker


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
