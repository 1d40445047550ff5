"""Wall-clock pacing: turn elapsed wall time into a budget of fixed simulation steps."""

from __future__ import annotations

import collections
import math

MIN_SPEED, MAX_SPEED = 0.1, 64.0  # x real time, the Simulation panel's range (the loop says when it falls behind)
MAX_LAG_S = 0.25  # s of wall time the budget may owe (a scheduling stall is caught up); older debt is dropped
RTF_WINDOW_S = 1.0  # s of wall time the real-time factor is averaged over
BEHIND_FRACTION = 0.95  # delivered / asked speed below this means "cannot keep up"


class Pacer:
    """Accumulates `wall_dt * speed` as a budget of simulated seconds and hands out whole steps.

    The budget is capped at MAX_LAG_S of wall time so a slow machine runs slower than real time
    instead of spiralling; the real-time factor then shows it.
    """

    def __init__(self, timestep: float, speed: float = 1.0) -> None:
        self.timestep = timestep
        self.speed = speed
        self.paused = False
        self._budget = 0.0  # s of simulation owed
        self._last: float | None = None
        self._steps = 0  # cumulative steps done, for the real-time factor
        self._samples: collections.deque[tuple[float, int]] = collections.deque()  # (wall s, steps)

    @staticmethod
    def check_speed(speed: float) -> None:
        """Raise ValueError unless `speed` (x real time) is a number in [MIN_SPEED, MAX_SPEED]."""
        if not (isinstance(speed, (int, float)) and math.isfinite(speed) and MIN_SPEED <= speed <= MAX_SPEED):
            raise ValueError(f"speed must be a number in [{MIN_SPEED:g}, {MAX_SPEED:g}] x real time, got {speed!r}")

    def set_speed(self, speed: float) -> None:
        """Set the asked speed (x real time); raises ValueError outside [MIN_SPEED, MAX_SPEED]."""
        self.check_speed(speed)
        self.speed = float(speed)

    def due(self, now: float, most: int | None = None) -> int:
        """Whole steps owed at wall time `now` (s, monotonic clock), at `most` this many.

        The rest stays owed (up to MAX_LAG_S): a loop that cannot keep up still publishes between
        batches of steps instead of stepping a quarter second of wall time at once.
        """
        wall_dt = 0.0 if self._last is None else max(now - self._last, 0.0)
        self._last = now
        if self.paused:
            self._budget = 0.0
            return 0
        self._budget = min(self._budget + wall_dt * self.speed, MAX_LAG_S * self.speed)
        steps = int(self._budget / self.timestep + 1e-6)
        return steps if most is None else min(steps, most)

    def done(self, budgeted: int, now: float, extra: int = 0) -> None:
        """Record steps taken at `now`: `budgeted` are paid from the budget, `extra` (single steps) are not."""
        self._budget = max(self._budget - budgeted * self.timestep, 0.0)
        self._steps += budgeted + extra
        self._samples.append((now, self._steps))
        while len(self._samples) > 2 and now - self._samples[1][0] >= RTF_WINDOW_S:
            self._samples.popleft()

    def restart_window(self) -> None:
        """Forget the real-time-factor history (after a pause or a speed change)."""
        self._samples.clear()

    def real_time_factor(self) -> float:
        """Simulated seconds per wall second over about the last RTF_WINDOW_S."""
        if len(self._samples) < 2:
            return 0.0
        (t0, n0), (t1, n1) = self._samples[0], self._samples[-1]
        return (n1 - n0) * self.timestep / (t1 - t0) if t1 > t0 else 0.0

    @property
    def behind(self) -> bool:
        """True when the delivered speed falls noticeably short of the asked one."""
        return not self.paused and len(self._samples) > 10 and self.real_time_factor() < BEHIND_FRACTION * self.speed
