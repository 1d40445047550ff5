"""Reading bad logs in tests: each must be refused with one line that starts with the file's path."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from hopper.logs.schema import LogError


def refused(read: Callable[[Path], object], path: Path) -> str:
    """The LogError message of `read(path)`, checked to be one line naming the file."""
    with pytest.raises(LogError) as caught:
        read(path)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(str(path)), message
    return message
