"""hopper-sim capture, replay and identify, in process: outputs, figures, the MJCF, and refusals (exit 2)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest
from hopper.app.sim_cli import main

from hopper.logs.io import read_log


@pytest.fixture(scope="module")
def logged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("logs") / "robot.csv"
    assert main(["capture", str(out), "--hops", "2", "--mismatch", "motor_torque=0.9", "--gyro-bias", "0.5"]) == 0
    return out


def test_capture_writes_a_log_that_reads_back(logged: Path, capsys: pytest.CaptureFixture) -> None:
    log = read_log(logged)
    assert log.has_state() and log.time[-1] > 4.0


def test_replay_prints_each_hop_and_writes_its_figure(logged: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    assert main(["replay", str(logged), "--hops", "1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "hop 1 from" in out and "pitch RMS" in out and "all (1 replay(s)" in out
    assert (tmp_path / "replay.png").stat().st_size > 10_000 and (tmp_path / "replay.pdf").exists()
    assert main(["replay", str(logged), "--from", "2.0", "--to", "2.5"]) == 0
    assert "from 2.000 s" in capsys.readouterr().out
    assert main(["replay", str(logged), "--every", "0.3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].startswith("hop 1 from") and lines[1].split(":")[0].endswith("re-anchored every 0.3 s"), lines
    assert main(["replay", str(logged), "--hops", "1", "--legs", "servo"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split(":")[0].endswith("legs held to the log's angles"), lines


def test_identify_prints_the_table_and_writes_the_mjcf(logged: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    out = tmp_path / "identified.xml"
    argv = ["identify", str(logged), "--out", str(out), "--hops", "1", "--params", "motor_torque,gyro_bias"]
    argv += ["--windows", "0.1", "--truth", "motor_torque=0.9", "--truth", "gyro_bias=0.5", "--max-evaluations", "15"]
    assert main(argv) == 0
    text, err = capsys.readouterr()
    assert err.startswith("identify: stage 1 of 1: ") and " windows of 0.1 s (" in err, err  # a fit takes minutes
    row = next(line for line in text.splitlines() if line.startswith("motor_torque"))
    estimate = float(row.split()[4])
    assert estimate == pytest.approx(0.9, rel=0.01)
    assert "windows of 0.1 s at the last stage" in text
    assert "residual RMS on those windows, the starting model -> the identified: pitch " in text
    held = "whole, each from its liftoff, legs held to the log's angles"
    for measure in ("re-anchored every 0.3 s", held, "whole, each from its liftoff"):
        assert f"replay of hops 1..1 ({measure}) before" in text and f"({measure}) after" in text
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.actuator_gainprm[model.actuator("wheel").id, 0] == pytest.approx(0.9833 * estimate, rel=1e-5)
    # usable with --model: the identified robot replays the first flight's half second far closer
    flight = ["replay", str(logged), "--from", "1.6", "--to", "2.1"]
    rms = []
    for extra in ([], ["--model", str(out)]):
        assert main(flight + extra) == 0
        rms.append(float(capsys.readouterr().out.split("pitch RMS ")[1].split()[0]))
    assert rms[1] < 0.05 * rms[0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["replay", "missing.csv"], "missing.csv: no such file"),
        (["replay", "LOG", "--from", "999"], "--from 999 s is outside the log"),
        (["replay", "LOG", "--hops", "9"], "--hops 9: the log has 2 hop"),
        (["replay", "LOG", "--every", "0"], "--every must be a positive number of seconds, got 0"),
        (["identify", "LOG", "--out", "OUT", "--params", "leg_length"], "unknown parameter(s) leg_length"),
        (
            ["identify", "LOG", "--out", "OUT", "--params", "torso_mass,torso_mass,gyro_bias"],
            "--params: torso_mass given more than once",
        ),
        (["identify", "LOG", "--out", "OUT", "--hops", "5"], "has 2 hop(s), the fit asks for hops 1..5"),
        (["identify", "LOG", "--out", "OUT", "--windows", "0.1,-1"], "window lengths must be positive"),
        (["identify", "LOG", "--out", "OUT", "--max-evaluations", "0"], "--max-evaluations must be at least 1, got 0"),
        (
            ["identify", "LOG", "--out", "OUT", "--max-evaluations", "-1"],
            "--max-evaluations must be at least 1, got -1",
        ),
        (["capture", "OUT", "--mismatch", "torso_mass=9"], "outside [0.2, 5]"),
        (["capture", "OUT", "--mismatch", "wheel_size=2"], "unknown mismatch 'wheel_size'"),
        (["replay", "EMPTY"], "empty.npz: empty file (not a .npz log)"),
        (["identify", "EMPTY", "--out", "OUT"], "empty.npz: empty file (not a .npz log)"),
    ],
)
def test_bad_input_is_refused_in_one_line(argv, message, logged: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    (tmp_path / "empty.npz").write_bytes(b"")
    names = {"LOG": str(logged), "OUT": str(tmp_path / "out.xml"), "EMPTY": str(tmp_path / "empty.npz")}
    argv = [names.get(a, a) for a in argv]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(
    ("out", "extra", "message"),
    [
        ("victim.csv", [], "--out: victim.csv: an MJCF file is read back (--model) only if its name ends in .xml"),
        ("./victim.csv", [], "--out: ./victim.csv: an MJCF file is read back"),  # the same file by another spelling
        ("link.xml", [], "--out link.xml: is the log; write the identified MJCF to another file"),  # a symlink to it
        ("hard.xml", [], "--out hard.xml: is the log"),  # a hard link to it
        ("m.xml", ["--model", "m.xml"], "--out m.xml: is the model the fit starts from"),
        ("x.XML", [], "--out: x.XML: an MJCF file is read back (--model) only if its name ends in .xml"),
    ],
)
def test_identify_refuses_an_out_that_would_overwrite_its_inputs_before_any_work(
    out: str,
    extra: list[str],
    message: str,
    logged: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """identify --out victim.csv on victim.csv wrote an MJCF over the log (exit 0), and over --model's."""
    import shutil

    from hopper.model import MODEL_XML

    monkeypatch.chdir(tmp_path)
    shutil.copy(logged, "victim.csv")
    shutil.copy(MODEL_XML, "m.xml")
    Path("link.xml").symlink_to("victim.csv")
    Path("hard.xml").hardlink_to("victim.csv")
    before = {p: p.read_bytes() for p in (Path("victim.csv"), Path("m.xml"))}
    with pytest.raises(SystemExit) as stop:
        main(["identify", "victim.csv", "--out", out, "--hops", "1", "--max-evaluations", "1", *extra])
    got, err = capsys.readouterr()
    assert stop.value.code == 2 and got == "", got  # before the log is read: no world line
    assert err.startswith("hopper-sim: error: ") and len(err.splitlines()) == 1 and message in err, err
    assert all(p.read_bytes() == data for p, data in before.items())
    assert not Path("x.csv").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--out", "FILE"], "--out: FILE is not a folder"),
        (["--out", "FILE/sub"], "--out: FILE is not a folder"),  # the nearest folder that exists
        # a folder is made for the figure, not a path to it (as identify's and export's files: folder must exist)
        (["--out", "TMP/none/deeper/out"], "--out: folder TMP/none/deeper does not exist"),
        (["--out", "/proc/replay"], "--out: cannot write to /proc/replay"),
        (["--to", "3"], "--to 3 needs --from"),
        (["--from", "1", "--hops", "1"], "--hops replays hops from their liftoffs; --from 1 replays one span"),
        (["--from", "1", "--every", "0.3"], "--every replays hops from their liftoffs; --from 1 replays one span"),
        (["--hops", "0"], "--hops must be at least 1, got 0"),
        (["--every", "-1"], "--every must be a positive number of seconds, got -1"),
    ],
)
def test_replay_refuses_an_out_it_cannot_write_or_flags_it_would_ignore_before_any_work(
    argv: list[str], message: str, logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    file = tmp_path / "file"
    file.write_text("")
    with pytest.raises(SystemExit) as stop:
        main(["replay", str(logged), *(a.replace("FILE", str(file)).replace("TMP", str(tmp_path)) for a in argv)])
    out, err = capsys.readouterr()
    assert stop.value.code == 2 and out == ""  # refused before the log is read ("world: ..." not printed)
    assert err.startswith("hopper-sim: error: ") and len(err.splitlines()) == 1, err
    assert message.replace("FILE", str(file)).replace("TMP", str(tmp_path)) in err
    assert not (tmp_path / "none").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["MISSING"], "missing.csv: no such file"),
        (["LOG", "--from", "999"], "--from 999 s is outside the log"),
        (["LOG", "--hops", "9"], "--hops 9: the log has 2 hop"),
    ],
)
def test_replay_refused_after_reading_the_log_leaves_no_folder_it_made(
    argv: list[str], message: str, logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """--out is made before the log is read; a check on the log that refuses removes what it made
    (and only that: a folder that was there, empty or not, stays)."""
    names = {"LOG": str(logged), "MISSING": str(tmp_path / "missing.csv")}
    kept = tmp_path / "kept"
    kept.mkdir()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    for out in (tmp_path / "new", kept, tmp_path / "full"):
        with pytest.raises(SystemExit) as stop:
            main(["replay", *(names.get(a, a) for a in argv), "--out", str(out)])
        err = capsys.readouterr().err
        assert stop.value.code == 2 and message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "new").exists()
    assert kept.is_dir() and not any(kept.iterdir()) and (tmp_path / "full" / "notes.txt").read_text() == "mine"


def test_capture_refuses_a_suffix_it_cannot_write_before_capturing(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    import hopper.logs.capture

    monkeypatch.setattr(hopper.logs.capture, "capture", lambda *_, **__: pytest.fail("captured before the check"))
    with pytest.raises(SystemExit) as stop:
        main(["capture", str(tmp_path / "out.rrd")])
    assert stop.value.code == 2
    known = "cannot write a log as '.rrd'; known: .csv, .mcap, .npz"
    assert capsys.readouterr().err == f"hopper-sim: error: {tmp_path / 'out.rrd'}: {known}\n"


@pytest.mark.parametrize(
    ("command", "says"),
    [
        ("capture", "the log to write: .csv, .mcap, .npz"),
        *((c, "the log: .csv, .mcap, .npz, our own .rrd") for c in ("replay", "identify")),
    ],
)
def test_help_names_every_format_the_command_reads_or_writes(
    command: str, says: str, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "200")  # argparse wraps at the terminal's width
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0 and says in capsys.readouterr().out


def test_help_says_what_identify_fits_and_each_commands_exit_statuses(
    capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """identify --params said "default: all of them" and fits 8 of 10; the three had no exit statuses."""
    from hopper.logs.sysid import DEFAULT_FIT, PARAMS

    monkeypatch.setenv("COLUMNS", "200")  # argparse wraps at the terminal's width
    texts = {}
    for command in ("capture", "replay", "identify"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        texts[command] = " ".join(capsys.readouterr().out.split())
        assert "exit status: 0 " in texts[command] and "130 interrupted" in texts[command], texts[command]
    assert len(DEFAULT_FIT) == 8 and set(PARAMS) - set(DEFAULT_FIT) == {"wheel_armature", "motor_damping"}
    assert f"(default these 8: {', '.join(DEFAULT_FIT)}; not wheel_armature or motor_damping," in texts["identify"]
    assert "1 the robot fell or the run reached its time limit before the hops asked" in texts["capture"]


def test_a_robot_with_its_own_motor_replays_and_identifies_its_log(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """capture --model kt.xml (k_t x 0.85) then replay --model kt.xml was 10 deg RMS off, and identify found
    motor_torque 1.0008 for 0.85: the drive inverted the packaged motor, not the one the log's commands were for."""
    import variants

    kt = str(variants.motor_constant(tmp_path, 0.85))
    log = tmp_path / "c_kt.npz"
    assert main(["capture", str(log), "--model", kt, "--hops", "1"]) == 0
    capsys.readouterr()
    assert main(["replay", str(log), "--model", kt, "--every", "0.3"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("wheel commands 3 ticks late for a 25.07 N m, 49.28 rad/s wheel motor (the log's)"), out
    assert "pitch RMS 0.000 deg, wheel speed RMS 0.000 rad/s" in out[-1], out
    argv = ["identify", str(log), "--out", str(tmp_path / "id.xml"), "--hops", "1", "--params", "motor_torque"]
    assert main([*argv, "--windows", "0.3", "--max-evaluations", "8", "--truth", "motor_torque=0.85"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("motor_torque"))
    assert float(row.split()[4]) == pytest.approx(0.85, rel=0.01), row
    # A CSV keeps no world: its drive is the packaged motor's unless --drive names the robot's.
    csv = tmp_path / "c_kt.csv"
    assert main(["log", "export", str(log), str(csv)]) == 0
    capsys.readouterr()
    rms = []
    for extra in ([], ["--drive", kt]):
        assert main(["replay", str(csv), "--model", kt, "--every", "0.3", *extra]) == 0
        rms.append(float(capsys.readouterr().out.splitlines()[-1].split("pitch RMS ")[1].split()[0]))
    assert rms[1] == 0.0 < 1.0 < rms[0], rms


def test_replay_and_identify_never_score_across_a_gap(logged: Path, tmp_path: Path, capsys) -> None:  # noqa: ANN001
    """Rows 2000-2499 removed (log check: 0.501 s without samples): replay ran straight through the gap
    (hop 1 at 32 deg RMS), said nothing, and its figure drew a line across it."""
    import numpy as np
    from hopper.app.replay_figure import error_figure

    from hopper.logs.io import write_log
    from hopper.logs.replay import REANCHOR_S, replay_hops, world_model
    from hopper.logs.schema import Log, find_gaps
    from hopper.logs.world import World

    log = read_log(logged)
    keep = np.ones(len(log.time), bool)
    keep[2000:2500] = False
    time = log.time[keep]
    path = write_log(Log(time, {k: v[keep] for k, v in log.signals.items()}, "t", find_gaps(time)), tmp_path / "g.csv")
    gap = "holds a gap, 0.501 s without samples (1.999-2.500 s)"
    assert main(["replay", str(path)]) == 0
    out, err = capsys.readouterr()
    assert err == f"replay: hop 1 (1.501-4.848 s) {gap}: not scored\n", err
    assert "hop 1 from" not in out and "hop 2 from 4.849 s:" in out and "all (1 replay(s)" in out, out
    assert main(["replay", str(path), "--every", "0.3"]) == 0
    out, err = capsys.readouterr()
    assert err == f"replay: hop 1 (1.501-4.848 s) {gap}: re-anchored on the log's state at its far side\n", err
    assert "hop 1 from 1.501 s, re-anchored every 0.3 s" in out and "all (2 replay(s)" in out, out
    with pytest.raises(SystemExit) as stop:
        main(["replay", str(path), "--hops", "1"])
    assert stop.value.code == 2 and "each hop asked holds a gap" in capsys.readouterr().err
    argv = ["identify", str(path), "--out", str(tmp_path / "id.xml"), "--hops", "1", "--params", "gyro_bias"]
    assert main([*argv, "--windows", "0.3", "--max-evaluations", "1"]) == 0
    out, err = capsys.readouterr()
    assert f"identify: hop 1 (1.501-4.848 s) {gap}: re-anchored on the log's state at its far side (the fit's " in err
    assert "(re-anchored every 0.3 s) after" in out and "(whole, each from its liftoff) after" not in out, out
    # The figure breaks each line at the gap: no straight line across it.
    gapped = read_log(path)
    model, _ = world_model(World())
    parts = replay_hops(model, gapped, 1, every=REANCHOR_S)
    from hopper.logs.replay import Errors

    fig = error_figure([("hop 1", Errors.concat([e for _, e in parts]))], "g.csv")
    for ax in fig.axes[:2]:
        x, y = ax.lines[0].get_xdata(), ax.lines[0].get_ydata()
        k = np.flatnonzero(np.isnan(y))
        assert k.size == 1 and x[k[0] - 1] < 2.0 and x[k[0] + 1] > 2.5, (x[k[0] - 1 : k[0] + 2], k)
