"""`hopper-sim compare`, `league` and `stress` stopped (SIGINT) at a chosen moment: before their last result
is in they exit 130; once every result is in nothing was cut short, and they end as complete commands,
their table printed and their own status (0, or 1 or 4 on what they found), as `sweep` does."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from in_process import cli
from stops import StopAt, ctrl_c, pool_stopping_after
from sweep_data import FLAKY

from hopper.experiments import executor, league, reduction, stress

pytestmark = pytest.mark.integration  # episodes flown in the test's process, the CLI's signal handlers

# (moment, status): `first` after one of two results, `last` once the last is taken, `close` as the
# executor closes, `table` as the command prints its table (hopper.app.cli_common.finish_complete).
MOMENTS = [("first", 130), ("last", 0), ("close", 0), ("table", 0)]


def check(code: int, printed: str, err: str, status: int, command: str, noun: str) -> None:
    """A real interruption exits 130 with nothing printed; a late stop, the command's own status and table."""
    if status == 130:
        assert code == 130 and err.strip().splitlines()[-1] == "hopper-sim: interrupted", err
        assert not printed, printed
    else:
        assert code == status and "interrupted" not in err, (code, err)
        assert f"hopper-sim: the stop came after every {noun} was done: {command} is complete" in err, err


@pytest.mark.parametrize("moment, status", [*MOMENTS, ("close", 4)], ids=[*(m for m, _ in MOMENTS), "close-fault"])
def test_compare_stopped_after_its_last_run_ends_complete(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, handlers: None,
    moment: str, status: int,
) -> None:  # fmt: skip
    """A Ctrl-C once both runs were in (the executor closing, the table printing) exited 130
    `interrupted`, its JSON unwritten, though every run had flown."""
    (tmp_path / "flaky.py").write_text(FLAKY)
    controller = f"{tmp_path / 'flaky.py'}:Flaky" if status == 4 else "pid"
    monkeypatch.setattr(executor, "choose", lambda *args, **kwargs: StopAt(moment))
    if moment == "table":
        median = reduction.median_reduction
        monkeypatch.setattr(reduction, "median_reduction", lambda pairs: (ctrl_c(), median(pairs))[1])
    out = tmp_path / "compare.json"
    flags = ["--seeds", "1", "--hops", "2", "--terrain", "flat", "--controller", controller, "--json", str(out)]
    code, printed, err = cli(capsys, "compare", *flags)
    check(code, printed, err, status, "compare", "run")
    assert out.exists() == (status != 130)
    if status != 130:
        assert printed.splitlines()[-1].startswith("median reduction of the peak mid-air pitch deviation"), printed
        assert len(json.loads(out.read_text())["runs"]) == 2


def test_a_second_stop_while_a_late_stop_finishes_the_command_ends_it_complete_too(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, handlers: None
) -> None:
    """A Ctrl-C once every run was in, then another while the table printed: the second was held to
    the finish's end and then exited 130 `interrupted`, though the table and the JSON were written."""
    monkeypatch.setattr(executor, "choose", lambda *args, **kwargs: StopAt("close"))
    median = reduction.median_reduction
    monkeypatch.setattr(reduction, "median_reduction", lambda pairs: (ctrl_c(), median(pairs))[1])
    out = tmp_path / "compare.json"
    code, printed, err = cli(capsys, "compare", "--seeds", "1", "--hops", "2", "--terrain", "flat", "--json", str(out))
    check(code, printed, err, 0, "compare", "run")
    assert printed.splitlines()[-1].startswith("median reduction of the peak mid-air pitch deviation"), printed
    assert len(json.loads(out.read_text())["runs"]) == 2


@pytest.mark.parametrize("moment, status", MOMENTS, ids=[m for m, _ in MOMENTS])
def test_league_stopped_after_its_last_episode_ends_complete(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, handlers: None,
    moment: str, status: int,
) -> None:  # fmt: skip
    battery = league.battery
    monkeypatch.setattr(league, "battery", lambda **kwargs: battery(**kwargs)[:2])  # two episodes
    monkeypatch.setattr(executor, "choose", lambda *args, **kwargs: StopAt(moment))
    if moment == "table":
        table = league.table
        monkeypatch.setattr(league, "table", lambda rows: (ctrl_c(), table(rows))[1])
    code, printed, err = cli(capsys, "league", "--controllers", "pid", "--quick", "--json", str(tmp_path / "l.json"))
    check(code, printed, err, status, "league", "episode")
    if status != 130:
        assert printed.startswith("league: 2 episodes per controller") and "\npid " in printed, printed


@pytest.mark.parametrize("moment, status", [m for m in MOMENTS if m[0] != "close"], ids=["first", "last", "table"])
def test_stress_stopped_after_its_last_case_ends_complete(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, handlers: None, moment: str, status: int
) -> None:
    battery = stress.battery
    monkeypatch.setattr(stress, "battery", lambda **kwargs: battery(**kwargs)[4:6])  # two short ground cases
    pool_stopping_after(monkeypatch, {"first": 0, "last": 1}.get(moment))
    if moment == "table":
        table = stress.table
        monkeypatch.setattr(stress, "table", lambda outcomes: (ctrl_c(), table(outcomes))[1])
    code, printed, err = cli(capsys, "stress", "--quick", "--groups", "ground", "--workers", "1")
    check(code, printed, err, status, "stress", "case")
    if status != 130:
        assert printed.splitlines()[1].startswith("ground") and printed.splitlines()[1].split()[1:4] == ["2", "/", "2"]
