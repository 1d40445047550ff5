"""One recording set-up for hopper-sim and the dashboard: a .rrd file cut into parts, a rerun viewer, or both."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hopper.app.rerun_viewer import ViewerKind

    from hopper.sim import Simulation
    from hopper.telemetry import Telemetry


@dataclasses.dataclass(frozen=True, kw_only=True)
class FileLimits:
    """How a recording is cut into files and how often it is flushed (hopper.telemetry.Telemetry)."""

    max_mb: float | None = None  # MB (1e6 bytes) per part; None: no size limit
    max_min: float | None = None  # minutes of simulation per part; None: no duration limit
    flush_s: float = 1.0  # s of wall time between flushes

    @property
    def rolls(self) -> bool:
        """Whether the recording is cut into numbered parts."""
        return self.max_mb is not None or self.max_min is not None

    def telemetry_options(self) -> dict[str, Any]:
        return {
            "max_bytes": round(self.max_mb * 1e6) if self.max_mb is not None else None,
            "max_seconds": self.max_min * 60.0 if self.max_min is not None else None,
            "flush_s": self.flush_s,
        }


WHOLE_FILE = FileLimits()  # one file, flushed every second


def open_recording(
    sim: Simulation,
    path: Path | None,
    viewer: ViewerKind = "off",
    limits: FileLimits = WHOLE_FILE,
    name: str | None = None,
    on_part: Callable[[Path, Path], None] | None = None,
    on_stop: Callable[[str], None] | None = None,
    on_lag: Callable[[str | None], None] | None = None,
) -> tuple[Telemetry, str | None]:
    """Start recording `sim` to `path` (None: no file) and/or a rerun viewer; the Telemetry, attached
    to `sim`, and the served viewer's URL (None unless `viewer` is "serve").

    Raises hopper.app.rerun_viewer.ViewerError if the viewer cannot start, OSError or ValueError if
    the file cannot be written; a viewer already started is closed again.
    """
    # rerun's import costs ~0.5 s: only when recording (hopper-sim --help stays fast)
    from hopper.app.rerun_viewer import open_viewer

    from hopper.telemetry import Telemetry

    live = open_viewer(viewer)
    try:
        telemetry = Telemetry(
            sim,
            path=path,
            sinks=live.sinks,
            on_close=live.close,
            recording_name=name,
            on_part=on_part,
            on_stop=on_stop,
            on_lag=on_lag,
            **(limits.telemetry_options() if path is not None else {}),
        )
    except BaseException:
        live.close()
        raise
    return telemetry, live.url
