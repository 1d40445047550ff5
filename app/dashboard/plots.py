"""Live uPlot charts of pitch, wheel speed and wheel torque over a rolling window of simulation time."""

from __future__ import annotations

import math

import numpy as np
import viser
import viser.uplot as uplot
from hopper.app.dashboard.chart_feed import ChartFeed, ChartSpec
from hopper.app.dashboard.viser_compat import element_id

from hopper.metrics import RAD_S_TO_RPM
from hopper.robot import PACKAGED, Robot

PLOT_WINDOW_S = 10.0  # s of simulation shown
PLOT_SAMPLE_S = 0.025  # s of simulation between samples: 8 a period of the wn = 30 rad/s pitch loop
PLOT_PUBLISH_S = 0.2  # s of wall time between chart refreshes (5 a second); each sends what is new (chart_feed)
PLOT_HEIGHT_PX = 105  # px: CHART_HEIGHT less the time axis (26) and the top padding (4)
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


# Decimals sent per column, a quarter pixel at most of its chart (chart_feed): time, pitch, rpm, torque.
T_DECIMALS, PITCH_DECIMALS, RPM_DECIMALS, TORQUE_DECIMALS = 3, 2, 0, 1


class LivePlots:
    """Pitch, wheel RPM and wheel torque (applied and asked) over the last PLOT_WINDOW_S, with the wheel's limits."""

    def __init__(self, server: viser.ViserServer, robot: Robot = PACKAGED) -> None:
        gui = server.gui
        self.window = RollingWindow(_N, 5)
        self._next_publish = -math.inf
        self.rpm_limit = robot.wheel_no_load_speed * RAD_S_TO_RPM  # 400 rpm on the packaged robot
        self.torque_limit = robot.wheel_torque_limit  # N m
        time = _series("t (s)", "")
        self.pitch = _chart(gui, (time, _series("pitch (°)", "#ffb03b")), None)
        self.rpm_range = 2 * self.rpm_limit * 1.05  # rpm, fixed
        self.rpm = _chart(
            gui,
            (time, _series("wheel speed (rpm)", "#5aa9ff"), *_limit_series()),
            (-self.rpm_range / 2, self.rpm_range / 2),
        )
        limit = self.torque_limit * 1.08
        self.torque_range = 2 * limit  # N m, fixed
        torque = (_series("torque (N m)", "#f25f5c"), _series("asked", "#cfd6dd", 1.0, (4, 3)))
        self.torque = _chart(gui, (time, *torque, *_limit_series()), (-limit, limit))
        rpm, nm, t = float(self.rpm_limit), float(self.torque_limit), T_DECIMALS
        self.feed = ChartFeed(
            server,
            (
                ChartSpec(element_id(self.pitch), (_T, _PITCH), (t, PITCH_DECIMALS)),
                ChartSpec(element_id(self.rpm), (_T, _RPM, rpm, -rpm), (t, RPM_DECIMALS, 0, 0)),
                ChartSpec(
                    element_id(self.torque),
                    (_T, _TORQUE, _COMMAND, nm, -nm),
                    (t, TORQUE_DECIMALS, TORQUE_DECIMALS, 1, 1),
                ),
            ),
        )

    def sample(self, time: float, pitch: float, wheel_speed: float, torque: float, command: float) -> None:
        """Add one sample (SI units); the caller keeps one every PLOT_SAMPLE_S of simulation time."""
        self.window.append((time, math.degrees(pitch), wheel_speed * RAD_S_TO_RPM, torque, command))

    def clear(self) -> None:
        self.window.clear()
        self.feed.replaced()

    def drop_after(self, time: float) -> None:
        self.window.drop_after(time)
        self.feed.replaced()

    def publish(self, now: float) -> None:
        """Send each page what it lacks of the window, every PLOT_PUBLISH_S of wall time `now` at most.

        Refreshes keep to a fixed grid of PLOT_PUBLISH_S (a refresh due between two frames goes out at
        the next one), so they average one per PLOT_PUBLISH_S rather than one per whole number of frames.
        A page that connects while the simulation is paused gets the window at the next refresh.
        """
        if len(self.window) < 2 or now < self._next_publish:
            return
        c = self.window.columns()
        if not self.feed.behind(float(c[_T][-1])):
            return
        late = now - self._next_publish
        self._next_publish = now + PLOT_PUBLISH_S if late >= PLOT_PUBLISH_S else self._next_publish + PLOT_PUBLISH_S
        self.feed.publish(c)


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


LOGGED_COLOR, SIMULATED_COLOR = BEFORE_COLOR, AFTER_COLOR  # a log's replay: the log (orange), the simulation (blue)
LOG_REPLAY_POINTS = 4000  # at most, per chart: a few hops at full rate would be tens of thousands


class LogReplayPlots:
    """A log replayed beside the simulation, against the log's time: pitch and wheel speed errors
    (simulated minus logged) and the feet's contact, logged and simulated (its edges show the timing)."""

    def __init__(self, gui: viser.GuiApi) -> None:
        time = _series("log t (s)", "")
        self.pitch = _chart(gui, (time, _series("pitch error (°)", SIMULATED_COLOR)), None)
        self.wheel = _chart(gui, (time, _series("wheel speed error (rpm)", SIMULATED_COLOR)), None)
        contact = (_series("log on ground", LOGGED_COLOR), _series("sim on ground", SIMULATED_COLOR, 2.0, (5, 3)))
        self.contact = _chart(gui, (time, *contact), (-0.15, 1.25))

    def show(
        self,
        time: np.ndarray,
        pitch_error: np.ndarray,
        wheel_error: np.ndarray,
        logged_on: np.ndarray,
        simulated_on: np.ndarray,
    ) -> None:
        """Per sample: time s, pitch error rad, wheel speed error rad/s, either foot down (bool), thinned
        to LOG_REPLAY_POINTS; the simulated contact is drawn at 0.95 so that both lines show where they agree."""
        k = slice(None, None, max(1, -(-len(time) // LOG_REPLAY_POINTS)))
        t = time[k].astype(np.float32)
        self.pitch.data = (t, np.degrees(pitch_error[k]).astype(np.float32))
        self.wheel.data = (t, (wheel_error[k] * RAD_S_TO_RPM).astype(np.float32))
        self.contact.data = (t, logged_on[k].astype(np.float32), 0.95 * simulated_on[k].astype(np.float32))
