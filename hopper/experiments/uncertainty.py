"""Model uncertainty: a sweep's [model] table of distributions, drawn into concrete robots, seeded.

    [model]
    samples = 500                                    # robots drawn
    seed = 1                                         # same seed, same robots
    mass_torso = { uniform = [0.9, 1.1], relative = true }   # x nominal
    friction = { uniform = [0.5, 1.0] }              # absolute, in the parameter's unit
    com_x = { normal = [0.0, 0.005] }                # mean, standard deviation (m)

A sample is a tuple of (name, value) in each parameter's unit (PARAMS). Its model part becomes
hopper.mismatch factors and offsets (the MuJoCo model is changed, not the controller's design),
its sensing part SensingParams fields. Sample k of a seed is drawn from its own generator per
parameter, so it does not depend on how many samples are drawn nor on the other parameters.
Normals are truncated at TRUNCATE_SD standard deviations (redrawn beyond, so nothing piles up at
the bounds); a distribution whose range (uniform) or truncated range (normal) reaches a
non-physical value (a negative mass, a factor outside hopper.config.MISMATCH_RANGE, ...) is refused.
An integer-valued parameter (the delay, in whole control ticks) takes whole steps: a uniform gives
each step from LOW to HIGH (whole steps, both included) equally often, a normal is rounded to the
nearest step.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, Literal

import numpy as np

from hopper.config import (
    COM_OFFSET_LIMIT,
    MAX_MOTOR_DELAY_TICKS,
    MISMATCH_RANGE,
    MOTOR_TORQUE_CONSTANT,
    TIMESTEP,
    SensingParams,
    SimConfig,
)
from hopper.errors import HopperError

TRUNCATE_SD = 3.0  # a normal's draws lie within mean +- this many standard deviations
MAX_SAMPLES = 1_000_000
MODEL_PREFIX = "model_"  # a sampled parameter's column in the Parquet datasets


class UncertaintyError(HopperError, ValueError):
    """A [model] table that cannot be drawn, with a one-line reason."""


@dataclasses.dataclass(frozen=True)
class Param:
    """A parameter a sample sets: its unit, nominal value and physical range (in that unit), and where it goes."""

    unit: str
    nominal: float
    low: float
    high: float
    what: str
    kind: Literal["factor", "offset", "sensor"]  # a hopper.mismatch factor (value / nominal), offset, or sensing
    step: float = 0.0  # > 0: integer-valued, its values are whole multiples of this (in its unit); 0: continuous


@functools.cache
def _nominal_model() -> dict[str, float]:
    from hopper.mismatch import quantities
    from hopper.model import build_model

    return quantities(build_model(SimConfig(terrain="flat")))


def _factor(unit: str, nominal: float, what: str) -> Param:
    low, high = MISMATCH_RANGE
    return Param(unit, nominal, low * nominal, high * nominal, what, "factor")


@functools.cache
def params() -> dict[str, Param]:
    """Every parameter a [model] table may sample, by name (the order of the dataset's columns)."""
    q, s, ms = _nominal_model(), SensingParams(), TIMESTEP * 1e3
    each = {"thigh": " (each)", "shank": " (each)"}  # the legs' two, scaled alike
    out = {f"mass_{p}": _factor("kg", q[f"mass_{p}"], f"the {p}'s mass{each.get(p, '')}")
           for p in ("torso", "wheel", "thigh", "shank")}  # fmt: skip
    out |= {f"inertia_{p}": _factor("kg m^2", q[f"inertia_{p}"], f"the {p}'s pitch inertia{each.get(p, '')}")
            for p in ("torso", "thigh", "shank")}  # fmt: skip
    out["wheel_inertia"] = _factor("kg m^2", q["wheel_spin"], "the wheel's spin inertia + rotor")
    out["motor_torque"] = _factor("N m/A", MOTOR_TORQUE_CONSTANT, "the wheel motor's k_t")
    out["friction"] = _factor("", q["friction"], "the ground's and the feet's friction")
    for axis in ("x", "z"):
        out[f"com_{axis}"] = Param("m", 0.0, -COM_OFFSET_LIMIT, COM_OFFSET_LIMIT, f"the torso CoM's {axis} offset",
                                   "offset")  # fmt: skip
    out["delay"] = Param("ms", s.motor_delay_ticks * ms, 0.0, MAX_MOTOR_DELAY_TICKS * ms,
                         "the wheel command's delay (whole 1 ms ticks)", "sensor", step=ms)  # fmt: skip
    out["gyro_noise"] = Param("deg/s/sqrt(Hz)", s.gyro_noise_density, 0.0, 1.0, "the gyro's noise density", "sensor")
    out["accel_noise"] = Param("ug/sqrt(Hz)", s.accel_noise_density, 0.0, 5000.0, "the accelerometer's", "sensor")
    out["gyro_bias"] = Param("deg/s", 0.0, -10.0, 10.0, "the gyro's turn-on bias", "sensor")
    for axis in ("x", "z"):
        out[f"accel_bias_{axis}"] = Param("mg", 0.0, -100.0, 100.0, f"the accelerometer's {axis} offset", "sensor")
    return out


@dataclasses.dataclass(frozen=True)
class Distribution:
    """uniform on [a, b] or normal of mean a, standard deviation b (truncated); `relative`: x nominal."""

    shape: Literal["uniform", "normal"]
    a: float
    b: float
    relative: bool = False

    def support(self, nominal: float) -> tuple[float, float]:
        """The values it can give, in the parameter's unit."""
        scale = nominal if self.relative else 1.0
        if self.shape == "uniform":
            return self.a * scale, self.b * scale
        return (self.a - TRUNCATE_SD * self.b) * scale, (self.a + TRUNCATE_SD * self.b) * scale

    def draw(self, rng: np.random.Generator, nominal: float, step: float = 0.0) -> float:
        """One value in the parameter's unit; `step` > 0: a whole multiple of it (Param.step)."""
        if self.shape == "uniform" and step > 0.0:
            # Each whole step of [low, high] equally likely. Rounding a continuous draw would give
            # the two ends half a step's share each. The same one double as rng.uniform's draw, so
            # most robots keep the delay they drew before (and every other parameter, always).
            low, high = (round(end / step) for end in self.support(nominal))
            n = high - low + 1
            return float((low + min(int(rng.random() * n), n - 1)) * step)
        if self.shape == "uniform":
            x = rng.uniform(self.a, self.b)
        else:
            z = rng.standard_normal()
            while abs(z) > TRUNCATE_SD:  # truncated by redrawing: seeded, so still reproducible
                z = rng.standard_normal()
            x = self.a + self.b * z
        x = x * nominal if self.relative else x
        return float(round(x / step) * step if step > 0.0 else x)

    def to_toml(self) -> str:
        relative = ", relative = true" if self.relative else ""
        return f"{{{self.shape} = [{self.a!r}, {self.b!r}]{relative}}}"


Sample = tuple[tuple[str, float], ...]  # (name, value in its unit), in params() order


@dataclasses.dataclass(frozen=True)
class ModelAxis:
    """`samples` robots drawn from `distributions` with `seed`."""

    samples: int
    seed: int
    distributions: tuple[tuple[str, Distribution], ...]  # in params() order

    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.distributions)

    def sample(self, index: int) -> Sample:
        """Sample `index` (0-based): the same for the same seed, whatever else is drawn."""
        table, order = params(), list(params())
        out = []
        for name, dist in self.distributions:
            rng = np.random.default_rng((self.seed, index, order.index(name)))
            out.append((name, dist.draw(rng, table[name].nominal, table[name].step)))
        return tuple(out)

    def sensing(self) -> bool:
        """It samples a sensing parameter (which acts in realistic sensing only)."""
        return any(n in sensor_params() for n in self.names())

    def to_toml(self) -> list[str]:
        lines = ["[model]", f"samples = {self.samples}", f"seed = {self.seed}"]
        return lines + [f"{name} = {dist.to_toml()}" for name, dist in self.distributions]


def sensor_params() -> tuple[str, ...]:
    """The sensing parameters: the IMU's and the command delay, which act in realistic sensing only."""
    return tuple(name for name, p in params().items() if p.kind == "sensor")


def mismatch_of(sample: Sample) -> tuple[tuple[str, float], ...]:
    """The sample's model part as hopper.mismatch (name, factor or offset) pairs."""
    table = params()
    out = []
    for name, value in sample:
        p = table[name]
        if p.kind == "factor":
            out.append((name, value / p.nominal))
        elif p.kind == "offset":
            out.append((name, value))
    return tuple(out)


def sensor_of(sample: Sample, base: SensingParams | None = None) -> SensingParams:
    """`base` (default SensingParams()) with the sample's sensing part: a sampled bias replaces the
    seeded draw of its sensor (both accelerometer axes for either), so the IMU flown is the sample's."""
    values = {name: value for name, value in sample if params()[name].kind == "sensor"}
    fields: dict[str, Any] = {}
    if "delay" in values:
        fields["motor_delay_ticks"] = round(values["delay"] / (TIMESTEP * 1e3))
    if "gyro_noise" in values:
        fields["gyro_noise_density"] = values["gyro_noise"]
    if "accel_noise" in values:
        fields["accel_noise_density"] = values["accel_noise"]
    if "gyro_bias" in values:
        fields |= {"gyro_turn_on_bias": 0.0, "gyro_bias_fixed": values["gyro_bias"]}
    if "accel_bias_x" in values or "accel_bias_z" in values:
        fields |= {"accel_bias": 0.0, "accel_bias_fixed_x": values.get("accel_bias_x", 0.0)}
        fields["accel_bias_fixed_z"] = values.get("accel_bias_z", 0.0)
    return dataclasses.replace(base or SensingParams(), **fields)


# -- parsing -----------------------------------------------------------------------------------

SHAPES = {"uniform": "[LOW, HIGH]", "normal": "[MEAN, SD]"}


def parse_model(table: Any) -> ModelAxis:
    """The [model] table (samples, seed, NAME = distribution ...); UncertaintyError in one line."""
    if not isinstance(table, dict):
        raise UncertaintyError("model: expected a table of samples, seed and NAME = {uniform|normal = [A, B]}")
    known = params()
    for key in ("samples", "seed"):
        if key not in table:
            raise UncertaintyError(f"model: missing {key} (samples: the robots drawn; seed: what they are drawn with)")
    samples, seed = table["samples"], table["seed"]
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= MAX_SAMPLES:
        raise UncertaintyError(f"model.samples: expected an integer in [1, {MAX_SAMPLES}], got {samples!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise UncertaintyError(f"model.seed: expected a non-negative integer, got {seed!r}")
    given = {k: v for k, v in table.items() if k not in ("samples", "seed")}
    for name in given:
        if name not in known:
            raise UncertaintyError(f"model: unknown parameter {name!r} (known: {', '.join(known)})")
    if not given:
        raise UncertaintyError(f"model: no parameter to sample (known: {', '.join(known)})")
    distributions = tuple((name, _distribution(name, given[name], known[name])) for name in known if name in given)
    return ModelAxis(samples, seed, distributions)


def _distribution(name: str, value: Any, param: Param) -> Distribution:
    where = f"model.{name}"
    if not isinstance(value, dict):
        raise UncertaintyError(f"{where}: expected {{uniform = [LOW, HIGH]}} or {{normal = [MEAN, SD]}}, got {value!r}")
    unknown = sorted(set(value) - {*SHAPES, "relative"})
    if unknown:
        raise UncertaintyError(f"{where}: unknown key {unknown[0]!r} (known: uniform, normal, relative)")
    shapes = [s for s in SHAPES if s in value]
    if len(shapes) != 1:
        raise UncertaintyError(f"{where}: give one of uniform = [LOW, HIGH] or normal = [MEAN, SD]")
    shape = shapes[0]
    pair = value[shape]
    if not (isinstance(pair, list) and len(pair) == 2 and all(_finite(v) for v in pair)):
        raise UncertaintyError(f"{where}: {shape} = {SHAPES[shape]}, two finite numbers, got {pair!r}")
    relative = value.get("relative", False)
    if not isinstance(relative, bool):
        raise UncertaintyError(f"{where}: relative is true (x nominal) or false (in {param.unit or 'its unit'})")
    if relative and param.nominal == 0.0:
        raise UncertaintyError(f"{where}: its nominal value is 0, so relative means nothing: give it in {param.unit}")
    a, b = float(pair[0]), float(pair[1])
    if shape == "uniform" and a > b:
        raise UncertaintyError(f"{where}: uniform LOW {a:g} is above HIGH {b:g}")
    if shape == "normal" and b < 0:
        raise UncertaintyError(f"{where}: negative spread (SD {b:g}); a standard deviation is >= 0")
    dist = Distribution(shape, a, b, relative)
    low, high = dist.support(param.nominal)
    unit = f" {param.unit}" if param.unit else ""
    if shape == "uniform" and param.step > 0.0 and any(abs(end / param.step - round(end / param.step)) > 1e-9
                                                       for end in (low, high)):  # fmt: skip
        raise UncertaintyError(
            f"{where}: uniform [{low:g}, {high:g}]{unit}: it takes whole steps of {param.step:g}{unit}, each from "
            "LOW to HIGH equally likely: give LOW and HIGH in whole steps"
        )
    slack = 1e-12 * max(abs(param.low), abs(param.high))  # 0.2 x 0.8 is 0.16000000000000003: 0.16 is in range
    if low < param.low - slack or high > param.high + slack:
        reach = "its range" if shape == "uniform" else f"mean +- {TRUNCATE_SD:g} SD"
        raise UncertaintyError(
            f"{where}: {reach} [{low:.4g}, {high:.4g}]{unit} leaves the physical range [{param.low:.4g}, "
            f"{param.high:.4g}]{unit} ({param.what}): narrow it (values are refused, never clipped)"
        )
    return dist


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
