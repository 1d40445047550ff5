"""The predicted flight (hopper.ballistics) against the parabola and against the simulation."""

from __future__ import annotations

import math

import pytest
from hopper.terrain import CraterParams, FlatField, Window

from hopper.ballistics import STEP_S, Ground, predict
from hopper.config import FOOT_RADIUS, SimConfig
from hopper.control import Phase
from hopper.sim import Simulation


def test_on_flat_ground_the_landing_is_the_parabolas_root() -> None:
    params = CraterParams()
    ground = Ground(Window(FlatField(params), params))
    g, h, vx, vz = 1.62, 0.4, 0.8, 1.1  # foot 0.4 m above its contact height, rising
    feet = [(0.2, FOOT_RADIUS + h), (-0.1, FOOT_RADIUS + h + 0.05)]  # the left foot is the lower one
    arc = predict(3.0, (0.0, 1.0), (vx, vz), feet, g, ground)
    t = (vz + math.sqrt(vz * vz + 2 * g * h)) / g
    assert arc.landing_s == pytest.approx(t, abs=STEP_S)
    assert arc.feet[0] == pytest.approx((0.2 + vx * arc.landing_s, 0.0), abs=1e-9)
    assert arc.feet[1][0] == pytest.approx(-0.1 + vx * arc.landing_s)
    assert arc.com_at(3.0 + t)[1] == pytest.approx(1.0 + vz * t - 0.5 * g * t * t, abs=vz * STEP_S)


def test_after_the_apex_the_prediction_is_where_and_when_the_feet_come_down() -> None:
    """From the apex on, the controller's planned reach is known: the feet land where and when predicted,
    but for landings where that reach does not fit (a low hop against a crater wall: the legs stay short)."""
    good, landings = 0, 0
    for seed in (3, 5, 11, 17, 29):
        for error_m, error_s in _landing_errors(seed, hops=8):
            landings += 1
            good += error_m < 0.015 and error_s < 0.015
    assert landings >= 35 and good >= 0.8 * landings, (good, landings)


def _landing_errors(seed: int, hops: int) -> list[tuple[float, float]]:
    """(largest foot x error in m, touchdown time error in s) of each landing, predicted at the apex."""
    sim = Simulation(SimConfig(seed=seed))
    layout, feet = sim.layout, [sim.model.geom(f"foot_{side}").id for side in "LR"]
    arc, errors = None, []
    while len(sim.hops) < hops and not sim.fallen:
        sim.step()
        s = sim.data.sensordata
        if sim.phase is Phase.FLIGHT and arc is None and s[layout.s_com_vel + 2] <= 0.0 and sim.time > 0.5:
            com = (float(s[layout.s_com]), float(s[layout.s_com + 2]))
            velocity = (float(s[layout.s_com_vel]), float(s[layout.s_com_vel + 2]))
            feet_now = sim.controller.landing_feet(sim.data, layout)
            arc = predict(sim.time, com, velocity, feet_now, sim.config.gravity, sim.ground_profile())
        elif arc is not None and sim.phase is not Phase.FLIGHT:
            actual = [float(sim.data.geom_xpos[g][0]) for g in feet]
            error_m = max(abs(p[0] - a) for p, a in zip(arc.feet, actual, strict=True))
            errors.append((error_m, abs(arc.landing_s - (sim.time - arc.t0))))
            arc = None
    return errors
