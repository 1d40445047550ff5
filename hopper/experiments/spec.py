"""A sweep's spec: axes of values or ranges (TOML or flags), validated, expanded into episodes.

The TOML keys (every one optional; a scalar is a one-value axis):

    kp = {start = 300, stop = 800, num = 6}   # N m/rad; a list, a number, or a linspace range
    ki = 50                                   # N m/(rad s)
    kd = [20, 30]                             # N m s/rad
    gravity = ["moon", 3.72]                  # m/s^2 or a preset name
    seeds = 10                                # 0..9; or [3, 5]; or {start = 0, stop = 100} (stop excluded)
    hops = 3
    terrain = "crater"                        # crater | flat
    wheel = [true, false]
    sensing = ["ideal", "realistic"]
    [gait]                                    # any hopper.config.GaitParams field
    apex_height = [0.2, 0.25]
    [[disturbance]]                           # the disturbance axis, one entry per schedule
    kind = "none"                             # the undisturbed case
    [[disturbance]]
    kind = "push_forward"                     # a hopper.disturbances.DISTURBANCE_LIMITS key
    size = [2.0, 4.0]                         # in the kind's unit (N s, N m s or N m)
    phase = "stance"                          # entered this long (s) before it acts ...
    delay = 0.1
    hop = 2                                   # ... in this hop (1: before the first liftoff)
    [model]                                   # robots drawn from distributions (hopper.experiments.uncertainty)
    samples = 100
    seed = 1
    mass_torso = {uniform = [0.9, 1.1], relative = true}
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hopper.config import (
    GAIN_RANGES,
    GRAVITY_LIMITS,
    GRAVITY_PRESETS,
    Gains,
    GaitParams,
    InvalidConfig,
    SimConfig,
    require_finite,
)
from hopper.control.phases import Phase
from hopper.controllers import ControllerError, load_class, with_controller
from hopper.controllers.loading import canonical, declared_params
from hopper.disturbances import DISTURBANCE_LIMITS
from hopper.errors import HopperError
from hopper.experiments.stress import Schedule
from hopper.experiments.uncertainty import (
    MODEL_PREFIX,
    ModelAxis,
    Sample,
    UncertaintyError,
    mismatch_of,
    parse_model,
    sensor_of,
    sensor_params,
)

AXES = ("kp", "ki", "kd", "gravity", "seeds", "hops", "terrain", "wheel", "sensing")
GAINS = ("kp", "ki", "kd")  # the PID's axes: no other controller flies them (SweepSpec.flown)
GAIT_FIELDS = tuple(f.name for f in dataclasses.fields(GaitParams))
PARAM_PREFIX = "param_"  # a controller param's column: its own names (kp, ...) may be a setting's
MAX_EPISODES = 10_000_000  # a typo guard: 1e7 episodes is months of CPU
MAX_HOPS = 1000


class SpecError(HopperError, ValueError):
    """A spec that cannot be run, with a one-line reason."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class Episode:
    """One simulation of a sweep: every setting that produced its rows."""

    kp: float  # N m/rad
    ki: float  # N m/(rad s)
    kd: float  # N m s/rad
    gravity: float  # m/s^2
    seed: int
    hops_target: int
    terrain: str
    wheel: bool
    sensing: str
    disturbance: Schedule | None = None
    gait: tuple[tuple[str, float], ...] = ()  # swept GaitParams fields, the rest default
    controller: str = "pid"  # the flight's wheel law (hopper.controllers.loading)
    params: tuple[tuple[str, float], ...] = ()  # the controller's swept params, the rest default
    mismatch: tuple[tuple[str, float], ...] = ()  # the simulated robot's factors off nominal (hopper.mismatch)
    sample: int = -1  # which robot of the [model] table's draws (hopper.experiments.uncertainty); -1: none
    model: Sample = ()  # that robot's sampled values, each in its parameter's unit
    mjcf: str | None = None  # a user's MJCF of the robot (SimConfig.model); None: the packaged one
    # Also keep its 100 Hz time series (hopper.trace) in the result, as `hopper-sim run` does (compare's
    # runs, for `report`). What is kept, not a setting: in neither settings() nor the id.
    trace: bool = False

    def settings(self) -> dict[str, Any]:
        """The setting columns of its Parquet rows (hopper.experiments.store)."""
        d = self.disturbance
        return {
            "kp": self.kp, "ki": self.ki, "kd": self.kd, "gravity": self.gravity, "seed": self.seed,
            "hops_target": self.hops_target, "terrain": self.terrain, "wheel": self.wheel, "sensing": self.sensing,
            "disturbance": describe(d), "disturbance_size": d.magnitude if d is not None else 0.0, **dict(self.gait),
            "controller": self.controller, **{PARAM_PREFIX + name: v for name, v in self.params},
            **({"mismatch": " ".join(f"{k} x{v:g}" for k, v in self.mismatch)} if self.mismatch else {}),
            **({"sample": self.sample, **{MODEL_PREFIX + k: v for k, v in self.model}} if self.model else {}),
            **({"mjcf": self.mjcf} if self.mjcf is not None else {}),
        }  # fmt: skip

    @property
    def episode_id(self) -> str:
        """A stable hash of the settings: the same settings give the same id in any run or process."""
        text = json.dumps(self.settings(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def config(self) -> SimConfig:
        config = SimConfig(
            seed=self.seed,
            terrain=self.terrain,  # type: ignore[arg-type]
            gravity=self.gravity,
            gains=Gains(kp=self.kp, ki=self.ki, kd=self.kd),
            gait=GaitParams(**dict(self.gait)),
            wheel=self.wheel,
            sensing=self.sensing,  # type: ignore[arg-type]
            mismatch=self.mismatch + mismatch_of(self.model),
            sensor=sensor_of(self.model),
            model=self.mjcf,
        )
        return with_controller(config, self.controller, self.params) if self.controller != "pid" else config


def describe(schedule: Schedule | None) -> str:
    """A disturbance schedule in words ("" for none): what, how big, when."""
    if schedule is None:
        return ""
    unit = DISTURBANCE_LIMITS[schedule.kind][1]
    return (
        f"{schedule.kind} {schedule.magnitude:+g} {unit} at {schedule.phase.label} "
        f"+{schedule.delay_s:g} s of hop {schedule.hop}"
    )


@dataclasses.dataclass(frozen=True, kw_only=True)
class SweepSpec:
    """Every axis as its tuple of values; the sweep is their product."""

    kp: tuple[float, ...] = (Gains().kp,)
    ki: tuple[float, ...] = (Gains().ki,)
    kd: tuple[float, ...] = (Gains().kd,)
    gravity: tuple[float, ...] = (GRAVITY_PRESETS["moon"],)
    seeds: tuple[int, ...] = (0,)
    hops: tuple[int, ...] = (7,)
    terrain: tuple[str, ...] = ("crater",)
    wheel: tuple[bool, ...] = (True,)
    sensing: tuple[str, ...] = ("ideal",)
    disturbance: tuple[Schedule | None, ...] = (None,)
    gait: tuple[tuple[str, tuple[float, ...]], ...] = ()
    controller: tuple[str, ...] = ("pid",)  # specs (hopper.controllers.loading)
    params: tuple[tuple[str, tuple[float, ...]], ...] = ()  # declared params of the (non-pid) controllers
    model: ModelAxis | None = None  # robots drawn from distributions (hopper.experiments.uncertainty)
    mjcf: str | None = None  # a user's MJCF of the robot (SimConfig.model, `--model`); None: the packaged one

    @property
    def size(self) -> int:
        n = math.prod(len(getattr(self, a)) for a in (*AXES, "disturbance") if a not in GAINS)
        return n * len(self.flown()) * math.prod(len(values) for _, values in (*self.gait, *self.params)) * self.samples

    def flown(self) -> list[tuple[str, float, float, float]]:
        """(controller, kp, ki, kd) of every flight law: the PID once per point of the gain axes, any
        other controller once, with the default gains (its fallback PID's, as `hopper-sim run` gives
        it): the gain axes would only repeat its episodes."""
        default = Gains()
        return [
            (controller, *gains)
            for controller in self.controller
            for gains in (
                itertools.product(self.kp, self.ki, self.kd) if controller == "pid"
                else [(default.kp, default.ki, default.kd)]
            )
        ]  # fmt: skip

    @property
    def samples(self) -> int:
        return self.model.samples if self.model is not None else 1

    def robots(self) -> list[tuple[int, Sample]]:
        """(index, sample) of every robot flown: the nominal one alone, (-1, ()), without a [model] table."""
        if self.model is None:
            return [(-1, ())]
        return [(i, self.model.sample(i)) for i in range(self.model.samples)]

    def episodes(self) -> Iterator[Episode]:
        """The product of the axes, terrain and seed outermost (a worker's terrain changes least often)."""
        names = [name for name, _ in self.gait]
        gait_values = list(itertools.product(*(values for _, values in self.gait)))
        param_names = [name for name, _ in self.params]
        param_values = list(itertools.product(*(values for _, values in self.params)))
        robots = self.robots()
        for terrain, seed, (sample, model), gravity, hops, wheel, sensing, disturbance, (controller, kp, ki, kd), \
                gait, params in itertools.product(
                    self.terrain, self.seeds, robots, self.gravity, self.hops, self.wheel, self.sensing,
                    self.disturbance, self.flown(), gait_values, param_values,
                ):  # fmt: skip
            yield Episode(
                kp=kp, ki=ki, kd=kd, gravity=gravity, seed=seed, hops_target=hops, terrain=terrain, wheel=wheel,
                sensing=sensing, disturbance=disturbance, gait=tuple(zip(names, gait, strict=True)),
                controller=controller, params=tuple(zip(param_names, params, strict=True)), sample=sample, model=model,
                mjcf=self.mjcf,
            )  # fmt: skip

    def axes(self) -> dict[str, tuple[Any, ...]]:
        """Column name -> values, for the per-axis summary (Parquet column names)."""
        axes: dict[str, tuple[Any, ...]] = {a: getattr(self, a) for a in AXES if a not in ("seeds", "hops")}
        axes |= {"seed": self.seeds, "hops_target": self.hops, "disturbance": tuple(map(describe, self.disturbance))}
        return axes | dict(self.gait) | {"controller": self.controller} | {PARAM_PREFIX + n: v for n, v in self.params}

    def to_toml(self) -> str:
        """The resolved spec: every axis as its list of values (load_spec reads it back unchanged)."""
        lines = ["# hopper-sim sweep: the resolved spec, every axis as its list of values"]
        lines += [f"{a} = {_toml(list(getattr(self, a)))}" for a in AXES]
        lines.append(f"controller = {_toml(list(self.controller))}")
        if self.mjcf is not None:
            lines.append(f"mjcf = {_toml(self.mjcf)}")
        if self.gait:
            lines += ["", "[gait]", *(f"{name} = {_toml(list(values))}" for name, values in self.gait)]
        if self.params:
            lines += ["", "[params]", *(f"{name} = {_toml(list(values))}" for name, values in self.params)]
        if self.model is not None:
            lines += ["", *self.model.to_toml()]
        for d in self.disturbance:
            lines += ["", "[[disturbance]]"]
            if d is None:
                lines.append('kind = "none"')
            else:
                lines += [f"kind = {_toml(d.kind)}", f"size = {_toml(d.magnitude)}", f"phase = {_toml(d.phase.label)}"]
                lines += [f"delay = {_toml(d.delay_s)}", f"hop = {d.hop}"]
        return "\n".join(lines) + "\n"


def _toml(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)  # shortest round-trip form, valid TOML for finite floats
    if isinstance(value, int):
        return str(value)
    return json.dumps(value)  # a TOML basic string


# -- parsing -----------------------------------------------------------------------------------


def load_spec(path: Path, overrides: dict[str, Any] | None = None) -> SweepSpec:
    """Read a TOML spec; `overrides` (from flags, same keys) replace its axes."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise SpecError(f"cannot read {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SpecError(f"{path} is not valid TOML: {exc}") from None
    overrides = dict(overrides or {})
    if isinstance(data.get("model"), dict) and isinstance(overrides.get("model"), dict):  # flags add to the table
        overrides["model"] = {**data["model"], **overrides["model"]}
    return parse_spec({**data, **overrides})


def parse_spec(data: dict[str, Any]) -> SweepSpec:
    """A SweepSpec from TOML-shaped data; raises SpecError saying what is wrong, in one line."""
    known = (*AXES, "gait", "disturbance", "controller", "params", "model", "mjcf")
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise SpecError(f"unknown key {unknown[0]!r} (known: {', '.join(known)})")
    axes: dict[str, Any] = {}
    for name in ("kp", "ki", "kd"):
        if name in data:
            low, high, unit = GAIN_RANGES[name]
            axes[name] = _floats(name, data[name], low, high, unit)
    if "gravity" in data:
        axes["gravity"] = tuple(_gravity(v) for v in _values("gravity", data["gravity"], numeric=False))
    if "seeds" in data:
        axes["seeds"] = _seeds(data["seeds"])
    if "hops" in data:
        axes["hops"] = tuple(_int("hops", v, 1, MAX_HOPS) for v in _values("hops", data["hops"]))
    for name, choices in (("terrain", ("crater", "flat")), ("sensing", ("ideal", "realistic"))):
        if name in data:
            axes[name] = tuple(_choice(name, v, choices) for v in _values(name, data[name], numeric=False))
    if "wheel" in data:
        axes["wheel"] = tuple(_wheel(v) for v in _values("wheel", data["wheel"], numeric=False))
    if "gait" in data:
        axes["gait"] = _gait(data["gait"])
    if "controller" in data:
        axes["controller"] = tuple(_controller(v) for v in _values("controller", data["controller"], numeric=False))
    if "params" in data:
        axes["params"] = _params(data["params"], axes.get("controller", ("pid",)))
    if "disturbance" in data:
        axes["disturbance"] = _disturbances(data["disturbance"])
    if "model" in data:
        axes["model"] = _model(data["model"], axes.get("sensing", ("ideal",)))
    if "mjcf" in data:
        if not isinstance(data["mjcf"], str) or not data["mjcf"].strip():
            raise SpecError(f"mjcf: the path of an MJCF file, got {data['mjcf']!r}")
        axes["mjcf"] = data["mjcf"]
    for name, values in axes.items():
        if name in ("model", "mjcf"):
            continue
        if len(values) == 0:
            raise SpecError(f"{name}: no values")
        if len(set(values)) != len(values):
            raise SpecError(f"{name}: a value is repeated")
    spec = SweepSpec(**axes)
    late = [d for d in spec.disturbance if d is not None and d.hop > min(spec.hops)]
    if late:  # its hop never comes in the shorter episodes: a robot never disturbed is no survivor of it
        d = late[0]
        raise SpecError(f"disturbance {d.kind}: hop {d.hop} never comes in an episode of {min(spec.hops)} hops: "
                        f"give a hop from 1 to {min(spec.hops)}, or more hops")  # fmt: skip
    if spec.size > MAX_EPISODES:
        raise SpecError(f"{spec.size} episodes is more than {MAX_EPISODES}")
    return spec


def _model(table: Any, sensing: tuple[str, ...]) -> ModelAxis:
    try:
        model = parse_model(table)
    except UncertaintyError as exc:
        raise SpecError(str(exc)) from None
    if model.sensing() and "ideal" in sensing:
        names = ", ".join(n for n in model.names() if n in sensor_params())
        raise SpecError(f'model: {names} act in realistic sensing only: set sensing = "realistic"')
    return model


def _controller(value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise SpecError(f"controller: expected a spec such as pid, lqr, mpc or FILE.py:Class, got {value!r}")
    return canonical(value)


def _params(value: Any, controllers: tuple[str, ...]) -> tuple[tuple[str, tuple[float, ...]], ...]:
    """The [params] table: each declared param of every swept controller but pid, as a list of values."""
    if not isinstance(value, dict):
        raise SpecError(f"params: expected a table of NAME = VALUES, got {value!r}")
    if "pid" in controllers:
        raise SpecError("params: the pid's params are the kp, ki and kd axes; sweep [params] with other controllers")
    axes = []
    for name, values in value.items():
        floats = tuple(_number(f"params.{name}", v) for v in _values(f"params.{name}", values))
        for spec in controllers:
            try:
                with_controller(SimConfig(), spec, [(name, floats[0])])
                declared = {p.name: p for p in declared_params(load_class(spec))}
            except ControllerError as exc:
                raise SpecError(f"params.{name}: {exc}") from None
            if name not in declared:
                raise SpecError(f"params.{name}: {spec} declares no such param ({', '.join(declared) or 'none'})")
            for v in floats:
                try:
                    declared[name].check(v, spec)
                except ControllerError as exc:
                    raise SpecError(str(exc)) from None
        if len(set(floats)) != len(floats):
            raise SpecError(f"params.{name}: a value is repeated")
        axes.append((name, floats))
    return tuple(axes)


def _values(name: str, value: Any, numeric: bool = True) -> list[Any]:
    """A scalar, a list, or (numeric) a {start, stop, num} linspace, as a list."""
    if isinstance(value, dict):
        if not numeric:
            raise SpecError(f"{name}: a range is not allowed here, give a value or a list")
        return _range(name, value)
    values = value if isinstance(value, list) else [value]
    for v in values:
        if isinstance(v, (list, dict)):
            raise SpecError(f"{name}: expected a value or a list of values, got {v!r}")
    return values


def _range(name: str, value: dict[str, Any]) -> list[float]:
    if set(value) != {"start", "stop", "num"}:
        raise SpecError(f"{name}: a range is {{start, stop, num}}, got keys {sorted(value)}")
    start, stop = (_number(name, value[k]) for k in ("start", "stop"))
    num = _int(f"{name}.num", value["num"], 1, MAX_EPISODES)
    return [float(x) for x in np.linspace(start, stop, num)]


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpecError(f"{name}: expected a finite number, got {value!r}")
    return float(value)


def _floats(name: str, value: Any, low: float, high: float, unit: str) -> tuple[float, ...]:
    values = tuple(_number(name, v) for v in _values(name, value))
    for v in values:
        try:
            require_finite(name, v, low, high, unit)
        except InvalidConfig as exc:
            raise SpecError(str(exc)) from None
    return values


def _int(name: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SpecError(f"{name}: expected an integer in [{low}, {high}], got {value!r}")
    return value


def _gravity(value: Any) -> float:
    if isinstance(value, str):
        if value.lower() not in GRAVITY_PRESETS:
            raise SpecError(f"gravity: {value!r} is neither m/s^2 nor one of {', '.join(GRAVITY_PRESETS)}")
        return GRAVITY_PRESETS[value.lower()]
    g = _number("gravity", value)
    try:
        require_finite("gravity", g, *GRAVITY_LIMITS, "m/s^2")
    except InvalidConfig as exc:
        raise SpecError(str(exc)) from None
    return g


def _seeds(value: Any) -> tuple[int, ...]:
    """N (seeds 0..N-1), a list, or {start, stop} (stop excluded)."""
    if isinstance(value, dict):
        if set(value) != {"start", "stop"}:
            raise SpecError(f"seeds: a range is {{start, stop}} (stop excluded), got keys {sorted(value)}")
        start, stop = (_int(f"seeds.{k}", value[k], 0, 2**63 - 1) for k in ("start", "stop"))
        if stop <= start:
            raise SpecError(f"seeds: stop ({stop}) must be above start ({start})")
        return tuple(range(start, stop))
    if isinstance(value, int) and not isinstance(value, bool):
        return tuple(range(_int("seeds", value, 1, MAX_EPISODES)))
    if not isinstance(value, list):
        raise SpecError(f"seeds: expected a count, a list or {{start, stop}}, got {value!r}")
    return tuple(_int("seeds", v, 0, 2**63 - 1) for v in value)


def _choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise SpecError(f"{name}: {value!r} is not one of {', '.join(choices)}")
    return value


def _wheel(value: Any) -> bool:
    words = {"on": True, "off": False, "true": True, "false": False}
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in words:
        return words[value.lower()]
    raise SpecError(f"wheel: expected true/false (or on/off), got {value!r}")


def _gait(table: Any) -> tuple[tuple[str, tuple[float, ...]], ...]:
    if not isinstance(table, dict):
        raise SpecError("gait: expected a table of GaitParams fields")
    axes = []
    for name, value in table.items():
        if name not in GAIT_FIELDS:
            raise SpecError(f"gait: unknown parameter {name!r} (known: {', '.join(GAIT_FIELDS)})")
        axes.append((name, tuple(_number(f"gait.{name}", v) for v in _values(f"gait.{name}", value))))
    for combination in itertools.product(*(values for _, values in axes)):  # GaitParams checks them together
        try:
            GaitParams(**dict(zip((name for name, _ in axes), combination, strict=True)))
        except InvalidConfig as exc:
            raise SpecError(f"gait: {exc}") from None
    return tuple(axes)


DISTURBANCE_KEYS = {"kind", "size", "phase", "delay", "hop"}
PHASES = {p.label: p for p in Phase if p is not Phase.FALLEN}


def _disturbances(entries: Any) -> tuple[Schedule | None, ...]:
    if isinstance(entries, dict):
        entries = [entries]
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise SpecError("disturbance: expected [[disturbance]] tables")
    schedules: list[Schedule | None] = []
    for e in entries:
        unknown = sorted(set(e) - DISTURBANCE_KEYS)
        if unknown:
            raise SpecError(f"disturbance: unknown key {unknown[0]!r} (known: {', '.join(sorted(DISTURBANCE_KEYS))})")
        kind = e.get("kind")
        if kind == "none":
            if set(e) != {"kind"}:
                raise SpecError("disturbance: kind = 'none' takes no other keys")
            schedules.append(None)
            continue
        if kind not in DISTURBANCE_LIMITS:
            raise SpecError(f"disturbance: kind {kind!r} is not one of none, {', '.join(DISTURBANCE_LIMITS)}")
        missing = sorted({"size", "phase", "delay"} - set(e))
        if missing:
            raise SpecError(f"disturbance {kind}: missing {', '.join(missing)}")
        limit, unit = DISTURBANCE_LIMITS[kind]
        phase = PHASES.get(e["phase"])
        if phase is None:
            raise SpecError(f"disturbance {kind}: phase {e['phase']!r} is not one of {', '.join(PHASES)}")
        delay = _number(f"disturbance {kind} delay", e["delay"])
        if not 0.0 <= delay <= 60.0:
            raise SpecError(f"disturbance {kind}: delay must be in [0, 60] s, got {delay:g}")
        hop = _int(f"disturbance {kind} hop", e.get("hop", 2), 1, MAX_HOPS)
        for size in _floats(f"disturbance {kind} size", e["size"], -limit, limit, unit):
            schedules.append(Schedule(kind, size, phase, delay, hop))
    return tuple(schedules)
