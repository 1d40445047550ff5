"""A controller bound to a simulation: built from the config's spec, called and guarded each flight tick.

The guard turns every way a controller can misbehave into a ControllerFault with one line naming
it: an exception, a value that is not a finite number, or calls slower than the budget (the median
call of BUDGET_WINDOW flight ticks: one call descheduled by a loaded machine, or holding a garbage
collection, is not the controller's cost, and measured 100-300 ms here; a controller whose typical
call is over the budget is caught within the window). The Simulation then flies the rest of the session on the
built-in PID and emits ControllerFailed (hopper.sim); batches mark the episode failed.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import statistics
import time
from collections.abc import Iterable

from hopper.config import Gains, SimConfig
from hopper.controllers.api import ControllerContext, ControllerError, Observation, Param
from hopper.controllers.loading import build, canonical, declared_params

BUDGET_US = 1000.0  # us for the median call: the 1 kHz control period; a slower law cannot keep up
BUDGET_WINDOW = 100  # flight calls whose median is held against the budget
WARM_UP_CALLS = 5  # calls the budget forgives after each attach (imports, first solves, JIT)
PROBE_CALLS = 30  # calls of the pre-run check
PID_PARAMS = ("kp", "ki", "kd")  # the built-in PID's params are the config's Gains


class ControllerFault(ControllerError):
    """A controller misbehaved during a run; the message says how."""


def with_controller(config: SimConfig, spec: str, values: Iterable[tuple[str, float]] = ()) -> SimConfig:
    """`config` flying `spec` with `values` for its params. For the compiled PID the values are
    its gains (SimConfig.gains): one place holds them, whichever front end set them."""
    spec, values = canonical(spec), dict(values)
    if spec == "pid":
        unknown = sorted(set(values) - set(PID_PARAMS))
        if unknown:
            raise ControllerError(f"PaperPID has no parameter {', '.join(unknown)} (its parameters: kp, ki, kd)")
        try:
            gains = dataclasses.replace(config.gains, **{k: float(v) for k, v in values.items()})
        except (TypeError, ValueError) as exc:
            raise ControllerError(f"PaperPID: {exc}") from None
        return dataclasses.replace(config, controller="pid", controller_params=(), gains=gains)
    params = tuple(sorted((str(k), float(v)) for k, v in values.items()))
    return dataclasses.replace(config, controller=spec, controller_params=params)


def params_of(config: SimConfig) -> dict[str, float]:
    """The controller's parameter values the config holds (the gains for the PID)."""
    if config.controller == "pid":
        g: Gains = config.gains
        return {"kp": g.kp, "ki": g.ki, "kd": g.kd}
    return dict(config.controller_params)


class FlightLaw:
    """The config's controller, built, with its declared params set and its calls timed."""

    def __init__(self, config: SimConfig, budget_us: float = BUDGET_US) -> None:
        self.spec = config.controller
        self.controller = build(self.spec, params_of(config))
        self.params: tuple[Param, ...] = declared_params(type(self.controller))
        self.name = type(self.controller).__name__
        # A built-in may say its law is compiled into the kernel ("pid"): then the kernel flies it
        # and this object is only its description. Its Python __call__ is the same law (tested).
        self.compiled = getattr(self.controller, "compiled", None)
        self.budget_ns = budget_us * 1e3
        self._reset = getattr(self.controller, "reset", None)
        self.needs_reset = True  # reset(obs) before the first call (attached mid-flight too)
        self.calls = 0  # calls since attach
        self.compute_ns = 0  # spent in calls since attach
        self._window: list[int] = []  # ns of the window's calls

    @property
    def values(self) -> dict[str, float]:
        return {p.name: float(getattr(self.controller, p.name)) for p in self.params}

    def set_param(self, name: str, value: float) -> None:
        """Change one declared param between ticks (a dashboard slider); ControllerError, with the
        param unchanged, if it is out of its range or the controller refuses it (raising ControllerError)."""
        for p in self.params:
            if p.name == name:
                value = p.check(value, self.name)
                try:
                    setattr(self.controller, name, value)
                except ControllerError as exc:  # the law's own word (a property's setter): say which value
                    raise ControllerError(
                        f"{self.name} refused {name} = {value:g} {p.unit}".rstrip() + f": {exc}"
                    ) from None
                return
        raise ControllerError(
            f"{self.name} has no parameter {name} (its parameters: {', '.join(p.name for p in self.params) or 'none'})"
        )

    def configure(self, context: ControllerContext) -> None:
        """Tell the controller its plant (at attach and after gravity, sensing or model changes)."""
        hook = getattr(self.controller, "configure", None)
        if hook is None:
            return
        try:
            hook(context)
        except ControllerError:
            raise
        except Exception as exc:
            raise ControllerError(f"{self.name}.configure failed: {type(exc).__name__}: {exc}") from exc

    def __call__(self, obs: Observation) -> float:
        """The torque command (N m) for this tick, or ControllerFault."""
        if self.needs_reset:
            self.needs_reset = False
            if self._reset is not None:
                try:
                    self._reset(obs)
                except Exception as exc:
                    raise ControllerFault(f"{self.name}.reset raised {type(exc).__name__}: {exc}") from exc
        start = time.perf_counter_ns()
        try:
            command = self.controller(obs)
        except ControllerFault:
            raise  # it says what happened (a remote peer that left)
        except Exception as exc:
            raise ControllerFault(f"{self.name} raised {type(exc).__name__}: {exc}") from exc
        spent = time.perf_counter_ns() - start
        self.calls += 1
        self.compute_ns += spent
        if self.calls > WARM_UP_CALLS:
            window = self._window
            window.append(spent)
            if len(window) == BUDGET_WINDOW:
                median_us = statistics.median(window) / 1e3
                window.clear()
                if median_us * 1e3 > self.budget_ns:
                    raise ControllerFault(
                        f"{self.name} took {median_us:.0f} us a call (the median of {BUDGET_WINDOW} ticks), "
                        f"over its budget of {self.budget_ns / 1e3:.0f} us"
                    )
        return self._checked(command)

    def _checked(self, command: object) -> float:
        if isinstance(command, bool) or not isinstance(command, (int, float)):
            try:
                value = float(command)  # numpy scalars and 0-d arrays
            except (TypeError, ValueError):
                raise ControllerFault(
                    f"{self.name} returned {type(command).__name__} {command!r:.40}, not a torque in N m"
                ) from None
        else:
            value = float(command)
        if not math.isfinite(value):
            raise ControllerFault(f"{self.name} returned {value} N m, not a finite torque")
        return value

    def probe(self, obs: Observation) -> float:
        """The pre-run check on a typical flight tick: it answers, with a finite number, within the
        budget (median of PROBE_CALLS calls). Raises ControllerError; leaves the law freshly reset."""
        saved = self.state()
        try:
            times = []
            for i in range(WARM_UP_CALLS + PROBE_CALLS):
                start = time.perf_counter_ns()
                self(obs._replace(time=obs.time + i * obs.dt, time_since_liftoff=obs.time_since_liftoff + i * obs.dt))
                times.append(time.perf_counter_ns() - start)
        except ControllerFault as fault:
            raise ControllerError(f"{self.spec}: {fault}") from None
        finally:
            self.set_state(saved)  # what the probe's calls did to it is undone
            self.needs_reset = True
            self.calls = self.compute_ns = 0
            self._window = []
        median_us = statistics.median(times[WARM_UP_CALLS:]) / 1e3
        if median_us * 1e3 > self.budget_ns:
            raise ControllerError(
                f"{self.spec}: {median_us:.0f} us a call, over the budget of {self.budget_ns / 1e3:.0f} us"
            )
        return median_us

    # -- state (snapshots) ------------------------------------------------------------------
    def state(self) -> object | None:
        """A copy of the controller's state for a snapshot, or None if it cannot be copied (a
        remote controller: it is reset at the next liftoff instead)."""
        if getattr(self.controller, "stateless_copy", False):
            return None
        try:
            return (copy.deepcopy(self.controller), self.needs_reset)
        except Exception:
            return None

    def set_state(self, state: object | None) -> None:
        if state is None:
            self.needs_reset = True
            return
        controller, self.needs_reset = state
        self.controller = copy.deepcopy(controller)
        self._reset = getattr(self.controller, "reset", None)
