"""The hop controller: the paper's contact-driven cycle as one compiled kernel per 1 kHz tick.

Modules, one concern each: `phases` (the cycle and its thresholds), `memory` (the kernel's
named record), `legs` (kinematics and leg torques), `wheel` (motor envelope and flight PID),
`contact` (debounced foot contact), `stance` (virtual-model control on the ground), `sensing`
(the simulated IMU, the attitude estimate and the wheel's command delay), `kernel` (the tick:
phases, actuation, metrics) and `controller` (its Python face).
"""

import hashlib
from pathlib import Path


def _drop_stale_compiled_kernel() -> None:
    """numba's cache=True checks only the cached function's own source file, so an edit to
    stance.py (or an upgrade that changes it) would leave control_tick compiled with the old
    stance. Drop this package's compiled cache whenever any of its sources changed."""
    here = Path(__file__).parent
    digest = hashlib.sha1(b"".join(p.read_bytes() for p in sorted(here.glob("*.py")))).hexdigest()
    cache, stamp = here / "__pycache__", here / "__pycache__" / "numba-sources.sha1"
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        for compiled in cache.glob("*.nb[ic]"):
            compiled.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:
        pass  # a read-only install: numba then caches elsewhere, or not at all


_drop_stale_compiled_kernel()

from hopper.control.controller import HopController  # noqa: E402
from hopper.control.kernel import EV_APEX, EV_FALL, EV_LIFTOFF, EV_TOUCHDOWN, control_tick  # noqa: E402
from hopper.control.phases import FallCause, Phase  # noqa: E402

__all__ = ["EV_APEX", "EV_FALL", "EV_LIFTOFF", "EV_TOUCHDOWN", "FallCause", "HopController", "Phase", "control_tick"]
