"""The control kernel's pieces: PID sign and anti-windup, the torque-speed envelope, contacts."""

from __future__ import annotations

import numpy as np
import pytest

from hopper import controller as c
from hopper.config import WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT, Gains, GaitParams, InvalidConfig


def _pid(gains: Gains) -> tuple[np.ndarray, np.ndarray]:
    ctl = c.HopController(gains, GaitParams(), gravity=1.625)
    return ctl.params, ctl.state


def test_pid_pushes_the_torso_back_toward_upright() -> None:
    p, k = _pid(Gains(kp=400, ki=0, kd=20))
    # Nose down (positive pitch): the motor spins the wheel positive, the torso takes the negative reaction.
    assert c.wheel_pid(0.05, 0.0, 0.0, 0.001, p, k) == pytest.approx(400 * 0.05)
    assert c.wheel_pid(0.0, -0.5, 0.0, 0.001, p, k) == pytest.approx(20 * -0.5)


def test_pid_clamps_to_the_envelope_and_stops_integrating_when_saturated() -> None:
    p, k = _pid(Gains(kp=400, ki=100, kd=20))
    torque = c.wheel_pid(1.0, 0.0, 0.0, 0.001, p, k)  # 400 N m asked
    assert torque == pytest.approx(WHEEL_TORQUE_LIMIT)
    assert k[c.K_INTEGRAL] == 0.0 and k[c.K_SATURATED] == 1.0
    c.wheel_pid(0.01, 0.0, 0.0, 0.001, p, k)  # 4 N m: inside the envelope, integrates
    assert k[c.K_INTEGRAL] == pytest.approx(0.01 * 0.001)
    # At half the no-load speed only half the torque is left in the direction of motion.
    assert c.wheel_pid(1.0, 0.0, WHEEL_NO_LOAD_SPEED / 2, 0.001, p, k) == pytest.approx(WHEEL_TORQUE_LIMIT / 2)


def test_wheel_ctrl_inverts_the_motor_model() -> None:
    for speed in (-20.0, 0.0, 15.0):
        for torque in (-10.0, 0.0, 5.0):
            u = c.wheel_ctrl(torque, speed)
            assert WHEEL_TORQUE_LIMIT * u - c.WHEEL_DAMPING * speed == pytest.approx(torque)


def test_contact_debounce_and_hysteresis() -> None:
    k = np.zeros(c.N_STATE)
    k[c.K_PENDING_L] = -1.0
    forces = [5, 5, 5, 0.5] + [0.1] * 10 + [5] + [0.1] * 16
    seen = [c.debounce(f, i * 0.001, k, c.K_CONTACT_L, c.K_PENDING_L) for i, f in enumerate(forces)]
    assert seen[:3] == [False, False, True]  # on after 2 ms above 1 N
    assert seen[3] is True  # 0.5 N is above the 0.2 N off threshold
    assert all(seen[4:15])  # a 10 ms gap, then a tap: the foot is still down
    assert seen[15:29] == [True] * 14 and seen[30] is False  # off after 15 ms below 0.2 N


def test_leg_jacobian_matches_finite_differences() -> None:
    pitch, hip, knee, eps = 0.1, 0.5, -1.1, 1e-6
    px, pz, jx, jz = c.leg_kinematics(pitch, hip, knee)
    px_h, pz_h, _, _ = c.leg_kinematics(pitch, hip + eps, knee)
    px_k, pz_k, _, _ = c.leg_kinematics(pitch, hip, knee + eps)
    assert (px_h - px) / eps == pytest.approx(pz, abs=1e-5)
    assert (pz_h - pz) / eps == pytest.approx(-px, abs=1e-5)
    assert (px_k - px) / eps == pytest.approx(jx, abs=1e-5)
    assert (pz_k - pz) / eps == pytest.approx(jz, abs=1e-5)


@pytest.mark.parametrize("bad", [{"kp": -1.0}, {"ki": float("nan")}, {"kd": float("inf")}, {"kp": 1e9}])
def test_invalid_gains_raise_with_the_allowed_range(bad: dict) -> None:
    with pytest.raises(InvalidConfig, match=r"must be a finite number in \["):
        Gains(**bad)
