"""The default rerun blueprint: 3D view, hop table, signal plots, phases and the event log."""

from __future__ import annotations

from typing import Any

import rerun as rr
import rerun.blueprint as rrb
from rerun.blueprint.encodings import ComponentSourceKind, VisualizerComponentMapping

from hopper.layout import LEG_JOINTS
from hopper.telemetry import rerun_compat as compat
from hopper.telemetry.columns import SCALARS
from hopper.telemetry.schema import HOP, TIME

BLUE, ORANGE, GREEN, RED, PURPLE = (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189)


def _lines(*fields: tuple[str, str, tuple[int, int, int]]) -> list[Any]:
    """One line visualizer per (struct field of `signals`, legend name, colour)."""
    return [
        rr.SeriesLines(names=name, colors=[color]).visualizer(
            mappings=[
                VisualizerComponentMapping(
                    target=str(SCALARS.component),
                    source_kind=ComponentSourceKind.SourceComponent,
                    source_component="signals",
                    selector=f".{field}",
                )
            ]
        )
        for field, name, color in fields
    ]


def _plot(name: str, *fields: tuple[str, str, tuple[int, int, int]], extra: str | None = None) -> rrb.View:
    contents = ["/signals", extra] if extra else ["/signals"]
    return rrb.TimeSeriesView(name=name, origin="/", contents=contents, overrides={"/signals": _lines(*fields)})


def default_blueprint() -> rrb.Blueprint:
    """Robot and hop table on the left; pitch, wheel speed and torque, more plots, phases, events."""
    colors = (BLUE, ORANGE, GREEN, RED)
    robot = rrb.Spatial3DView(
        name="robot",
        origin="/world",
        # From the -y side, following the torso; the trail shows everything up to the time cursor.
        eye_controls=rrb.EyeControls3D(
            position=(0.0, -3.5, 1.2),
            look_target=(0.0, 0.0, 0.7),
            eye_up=(0, 0, 1),
            tracking_entity="/world/robot/torso",
        ),
        time_ranges=rrb.VisibleTimeRange(
            TIME, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()
        ),
    )
    hops = rrb.DataframeView(name="hop metrics", origin="/hops", query=rrb.archetypes.DataframeQuery(timeline=HOP))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(robot, hops, row_shares=[3, 2]),
            rrb.Vertical(
                _plot("pitch (deg)", ("pitch_deg", "pitch", BLUE), ("pitch_est_deg", "estimate", ORANGE)),
                _plot("wheel speed (rpm)", ("wheel_rpm", "wheel", PURPLE)),
                _plot(  # applied, and asked (before the motor's delay and speed envelope), as the dashboard's chart
                    "wheel torque (N m)",
                    ("wheel_torque_nm", "torque", ORANGE),
                    ("wheel_cmd_nm", "asked", BLUE),
                    extra="/limits/wheel_torque",
                ),
                rrb.Tabs(
                    _plot("wheel momentum (% of capacity)", ("wheel_capacity_pct", "capacity used", PURPLE)),
                    _plot("pitch rate (deg/s)", ("pitch_rate_deg_s", "pitch rate", GREEN)),
                    _plot("leg angles (deg)", *[(f"{j}_deg", j, c) for j, c in zip(LEG_JOINTS, colors, strict=True)]),
                    _plot(
                        "leg torques (N m)",
                        *[(f"{j}_torque_nm", j, c) for j, c in zip(LEG_JOINTS, colors, strict=True)],
                    ),
                    _plot("foot forces (N)", ("foot_L_n", "left", BLUE), ("foot_R_n", "right", RED)),
                ),
                rrb.StateTimelineView(name="phase", origin="/phase"),
                row_shares=[3, 3, 3, 3, 2],
            ),
            rrb.TextLogView(name="events", origin="/events"),
            column_shares=[5, 5, 3],
        ),
        collapse_panels=True,
    )


class BlueprintSource:
    """The default blueprint, ready to go with each new set of sinks (each rolled-over part).

    rerun 0.41's `set_sinks(default_blueprint=...)` builds a new blueprint stream per call and
    about 2.4 MB of each is never freed (measured: 40 calls, +100 MB of resident memory), which
    made an hour's recording with rollover grow without bound. One blueprint stream, re-logged into
    a fresh memory sink for each part, is freed as it should be (40 parts, flat). The private
    touches this takes are in hopper.telemetry.rerun_compat.
    """

    def __init__(self, application_id: str) -> None:
        self._blueprint = default_blueprint()
        self._stream = compat.blueprint_stream(application_id)  # what rerun.blueprint.api does, once
        self._stream.set_time("blueprint", sequence=0)
        self._memory: Any = None

    def storage(self) -> Any:
        """A memory sink holding the blueprint, for `rerun_compat.set_sinks(default_blueprint=...)`."""
        self._memory = self._stream.memory_recording()  # kept until the next part's
        compat.log_blueprint(self._blueprint, self._stream)
        return self._memory.storage

    def close(self) -> None:
        self._stream.disconnect()
