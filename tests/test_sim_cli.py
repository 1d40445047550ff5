"""`hopper-sim` as a user runs it: real processes, real files, one-line errors."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rrd import verify
from sweep_data import FLAKY

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)

HOP_KEYS = {
    "distance_m",
    "apex_height_m",
    "flight_time_s",
    "peak_pitch_deg",
    "rms_pitch_rate_deg_s",
    "landing_pitch_deg",
    "saturation_time_s",
    "peak_wheel_rpm",
}


def hopper_sim(
    *args: str, cwd: Path | None = None, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        env=env,
    )


def test_run_prints_a_table_and_writes_json(tmp_path) -> None:
    out = tmp_path / "run.json"
    result = hopper_sim("run", "--hops", "2", "--seed", "3", "--json", str(out))
    assert result.returncode == 0, result.stderr
    assert "peak deg" in result.stdout and "seed 3" in result.stdout and "wheel on: 2 hops" in result.stdout
    data = json.loads(out.read_text())
    assert {"seed", "wheel", "fell", "sim_time_s", "wall_time_s", "hops"} <= data.keys()
    assert data["seed"] == 3 and data["wheel"] is True and data["fell"] is False
    assert len(data["hops"]) == 2 and all(hop.keys() >= HOP_KEYS for hop in data["hops"])
    assert 0.6 < data["hops"][1]["distance_m"] < 1.0


def test_the_json_holds_the_settings_that_reproduce_the_run(tmp_path: Path) -> None:
    from hopper.app.sim_cli import sim_config

    from hopper.config import GaitParams
    from hopper.sim import Simulation

    out = tmp_path / "run.json"
    flags = ["--hops", "2", "--seed", "5", "--gravity", "1.7", "--kp", "520", "--ki", "40", "--kd", "25"]
    result = hopper_sim("run", *flags, "--json", str(out))
    assert result.returncode == 0, result.stderr
    summary = result.stdout.splitlines()[-2]
    for named in ("terrain crater", "seed 5", "gravity 1.7 m/s^2", "kp 520", "ki 40", "kd 25", "wheel on"):
        assert named in summary, summary
    data = json.loads(out.read_text())
    settings = data["settings"]
    assert settings["version"] == importlib.metadata.version("hopper-dashboard") and settings["hops"] == 2
    assert settings["seed"] == 5 and settings["terrain"] == "crater" and settings["gravity"] == 1.7
    assert settings["gains"] == {"kp": 520.0, "ki": 40.0, "kd": 25.0} and settings["wheel"] is True
    assert settings["timestep"] == 0.001 and settings["gait"] == dataclasses.asdict(GaitParams())

    sim = Simulation(sim_config(settings))  # the run again, in this process, from the JSON alone
    sim.run(settings["hops"])
    assert json.loads(json.dumps([hop.as_dict() for hop in sim.hops])) == data["hops"]


def test_wheel_off_run_reports_the_fall_and_its_flight(tmp_path) -> None:
    out = tmp_path / "off.json"
    result = hopper_sim("run", "--hops", "3", "--no-wheel", "--terrain", "flat", "--json", str(out))
    assert result.returncode == 1, result.stderr  # a fall is the run's failure
    data = json.loads(out.read_text())
    assert data["fell"] is True and data["wheel"] is False
    assert data["hops"][-1]["completed"] is False and data["hops"][-1]["peak_pitch_deg"] > 30


def test_compare_reports_the_median_reduction(tmp_path) -> None:
    out = tmp_path / "compare.json"
    result = hopper_sim("compare", "--seeds", "2", "--hops", "1", "--json", str(out))
    assert result.returncode == 0, result.stderr
    data = json.loads(out.read_text())
    assert data["median_peak_reduction_pct"] > 65
    assert len(data["runs"]) == 4 and {r["wheel"] for r in data["runs"]} == {True, False}
    assert [(r["settings"]["seed"], r["settings"]["wheel"]) for r in data["runs"]] == [
        (0, True),
        (0, False),
        (1, True),
        (1, False),
    ]
    assert all(r["settings"]["hops"] == 1 and "gait" in r["settings"] for r in data["runs"])
    assert "median reduction" in result.stdout


def test_compare_with_a_faulting_controller_exits_4_saying_why_and_its_report_says_so_too(tmp_path: Path) -> None:
    (tmp_path / "flaky.py").write_text(FLAKY)
    out = tmp_path / "compare.json"
    flags = ("--controller", "flaky.py:Flaky", "--seeds", "1", "--hops", "2", "--workers", "1", "--json", str(out))
    result = hopper_sim("compare", *flags, cwd=tmp_path)
    assert result.returncode == 4, result  # as run's: the PID flew the rest, not the controller asked for
    cause = "Flaky returned nan N m"
    error = result.stderr.strip().splitlines()[-1]
    assert error.startswith("hopper-sim: error: controller ") and cause in error and "seed 0 wheel on" in error
    assert " 2 fault " in result.stdout, result.stdout  # the wheel-on run's hops, marked
    data = json.loads(out.read_text())
    on = next(r for r in data["runs"] if r["wheel"])
    assert cause in on["fault"] and data["controller_faults"] == 1
    report = hopper_sim("report", str(out), "--out", str(tmp_path / "fig"), cwd=tmp_path)
    assert report.returncode == 0, report.stderr
    page = (tmp_path / "fig" / "report.html").read_text()
    assert "Controller faults" in page and "the controller failed in 1 of them" in page and cause in page
    assert "2 fault" in page  # the per-seed table's hops


# A controller file (write it as picky.py): a PD that, in its second flight in the runs of seeds `bad` and up,
# tips the robot to 5 deg and then returns NaN, so that the PID flies on from a peak that is this law's doing.
PICKY = """
from hopper.controllers import Param


class Picky:
    params = (Param("bad", 1.0, (0.0, 100.0), "seed"),)

    def configure(self, context):
        self.seed = context.config.seed

    def reset(self, obs):
        self.flights = getattr(self, "flights", 0) + 1

    def __call__(self, obs):
        if getattr(self, "flights", 0) >= 2 and self.seed >= self.bad:
            return 10.0 if abs(obs.pitch) < 0.09 else float("nan")
        return 450.0 * obs.pitch + 30.0 * obs.rate
"""


@pytest.mark.parametrize("bad, seeds", [(1, 3), (0, 2)], ids=["some-seeds-fault", "every-seed-faults"])
def test_compares_median_leaves_out_the_seeds_whose_controller_faulted(tmp_path: Path, bad: int, seeds: int) -> None:
    """The median reduction took in the runs where the PID flew on from a fault: their figures are
    the PID's (and here the faulting law's 5 deg), not the controller's."""
    (tmp_path / "picky.py").write_text(PICKY)
    out = tmp_path / "compare.json"
    flags = ("--controller", "picky.py:Picky", "--controller-param", f"bad={bad}", "--seeds", str(seeds), "--hops",
             "2", "--workers", "1", "--json", str(out))  # fmt: skip
    result = hopper_sim("compare", *flags, cwd=tmp_path)
    assert result.returncode == 4, result  # a fault is still the run's failure
    data = json.loads(out.read_text())
    rows = data["seeds"]
    median = result.stdout.strip().splitlines()[-1]
    if bad:
        kept = rows[0]["reduction_pct"]
        assert max(r["reduction_pct"] for r in rows[1:]) < kept - 1, rows  # the faulted seeds' would move it
        assert data["median_peak_reduction_pct"] == kept, data["median_peak_reduction_pct"]
        assert f": {kept:.1f}% (over 1 seed of 3; 2 faulted runs left out (seeds 1, 2); wheel off" in median, median
    else:
        assert data["median_peak_reduction_pct"] is None
        assert median.endswith(": none, every seed has a faulted run (2 faulted runs of 4): the PID flew on from "
                               "the fault, so no figure is the controller's"), median  # fmt: skip
    assert [r["left_out"] for r in rows] == [r["seed"] >= bad for r in rows]  # the JSON's per-seed rows say which


@pytest.mark.parametrize(
    "args, message",
    [
        (["run", "--kp", "-5"], "kp must be a finite number"),
        (["run", "--kd", "nan"], "not a finite number"),
        (["run", "--terrain", "moon"], "invalid choice"),
        (["run", "--json", "/nonexistent/dir/out.json"], "does not exist"),
        (["run", "--json", "/proc/x.json"], "cannot write /proc/x.json"),
        (["run", "--gravity", "pluto"], "neither m/s^2 nor one of moon, mars, ceres, earth"),
        (["run", "--gravity", "0.01"], "gravity must be a finite number in [0.05, 30]"),
        (["run", "--hops", "0"], "--hops must be at least 1"),
        (["run", "--seed", "-1"], "seed must be a non-negative integer"),
        (["run", "--bogus"], "unrecognized arguments: --bogus"),
        (["compare", "--seeds", "0"], "--seeds must be at least 1"),
        (["compare", "--hops", "0"], "--hops must be at least 1"),
        (["compare", "--workers", "0"], "--workers must be at least 1"),
        (["compare", "--workers", "-3"], "--workers must be at least 1"),
        (["compare", "--json", "/proc/x.json"], "cannot write /proc/x.json"),
        (["terrain", "--png", "/proc/x.png"], "cannot write /proc/x.png"),
        (["terrain", "--seed", "-4", "--png", "y.png"], "seed must be a non-negative integer"),
        (["terrain"], "the following arguments are required: --png"),
        (["terrain", "--png", "t.jpg"], "t.jpg: the file must end in .png"),  # PIL: cannot write mode I;16 as JPEG
        (["terrain", "--png", "t"], "t: the file must end in .png"),  # PIL: unknown file extension
        (["terrain", "--png", "t.png", "--x0", "1e300"], "--x0: must lie within +-1e+09 m, got 1e300"),
        ([], "the following arguments are required: command"),
        # Flags the command would have ignored, or one silently overriding the other:
        (["run", "--controller", "lqr", "--kp", "300"], "--kp is the PID's gain, which --controller lqr does not fly"),
        (["run", "--kp", "300", "--controller-param", "kp=600"], "--kp and --controller-param kp=... both set kp"),
        (["run", "--controller-param", "kd=20", "--controller-param", "kd=40"], "--controller-param kd given more"),
        (["stress", "--quick", "--seeds", "5"], "--quick flies its own few seeds, so it ignores --seeds"),
        (["compare", "--executor", "local", "--address", "1.2.3.4:1"], "--address names a Ray cluster, which"),
        (["sweep", "--out", "o", "--executor", "local", "--address", "1.2.3.4:1"], "--executor local does not use"),
        # No abbreviations: each of these was taken for a longer flag (--seeds, --gravity-seeds).
        (["compare", "--seed", "1"], "unrecognized arguments: --seed 1"),
        (["stress", "--gravity", "3"], "unrecognized arguments: --gravity 3"),
        (["sweep", "--out", "o", "--seed", "1"], "unrecognized arguments: --seed"),
        (["run", "--sched", "pitch_kick:0.3"], "unrecognized arguments: --sched pitch_kick:0.3"),
    ],
)
def test_bad_arguments_fail_in_one_line_before_any_work(tmp_path: Path, args: list[str], message: str) -> None:
    result = hopper_sim(*args, cwd=tmp_path)
    assert result.returncode == 2, result
    assert result.stderr.count("\n") == 1 and message in result.stderr, result.stderr
    assert result.stderr.startswith("hopper-sim: error: "), result.stderr  # one prefix, subcommands included
    assert "Traceback" not in result.stderr
    assert result.stdout == "" and not any(tmp_path.iterdir()), "work started before the arguments were checked"


@pytest.mark.parametrize(
    "argv",
    [
        ["sweep", "--out", "MISSING/x", "--seeds", "1", "--hops", "1", "--workers", "1"],
        ["report", "IN.json", "--out", "MISSING/x"],
        ["envelope", "--sizes", "0.5", "--moments", "0.5", "--workers", "1", "--out", "MISSING/x"],
        ["run", "--hops", "1", "--json", "MISSING/x.json"],
        ["run", "--hops", "1", "--rrd", "MISSING/x.rrd"],
        ["compare", "--seeds", "1", "--hops", "1", "--json", "MISSING/x.json"],
        ["size", "--gravity", "earth", "--out", "MISSING/x.xml"],
    ],
)
def test_every_output_path_in_a_missing_folder_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    """sweep, report and envelope made a whole --out path (/nonexistent/dir/x: both folders) where --json
    refused 'folder /nonexistent does not exist': one rule now, the last folder alone may be made."""
    from in_process import cli

    (tmp_path / "IN.json").write_text("{}")
    missing = tmp_path / "missing"
    argv = [a.replace("MISSING", str(missing)).replace("IN.json", str(tmp_path / "IN.json")) for a in argv]
    code, printed, err = cli(capsys, *argv)
    assert code == 2 and printed == "" and err.count("\n") == 1, err
    said = f"{missing}' does not exist" if "--rrd" in argv else f"folder {missing} does not exist"  # --rrd: telemetry's
    assert err.startswith("hopper-sim: error: ") and err.endswith(f"{said}\n"), err
    assert [p.name for p in tmp_path.iterdir()] == ["IN.json"], "an output folder was made"


def test_every_flag_with_a_default_says_it_and_every_command_its_exit_statuses() -> None:
    """`run --terrain` showed no default (crater); capture, replay and identify had no exit statuses."""
    import argparse

    from hopper.app.sim_cli import parser

    def walk(p: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]  # noqa: SLF001
        return [p] + [q for a in subs for child in a.choices.values() for q in walk(child)]

    silent = [
        f"{p.prog} {a.option_strings[0]}"
        for p in walk(parser())
        for a in p._actions  # noqa: SLF001
        if a.option_strings and a.default not in (None, False, [], argparse.SUPPRESS) and "default" not in a.help
    ]
    assert silent == []
    commands = [p for p in walk(parser()) if not any(isinstance(a, argparse._SubParsersAction) for a in p._actions)]  # noqa: SLF001
    assert [p.prog for p in commands if not (p.epilog or "").startswith("exit status: ")] == []


def test_tune_promises_no_resume_it_never_does() -> None:
    """tune keeps no folder (sweep's exit-status text, copied, said the same command skips the finished)."""
    tune, sweep = (" ".join(hopper_sim(c, "--help").stdout.split()) for c in ("tune", "sweep"))
    assert "skips the finished episodes" not in tune and "skips the finished episodes" in sweep
    promise = "130 interrupted (Ctrl-C or SIGTERM): nothing is kept and no --json written, the same command starts"
    assert f"{promise} the search over" in tune, tune


def test_no_parser_of_any_command_takes_an_abbreviated_flag() -> None:
    """allow_abbrev=False on hopper-sim's top parser and every subcommand's (add_parser does not inherit
    it), hopper-dashboard's and the policy training's: each is cli_common.Parser."""
    import argparse

    from hopper.app import sim_cli, train_policy
    from hopper.app.cli_common import Parser
    from hopper.app.dashboard import cli as dashboard_cli

    def walk(p: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]  # noqa: SLF001
        return [p] + [q for a in subs for child in a.choices.values() for q in walk(child)]

    parsers = [q for module in (sim_cli, dashboard_cli, train_policy) for q in walk(module.parser())]
    assert len(parsers) > 17 and {p.prog for p in parsers} >= {
        "hopper-sim compare", "hopper-sim log check", "hopper-dashboard", "python -m hopper.app.train_policy"
    }  # fmt: skip
    assert [p.prog for p in parsers if p.allow_abbrev or not isinstance(p, Parser)] == []


@pytest.mark.parametrize("command", [["sweep", "--out", "out", "--seeds", "1", "--hops", "1"], ["compare"]])
def test_a_ray_address_that_accepts_tcp_but_is_no_ray_head_fails_in_one_line_in_bounded_time(
    tmp_path: Path, command: list[str]
) -> None:
    """A listening socket that never answers (127.0.0.1, this test's own): ray.init would retry it for
    minutes; the probe's 5 s budget refuses it, before the sweep's folder is made."""
    import socket

    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen(4)  # the kernel completes the connections; nothing reads or answers them
        address = f"127.0.0.1:{listening.getsockname()[1]}"
        started = time.monotonic()
        result = hopper_sim(*command, "--executor", "ray", "--address", address, cwd=tmp_path)
        took = time.monotonic() - started
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert result.stderr == (
        f"hopper-sim: error: cannot reach the Ray cluster at {address}: it accepts TCP but gave no gRPC handshake "
        "within 5 s: not a Ray head\n"
    )
    assert took < 60.0 and result.stdout == "" and not any(tmp_path.iterdir())


def test_a_small_job_says_why_it_runs_in_process_instead_of_on_the_workers_asked(tmp_path: Path) -> None:
    """5 one-hop episodes are ~0.2 s of work: choose keeps them in this process (a pool starts in ~1 s)
    and says so, and that --workers 2 is not used, in one line."""
    why = "s of work, too little for a pool of processes to repay its start-up (~1 s); --workers 2 not used\n"
    sweep = hopper_sim("sweep", "--out", str(tmp_path / "s"), "--seeds", "5", "--hops", "1", "--workers", "2")
    assert sweep.returncode == 0, sweep.stderr
    line = next(x for x in sweep.stderr.splitlines(keepends=True) if x.startswith("running 5 episodes"))
    assert line.startswith("running 5 episodes on in-process (1 worker): about 0.") and line.endswith(why), line
    compare = hopper_sim("compare", "--seeds", "1", "--hops", "1", "--workers", "2")
    assert compare.returncode in (0, 1), compare.stderr
    assert compare.stderr.startswith("running 2 runs in this process: about 0.") and why in compare.stderr
    assert "(over 1 seed; " in compare.stdout  # not "1 seeds"
    one = hopper_sim("sweep", "--out", str(tmp_path / "one"), "--seeds", "1", "--hops", "1")
    assert one.returncode == 0 and "running 1 episode on in-process (1 worker)" in one.stderr, one.stderr


def test_help_documents_the_exit_statuses() -> None:
    for command in ([], ["run"], ["compare"], ["stress"], ["envelope"]):
        result = hopper_sim(*command, "--help")
        assert result.returncode == 0, result.stderr
        text = " ".join(result.stdout.split())
        expected = (
            "exit status: 0 success, 1 the robot fell (run), a case failed (stress) or a kick under the physical "
            "limit fell (envelope), 2 bad arguments (a controller that cannot fly included), 3 the run stopped "
            "short of the hops asked without a fall (run; it says why), 4 the controller failed mid-run and the "
            "PID flew on (run, and compare, league or sweep once finished; it says why), 130"
        )
        assert expected in text, text
        assert "141 the reader of its output went away (e.g. | head): it stops quietly" in text, text


def small_pipe() -> tuple[int, int]:
    """A pipe (read, write) that holds 4 KB (Linux's F_SETPIPE_SZ; skip elsewhere): a command's output
    of more than that is still being written when the reader closes after its first line."""
    fcntl = pytest.importorskip("fcntl")
    if not hasattr(fcntl, "F_SETPIPE_SZ"):
        pytest.skip("no F_SETPIPE_SZ: the pipe would hold the whole output")
    read, write = os.pipe()
    fcntl.fcntl(write, fcntl.F_SETPIPE_SZ, 4096)
    return read, write


@pytest.mark.parametrize("unbuffered", ["", "1"], ids=["buffered", "PYTHONUNBUFFERED"])
def test_a_reader_that_closes_early_ends_the_command_quietly_with_141(unbuffered: str) -> None:
    """`hopper-sim run --hops 40 | head -1`: no BrokenPipeError traceback, nor 1 ("the robot fell"),
    but 141 (128 + SIGPIPE) and nothing on stderr, as a Unix tool a closed pipe ends. Its output
    (~9 KB) outgrows the pipe, so the run is writing when the reader goes: in the interpreter's last
    flush when stdout is buffered, in a print when it is not."""
    read, write = small_pipe()
    env = {**os.environ, "PYTHONUNBUFFERED": unbuffered}
    process = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.sim_cli", "run", "--hops", "40", "--terrain", "flat"],
        stdout=write,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    os.close(write)
    try:
        with open(read, "rb", buffering=0) as out:  # unbuffered: readline takes exactly the first line
            first = out.readline()
        _, err = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
    assert first.startswith(b"hop    dist m"), first
    assert process.returncode == 141, (process.returncode, err)
    assert err == "", err


def test_terrain_export_writes_the_png_the_paper_loads(tmp_path) -> None:
    import numpy as np
    from hopper.terrain import CraterField, CraterParams, read_png

    params = CraterParams()
    for x0, first in (("-2", -40), ("1000.02", 20000)):  # the start window, and one 1 km along
        out = tmp_path / "craters.png"
        result = hopper_sim("terrain", "--seed", "4", "--png", str(out), "--x0", x0)
        assert result.returncode == 0, result.stderr
        expected = CraterField(params, 4).columns(first, params.shape[1])
        assert np.abs(read_png(out) - expected).max() < 1e-5


def size(path: Path) -> int:
    """Bytes in `path`, 0 while it is missing (the argument check creates and removes it)."""
    try:
        return path.stat().st_size
    except FileNotFoundError:
        return 0


def test_a_stop_signal_whose_exception_was_swallowed_is_raised_again() -> None:
    script = (
        "import signal\n"
        "from hopper.interrupts import raise_if_stop_requested, stop_like_ctrl_c\n"
        "stop_like_ctrl_c()\n"
        "raise_if_stop_requested()  # nothing asked yet: returns\n"
        "try:\n"
        "    signal.raise_signal(signal.SIGTERM)\n"
        "except KeyboardInterrupt:\n"
        "    pass  # as C code that clears the errors of a lazy import does\n"
        "try:\n"
        "    raise_if_stop_requested()\n"
        "except KeyboardInterrupt:\n"
        "    print('raised again')\n"
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and result.stdout == "raised again\n", result


@pytest.mark.parametrize(
    ("signum", "after"),
    [(signal.SIGTERM, 0.0), (signal.SIGTERM, 0.3), (signal.SIGTERM, 1.5), (signal.SIGINT, 0.0), (signal.SIGINT, 0.8)],
    ids=["SIGTERM-first-byte", "SIGTERM-0.3s", "SIGTERM-1.5s", "SIGINT-first-byte", "SIGINT-0.8s"],
)
def test_a_signal_mid_run_exits_130_with_a_finalized_recording(tmp_path: Path, signum: int, after: float) -> None:
    """Whatever the moment (here: `after` s past the file's first byte), the file verifies."""
    pytest.importorskip("hopper.telemetry")
    rrd = tmp_path / "run.rrd"
    process = subprocess.Popen(
        # Flat ground and more hops than any machine flies in a test: the run is still going at the
        # moment of the signal, however fast the machine (30 crater hops took under 1.5 s on one).
        [sys.executable, "-m", "hopper.app.sim_cli", "run", "--terrain", "flat", "--hops", "100000", "--rrd", str(rrd)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while size(rrd) == 0 and time.monotonic() < deadline:  # the recording has begun
            time.sleep(0.01)
        assert size(rrd) > 0, "the recording never began"
        time.sleep(after)  # the moment of the signal: any moment must leave a valid file
        process.send_signal(signum)
        out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, (process.returncode, out, err)
    assert err.strip().splitlines()[-1] == "hopper-sim: interrupted" and "Traceback" not in err
    verify(rrd)


def test_a_run_that_stops_short_says_why_and_exits_3(monkeypatch, capsys, tmp_path: Path) -> None:
    from hopper.app import sim_cli

    from hopper.sim import Simulation

    monkeypatch.setattr(Simulation, "time_limit", lambda self, hops: 1.0)  # 1 s simulated: not one hop
    out = tmp_path / "run.json"
    status = sim_cli.main(["run", "--hops", "3", "--terrain", "flat", "--json", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 3, err
    assert err[-1].startswith("hopper-sim: error: 0 of 3 hops done when the run's limit of 1 s simulated ran out"), err
    assert json.loads(out.read_text())["short"].startswith("0 of 3 hops"), "the JSON says it too"


def test_ctrl_c_during_compare_exits_130_without_worker_tracebacks() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "hopper.app.sim_cli", "compare", "--seeds", "30", "--hops", "7", "--workers", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's Ctrl-C reaches every process of it
    )
    try:
        progress = ""
        while "/60 [" not in progress and process.poll() is None:  # the workers are running their first runs
            progress += process.stderr.read(1)
        time.sleep(2.0)  # not a wait: the moment of the Ctrl-C, inside the workers' runs (any moment must do)
        os.killpg(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "Traceback" not in err and "SpawnPoolWorker" not in err, err
    assert err.strip().splitlines()[-1] == "hopper-sim: interrupted"


def test_realistic_sensing_from_the_command_line(tmp_path) -> None:
    out = tmp_path / "run.json"
    result = hopper_sim("run", "--hops", "2", "--terrain", "flat", "--sensing", "realistic", "--json", str(out))
    assert result.returncode == 0, result.stderr
    report = json.loads(out.read_text())
    assert report["settings"]["sensing"] == "realistic" and len(report["hops"]) == 2
    assert max(h["landing_pitch_deg"] for h in report["hops"]) < 3.5


def test_run_says_when_its_robot_was_trapped() -> None:
    """Mars seed 0 hopped 1000 times, 800 of them back and forth in one crater, and the run said
    only "mean distance 0.143 m/hop". A gait that hops in place is not trapped."""
    from hopper.app.sim_cli import trapped

    def result(distances: list[float], forward: float = 0.4) -> dict:
        hops = [{"completed": True, "distance_m": d} for d in distances]
        return {"hops": hops, "settings": {"gait": {"forward_speed": forward}}}

    note = trapped(result([0.8] * 200 + [0.3, -0.25] * 400))
    assert note is not None and note.startswith("note: trapped from hop 201: 50 hops")
    assert trapped(result([0.8] * 1000)) is None
    assert trapped(result([0.01] * 100, forward=0.0)) is None
