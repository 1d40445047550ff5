"""`compare`'s figure: per seed, how much the wheel cut the peak mid-air pitch, and the median over the
seeds whose runs the controller flew to the end. A run whose controller faulted is a failure
(hopper.experiments.outcome's rule): the PID flew its later flights, so its seed is left out."""

from __future__ import annotations

import dataclasses
import statistics

WHEEL_OFF = "wheel off = zero torque, wheel free to spin"


@dataclasses.dataclass(frozen=True)
class SeedPair:
    """One seed's two runs, wheel on and wheel off."""

    seed: int
    peak_on_deg: float  # the largest mid-air pitch deviation, wheel on
    peak_off_deg: float  # the same, wheel off
    faulted_runs: int  # of the two, those whose controller faulted (the PID flew on)

    @property
    def reduction_pct(self) -> float:
        """%, of the wheel-off peak (0 where that peak is 0)."""
        off = self.peak_off_deg
        return 100.0 * (off - self.peak_on_deg) / off if off > 0 else 0.0


@dataclasses.dataclass(frozen=True)
class MedianReduction:
    median_pct: float | None  # %, over the seeds kept; None when every seed was left out
    seeds: int  # all the seeds flown
    left_out: tuple[int, ...]  # the seeds with a faulted run
    faulted_runs: int

    def line(self) -> str:
        """The median in one line, saying what it is over and what it leaves out."""
        head = "median reduction of the peak mid-air pitch deviation, wheel on vs off"
        runs = f"{self.faulted_runs} faulted run{'s' if self.faulted_runs != 1 else ''}"
        if self.median_pct is None:
            return (f"{head}: none, every seed has a faulted run ({runs} of {2 * self.seeds}): the PID flew on "
                    "from the fault, so no figure is the controller's")  # fmt: skip
        kept = self.seeds - len(self.left_out)
        over = f"over {kept} seed{'s' if kept != 1 else ''}"
        if self.left_out:
            seeds = ", ".join(map(str, self.left_out))
            over += f" of {self.seeds}; {runs} left out (seed{'s' if len(self.left_out) != 1 else ''} {seeds})"
        return f"{head}: {self.median_pct:.1f}% ({over}; {WHEEL_OFF})"


def median_reduction(pairs: list[SeedPair]) -> MedianReduction:
    """The median reduction over the pairs without a faulted run."""
    kept = [p.reduction_pct for p in pairs if not p.faulted_runs]
    return MedianReduction(
        median_pct=statistics.median(kept) if kept else None,
        seeds=len(pairs),
        left_out=tuple(p.seed for p in pairs if p.faulted_runs),
        faulted_runs=sum(p.faulted_runs for p in pairs),
    )
