"""Ready-made Arrow columns for rr.send_columns: component columns, vectors, time columns."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import rerun as rr

from hopper.telemetry.schema import HOP, TIME

TRANSLATION = rr.Transform3D.descriptor_translation()
QUATERNION = rr.Transform3D.descriptor_quaternion()
CHILD_FRAME = rr.Transform3D.descriptor_child_frame()
STRIPS = rr.LineStrips3D.descriptor_strips()
SCALARS = rr.Scalars.descriptor_scalars()
TEXT = rr.TextLog.descriptor_text()
LEVEL = rr.TextLog.descriptor_level()
STATE = rr.StateChange.descriptor_state()


class Column:
    """A component column for rr.send_columns: one `per_row` slice of `values` a row.

    The archetypes' .columns() helpers convert element by element in Python, ~100x slower.
    """

    def __init__(self, descriptor: rr.ComponentDescriptor | str, values: pa.Array, per_row: int = 1) -> None:
        self.descriptor = rr.ComponentDescriptor(descriptor) if isinstance(descriptor, str) else descriptor
        self.array = pa.ListArray.from_arrays(np.arange(0, len(values) + 1, per_row, dtype=np.int32), values)

    def component_descriptor(self) -> rr.ComponentDescriptor:
        return self.descriptor

    def as_arrow_array(self) -> pa.Array:
        return self.array


def vectors(values: np.ndarray) -> pa.Array:
    """(n, k) floats as Arrow fixed-size lists of float32: rerun's Vec3D and Quaternion layout."""
    k = values.shape[-1]
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).ravel())
    return pa.FixedSizeListArray.from_arrays(flat, type=pa.list_(pa.field("item", pa.float32(), False), k))


def time_columns(ns: np.ndarray | list[int], hops: np.ndarray | list[int] | None = None) -> list[rr.TimeColumn]:
    """The sim_time column (ns), and the hop column if `hops` is given."""
    columns = [rr.TimeColumn(TIME, duration=np.asarray(ns, dtype=np.int64).astype("timedelta64[ns]"))]
    if hops is not None:
        columns.append(rr.TimeColumn(HOP, sequence=hops))
    return columns
