"""Wall-clock pacing: turn elapsed wall time into a budget of fixed simulation steps."""

from __future__ import annotations

import collections
import math

MIN_SPEED, MAX_SPEED = 0.1, 64.0  # x real time, the Simulation panel's range (the loop says when it falls behind)
MAX = math.inf  # the "Max" speed: as fast as the machine allows, the budget ignored
MAX_ROUND_STEPS = 100  # steps a round takes at Max (~3 ms) before the loop looks at its clock again
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
        """Raise ValueError unless `speed` (x real time) is a number in [MIN_SPEED, MAX_SPEED] or MAX."""
        if not (isinstance(speed, (int, float)) and (speed == MAX or MIN_SPEED <= speed <= MAX_SPEED)):
            raise ValueError(
                f"speed must be a number in [{MIN_SPEED:g}, {MAX_SPEED:g}] x real time or Max, got {speed!r}"
            )

    @property
    def flat_out(self) -> bool:
        """At Max: every round steps MAX_ROUND_STEPS, whatever the wall clock says."""
        return self.speed == MAX

    @property
    def pace(self) -> float:
        """Simulated s per wall s to expect: the asked speed, or at Max the delivered one (at least 1)."""
        return max(self.real_time_factor(), 1.0) if self.flat_out else self.speed

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
        if self.flat_out:
            return MAX_ROUND_STEPS if most is None else min(MAX_ROUND_STEPS, most)
        self._budget = min(self._budget + wall_dt * self.speed, MAX_LAG_S * self.speed)
        steps = int(self._budget / self.timestep + 1e-6)
        return steps if most is None else min(steps, most)

    def done(self, budgeted: int, now: float, extra: int = 0) -> None:
        """Record steps taken at `now`: `budgeted` are paid from the budget, `extra` (single steps) are not."""
        self._budget = 0.0 if self.flat_out else max(self._budget - budgeted * self.timestep, 0.0)
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
        if self.paused or self.flat_out or len(self._samples) <= 10:
            return False
        return self.real_time_factor() < BEHIND_FRACTION * self.speed


def chart_scale(pace: float, wall_s: float, window_s: float) -> int:
    """How many times to stretch a chart window of `window_s` (s of simulation) so that at `pace` (x
    real time) it spans at least `wall_s` of wall time: 1 up to window_s / wall_s x, then a power of
    two (it changes seldom as a delivered pace wanders)."""
    need = pace * wall_s / window_s
    return 1 if need <= 1.0 else 2 ** math.ceil(math.log2(need))
