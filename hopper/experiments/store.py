"""A sweep's output folder: two Parquet datasets written part by part as work completes, and the spec.

    OUT/spec.toml        the resolved spec (hopper.experiments.spec.SweepSpec.to_toml)
    OUT/episodes/*.parquet   one row per episode (EPISODE_COLUMNS, then one column per swept gait field)
    OUT/hops/*.parquet       one row per hop: episode_id, the settings, `hop` and every HopMetrics field

A part is written under a hidden temporary name and renamed into place (readers never see half a
file), hops before episodes: an episode is done when its episodes row exists, and a hops part
whose episodes part never came (the process was killed between the two) is removed at the next start.
"""

from __future__ import annotations

import dataclasses
import os
import secrets
import time
import typing
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.dataset as ds
import pyarrow.parquet as pq

from hopper.errors import HopperError
from hopper.experiments.spec import PARAM_PREFIX, SweepSpec
from hopper.experiments.uncertainty import MODEL_PREFIX
from hopper.experiments.worker import EpisodeResult
from hopper.interrupts import held
from hopper.metrics import HopMetrics

SETTING_COLUMNS: list[tuple[str, pa.DataType]] = [
    ("episode_id", pa.string()),
    ("kp", pa.float64()),  # N m/rad
    ("ki", pa.float64()),  # N m/(rad s)
    ("kd", pa.float64()),  # N m s/rad
    ("gravity", pa.float64()),  # m/s^2
    ("seed", pa.int64()),
    ("hops_target", pa.int64()),
    ("terrain", pa.string()),
    ("wheel", pa.bool_()),
    ("sensing", pa.string()),
    ("disturbance", pa.string()),  # hopper.experiments.spec.describe, "" for none
    ("disturbance_size", pa.float64()),  # in the disturbance's unit: N m s (kicks), N s (pushes), N m (pulses)
]
RESULT_COLUMNS: list[tuple[str, pa.DataType]] = [
    ("hops_completed", pa.int64()),
    ("fell", pa.bool_()),
    ("worst_landing_deg", pa.float64()),  # max over completed hops, 0 without one
    ("peak_pitch_deg", pa.float64()),  # max over hops
    ("rms_pitch_rate_deg_s", pa.float64()),  # max over hops
    ("momentum_used_pct", pa.float64()),  # the most wheel momentum a flight used / capacity, %
    ("saturation_s", pa.float64()),  # total
    ("sim_time_s", pa.float64()),
    ("wall_s", pa.float64()),
    ("controller_fault", pa.string()),  # why the controller was replaced by the PID mid-episode, "" if it was not
    ("energy_j_per_hop", pa.float64()),  # J, mean electrical energy per hop, wheel and legs (worker.energy_per_hop)
    # False where the disturbance never happened (its hop or phase never came); True without one. An
    # older folder has no such column: hopper.experiments.outcome.applied reads it as applied.
    ("disturbance_applied", pa.bool_()),
]
_ARROW_TYPES = {int: pa.int64(), float: pa.float64(), bool: pa.bool_()}
HOP_FIELDS: list[tuple[str, pa.DataType]] = [
    (f.name, _ARROW_TYPES[hint]) for f, hint in zip(
        dataclasses.fields(HopMetrics), typing.get_type_hints(HopMetrics).values(), strict=True
    )
]  # fmt: skip
FLUSH_S = 2.0  # s between parts at most while results stream in (and at the end, and on Ctrl-C)


def worst_landing(episodes: pa.Table) -> pa.ChunkedArray:
    """Each episode's worst landing (deg), null for one without a completed hop (stored as 0 there):
    a robot that fell in its first flight never landed, which is not a perfect landing."""
    return pc.if_else(pc.greater(episodes.column("hops_completed"), 0), episodes.column("worst_landing_deg"), None)


def schemas(spec: SweepSpec) -> tuple[pa.Schema, pa.Schema]:
    """(episodes, hops) schemas for a spec: its swept gait fields and controller params are float64
    setting columns, after the controller's spec."""
    settings = SETTING_COLUMNS + [(name, pa.float64()) for name, _ in spec.gait] + [("controller", pa.string())]
    settings += [(PARAM_PREFIX + name, pa.float64()) for name, _ in spec.params]  # the controller's swept params
    if spec.model is not None:  # which robot, and its sampled values in their units (hopper.experiments.uncertainty)
        settings += [("sample", pa.int64())] + [(MODEL_PREFIX + name, pa.float64()) for name in spec.model.names()]
    return pa.schema(settings + RESULT_COLUMNS), pa.schema(settings + [("hop", pa.int64())] + HOP_FIELDS)


class SpecMismatch(HopperError, ValueError):
    """The output folder holds another sweep."""


class DamagedSweep(HopperError, ValueError):
    """The output folder's datasets hold what is not theirs, or a part that cannot be read."""


# What a sweep's folder holds before its spec.toml is there (SweepStore.create makes them first).
OWN_ENTRIES = frozenset({"episodes", "hops", ".tmp-spec.toml"})


def is_sweep_folder(out: Path) -> bool:
    """`out` (a folder) is a sweep's: it holds a spec.toml, or nothing but what a sweep's holds
    before its spec.toml is written (a start killed there). A sweep's episodes/ folder is not one."""
    return (out / "spec.toml").is_file() or all(p.name in OWN_ENTRIES for p in out.iterdir())


class SweepStore:
    """Appends results to OUT's datasets; knows which episodes are done."""

    def __init__(self, out: Path, spec: SweepSpec) -> None:
        self.out, self.spec = out, spec
        self.episodes_dir, self.hops_dir = out / "episodes", out / "hops"
        self.episode_schema, self.hop_schema = schemas(spec)
        self._pending: list[EpisodeResult] = []
        self._last_flush = time.monotonic()
        # Parts of this run. The second and the pid alone named two stores of one process alike within
        # a second, and the second's part 1 overwrote the first's (a resumed sweep lost its rows).
        self._stamp = f"{time.strftime('%Y%m%dT%H%M%S')}-{os.getpid()}-{secrets.token_hex(4)}"
        self._parts = 0
        self.written = 0  # episodes this store has written (committed parts)

    def check(self) -> set[str]:
        """Refuse another sweep's OUT, clean up a killed run's leftovers, return the done ids. Nothing
        new is written: OUT need not exist yet (run_sweep starts its executor before it creates OUT)."""
        spec_file = self.out / "spec.toml"
        if spec_file.exists() and spec_file.read_text(encoding="utf-8") != self.spec.to_toml():
            raise SpecMismatch(f"{self.out} holds another sweep (its spec.toml differs): use another --out")
        for folder in (self.episodes_dir, self.hops_dir):
            for temporary in folder.glob(".tmp-*"):
                temporary.unlink()
            self._check_dataset(folder)
        committed = {p.name for p in self.episodes_dir.glob("*.parquet")}
        for orphan in self.hops_dir.glob("*.parquet"):
            if orphan.name not in committed:
                orphan.unlink()
        return self.done_ids()

    def _check_dataset(self, folder: Path) -> None:
        """DamagedSweep if `folder` (a dataset) is no folder or holds what Arrow would read that is not
        a Parquet part (a file or a folder; Arrow skips names that start with . or _)."""
        if folder.exists() and not folder.is_dir():
            raise DamagedSweep(f"{self.out} is a damaged sweep: {folder} is not a folder")
        strays = sorted(
            p.name + ("/" if p.is_dir() else "") for p in folder.glob("*")
            if p.name[0] not in "._" and not (p.suffix == ".parquet" and p.is_file())
        )  # fmt: skip
        if strays:
            raise DamagedSweep(
                f"{self.out} is a damaged sweep: {folder} holds {', '.join(strays)}, which are not its Parquet "
                "parts: move them out of it and run again"
            )

    def create(self) -> None:
        """Make OUT and its datasets' folders and write its spec.toml (after check), if not there yet."""
        spec_file = self.out / "spec.toml"
        self.out.mkdir(parents=True, exist_ok=True)
        self.episodes_dir.mkdir(exist_ok=True)
        self.hops_dir.mkdir(exist_ok=True)
        if not spec_file.exists():
            _write_atomically(spec_file, self.spec.to_toml().encode())

    def open(self) -> set[str]:
        """check, then create: OUT ready for results; the done ids."""
        done = self.check()
        self.create()
        return done

    def done_ids(self) -> set[str]:
        table = self.read_episodes(columns=["episode_id"])
        return set(table.column("episode_id").to_pylist())

    def read_episodes(self, columns: list[str] | None = None) -> pa.Table:
        if not any(self.episodes_dir.glob("*.parquet")):
            return self.episode_schema.empty_table().select(columns or self.episode_schema.names)
        try:
            return ds.dataset(self.episodes_dir, format="parquet").to_table(columns=columns)
        except (pa.ArrowException, OSError) as exc:  # a part cut short or not Parquet at all
            raise DamagedSweep(f"{self.out} is a damaged sweep: cannot read {self.episodes_dir} ({exc})") from None

    def spec_episodes(self) -> tuple[pa.Table, int]:
        """The rows of the spec's episodes, each once, and how many other rows OUT holds. A folder
        written before the gain axes became the PID's alone holds, for another controller, a row per
        gain point; resumed, it runs that controller once at the default gains beside them: counted
        too, those rows made its episodes count two or more times."""
        table = self.read_episodes()
        wanted = {e.episode_id for e in self.spec.episodes()}
        seen: set[str] = set()
        keep = []
        for i, episode_id in enumerate(table.column("episode_id").to_pylist()):
            if episode_id in wanted and episode_id not in seen:
                seen.add(episode_id)
                keep.append(i)
        return table.take(keep), table.num_rows - len(keep)

    def add(self, results: list[EpisodeResult]) -> None:
        """Queue results; they are written once FLUSH_S has passed since the last part."""
        self._pending.extend(results)
        if time.monotonic() - self._last_flush >= FLUSH_S:
            self.flush()

    def flush(self) -> int:
        """Write what is queued as one part of each dataset; returns the episodes written. A stop signal
        waits for the part (held): one cut short lost the results it held, already taken off the queue."""
        with held():
            pending, self._pending = self._pending, []
            self._last_flush = time.monotonic()
            if not pending:
                return 0
            self._parts += 1
            name = f"part-{self._stamp}-{self._parts:05d}.parquet"
            hops = pa.Table.from_pylist([row for r in pending for row in r.hop_rows()], schema=self.hop_schema)
            episodes = pa.Table.from_pylist([r.row() for r in pending], schema=self.episode_schema)
            _write_table(self.hops_dir / name, hops)
            _write_table(self.episodes_dir / name, episodes)  # last: this commits the episodes
            self.written += len(pending)
            return len(pending)


def _write_table(path: Path, table: pa.Table) -> None:
    temporary = path.with_name(f".tmp-{path.name}")
    pq.write_table(table, temporary)
    os.replace(temporary, path)


def _write_atomically(path: Path, data: bytes) -> None:
    temporary = path.with_name(f".tmp-{path.name}")
    temporary.write_bytes(data)
    os.replace(temporary, path)
