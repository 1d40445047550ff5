"""Every touch of rerun's private internals, one small function each, version-checked when imported.

All three serve one need: each part of a rolled-over recording gets the default blueprint without
rerun building (and leaking) a new blueprint stream per part. rerun 0.41's public
`rr.set_sinks(default_blueprint=...)` and `rr.send_blueprint` both go through
`rerun.blueprint.api.create_in_memory_blueprint`, which makes a fresh blueprint stream each call,
and about 2.4 MB of each is never freed (measured: 40 calls, +100 MB resident), so an hour's
recording with rollover grew without bound. One stream, re-logged into a fresh memory sink for
each part, is freed as it should be. tests/test_rerun_compat.py proves what each touch does.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import rerun_bindings as _bindings
from rerun.recording_stream import RecordingStream

from hopper.versions import installed_version, require_series

if TYPE_CHECKING:
    import rerun.blueprint as rrb
    from rerun.sinks import LogSinkLike

SERIES = "0.41"  # pyproject.toml pins rerun-sdk>=0.41,<0.42; every touch below was read in 0.41.0


def check_version(found: str | None = None) -> None:
    """UnsupportedVersion unless the installed rerun-sdk (or `found`) is a 0.41 release."""
    require_series("rerun-sdk", SERIES, installed_version("rerun-sdk") if found is None else found, module=__name__)


check_version()


def blueprint_stream(application_id: str) -> RecordingStream:
    """A new blueprint stream (not a data recording) for this application, neither global nor thread default.

    Private: `rr.RecordingStream(...)` makes data recordings only; this is how
    `create_in_memory_blueprint` makes its stream (`bindings.new_blueprint`, wrapped by
    `RecordingStream._from_native`), done once instead of once a part.
    """
    return RecordingStream._from_native(
        _bindings.new_blueprint(
            application_id=application_id, make_default=False, make_thread_default=False, default_enabled=True
        )
    )


def log_blueprint(blueprint: rrb.Blueprint, stream: RecordingStream) -> None:
    """Log every part of `blueprint` (viewport, containers, views, panels) into a blueprint stream.

    Private: `Blueprint._log_to_stream`; the only public callers of it build a new stream first.
    """
    blueprint._log_to_stream(stream)


def set_sinks(sinks: Sequence[LogSinkLike], *, default_blueprint: Any, recording: RecordingStream) -> None:
    """Replace the recording's sinks (each dropped one is finished) and give the new ones this default blueprint.

    `default_blueprint` is a memory sink's storage (`MemoryRecording.storage`) holding a logged
    blueprint. Private: `rerun_bindings.set_sinks`; the public `rr.set_sinks` takes a blueprint
    object only and builds a new blueprint stream from it each call.
    """
    _bindings.set_sinks([*sinks], default_blueprint=default_blueprint, recording=recording.to_native())
