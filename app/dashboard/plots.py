"""Live uPlot charts of pitch, wheel speed and wheel torque over a rolling window of simulation time."""

from __future__ import annotations

import math

import numpy as np
import viser
import viser.uplot as uplot

from hopper.config import WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT
from hopper.metrics import RAD_S_TO_RPM

PLOT_WINDOW_S = 10.0  # s of simulation shown
PLOT_SAMPLE_S = 0.025  # s of simulation between samples: 8 a period of the wn = 30 rad/s pitch loop
PLOT_PUBLISH_S = 0.1  # s of wall time between chart updates; each re-sends the window (~22 KB, float64)
CHART_HEIGHT = 135  # px
Y_SOFT = 2.0  # deg, the pitch chart shows at least +-Y_SOFT
LIMIT_COLOR = "#e5484d"  # red, dashed: the wheel's torque and speed limits
_N = int(round(PLOT_WINDOW_S / PLOT_SAMPLE_S))
# Columns of the ring buffer.
_T, _PITCH, _RPM, _TORQUE, _COMMAND = range(5)


class RollingWindow:
    """A fixed-size ring of rows (time, values...) in float32, read back oldest first."""

    def __init__(self, rows: int, columns: int) -> None:
        self._data = np.zeros((rows, columns), dtype=np.float32)
        self._next = 0
        self._full = False

    def append(self, row: tuple[float, ...]) -> None:
        self._data[self._next] = row
        self._next = (self._next + 1) % len(self._data)
        self._full = self._full or self._next == 0

    def clear(self) -> None:
        self._next, self._full = 0, False

    def drop_after(self, time: float) -> None:
        """Forget rows newer than `time` (s): the simulation was put back to that moment."""
        rows = self.columns().T
        keep = rows[rows[:, 0] <= time]
        self.clear()
        for row in keep[-len(self._data) :]:
            self.append(tuple(row))

    def columns(self) -> np.ndarray:
        """Shape (columns, n), oldest sample first (contiguous rows, ready to send)."""
        rows = (
            np.concatenate([self._data[self._next :], self._data[: self._next]])
            if self._full
            else self._data[: self._next]
        )
        return np.ascontiguousarray(rows.T)

    def __len__(self) -> int:
        return len(self._data) if self._full else self._next


def _series(label: str, color: str, width: float = 1.5, dash: tuple[float, ...] | None = None) -> uplot.Series:
    series: uplot.Series = {"label": label, "stroke": color, "width": width}
    if dash:
        series["dash"] = dash
    return series


def _chart(
    gui: viser.GuiApi, series: tuple[uplot.Series, ...], y_range: tuple[float, float] | None
) -> viser.GuiUplotHandle:
    """A compact chart: no title (the legend names the series and units, with live values on hover)."""
    empty = tuple(np.zeros(1, dtype=np.float32) for _ in series)
    scales: dict[str, uplot.Scale] = {"x": {"time": False, "auto": True}}
    # A fixed range shows the limit; otherwise auto-range, but never tighter than y_soft.
    scales["y"] = (
        {"range": y_range}
        if y_range
        else {"range": {"min": {"soft": -Y_SOFT, "mode": 1}, "max": {"soft": Y_SOFT, "mode": 1}}}
    )
    return gui.add_uplot(
        empty,
        series,
        scales=scales,
        # x, y: denser y ticks than uPlot's default on a short chart, short tick marks.
        axes=({"space": 40, "size": 26, "ticks": {"size": 3}}, {"space": 18, "size": 46, "ticks": {"size": 3}}),
        legend={"show": True, "live": True},
        cursor={"drag": {"x": False, "y": False}},
        height=CHART_HEIGHT,
        padding=(4, 12, 0, 0),
    )


def _limit_series() -> tuple[uplot.Series, uplot.Series]:
    """Two dashed red lines at +-the limit, as the rerun recording draws it (short labels: one legend line)."""
    return _series("+limit", LIMIT_COLOR, 1.0, (6, 4)), _series("-limit", LIMIT_COLOR, 1.0, (6, 4))


class LivePlots:
    """Pitch, wheel RPM and wheel torque (applied and asked) over the last PLOT_WINDOW_S, with the wheel's limits."""

    def __init__(self, gui: viser.GuiApi) -> None:
        self.window = RollingWindow(_N, 5)
        self._last_publish = -math.inf
        self._dirty = False
        self.rpm_limit = WHEEL_NO_LOAD_SPEED * RAD_S_TO_RPM  # 400 rpm
        time = _series("t (s)", "")
        self.pitch = _chart(gui, (time, _series("pitch (°)", "#ffb03b")), None)
        self.rpm = _chart(
            gui,
            (time, _series("wheel speed (rpm)", "#5aa9ff"), *_limit_series()),
            (-self.rpm_limit * 1.05, self.rpm_limit * 1.05),
        )
        limit = WHEEL_TORQUE_LIMIT * 1.08
        torque = (_series("torque (N m)", "#f25f5c"), _series("asked", "#cfd6dd", 1.0, (4, 3)))
        self.torque = _chart(gui, (time, *torque, *_limit_series()), (-limit, limit))

    def sample(self, time: float, pitch: float, wheel_speed: float, torque: float, command: float) -> None:
        """Add one sample (SI units); the caller keeps one every PLOT_SAMPLE_S of simulation time."""
        self.window.append((time, math.degrees(pitch), wheel_speed * RAD_S_TO_RPM, torque, command))
        self._dirty = True

    def clear(self) -> None:
        self.window.clear()
        self._dirty = True

    def drop_after(self, time: float) -> None:
        self.window.drop_after(time)
        self._dirty = True

    def publish(self, now: float) -> None:
        """Send the window to the charts if it changed, at most every PLOT_PUBLISH_S of wall time `now`."""
        if not self._dirty or len(self.window) < 2 or now - self._last_publish < PLOT_PUBLISH_S:
            return
        self._dirty, self._last_publish = False, now
        c = self.window.columns()
        t = c[_T]
        self.pitch.data = (t, c[_PITCH])
        self.rpm.data = (t, c[_RPM], *_constant(t, self.rpm_limit))
        self.torque.data = (t, c[_TORQUE], c[_COMMAND], *_constant(t, WHEEL_TORQUE_LIMIT))


def _constant(t: np.ndarray, value: float) -> tuple[np.ndarray, np.ndarray]:
    """+-value at every sample time (uPlot needs one y per x); compresses to nearly nothing on the wire."""
    return np.full_like(t, value), np.full_like(t, -value)


REFLY_EVERY = 5  # ticks between the re-fly charts' points (200 Hz: smooth at the wn = 30 rad/s loop)
BEFORE_COLOR, AFTER_COLOR = "#ffb03b", "#5aa9ff"  # the recorded flight (as the live pitch), the re-flown one


class ReflyPlots:
    """Pitch and wheel torque of one flight, before (recorded gains) and after (current gains), overlaid
    against the time since liftoff."""

    def __init__(self, gui: viser.GuiApi) -> None:
        time = _series("t since liftoff (s)", "")
        self.pitch = _chart(
            gui, (time, _series("before (°)", BEFORE_COLOR), _series("after (°)", AFTER_COLOR, 2.0, (5, 3))), None
        )
        # Auto-ranged (at least +-Y_SOFT N m): a flight's torque is often far below the 29.5 N m limit.
        self.torque = _chart(
            gui, (time, _series("before (N m)", BEFORE_COLOR), _series("after (N m)", AFTER_COLOR, 2.0, (5, 3))), None
        )

    def show(self, dt: float, before: tuple[np.ndarray, np.ndarray], after: tuple[np.ndarray, np.ndarray]) -> None:
        """Overlay two flights given as (pitch rad, torque N m) per tick of `dt` s; the shorter one is padded
        with NaN (uPlot leaves a gap)."""
        n = max(len(before[0]), len(after[0]))
        t = (np.arange(0, n, REFLY_EVERY) + 1) * dt

        def column(values: np.ndarray, scale: float) -> np.ndarray:
            padded = np.full(n, np.nan)
            padded[: len(values)] = values * scale
            return padded[::REFLY_EVERY].astype(np.float32)

        deg = 180.0 / math.pi
        self.pitch.data = (t.astype(np.float32), column(before[0], deg), column(after[0], deg))
        self.torque.data = (t.astype(np.float32), column(before[1], 1.0), column(after[1], 1.0))
