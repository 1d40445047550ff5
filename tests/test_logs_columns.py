"""hopper.logs.columns: blocks copied in, grown past a low estimate, trimmed to what was filled."""

from __future__ import annotations

import numpy as np

from hopper.logs.columns import MAX_CAPACITY, Columns


def test_blocks_fill_grow_and_trim() -> None:
    rng = np.random.default_rng(0)
    blocks = [{"a": rng.standard_normal(n), "b": rng.standard_normal(n)} for n in (3, 700, 1, 2000)]
    for capacity in (1, 5000, 10**12):  # too low (grown twice), too high (trimmed), absurd (capped)
        data = Columns(["a", "b"], capacity)
        assert len(data.arrays["a"]) <= MAX_CAPACITY
        for block in blocks:
            data.append(block)
        for name in ("a", "b"):
            column = data.take(name)
            np.testing.assert_array_equal(column, np.concatenate([b[name] for b in blocks]))
            assert column.shape == (2704,) and column.base is None  # its own buffer, not a view of the spare
