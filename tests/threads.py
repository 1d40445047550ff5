"""Signals aimed at one thread of another process, as the kernel may deliver a process's signal."""

from __future__ import annotations

import ctypes
import os
import platform

import pytest

# tgkill(2)'s number; Python exposes only pthread_kill, for threads of its own process.
_TGKILL = {"x86_64": 234, "aarch64": 131}


def signal_a_thread_not_main(pid: int, signum: int) -> None:
    """Send `signum` to a thread of process `pid` other than its main thread (Linux)."""
    number = _TGKILL.get(platform.machine())
    if number is None or not os.path.isdir(f"/proc/{pid}/task"):
        pytest.skip(f"tgkill is wired here for Linux on {', '.join(_TGKILL)} only, not {platform.machine()}")
    others = sorted(int(tid) for tid in os.listdir(f"/proc/{pid}/task") if int(tid) != pid)
    assert others, f"process {pid} has no thread but its main one"
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.syscall(number, pid, others[0], signum) != 0:
        raise OSError(ctypes.get_errno(), f"tgkill({pid}, {others[0]}, {signum}) failed")
