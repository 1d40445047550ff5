"""Loop analysis of the flight PID: closed-loop poles, the dominant pair, margins, what a push costs.

The wheel law `tau_w = kp theta + kd theta_dot + ki int theta` is state feedback, sampled at 1 kHz
with a zero-order hold and `delay` ticks of command latency (0 in ideal sensing, the motor delay in
realistic mode). It closes around a Plant: the sampled dynamics from the wheel torque to the state.
Two plants exist: `reduced_plant`, PHYSICS.md's `J theta_ddot = -tau_w` with the legs held rigid, and
hopper.analysis.linearize's flight plant, the whole MuJoCo model linearized with the leg servos closed. The
legs hold their angle in the world, not on the torso, so at the wheel loop's frequencies they are
partly decoupled and the reduced model's wn and zeta are off by 20 to 60 %; the flight plant is what
the simulation does (checked by hopper.analysis.identify).
"""

from __future__ import annotations

import dataclasses
import math

import control as ct
import mujoco
import numpy as np

from hopper.config import TIMESTEP, Gains
from hopper.layout import ModelLayout
from hopper.robot import PACKAGED, Robot

SETTLE_S = 2.0  # s simulated for a disturbance's peak torque and momentum: a lunar flight and more
HORIZON_S = 1.0  # s over which a mode's share of the pitch response counts: about a lunar flight
SHOWN_SHARE = 1e-4  # modes with a smaller share of the pitch response are not listed


@dataclasses.dataclass(frozen=True)
class PitchInertia:
    """Pitch inertias about the robot's CoM in the present pose, kg m^2."""

    locked: float  # I_locked: the whole robot with the wheel locked
    wheel: float  # I_w: the wheel's spin inertia (without the motor's reflected rotor inertia)
    effective: float  # J: torso pitch acceleration per unit wheel torque, inverted, legs held rigid
    torso: float  # the same with the legs free: what the wheel turns before the hip servos react


def pitch_inertia(model: mujoco.MjModel, data: mujoco.MjData) -> PitchInertia:
    """The present pose's pitch inertias, read from MuJoCo's mass matrix.

    `effective` is `I_locked - I_w` made exact: it includes the wheel joint's armature.
    """
    lay = ModelLayout.of(model)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dofs = [lay.v_x, lay.v_z, lay.v_pitch, lay.v_wheel]
    held = np.linalg.inv(full[np.ix_(dofs, dofs)])
    free = np.linalg.inv(full)
    # The whole robot about its CoM with the wheel locked: the pitch entry of the base's block once
    # x and z are eliminated (a Schur complement: translation decouples from rotation).
    base = full[np.ix_(dofs[:3], dofs[:3])]
    locked = base[2, 2] - base[2, :2] @ np.linalg.solve(base[:2, :2], base[:2, 2])
    return PitchInertia(
        locked=float(locked),
        wheel=float(model.body_inertia[model.body("wheel").id].max()),
        effective=float(-1.0 / held[2, 3]),  # torque on the wheel dof -> torso pitch acceleration
        torso=float(-1.0 / free[lay.v_pitch, lay.v_wheel]),
    )


@dataclasses.dataclass(frozen=True)
class Plant:
    """Sampled dynamics x' = A x + B tau_w (tau_w in N m on the wheel; the torso takes -tau_w)."""

    a: np.ndarray  # (n, n)
    b: np.ndarray  # (n, 1)
    pitch: int  # index of theta (rad) in x
    rate: int  # index of theta_dot (rad/s) in x
    kick: np.ndarray  # (n,): the state change of a 1 N m s angular impulse on the torso
    dt: float  # s
    inertia: PitchInertia | None = None
    # (n,): the state change per rad/s of the gyro's reading when it is modelled as a tick late
    # (hopper.analysis.predict); None: whatever reads the gyro reads this tick's rate, in `a`.
    gyro: np.ndarray | None = None
    # (n,): the state change per rad of the attitude estimate a tick starts from (realistic sensing:
    # the leg servos read it; hopper.analysis.predict carries the estimate as a state).
    estimate: np.ndarray | None = None
    robot: Robot = PACKAGED  # whose wheel: its torque limit and momentum capacity


def reduced_plant(inertia: float, dt: float = TIMESTEP) -> Plant:
    """PHYSICS.md's reduced model, J theta_ddot = -tau_w on x = [theta, theta_dot], held at dt."""
    if not (math.isfinite(inertia) and inertia > 0.0):
        raise ValueError(f"pitch inertia must be a positive number of kg m^2, got {inertia!r}")
    continuous = ct.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [-1.0 / inertia]], np.eye(2), np.zeros((2, 1)))
    sampled = ct.c2d(continuous, dt, method="zoh")
    return Plant(a=sampled.A, b=sampled.B, pitch=0, rate=1, kick=np.array([0.0, 1.0 / inertia]), dt=dt)


@dataclasses.dataclass(frozen=True)
class LoopAnalysis:
    """The flight loop at one gain set; frequencies in rad/s, angles in degrees."""

    delay_ticks: int
    poles: tuple[complex, ...]  # closed-loop poles as s = ln(z) / dt, 1/s, that the pitch shows
    wn: float  # natural frequency of the pair that dominates the pitch after a kick (nan: unstable)
    zeta: float  # its damping ratio
    phase_margin_deg: float  # at the highest gain crossover (inf: the loop gain never crosses 1)
    crossover_rad_s: float
    gain_margin_db: float  # against a gain increase (inf: none below Nyquist)
    stable: bool
    rate_disturbance_deg_s: float  # the whole robot turning at this rate, as after a skewed push-off
    peak_torque: float  # N m the loop asks for after that rate disturbance (no limit applied)
    peak_momentum: float  # N m s the wheel takes up meanwhile
    torque_limit: float = PACKAGED.wheel_torque_limit  # N m, the plant's wheel motor's
    momentum_capacity: float = PACKAGED.momentum_capacity  # N m s, the plant's wheel's

    @property
    def torque_fraction(self) -> float:
        """Peak torque over the motor's limit (29.5 N m on the packaged robot): above 1 the wheel saturates."""
        return self.peak_torque / self.torque_limit

    @property
    def momentum_fraction(self) -> float:
        """Peak wheel momentum over its capacity: above 1 the wheel alone cannot absorb it."""
        return self.peak_momentum / self.momentum_capacity


@dataclasses.dataclass(frozen=True)
class ClosedLoop:
    """The plant with the integral's and the delay's states added, and the wheel law's row."""

    a: np.ndarray  # open loop, (m, m)
    b: np.ndarray  # (m, 1)
    k: np.ndarray  # (1, m): tau_w = k x
    pitch: int
    rate: int
    dt: float

    @property
    def closed(self) -> np.ndarray:
        return self.a + self.b @ self.k


def close(plant: Plant, gains: Gains, delay: int = 0) -> ClosedLoop:
    """Add the integral of theta (when ki > 0) and `delay` registers between the law and the wheel."""
    n = len(plant.a)
    extra = int(gains.ki > 0.0)
    m = n + extra + delay
    a, b, k = np.zeros((m, m)), np.zeros((m, 1)), np.zeros((1, m))
    a[:n, :n] = plant.a
    k[0, plant.pitch], k[0, plant.rate] = gains.kp, gains.kd
    if extra:  # the kernel's integral: int += theta dt after the command used it
        a[n, plant.pitch], a[n, n] = plant.dt, 1.0
        k[0, n] = gains.ki
    if delay:
        first = n + extra
        a[:n, m - 1 : m] = plant.b  # the oldest register drives the wheel
        a[first + 1 : m, first : m - 1] = np.eye(delay - 1)  # each tick a command moves one register on
        b[first, 0] = 1.0
    else:
        b[:n] = plant.b
    return ClosedLoop(a=a, b=b, k=k, pitch=plant.pitch, rate=plant.rate, dt=plant.dt)


def analyse(plant: Plant, gains: Gains, delay: int = 0, rate_disturbance_deg_s: float = 60.0) -> LoopAnalysis:
    """Poles, the dominant pair, margins, and the torque and momentum a rate disturbance needs."""
    loop = close(plant, gains, delay)
    x0 = np.zeros(len(loop.a))
    x0[: len(plant.kick)] = plant.kick
    shown = [mode for mode in pitch_modes(loop.closed, x0, loop.pitch, loop.dt) if mode.share > SHOWN_SHARE]
    # Unstable: a mode the pitch shows that at least doubles within a flight. (The flight plant
    # has slow drifts, |s| < 1/s, that a flight of a second or two never sees grow.)
    stable = not any(mode.s.real > math.log(2.0) / HORIZON_S for mode in shown)
    wn, zeta = dominant_pair(shown) if stable else (math.nan, math.nan)
    pm, wcp, gm = _margins(loop)
    rate = math.radians(rate_disturbance_deg_s)
    spin = np.zeros(len(loop.a))
    spin[plant.rate] = rate  # the whole robot turning (the joints' rates are relative to the torso)
    torque, momentum = _disturbance_needs(loop, spin)
    return LoopAnalysis(
        delay_ticks=delay,
        poles=tuple(mode.s for mode in sorted(shown, key=lambda mode: abs(mode.s))),
        wn=wn,
        zeta=zeta,
        phase_margin_deg=pm,
        crossover_rad_s=wcp,
        gain_margin_db=gm,
        stable=stable,
        rate_disturbance_deg_s=rate_disturbance_deg_s,
        peak_torque=torque,
        peak_momentum=momentum,
        torque_limit=plant.robot.wheel_torque_limit,
        momentum_capacity=plant.robot.momentum_capacity,
    )


@dataclasses.dataclass(frozen=True)
class Mode:
    z: complex  # the sampled pole
    s: complex  # ln(z) / dt, 1/s
    share: float  # its share of the pitch response's energy over HORIZON_S, 0..1


def mode_shares(z: np.ndarray, residues: np.ndarray, dt: float) -> np.ndarray:
    """Each mode's share of sum_k theta_k^2 over HORIZON_S, theta_k = sum_i r_i z_i^k.

    Over a finite horizon, so that a neutral or slowly growing mode has a finite share.
    """
    steps = round(HORIZON_S / dt)
    r2 = np.abs(z) ** 2
    near_one = np.abs(1.0 - r2) < 1e-12
    sums = np.where(near_one, steps, (1.0 - r2**steps) / np.where(near_one, 1.0, 1.0 - r2))
    energy = np.abs(residues) ** 2 * sums
    return energy / (energy.sum() or 1.0)


def pitch_modes(a: np.ndarray, x0: np.ndarray, pitch: int, dt: float) -> list[Mode]:
    """The modes of x' = a x seen in theta = x[pitch] from x0, with their share of its energy."""
    z, vectors = np.linalg.eig(a)
    return modes(z.astype(complex), vectors[pitch, :] * np.linalg.solve(vectors, x0.astype(complex)), dt)


def modes(z: np.ndarray, residues: np.ndarray, dt: float) -> list[Mode]:
    """Modes from sampled poles `z` and their residues in the pitch, sampled every `dt` s."""
    shares = mode_shares(z, residues, dt)
    return [Mode(z=complex(zi), s=complex(np.log(zi) / dt), share=float(sh)) for zi, sh in zip(z, shares, strict=True)]


def dominant_pair(modes: list[Mode]) -> tuple[float, float]:
    """wn (rad/s) and zeta of the oscillation with the largest share, or of the two largest real modes.

    Drifts slower than 1 rad/s (the integral, the flight plant's slow modes) are not candidates.
    """
    fast = [m for m in modes if abs(m.s) >= 1.0]
    pairs = [m for m in fast if m.s.imag > 1e-6]
    reals = sorted((m for m in fast if abs(m.s.imag) <= 1e-6), key=lambda m: -m.share)
    top_pair = max(pairs, key=lambda m: m.share, default=None)
    if top_pair is not None and (len(reals) < 2 or 2.0 * top_pair.share >= reals[1].share):
        wn = abs(top_pair.s)
        return float(wn), float(-top_pair.s.real / wn)
    if len(reals) < 2:
        return math.nan, math.nan
    s1, s2 = reals[0].s.real, reals[1].s.real
    wn = math.sqrt(abs(s1 * s2))
    return float(wn), float(-(s1 + s2) / (2.0 * wn))


def _margins(loop: ClosedLoop) -> tuple[float, float, float]:
    """Phase margin (deg) at the highest gain crossover, that crossover (rad/s), gain margin (dB).

    On a frequency grid up to Nyquist rather than with control.margin, whose single answer for
    this conditionally stable loop (with the integral the phase is -270 deg at low frequency, where
    the gain is far above 1) is the low-frequency margin against a gain reduction.
    """
    open_loop = ct.ss(loop.a, loop.b, -loop.k, np.zeros((1, 1)), loop.dt)  # broken at the wheel torque
    w = np.logspace(-1, math.log10(0.999 * math.pi / loop.dt), 2000)
    response = np.asarray(ct.frequency_response(open_loop, w).complex).ravel()
    mag, phase = np.abs(response), np.degrees(np.unwrap(np.angle(response)))
    above = mag >= 1.0
    falls = np.flatnonzero(above[:-1] & ~above[1:])  # the loop gain falls through 1
    if not len(falls):
        return math.inf, math.nan, math.inf
    i = falls[-1]
    wcp = float(np.interp(0.0, -np.log(mag[i : i + 2]), w[i : i + 2]))
    pm = (float(np.interp(wcp, w[i : i + 2], phase[i : i + 2])) + 360.0) % 360.0 - 180.0
    wrapped = (phase + 180.0) % 360.0  # jumps where the phase passes -180 deg (mod 360)
    flips = [j for j in np.flatnonzero(np.abs(np.diff(wrapped)) > 180.0) if j > i]
    gm = -20.0 * math.log10(mag[flips[0]]) if flips else math.inf
    return pm, wcp, gm


def _disturbance_needs(loop: ClosedLoop, x0: np.ndarray) -> tuple[float, float]:
    """Peak |tau_w| (N m) and peak |wheel momentum taken up| (N m s) from x0, on the linear loop."""
    a, row = loop.closed, loop.k.ravel()
    steps = round(SETTLE_S / loop.dt)
    torques = np.empty(steps)
    x = x0.copy()
    for i in range(steps):
        torques[i] = row @ x
        x = a @ x
    return float(np.abs(torques).max()), float(np.abs(np.cumsum(torques) * loop.dt).max())
