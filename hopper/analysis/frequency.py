"""Frequency response by injection: chirps and stepped sines, the H1 estimate with coherence, margins.

A signal d is added at the plant input (the wheel torque, N m: u = u_c + d) or at the pitch
reference (rad). From the logged d, u and the controller's output u_c, scipy.signal's cross- and
auto-spectra give (H1: the excitation is known, so its noise-free spectrum is the denominator)

    S = S_du / S_dd        sensitivity at the plant input, d -> u = 1 / (1 + L)
    T = -S_duc / S_dd      complementary sensitivity, d -> -u_c = L / (1 + L)
    L = -S_duc / S_du      the loop broken at the plant input

with the kernel's sign convention (the law's command acts on the wheel, the torso takes the
reaction: negative feedback is inside the plant). At the reference r the closed loop's r -> pitch
response is measured instead. Margins come from the measured L, on the band the coherence trusts.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, NamedTuple

import numpy as np
from scipy import signal

from hopper.config import TIMESTEP, WHEEL_TORQUE_LIMIT
from hopper.control.phases import FALL_PITCH
from hopper.errors import HopperError

COHERENCE_TRUSTED = 0.8  # below this an estimate is not to be trusted (PHYSICS.md)
COHERENCE_USABLE = 0.5  # below this a bin is mostly noise: margins() does not look for crossings there
REFERENCE_LIMIT = FALL_PITCH / 4.0  # rad: a reference swing that leaves the fall limit far away
TAPER_S = 0.02  # s of cosine ramp at each end of a chirp: no step at its start or end
SWEEP_BEYOND = 1.5  # x: a chirp starts this far below f_min and ends this far above f_max
EXCITED_SHARE = 0.05  # of the median in-band excitation power: bins excited less are dropped
RESOLVED_BINS = 3  # a crossover closer to 0 Hz than this many frequency bins is not resolved
# Half-width (decades of frequency) of the local fit through which a measured loop's margins are
# read: +-20 % about each bin. Sensor noise through the law leaves each bin's |L| a dB or so off
# (coherence 0.9), and on a -20 dB/decade slope 1 dB moves a crossing by 12 %: the highest of the
# ripple's crossings was taken, 14-60 % above the true one (the same chirp less the same noise run
# alone gave the model's crossover). A straight line in log f through the bins around each one,
# weighted by their information, averages the ripple out and leaves a straight Bode slope as it is.
FIT_DECADES = 0.08
FIT_COHERENCE_CAP = 0.999  # a noise-free bin (coherence 1) weighs as one of coherence 0.999
STEPPED_CYCLES = 4  # whole cycles of each stepped sine that are analysed (after one to settle)
# s: the longest chirp, 600 k ticks (measured: 1.3 min and 0.36 GB on the stand); 1e9 s asked numpy for
# terabytes. A 0.05 Hz f_min needs only 40 s (2 cycles).
MAX_LENGTH_S = 600.0


class InvalidChirp(HopperError, ValueError):
    """A chirp or stepped-sine spec that cannot be injected; the message says what is allowed."""


class NotMeasured(HopperError, RuntimeError):
    """What a measurement cannot give (no crossover in the band, too little coherence); says why."""


class Limit(NamedTuple):
    """What one of ChirpSpec's numbers may be on its own: above `low` and up to `high` (under it if
    `below`), in `unit`; `why` names what sets `high` when the plant does (a refusal says so)."""

    low: float
    high: float
    unit: str
    below: bool = False  # `high` itself is refused
    why: str = ""

    def admits(self, value: float) -> bool:
        return math.isfinite(value) and self.low < value and (value < self.high if self.below else value <= self.high)

    @property
    def span(self) -> str:
        """The range as a refusal writes it: (0, 600] s."""
        return f"({self.low:g}, {self.high:g}{')' if self.below else ']'} {self.unit}"


def chirp_limits(at: str = "input", dt: float = TIMESTEP) -> dict[str, Limit]:
    """The range of each of ChirpSpec's numbers (f_min, f_max, amplitude, length) at the injection
    point `at` and the loop's period `dt` (s). ChirpSpec checks these, then what ties the numbers
    together (f_min under f_max, two cycles of f_min in the length, the stepped sines' cycles)."""
    band = Limit(0.0, 0.5 / dt, "Hz", below=True, why=f"the Nyquist frequency of the {1.0 / dt:g} Hz loop")
    if at == "reference":
        amplitude = Limit(0.0, REFERENCE_LIMIT, "rad", why="a quarter of the fall pitch")
    else:
        amplitude = Limit(0.0, WHEEL_TORQUE_LIMIT, "N m", why="the motor's torque limit")
    return {"f_min": band, "f_max": band, "amplitude": amplitude, "length": Limit(0.0, MAX_LENGTH_S, "s")}


@dataclasses.dataclass(frozen=True, kw_only=True)
class ChirpSpec:
    """An excitation: its band (Hz), amplitude (N m at the plant input, rad at the reference), length (s)."""

    f_min: float = 1.0  # Hz
    f_max: float = 100.0  # Hz
    amplitude: float = 0.5  # N m at "input", rad at "reference"
    length: float = 20.0  # s
    kind: Literal["linear", "log", "stepped"] = "log"
    at: Literal["input", "reference"] = "input"
    steps: int = 24  # stepped sines: how many frequencies, log spaced over the band
    dt: float = TIMESTEP  # s, the loop's period

    def __post_init__(self) -> None:
        if self.kind not in ("linear", "log", "stepped"):
            raise InvalidChirp(f"chirp kind {self.kind!r} is not one of linear, log, stepped")
        if self.at not in ("input", "reference"):
            raise InvalidChirp(f"injection point {self.at!r} is not one of input, reference")
        limits = chirp_limits(self.at, self.dt)
        if not limits["length"].admits(self.length):
            raise InvalidChirp(f"chirp length must be in {limits['length'].span}, got {self.length:g}")
        if not (math.isfinite(self.f_min) and math.isfinite(self.f_max) and 0.0 < self.f_min < self.f_max):
            raise InvalidChirp(f"chirp range must be 0 < f_min < f_max (Hz), got {self.f_min:g} to {self.f_max:g}")
        band = limits["f_max"]
        if not band.admits(self.f_max):
            raise InvalidChirp(f"chirp f_max {self.f_max:g} Hz must be under {band.why} ({band.high:g} Hz)")
        amplitude = limits["amplitude"]
        if not amplitude.admits(self.amplitude):
            raise InvalidChirp(f"chirp amplitude must be in {amplitude.span} ({amplitude.why}), got {self.amplitude:g}")
        if self.length * self.f_min < 2.0:
            raise InvalidChirp(
                f"a {self.length:g} s chirp holds under 2 cycles of f_min {self.f_min:g} Hz: lengthen it or raise f_min"
            )
        if self.kind == "stepped" and not (2 <= self.steps <= 500):
            raise InvalidChirp(f"stepped sines need 2 to 500 steps, got {self.steps}")
        if self.kind == "stepped" and self.length / self.steps * self.f_min < STEPPED_CYCLES + 1:
            raise InvalidChirp(
                f"each of {self.steps} stepped sines lasts {self.length / self.steps:g} s, under "
                f"{STEPPED_CYCLES + 1} cycles of f_min {self.f_min:g} Hz: lengthen the run or use fewer steps"
            )

    @property
    def sweep(self) -> tuple[float, float]:
        """The band a chirp sweeps (Hz): SWEEP_BEYOND wider than the one reported, so that every
        reported bin lies inside the sweep rather than at its abrupt start or end."""
        return self.f_min / SWEEP_BEYOND, min(self.f_max * SWEEP_BEYOND, 0.95 * 0.5 / self.dt)

    @property
    def ticks(self) -> int:
        return round(self.length / self.dt)

    def frequencies(self) -> np.ndarray:
        """Stepped sines: the frequencies (Hz), each rounded to a whole number of cycles in its step."""
        hold = self.ticks // self.steps * self.dt
        f = np.geomspace(self.f_min, self.f_max, self.steps)
        return np.maximum(np.round(f * hold), STEPPED_CYCLES + 1) / hold


def excitation(spec: ChirpSpec) -> np.ndarray:
    """The injected signal, one sample a tick, shape (spec.ticks,) (N m or rad)."""
    n, dt = spec.ticks, spec.dt
    t = np.arange(n) * dt
    if spec.kind == "stepped":
        hold = n // spec.steps
        d = np.zeros(n)
        for i, f in enumerate(spec.frequencies()):
            k = np.arange(hold)
            d[i * hold : (i + 1) * hold] = np.sin(2.0 * math.pi * f * k * dt)  # whole cycles: no step between
        return spec.amplitude * d
    method = "linear" if spec.kind == "linear" else "logarithmic"
    low, high = spec.sweep
    d = signal.chirp(t, low, t[-1], high, method=method, phi=-90.0)  # sine: starts at 0
    ramp = min(round(TAPER_S / dt), n // 4)
    if ramp:
        taper = 0.5 - 0.5 * np.cos(np.linspace(0.0, math.pi, ramp))
        d[:ramp] *= taper
        d[n - ramp :] *= taper[::-1]
    return spec.amplitude * d


@dataclasses.dataclass(frozen=True)
class Response:
    """Measured frequency responses on a grid; complex arrays of shape (len(f),)."""

    f: np.ndarray  # Hz
    loop: np.ndarray | None  # L at the plant input (None: injected at the reference)
    sensitivity: np.ndarray  # S: d -> u at the input; r -> tracking error r - pitch at the reference
    complementary: np.ndarray  # T: d -> -u_c at the input; r -> pitch at the reference
    coherence: np.ndarray  # 0..1, of the weaker of the two spectra each estimate divides
    at: str
    # Welch segments averaged, all records (stepped sines: their steps). With one the coherence is
    # 1 by construction (|S_dx|^2 = S_dd S_xx for a single segment): no estimate of anything.
    segments: int = 2

    def band(self, low: float, high: float) -> Response:
        keep = (self.f >= low) & (self.f <= high)
        pick = lambda a: None if a is None else a[keep]  # noqa: E731
        return Response(
            self.f[keep],
            pick(self.loop),
            pick(self.sensitivity),
            pick(self.complementary),
            self.coherence[keep],
            self.at,
            self.segments,
        )

    @property
    def coherent(self) -> bool:
        """Whether the coherence was estimated (from two segments or more)."""
        return self.segments >= 2


def resolving_segment(spec: ChirpSpec) -> int:
    """The Welch segment (samples) that resolves f_min / 2: a power of 2."""
    return 2 ** math.ceil(math.log2(2.0 / (spec.f_min * spec.dt)))


def segment_length(spec: ChirpSpec, record_ticks: int | None = None) -> int:
    """Welch segment (samples): a resolution of f_min / 2 at least; the whole record if it holds
    fewer than two such segments. A shorter segment than the record would leave the record's end
    out of every segment, and a chirp sweeps its highest frequencies there: a 3 s log chirp to
    200 Hz, in one 2.048 s segment, reached 43 Hz, and the bins above read the segment's edge."""
    n = spec.ticks if record_ticks is None else record_ticks
    wanted = resolving_segment(spec)
    return int(n if n < 2 * wanted else wanted)


def coherent_length(spec: ChirpSpec) -> float:
    """The shortest record (s) whose coherence is estimated: two segments (segment_length)."""
    return 2 * resolving_segment(spec) * spec.dt


def segments(record_ticks: int, nperseg: int) -> tuple[int, int]:
    """Half-overlapping Welch segments of `nperseg` in a record (as scipy.signal.welch lays them),
    and the samples at its end that none of them covers (welch leaves them out)."""
    if record_ticks <= nperseg:
        return 1, 0
    step = nperseg - nperseg // 2
    return 1 + (record_ticks - nperseg) // step, (record_ticks - nperseg) % step


def window_for(record_ticks: int, nperseg: int) -> str:
    """Hann segments where a record holds several; one rectangular segment for a record as short as
    its segment (a flight's chirp): a Hann window would zero the chirp's ends, its lowest and
    highest frequencies, and the chirp's own taper already ends it smoothly."""
    return "boxcar" if record_ticks < 2 * nperseg else "hann"


def _coherence(pdd: np.ndarray, pdx: np.ndarray, pxx: np.ndarray) -> np.ndarray:
    return np.abs(pdx) ** 2 / np.maximum(pdd * pxx, 1e-300)


def estimate(records: list[dict[str, np.ndarray]], spec: ChirpSpec, nperseg: int | None = None) -> Response:
    """The H1 estimate from one or more records, each with arrays "d" (injected), "u" (plant input,
    N m), "uc" (the law's output, N m) and "pitch" (rad), all of one length a record.

    Welch's averages (scipy.signal welch and csd, half-overlapping segments). Several records
    (short chirps over many flights) stitch into one estimate: their spectra, of one segment
    length (the shortest record's), are averaged weighted by their segment counts, then divided."""
    if not records:
        raise NotMeasured("no record to estimate a frequency response from")
    nper = nperseg or min(segment_length(spec, len(r["d"])) for r in records)
    names = ("u", "uc") if spec.at == "input" else ("pitch", "error")
    sums: dict[str, np.ndarray] = {}
    weight = 0
    for rec in records:
        d = np.asarray(rec["d"], float)
        outs = [np.asarray(rec[n], float) for n in names] if spec.at == "input" else _reference_outputs(rec)
        fs, window = 1.0 / spec.dt, window_for(len(d), nper)
        welch = {"fs": fs, "nperseg": nper, "detrend": False, "window": window}
        count, tail = segments(len(d), nper)
        # A tail no segment covers is where a chirp sweeps its highest frequencies: one more
        # segment, ending with the record, takes it in (the others stay half-overlapping).
        parts = [(d, outs, count)] + ([(d[-nper:], [x[-nper:] for x in outs], 1)] if tail else [])
        for dp, xs, w in parts:
            f, pdd = signal.welch(dp, **welch)
            pa, pb = (signal.csd(dp, x, **welch)[1] for x in xs)
            paa, pbb = (signal.welch(x, **welch)[1] for x in xs)
            for key, value in (("dd", pdd), ("da", pa), ("db", pb), ("aa", paa), ("bb", pbb)):
                sums[key] = sums.get(key, 0.0) + w * value
            weight += w
    s = {k: v / weight for k, v in sums.items()}
    coherence = np.minimum(_coherence(s["dd"], s["da"], s["aa"]), _coherence(s["dd"], s["db"], s["bb"]))
    if spec.at == "input":
        sens, comp = s["da"] / s["dd"], -s["db"] / s["dd"]
        loop = -s["db"] / s["da"]
    else:
        comp, sens = s["da"] / s["dd"], s["db"] / s["dd"]
        loop = None
    response = Response(f, loop, sens, comp, coherence, spec.at, weight).band(spec.f_min, spec.f_max)
    # A bin the chirp barely excites (its ends, a taper) is estimated from what leaks into it; a
    # record's transient can dominate it while the coherence of one segment still reads ~1.
    inside = (f >= spec.f_min) & (f <= spec.f_max)
    pdd = s["dd"][inside] * (f[inside] if spec.kind == "log" else 1.0)  # a log chirp's spectrum falls as 1/f
    excited = pdd >= EXCITED_SHARE * np.median(pdd)
    return dataclasses.replace(
        response,
        f=response.f[excited],
        loop=None if loop is None else response.loop[excited],
        sensitivity=response.sensitivity[excited],
        complementary=response.complementary[excited],
        coherence=response.coherence[excited],
    )


def _reference_outputs(rec: dict[str, np.ndarray]) -> list[np.ndarray]:
    pitch = np.asarray(rec["pitch"], float)
    return [pitch, np.asarray(rec["d"], float) - pitch]


def stepped_estimate(record: dict[str, np.ndarray], spec: ChirpSpec) -> Response:
    """Stepped sines: each step's Fourier coefficient at its frequency over its last STEPPED_CYCLES
    whole cycles (the first ones let the transient settle); the coherence of a step is the share of
    the output's power in the excited line (1: all of it is the linear response)."""
    hold = spec.ticks // spec.steps
    fs = spec.frequencies()
    out = {k: np.empty(len(fs), complex) for k in ("d", "a", "b")}
    coherence = np.empty(len(fs))
    names = ("u", "uc") if spec.at == "input" else None
    for i, f in enumerate(fs):
        cycle = 1.0 / (f * spec.dt)  # ticks a cycle
        n = int(round(STEPPED_CYCLES * cycle))
        stop = (i + 1) * hold
        sl = slice(stop - n, stop)
        k = np.arange(stop - n, stop) - i * hold
        phasor = np.exp(-2j * math.pi * f * k * spec.dt)
        d = np.asarray(record["d"], float)[sl]
        outs = [np.asarray(record[x], float)[sl] for x in names] if names else _reference_outputs(record)
        if not names:
            outs = [o[sl] for o in outs]
        line = []
        for key, x in (("d", d), ("a", outs[0]), ("b", outs[1])):
            c = 2.0 * np.mean(x * phasor)
            out[key][i] = c
            if key != "d":
                power = np.mean((x - x.mean()) ** 2)
                line.append(0.5 * abs(c) ** 2 / power if power > 0.0 else 0.0)
        coherence[i] = min(line)
    if spec.at == "input":
        sens, comp, loop = out["a"] / out["d"], -out["b"] / out["d"], -out["b"] / out["a"]
    else:
        comp, sens, loop = out["a"] / out["d"], out["b"] / out["d"], None
    return Response(fs, loop, sens, comp, np.minimum(coherence, 1.0), spec.at, len(fs))


def measure(records: list[dict[str, np.ndarray]], spec: ChirpSpec) -> Response:
    """The response of `records` to `spec`'s excitation, by its kind's estimator."""
    if spec.kind == "stepped":
        if len(records) != 1:
            raise NotMeasured("stepped sines are measured from one record")
        return stepped_estimate(records[0], spec)
    return estimate(records, spec)


@dataclasses.dataclass(frozen=True)
class Margins:
    """Crossover (Hz), phase margin (deg) and gain margin (dB) of a loop's frequency response.

    A NaN crossover means none was found; `note` says why (and what limits a measured one)."""

    crossover_hz: float
    phase_margin_deg: float
    gain_margin_db: float  # inf: the phase never reaches -180 deg above the crossover in the band
    coherence: float  # at the crossover (1 for a model's curve)
    note: str = ""


def margins(f: np.ndarray, loop: np.ndarray, coherence: np.ndarray | None = None) -> Margins:
    """Margins at the highest frequency where |L| falls through 1 (as hopper.analysis.loop does:
    with an integral the loop is conditionally stable, so the low-frequency crossing is not it)."""
    if coherence is not None:  # bins that are mostly noise (sensor noise through the law) cannot place a crossing
        usable = coherence >= COHERENCE_USABLE
        if usable.sum() < 2:
            return Margins(math.nan, math.nan, math.nan, math.nan, f"coherence under {COHERENCE_USABLE} everywhere")
        f, loop, coherence = f[usable], loop[usable], coherence[usable]
    dropped = "" if coherence is None or usable.all() else f" (coherence under {COHERENCE_USABLE} elsewhere)"
    mag = np.abs(loop)
    phase = np.degrees(np.unwrap(np.angle(loop)))
    coh = np.ones_like(mag) if coherence is None else coherence
    above = mag >= 1.0
    falls = np.flatnonzero(above[:-1] & ~above[1:])
    if not len(falls):
        where = "above" if above.all() else "below" if not above.any() else "not falling through"
        band = f"{f[0]:.3g}-{f[-1]:.3g} Hz{dropped}"
        return Margins(math.nan, math.nan, math.nan, math.nan, f"|L| stays {where} 1 over {band}")
    i = int(falls[-1])
    lf, lm = np.log(f[i : i + 2]), np.log(mag[i : i + 2])
    fc = float(np.exp(np.interp(0.0, -lm, lf)))
    pc = float(np.interp(math.log(fc), lf, phase[i : i + 2]))
    pm = (pc + 360.0) % 360.0 - 180.0
    cc = float(np.interp(math.log(fc), lf, coh[i : i + 2]))
    wrapped = (phase + 180.0) % 360.0
    flips = [j for j in np.flatnonzero(np.abs(np.diff(wrapped)) > 180.0) if j > i]
    gm = -20.0 * math.log10(mag[flips[0] + 1]) if flips else math.inf
    note = ""
    if cc < COHERENCE_TRUSTED:
        note = f"coherence {cc:.2f} at the crossover is below {COHERENCE_TRUSTED}: not to be trusted"
    return Margins(fc, pm, gm, cc, note)


def fitted(f: np.ndarray, values: np.ndarray, coherence: np.ndarray, half_width: float = FIT_DECADES) -> np.ndarray:
    """`values` (complex, on the grid f in Hz) fitted locally: at each bin, a straight line in log f
    through the bins within `half_width` decades, weighted by a tricube of their distance and by
    their information gamma^2 / (1 - gamma^2) (the inverse of an H1 estimate's variance). A bin
    with fewer than 3 neighbours keeps its value."""
    x = np.log10(np.asarray(f, float))  # ascending, as Welch's grid is
    gamma2 = np.minimum(np.asarray(coherence, float), FIT_COHERENCE_CAP)
    info = gamma2 / (1.0 - gamma2)
    values = np.asarray(values, complex)
    out = values.copy()
    # Each bin's neighbours only: memory stays linear in the bins (a 200 s chirp has 16 k of them).
    first, last = np.searchsorted(x, x - half_width, "left"), np.searchsorted(x, x + half_width, "right")
    for j, (a, b) in enumerate(zip(first.tolist(), last.tolist(), strict=True)):
        if b - a < 3:
            continue
        dx = x[a:b] - x[j]
        w = (1.0 - np.minimum(np.abs(dx) / half_width, 1.0) ** 3) ** 3 * info[a:b]
        s0, s1, s2 = w.sum(), (w * dx).sum(), (w * dx * dx).sum()
        det = s0 * s2 - s1 * s1
        if det > 1e-12 * s0 * s2 > 0.0:
            out[j] = (s2 * (w @ values[a:b]) - s1 * ((w * dx) @ values[a:b])) / det  # the line at the bin
    return out


def measured_margins(response: Response) -> Margins:
    """Margins of a measured loop, read from its local fit (fitted); NotMeasured if it was injected
    at the reference (no L) or if the crossover lies where the measurement cannot see it."""
    if response.loop is None:
        raise NotMeasured("a reference injection measures the closed loop, not L: inject at the plant input")
    usable = response.coherence >= COHERENCE_USABLE  # as margins() keeps them: noise bins fit nothing
    loop = response.loop.copy()
    if usable.sum() >= 3:
        loop[usable] = fitted(response.f[usable], response.loop[usable], response.coherence[usable])
    found = margins(response.f, loop, response.coherence)
    if math.isnan(found.crossover_hz):
        raise NotMeasured(f"no gain crossover measured: {found.note}")
    if not response.coherent:  # one segment's coherence is 1 whatever the noise: none is reported
        found = dataclasses.replace(found, coherence=math.nan)
    resolution = float(np.min(np.diff(response.f))) if len(response.f) > 1 else math.inf
    if found.crossover_hz < max(response.f[0], RESOLVED_BINS * resolution):
        raise NotMeasured(
            f"the crossover ({found.crossover_hz:.3g} Hz) lies within {RESOLVED_BINS} bins of {resolution:.3g} Hz"
            f" or below the band ({response.f[0]:.3g} Hz): records this short cannot resolve it; lengthen them"
            " or lower f_min"
        )
    return found
