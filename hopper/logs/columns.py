"""Float64 columns filled block by block: a reader's one full copy of the data, grown only if needed."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

MAX_CAPACITY = 1 << 25  # rows reserved up front at most (9.3 h at 1 kHz, 256 MiB a column); then grown


class Columns:
    """Columns of `capacity` rows (np.empty: pages untouched cost no memory), grown 1.5x when full."""

    def __init__(self, names: list[str], capacity: int) -> None:
        capacity = min(max(1, capacity), MAX_CAPACITY)  # an estimate from a file's size or index: trust it so far
        self.arrays = {name: np.empty(capacity) for name in names}
        self.n = 0  # rows filled

    def append(self, block: Mapping[str, np.ndarray]) -> None:
        """Add one block: an array of the same length per name (copied in)."""
        rows = len(next(iter(block.values())))
        if self.n + rows > len(next(iter(self.arrays.values()))):
            capacity = int(1.5 * (self.n + rows)) + 1024
            for name, array in self.arrays.items():  # one column at a time: a column's worth extra
                grown = np.empty(capacity)
                grown[: self.n] = array[: self.n]
                self.arrays[name] = grown
        for name, values in block.items():
            self.arrays[name][self.n : self.n + rows] = values
        self.n += rows

    def take(self, name: str) -> np.ndarray:
        """Column `name`, trimmed to the rows filled (the spare capacity freed)."""
        array = self.arrays.pop(name)
        return array[: self.n].copy() if len(array) > self.n else array
