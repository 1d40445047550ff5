"""The robot sized for another gravity: its actuators scaled from their design gravity by dynamic similarity.

The paper sized its robot for the Moon: 30 N m leg motors and a 29.5 N m, 1.6 N m s wheel. The gait
carries itself to any gravity (hopper.control.gait), but the actuators do not: at Earth's gravity
the legs hold barely the robot's weight crouched and the ground's moments, which grow with the
weight, fill the wheel in one or two landings. A robot built for that gravity has actuators that
keep their share of its weight (the same hop at the same Froude number then asks the same of them):

- every torque grows with the weight, x k = g / g_design: the leg motors' limits and the wheel
  motor's stall torque;
- the wheel's momentum capacity grows as torque x time, and times shrink as 1 / sqrt(g): x sqrt(k),
  through the wheel's inertia (and its motor's rotor), the no-load speed kept.

Masses and lengths stay: a stronger motor of the same mass is an idealisation, the one that keeps
the comparison about control. The wheel motor is scaled as k of its kind in parallel (the same k_t
and no-load speed, k times the current), which is also how the energy model counts a motor of k
times the rated torque (hopper.control.controller).
"""

from __future__ import annotations

import math

import mujoco

from hopper.config import MOON_GRAVITY

LEGS = ("hip_L", "knee_L", "hip_R", "knee_R")  # hopper.layout.NAMES: the leg actuators
PARTS = ("legs", "wheel")  # what size_for can scale: the leg motors, the wheel and its motor
DIGITS = 6  # significant digits MjSpec.to_xml writes
# The gravity (m/s^2) each part was sized for, written into the sized MJCF as <custom><numeric>, so
# that sizing a sized robot again starts from it (idempotent); a model without it is the paper's, Moon.
DESIGN_NUMERIC = "hopper_design_gravity_{part}"


def factor(gravity: float, design: float = MOON_GRAVITY) -> float:
    """The torque factor k = g / g_design (both m/s^2, magnitudes)."""
    if not (math.isfinite(gravity) and math.isfinite(design) and gravity > 0.0 and design > 0.0):
        raise ValueError(f"gravities must be finite and positive, got {gravity:g} and {design:g} m/s^2")
    return gravity / design


def design_gravity(spec: mujoco.MjSpec, part: str) -> float | None:
    """m/s^2, the gravity `spec`'s `part` (of PARTS) records it was sized for; None if it records none."""
    numeric = spec.numeric(DESIGN_NUMERIC.format(part=part))
    return None if numeric is None or len(numeric.data) != 1 else float(numeric.data[0])


def _record(spec: mujoco.MjSpec, part: str, gravity: float) -> None:
    name = DESIGN_NUMERIC.format(part=part)
    numeric = spec.numeric(name)
    if numeric is None:
        numeric = spec.add_numeric()
        numeric.name = name
    numeric.size, numeric.data = 1, [gravity]


def designs(spec: mujoco.MjSpec, parts: tuple[str, ...] = PARTS, design: float | None = None) -> dict[str, float]:
    """m/s^2, the gravity each part is scaled from: `design` if given, else the one the part records
    (design_gravity), else the Moon's, the paper's."""
    return {part: design if design is not None else design_gravity(spec, part) or MOON_GRAVITY for part in parts}


def size_for(spec: mujoco.MjSpec, gravity: float, design: float | None = None, parts: tuple[str, ...] = PARTS) -> float:
    """Scale `spec`'s actuators (in place) from their design gravity to `gravity` (m/s^2) and record
    `gravity` as their design; returns k (the first part's, if the parts were sized for different gravities).

    `design` (m/s^2) defaults to each part's own (designs). `parts` (of PARTS) limits the scaling to
    the legs or the wheel: which of them a gravity overloads (README: A robot sized for another gravity).
    """
    unknown = set(parts) - set(PARTS)
    if unknown or not parts:
        raise ValueError(f"parts must be some of {', '.join(PARTS)}, got {', '.join(parts) or 'none'}")
    ks = {part: factor(gravity, was) for part, was in designs(spec, parts, design).items()}  # all checked first
    for part, k in ks.items():
        (_scale_legs if part == "legs" else _scale_wheel)(spec, k)
        _record(spec, part, gravity)
    return ks[parts[0]]


def _scale_legs(spec: mujoco.MjSpec, k: float) -> None:
    """Every leg motor's torque limit x k."""
    for name in LEGS:
        leg = spec.actuator(name)
        leg.ctrlrange = [k * v for v in leg.ctrlrange]
        leg.forcerange = [k * v for v in leg.forcerange]


def _scale_wheel(spec: mujoco.MjSpec, k: float) -> None:
    """The wheel motor's stall torque x k at the same no-load speed; its momentum capacity x sqrt(k)."""
    wheel = spec.actuator("wheel")  # force = K u - b w: K and b together keep the no-load speed
    wheel.gainprm = [k * wheel.gainprm[0], *wheel.gainprm[1:]]
    wheel.biasprm = [*wheel.biasprm[:2], k * wheel.biasprm[2], *wheel.biasprm[3:]]
    wheel.forcerange = [k * v for v in wheel.forcerange]
    spin = math.sqrt(k)
    body = spec.body("wheel")
    body.inertia = _writable_inertia([spin * v for v in body.inertia])
    joint = spec.joint("wheel")
    joint.armature = spin * joint.armature


def _writable_inertia(moments: list[float]) -> list[float]:
    """Principal moments (kg m^2) rounded to what MjSpec.to_xml writes, the largest down and the
    others up: a disc's moments meet A + C = B exactly, and rounding each on its own can break the
    inequality the compiler checks, leaving a written model that does not load."""
    top = max(range(3), key=lambda i: moments[i])
    out = []
    for i, v in enumerate(moments):
        scale = 10.0 ** (DIGITS - 1 - math.floor(math.log10(v))) if v > 0.0 else 1.0
        out.append((math.floor if i == top else math.ceil)(v * scale) / scale)
    return out
