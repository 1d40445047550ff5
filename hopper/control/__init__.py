"""The hop controller: the paper's contact-driven cycle as one compiled kernel per 1 kHz tick.

Modules, one concern each: `phases` (the cycle and its thresholds), `memory` (the kernel's
named record), `legs` (kinematics and leg torques), `wheel` (motor envelope and flight PID),
`contact` (debounced foot contact), `stance` (virtual-model control on the ground), `sensing`
(the simulated IMU, the attitude estimate and the wheel's command delay), `kernel` (the tick:
phases, actuation, metrics) and `controller` (its Python face).
"""

import hashlib
from collections.abc import Iterable
from pathlib import Path

# Every source the compiled kernel is built from: numba inlines the functions a jitted one calls.
KERNEL_SOURCES = tuple(sorted(Path(__file__).parent.glob("*.py")))


def drop_stale_compiled(sources: Iterable[Path], cache: Path, pattern: str, stamp: str) -> None:
    """Remove the numba cache files `pattern` in `cache` unless `sources` are byte for byte those
    they were compiled from (a digest kept in `cache`/`stamp`).

    numba's cache=True checks only the cached function's own source file, so an edit to stance.py
    (or an upgrade that changes it) would leave control_tick, or hopper.stepping's burst that
    inlines it, compiled with the old stance: run() and step() would then fly different robots.
    """
    digest = hashlib.sha1(b"".join(p.read_bytes() for p in sources)).hexdigest()
    try:
        if (cache / stamp).read_text() == digest:
            return
    except OSError:
        pass
    try:
        for compiled in cache.glob(pattern):
            compiled.unlink()
        cache.mkdir(exist_ok=True)
        (cache / stamp).write_text(digest)
    except OSError:
        pass  # a read-only install: numba then caches elsewhere, or not at all


drop_stale_compiled(KERNEL_SOURCES, Path(__file__).parent / "__pycache__", "*.nb[ic]", "numba-sources.sha1")

from hopper.control.controller import HopController  # noqa: E402
from hopper.control.kernel import EV_APEX, EV_FALL, EV_LIFTOFF, EV_TOUCHDOWN, control_tick  # noqa: E402
from hopper.control.phases import FallCause, Phase  # noqa: E402

__all__ = ["EV_APEX", "EV_FALL", "EV_LIFTOFF", "EV_TOUCHDOWN", "FallCause", "HopController", "Phase", "control_tick"]
