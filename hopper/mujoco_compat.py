"""MuJoCo's private internals behind one seam (STYLE.md item 24): libmujoco's own mj_step, for compiled code.

The bindings offer compiled code no way to step a model: hopper.stepping calls the C library's
`mj_step` through ctypes on the addresses of the structs the bindings wrap (`MjModel._address`,
`MjData._address`, private). It is the very function `mujoco.mj_step` calls, on the same structs, so
a step is the same to the bit (tests/test_stepping.py). What the bindings' wrapper adds is not there:
an `mju_error` inside the call is not raised as a Python exception (MuJoCo's warnings, which the
simulation's health check reads, are unchanged).
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import mujoco

from hopper.versions import UnsupportedVersion, installed_version, require_series

SERIES = "4.0"  # the release series this module was written and tested against
require_series("mujoco", SERIES, installed_version("mujoco"), module=__name__)


def _library() -> ctypes.CDLL:
    """The libmujoco the bindings load (beside them in the package): dlopen hands back the same copy."""
    folder = Path(mujoco.__file__).parent
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(folder.glob(pattern))
        if found:
            return ctypes.CDLL(str(found[0]))
    raise UnsupportedVersion(f"{__name__}: no MuJoCo library beside the bindings in {folder}")


_mj_step = _library().mj_step
_mj_step.argtypes, _mj_step.restype = (ctypes.c_void_p, ctypes.c_void_p), None
MJ_STEP: int = ctypes.cast(_mj_step, ctypes.c_void_p).value  # void mj_step(const mjModel*, mjData*)


def mj_step(model: int, data: int) -> None:
    """libmujoco's mj_step on the structs at these addresses (address()): what compiled code calls."""
    _mj_step(model, data)


def address(struct: mujoco.MjModel | mujoco.MjData) -> int:
    """The C struct's address (mjModel* or mjData*), valid as long as the Python object lives."""
    return struct._address  # private: the bindings' pointer to the wrapped struct
