"""A synthetic hopper log (seeded sines and noise in every column): for tests and the import benchmark."""

from __future__ import annotations

import numpy as np

from hopper.logs.schema import ACCEL, COMMANDS, MEASUREMENTS, STATE, Log


def synthetic_log(seconds: float, rate_hz: float = 1000.0, seed: int = 0, optional: bool = True) -> Log:
    """`seconds` of samples at `rate_hz`, every required column (and the optional ones if `optional`).

    Values are plausible in size (a few rad/s, tens of N m) but follow no physics.
    """
    rng = np.random.default_rng(seed)
    n = int(round(seconds * rate_hz))
    time = np.arange(n) / rate_hz
    columns = (*COMMANDS, *MEASUREMENTS, *((*ACCEL, *STATE) if optional else ()))
    signals: dict[str, np.ndarray] = {}
    for k, column in enumerate(columns):
        frequency = 0.5 + 0.37 * k  # Hz: each column its own
        values = np.sin(2.0 * np.pi * frequency * time + rng.uniform(0.0, 2.0 * np.pi))
        values += 0.01 * rng.standard_normal(n)
        signals[column.name] = values * (10.0 if column.unit in ("N m", "N") else 1.0)
    return Log(time, signals, f"synthetic ({seconds:g} s at {rate_hz:g} Hz, seed {seed})")
