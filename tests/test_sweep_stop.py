"""`hopper-sim sweep` stopped (SIGINT) at a chosen moment: mid-sweep it exits 130 and keeps what it
wrote; once every episode is written the sweep is complete and ends as one (0, or 4 on a fault)."""

from __future__ import annotations

from pathlib import Path

import pyarrow.dataset as ds
import pytest
from in_process import cli
from stops import StopAt, ctrl_c
from sweep_data import FLAKY

from hopper.experiments import executor, store, summary

pytestmark = pytest.mark.integration  # episodes flown in the test's process, the CLI's signal handlers


@pytest.mark.parametrize(
    "moment, controller, status",
    [
        ("first", "pid", 130),
        ("last", "pid", 0),
        ("close", "pid", 0),
        ("write", "pid", 0),
        ("summary", "pid", 0),
        ("close", "flaky", 4),  # a controller fault: the verdict of a sweep that finished
    ],
)
def test_a_stop_after_the_last_episode_is_written_ends_the_sweep_as_complete(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    handlers: None,
    moment: str,
    controller: str,
    status: int,
) -> None:
    """A Ctrl-C as the executor closed, after the last part was written, exited 130 `interrupted`
    although nothing was lost (the same command then said all were done); one as the last part was
    written cut it short and lost its episodes."""
    (tmp_path / "flaky.py").write_text(FLAKY)
    spec = "pid" if controller == "pid" else f"{tmp_path / 'flaky.py'}:Flaky"
    out = tmp_path / "out"
    monkeypatch.setattr(executor, "choose", lambda *args, **kwargs: StopAt(moment))
    if moment == "write":  # as the last part starts: it waits for the part, which holds every episode
        monkeypatch.setattr(store, "FLUSH_S", 1e9)  # one part, at the end
        write = store._write_table  # noqa: SLF001
        monkeypatch.setattr(store, "_write_table", lambda path, table: (ctrl_c(), write(path, table)))
        monkeypatch.setattr(executor, "choose", lambda *args, **kwargs: executor.InProcess())
    if moment == "summary":  # once run_sweep has returned, as the summary is read
        overall = summary.overall_line
        monkeypatch.setattr(summary, "overall_line", lambda episodes: (ctrl_c(), overall(episodes))[1])
    flags = ["--out", str(out), "--seeds", "2", "--hops", "2", "--terrain", "flat", "--controller", spec]
    code, printed, err = cli(capsys, "sweep", *flags)
    written = ds.dataset(out / "episodes", format="parquet").to_table().column("episode_id").to_pylist()
    if status == 130:  # a real interruption: the episode done is kept, the rest left to the next run
        assert code == 130 and err.strip().splitlines()[-1] == "hopper-sim: interrupted", err
        assert len(written) == 1 and not printed, printed
    else:
        assert code == status, err
        assert len(written) == 2 and "interrupted" not in err, err
        assert f"{out}: the stop came after every episode was written: the sweep is complete" in err, err
        assert printed.startswith(f"{out}: 2 episodes, ") and "this run: 2 episodes on in-process" in printed, printed
    monkeypatch.undo()  # the next run: the plain executors and summary
    again = cli(capsys, "sweep", *flags)
    assert f"{len(written)} of 2 episodes already done, {2 - len(written)} to run" in again[2], again
    assert again[0] == (4 if controller == "flaky" else 0), again
