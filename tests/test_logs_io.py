"""read_log / write_log: one dispatcher by suffix over the log formats."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hopper.logs.io import READERS, WRITERS, read_log, write_log
from hopper.logs.schema import LogError
from hopper.logs.synthetic import synthetic_log


@pytest.mark.parametrize("suffix", sorted(WRITERS))
def test_every_writer_reads_back_through_read_log(suffix: str, tmp_path: Path) -> None:
    log = synthetic_log(0.1, seed=2)
    back = read_log(write_log(log, tmp_path / f"log{suffix.upper()}"))  # the suffix in any case
    np.testing.assert_array_equal(back.time, log.time)
    assert all(np.array_equal(back.signals[k], v) for k, v in log.signals.items())


def test_an_unknown_suffix_or_a_missing_file_is_refused_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(LogError, match=r"cannot read a log as '\.txt'; known: \.csv"):
        read_log(tmp_path / "log.txt")
    with pytest.raises(LogError, match="cannot write a log as 'no suffix'"):
        write_log(synthetic_log(0.01), tmp_path / "log")
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "absent.csv")
    assert set(WRITERS) <= set(READERS)
