"""Rollover: long recordings in numbered parts that each verify and open alone, and join without a gap."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hopper.app.dashboard import cli
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until
from rerun.chunk import RrdReader
from rrd import chunks, signal_times, verify

from hopper.config import SimConfig
from hopper.sim import Simulation
from hopper.telemetry import Telemetry, part_path

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

TICKS = 7000  # 7 s of simulation


def test_parts_stand_alone_and_join_without_a_gap(tmp_path: Path) -> None:
    base, switches = tmp_path / "long.rrd", []
    sim = Simulation(SimConfig(terrain="flat"))
    with Telemetry(
        sim,
        path=base,
        batch_ticks=500,
        flush_s=60,
        max_seconds=2.0,
        on_part=lambda a, b: switches.append((a.name, b.name)),
    ) as telemetry:
        for _ in range(TICKS):
            sim.step()
    parts = [part_path(base, i) for i in (1, 2, 3, 4)]
    assert telemetry.parts == parts and sorted(tmp_path.iterdir()) == parts  # no reserve file left behind
    assert switches == [(a.name, b.name) for a, b in zip(parts, parts[1:], strict=False)]
    verify(*parts)

    times, ids = [], set()
    for index, part in enumerate(parts, start=1):
        reader = RrdReader(part)
        assert len(reader.blueprints()) == 1, f"{part.name} has no blueprint of its own"
        ids |= {r.recording_id for r in reader.recordings()}
        entities = {(c.entity_path, c.is_static) for c in chunks(part)}
        for static in ("/world/robot/torso", "/limits/wheel_torque", "/world"):
            assert (static, True) in entities, f"{part.name} lacks {static}"
        tiles = {e for e, is_static in entities if e.startswith("/world/terrain/") and is_static}
        assert len(tiles) >= 9, f"{part.name} lacks the terrain window's tiles: {tiles}"  # 30 m of 4 m tiles
        props = {c.entity_path for c in chunks(part) if c.entity_path.startswith("/__properties")}
        assert {"/__properties", "/__properties/config", "/__properties/part"} <= props, props
        part_times = signal_times(part)
        assert ("/phase", False) in entities and len(part_times)
        times.append(part_times)
        if index < len(parts):  # a limit of 2 s checked every 0.5 s batch: parts of exactly 2 s
            assert len(part_times) == 2000
    assert len(ids) == 1, "parts of one recording share its id (opened together, they join)"
    joined = np.concatenate(times)
    np.testing.assert_allclose(joined, np.arange(TICKS) * 1e-3 + joined[0], atol=1e-9)  # every tick once


def test_size_limit_cuts_parts_near_it(tmp_path: Path) -> None:
    base, limit = tmp_path / "big.rrd", 2_000_000
    sim = Simulation(SimConfig(terrain="crater"))
    with Telemetry(sim, path=base, batch_ticks=1000, max_bytes=limit) as telemetry:
        while len(telemetry.parts) < 3:
            sim.step()
            if sim.fallen:
                sim.reset()
    sizes = [p.stat().st_size for p in telemetry.parts]
    print(f"\npart sizes at a {limit / 1e6:g} MB limit: {[f'{s / 1e6:.3f}' for s in sizes]} MB")
    print(f"each switch held the stepping thread {[f'{1e3 * s:.0f}' for s in telemetry.switch_s]} ms")
    assert len(telemetry.switch_s) == 2
    # Checked once a batch (1 s of simulation, ~70 kB) against what the writer has stored, which
    # trails what was sent by a batch or two when the simulation runs faster than real time (here,
    # ~50x); plus the footer (~25 kB).
    assert all(limit <= s <= limit + 400_000 for s in sizes[:-1]), sizes
    verify(*telemetry.parts)


def test_dashboard_rolls_over_and_shows_the_current_part(tmp_path: Path) -> None:
    config = DashboardConfig(
        port=free_port(), rrd=tmp_path / "d.rrd", rrd_max_min=0.05, speed=4.0, sessions_dir=tmp_path / "s"
    )
    with Dashboard(config, verbose=False) as dashboard:
        assert wait_until(lambda: dashboard.recorder.progress()[2] >= 3, timeout=60), "no rollover"
        assert wait_until(lambda: "(part" in dashboard.layout.record.info.content)
        text = dashboard.layout.record.info.content
        assert "d-00" in text and " MB" in text, text
        assert wait_until(lambda: "recording saved: " in dashboard.layout.events.content)
        assert "d-001.rrd" in dashboard.layout.events.content
    parts = sorted(tmp_path.glob("d-*.rrd"))
    assert len(parts) >= 3 and not list(tmp_path.glob(".*reserve"))
    verify(*parts)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--rrd-max-mb", "1"], "--rrd-max-mb must be at least 2 MB"),
        (["--rrd-max-min", "nan"], "--rrd-max-min must be at least"),
        (["--rrd-max-min", "5", "--rerun-viewer", "serve"], "cannot be combined with --rerun-viewer"),
        (["--rrd-flush-s", "0"], "--rrd-flush-s must be in"),
    ],
)
def test_bad_rollover_flags_fail_in_one_line(args: list[str], message: str, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exit_:
        cli.parse(args)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and message in err and err.count("\n") == 1, err


def test_hopper_sim_run_rolls_over(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from hopper.app import sim_cli

    base = tmp_path / "run.rrd"
    assert sim_cli.main(["run", "--hops", "3", "--terrain", "flat", "--rrd", str(base), "--rrd-max-min", "0.05"]) == 0
    parts = sorted(tmp_path.glob("run-*.rrd"))
    assert len(parts) >= 2 and f"recording: {parts[0]}, {parts[1]}" in capsys.readouterr().out
    verify(*parts)
    with pytest.raises(SystemExit) as exit_:
        sim_cli.main(["run", "--rrd", str(base), "--rrd-max-mb", "1"])
    assert exit_.value.code == 2 and "must be at least 2 MB" in capsys.readouterr().err
