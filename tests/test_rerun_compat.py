"""Contract tests of hopper.telemetry.rerun_compat: one per private touch of rerun, by what it does.

Each writes what the touch produces (a memory sink's bytes, .rrd files) and reads it back with
rerun's own reader and verifier: a blueprint store, not a recording; every view of the blueprint,
again in each fresh sink; data and the default blueprint in the sinks that were attached when
it was logged, and a finished file for each sink replaced.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import re
from pathlib import Path

import pyarrow as pa
import pytest
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import RrdReader
from rrd import verify

from hopper.telemetry import rerun_compat as compat
from hopper.versions import UnsupportedVersion

pytestmark = pytest.mark.integration  # files read back by rerun's own reader and verifier

APP = "hopper_compat_test"


def small_blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(rrb.TimeSeriesView(name="alpha", origin="/a"), rrb.TextLogView(name="beta", origin="/b"))
    )


def view_names(path: Path) -> list[str]:
    """Display names of the views in the file's blueprint store (fails unless it has exactly one)."""
    reader = RrdReader(path)
    (store,) = reader.blueprints()
    assert store.application_id == APP
    names = []
    for chunk in reader.stream(store=store):
        table = pa.Table.from_batches([chunk.to_record_batch()])
        if "ViewBlueprint:display_name" in table.column_names:
            names += [str(n) for row in table.column("ViewBlueprint:display_name").to_pylist() for n in row or []]
    return sorted(names)


def entity_paths(path: Path) -> set[str]:
    """Entity paths with data in the file's recording store."""
    return {chunk.entity_path for chunk in RrdReader(path).stream() if not chunk.entity_path.startswith("/__")}


def stream_with_time() -> rr.RecordingStream:
    stream = compat.blueprint_stream(APP)
    stream.set_time("blueprint", sequence=0)
    return stream


# -- the version check ---------------------------------------------------------------------------
def test_the_version_check_refuses_another_release_series(monkeypatch: pytest.MonkeyPatch) -> None:
    compat.check_version()  # the installed one
    for supported in ("0.41.0", "0.41.3", "0.41.1rc2"):
        compat.check_version(supported)
    for other in ("0.42.0", "0.4.1", "0.40.9", "1.41.0"):
        with pytest.raises(UnsupportedVersion, match=rf"rerun-sdk {re.escape(other)} is installed; .* 0\.41\.\* only"):
            compat.check_version(other)

    real = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "0.42.0" if name == "rerun-sdk" else real(name))
    spec = importlib.util.spec_from_file_location("rerun_compat_under_0_42", compat.__file__)
    assert spec is not None and spec.loader is not None
    with pytest.raises(UnsupportedVersion, match=r"rerun-sdk 0\.42\.0 is installed"):
        spec.loader.exec_module(importlib.util.module_from_spec(spec))


# -- blueprint_stream ------------------------------------------------------------------------------
def test_a_blueprint_stream_makes_a_blueprint_store_not_a_recording(tmp_path: Path) -> None:
    stream = stream_with_time()
    memory = stream.memory_recording()
    stream.log("viewport", rrb.archetypes.ViewportBlueprint(auto_layout=True))
    path = tmp_path / "stream.rrd"
    path.write_bytes(memory.drain_as_bytes())
    reader = RrdReader(path)
    assert [s.kind for s in reader.blueprints()] == ["blueprint"] and reader.recordings() == []
    assert reader.blueprints()[0].application_id == APP
    # Neither the global nor this thread's blueprint: nothing else logs into it by accident.
    assert rr.get_global_data_recording() is not stream
    stream.disconnect()


# -- log_blueprint ---------------------------------------------------------------------------------
def test_logging_a_blueprint_puts_every_view_in_each_fresh_sink(tmp_path: Path) -> None:
    stream, blueprint = stream_with_time(), small_blueprint()
    for part in (1, 2):  # what BlueprintSource does for each part of a rolled-over recording
        memory = stream.memory_recording()
        compat.log_blueprint(blueprint, stream)
        path = tmp_path / f"part{part}.rrd"
        path.write_bytes(memory.drain_as_bytes())
        assert view_names(path) == ["alpha", "beta"], f"part {part} lacks the views"
    stream.disconnect()


# -- set_sinks ---------------------------------------------------------------------------------------
def test_set_sinks_replaces_and_finishes_the_old_sink_and_gives_each_new_one_the_blueprint(tmp_path: Path) -> None:
    stream, blueprint = stream_with_time(), small_blueprint()

    def storage() -> object:
        memory = stream.memory_recording()
        compat.log_blueprint(blueprint, stream)
        storage.keep = memory  # type: ignore[attr-defined]  # held while its sink may read it
        return memory.storage

    rec = rr.RecordingStream(APP)
    first, second = tmp_path / "first.rrd", tmp_path / "second.rrd"
    compat.set_sinks([rr.FileSink(str(first))], default_blueprint=storage(), recording=rec)
    rec.log("before", rr.TextLog("in the first file"))
    compat.set_sinks([rr.FileSink(str(second))], default_blueprint=storage(), recording=rec)
    verify(first)  # replaced: finished with its footer while the recording goes on
    rec.log("after", rr.TextLog("in the second file"))
    rec.flush()
    rec.disconnect()
    verify(second)
    assert entity_paths(first) == {"/before"} and entity_paths(second) == {"/after"}
    assert view_names(first) == view_names(second) == ["alpha", "beta"]  # each file its default blueprint
    stream.disconnect()
