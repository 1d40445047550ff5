"""A learned flight wheel law: a small MLP with a linear skip path, inference in numpy, shipped weights.

    torque = 29.5 N m * clip(lin . x + w2 . tanh(w1 x + b1) + b2, -1, 1),  x = features(obs, integral)

x is hopper.controllers.features' layout (9 normalised fields, the last the integral of pitch since
liftoff, kept here as the paper's PID keeps it). The skip path makes that PID exactly representable:
training (hopper.app.train_policy) starts from it and the hidden layer learns what a PID cannot
(the landing's timing, the wheel's momentum, gravity).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from hopper.config import WHEEL_TORQUE_LIMIT
from hopper.controllers.api import ControllerError, Observation
from hopper.controllers.features import LAYOUT, NAMES, SCALES, SIZE, PitchIntegral, features

FORMAT = "hopper-policy/1"
WEIGHTS_FILE = "policy_weights.json"  # in the package hopper.laws (package-data)


@dataclass(frozen=True)
class Weights:
    """The MLP's parameters: w1 (H, SIZE), b1 (H,), w2 (H,), b2 scalar, lin (SIZE,); outputs in [-1, 1]."""

    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: float
    lin: np.ndarray

    @property
    def hidden(self) -> int:
        return self.w1.shape[0]

    def flat(self) -> np.ndarray:
        """All parameters as one vector (the optimiser's), in the order unflat reads them."""
        return np.concatenate([self.lin, self.w1.ravel(), self.b1, self.w2, [self.b2]])

    @classmethod
    def unflat(cls, theta: np.ndarray, hidden: int) -> Weights:
        theta = np.asarray(theta, dtype=float)
        n, h = SIZE, hidden
        if theta.shape != (n + h * n + 2 * h + 1,):
            raise ValueError(f"{theta.shape[0]} parameters, {n + h * n + 2 * h + 1} expected for {h} hidden units")
        lin, w1 = theta[:n], theta[n : n + h * n].reshape(h, n)
        b1, w2, b2 = theta[n + h * n : n + h * n + h], theta[n + h * n + h : -1], float(theta[-1])
        return cls(w1, b1, w2, b2, lin)

    @classmethod
    def pid(cls, kp: float, kd: float, ki: float, hidden: int = 16, seed: int = 0) -> Weights:
        """The PID `kp pitch + kd rate + ki integral` (N m/rad, N m s/rad, N m/(rad s)) on the skip
        path, exactly: the hidden units' input weights are random, their output weights zero."""
        rng = np.random.default_rng(seed)
        lin = np.zeros(SIZE)
        for name, gain in (("pitch", kp), ("rate", kd), ("pitch_integral", ki)):
            lin[NAMES.index(name)] = gain * SCALES[NAMES.index(name)] / WHEEL_TORQUE_LIMIT
        w1 = rng.normal(0.0, 1.0 / math.sqrt(SIZE), (hidden, SIZE))
        return cls(w1, np.zeros(hidden), np.zeros(hidden), 0.0, lin)

    def raw(self, x: np.ndarray) -> float:
        """The normalised torque for features x, before the clip to [-1, 1]."""
        return float(self.lin @ x + self.w2 @ np.tanh(self.w1 @ x + self.b1) + self.b2)

    def act(self, x: np.ndarray) -> float:
        """The normalised torque in [-1, 1] for features x."""
        a = self.raw(x)
        return -1.0 if a < -1.0 else 1.0 if a > 1.0 else a

    def save(self, path: str | Path, meta: dict | None = None) -> None:
        """Write the weights with the layout they expect (JSON, a few kB)."""
        doc = {"format": FORMAT, "layout": LAYOUT, "hidden": self.hidden, "lin": self.lin.tolist(),
               "w1": self.w1.tolist(), "b1": self.b1.tolist(), "w2": self.w2.tolist(), "b2": self.b2,
               "meta": meta or {}}  # fmt: skip
        Path(path).write_text(json.dumps(doc, indent=1) + "\n")


def load_weights(path: str | Path | None = None) -> Weights:
    """Weights from `path` (default: the shipped file), or ControllerError in one line saying why."""
    where = str(path) if path is not None else f"hopper.laws/{WEIGHTS_FILE}"
    if path is not None and not Path(path).is_file():
        raise ControllerError(f"policy weights {where}: no such file")
    try:
        file = Path(path) if path is not None else resources.files("hopper.laws").joinpath(WEIGHTS_FILE)
        doc = json.loads(file.read_text())
    except (OSError, ValueError) as exc:
        raise ControllerError(f"policy weights {where}: unreadable ({type(exc).__name__}: {exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ControllerError(f"policy weights {where}: not a {FORMAT} file")
    layout = doc.get("layout")
    if layout != LAYOUT:
        got = layout.get("hash") if isinstance(layout, dict) else layout
        raise ControllerError(
            f"policy weights {where}: trained for observation layout {got!r}, this build reads {LAYOUT['hash']} "
            f"(version {LAYOUT['version']}: {', '.join(LAYOUT['fields'])}); retrain with hopper.app.train_policy"
        )
    try:
        h = int(doc["hidden"])
        w1, b1 = np.array(doc["w1"], float).reshape(h, SIZE), np.array(doc["b1"], float).reshape(h)
        w2, lin = np.array(doc["w2"], float).reshape(h), np.array(doc["lin"], float).reshape(SIZE)
        w = Weights(w1, b1, w2, float(doc["b2"]), lin)
    except (KeyError, TypeError, ValueError) as exc:
        raise ControllerError(f"policy weights {where}: damaged ({type(exc).__name__}: {exc})") from None
    if not all(np.isfinite(a).all() for a in (w.w1, w.b1, w.w2, w.lin)) or not math.isfinite(w.b2):
        raise ControllerError(f"policy weights {where}: damaged (non-finite values)")
    return w


class Policy:
    """The shipped learned law (`--controller policy`), about 10 us a call; `--controller policy:FILE`
    flies FILE's weights (`from_file`). Its one state is the pitch integral, reset at each liftoff
    and integrated unless the command saturates, as PaperPID's."""

    weights_path: str | None = None  # a subclass may point at other weights; None: the shipped file

    def __init__(self, weights: Weights | None = None) -> None:
        self.weights = weights if weights is not None else load_weights(self.weights_path)
        self.integral = PitchIntegral()

    @classmethod
    def from_file(cls, path: str | Path) -> Policy:
        """The law flying the weights in `path` (hopper.controllers.loading's `policy:FILE`), or
        ControllerError in one line: missing, unreadable, damaged, or trained for another layout."""
        return cls(load_weights(path))

    def reset(self, obs: Observation) -> None:
        self.integral.reset()

    def __call__(self, obs: Observation) -> float:
        """The wheel motor's torque command, N m (the kernel's sign convention)."""
        command = WHEEL_TORQUE_LIMIT * self.weights.raw(features(obs, self.integral.value))
        self.integral.update(obs, command)  # on the unclipped command, as PaperPID tests its own
        return min(max(command, -WHEEL_TORQUE_LIMIT), WHEEL_TORQUE_LIMIT)
