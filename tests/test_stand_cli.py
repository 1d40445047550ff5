"""`hopper-sim stand` as a user runs it (a real process): measured against predicted, the Bode figure,
the JSON that `hopper-sim report` draws, and bad chirps refused in one line with exit 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rrd import verify

pytestmark = pytest.mark.integration  # processes (conftest: the suite in parts)


def hopper_sim(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "hopper.app.sim_cli", *args], capture_output=True, text=True, timeout=300
    )


def test_stand_measures_steps_and_writes_what_the_report_draws(tmp_path: Path):
    out, bode = tmp_path / "stand.json", tmp_path / "bode.PDF"  # the name as given, its format by its suffix
    rrd = tmp_path / "stand.rrd"
    done = hopper_sim(
        "stand",
        "--measure",
        "--length",
        "10",
        "--step",
        "2",
        "--kick",
        "0.5",
        "--json",
        str(out),
        "--bode",
        str(bode),
        "--rrd",
        str(rrd),
    )
    assert done.returncode == 0, done.stderr
    assert "crossover Hz" in done.stdout and "rise ms" in done.stdout
    document = json.loads(out.read_text())
    (m,) = document["measurements"]
    kick = document["kick"]  # as printed, in the JSON too
    assert kick["magnitude_nms"] == 0.5 and 0.0 < kick["peak_s"] < kick["back_within_10pct_s"] <= kick["watched_s"]
    assert f"kick 0.5 N m s on the stand: peak pitch {kick['peak_pitch_deg']:.3f} deg" in done.stdout
    t, pitch = np.asarray(kick["t"]), np.abs(kick["pitch_deg"])  # the trace the report draws, from the kick
    assert t[0] == 0.0 and t[-1] == pytest.approx(kick["watched_s"]) and len(pitch) == len(t)
    assert pitch.max() == kick["peak_pitch_deg"] and t[pitch.argmax()] == pytest.approx(kick["peak_s"])
    assert m["where"] == "stand (legs locked)" and m["controller"] == "PaperPID"
    measured, predicted = m["measured_margins"], m["predicted_margins"]
    assert measured["crossover_hz"] == pytest.approx(predicted["crossover_hz"], rel=0.05)
    assert bode.read_bytes().startswith(b"%PDF") and bode.stat().st_size > 10_000
    assert f"wrote {bode}\n" in done.stdout and not any(p.name.startswith("bode.PDF.") for p in tmp_path.iterdir())
    assert verify(rrd) and rrd.stat().st_size > 100_000  # the run, its injected signal too (test_stand)
    report = hopper_sim("report", str(out), "--out", str(tmp_path / "report"))
    assert report.returncode == 0, report.stderr
    assert {p.name for p in (tmp_path / "report").iterdir()} >= {"bode_1.png", "step.png", "kick.png", "report.html"}
    assert "back within 10 % from (ms)" in (tmp_path / "report" / "report.html").read_text()


def test_a_short_chirp_measures_its_whole_band_and_does_not_report_one_segments_coherence(tmp_path: Path):
    """3 s, 1-200 Hz: one Welch segment of the whole record (it was 2.048 s of it, to 43 Hz: |L| read
    flat above, no gain margin, and the one segment's coherence printed 1.000)."""
    out = tmp_path / "stand.json"
    done = hopper_sim("stand", "--measure", "--length", "3", "--f-max", "200", "--json", str(out))
    assert done.returncode == 0, done.stderr
    (m,) = json.loads(out.read_text())["measurements"]
    assert m["f"][-1] >= 199.0 and m["segments"] == 1
    measured, predicted = m["measured_margins"], m["predicted_margins"]
    assert measured["gain_margin_db"] == pytest.approx(predicted["gain_margin_db"], abs=0.5)
    assert measured["coherence"] is None and "coherence at the crossover" not in done.stdout
    assert "coherence not estimated: the record is one Welch segment" in done.stdout
    assert "a chirp of 4.096 s or more gives two" in done.stdout


def test_a_chirp_at_the_reference_has_its_own_default_amplitude(tmp_path: Path):
    """--at reference without --amplitude: 2 deg in rad, as the dashboard's Inject panel offers, not the
    input's 2 N m (refused as "chirp amplitude must be in (0, 0.261799] rad (a quarter of the fall pitch), got 2")."""
    from hopper.analysis.bench import REFERENCE_AMPLITUDE

    out = tmp_path / "reference.json"
    done = hopper_sim("stand", "--measure", "--at", "reference", "--length", "3", "--f-max", "200", "--json", str(out))
    assert done.returncode == 0, done.stderr
    assert f"{REFERENCE_AMPLITUDE:g} rad at the reference" in done.stdout
    assert "at the reference the closed loop T is measured" in done.stdout  # why no measured margin is shown
    (m,) = json.loads(out.read_text())["measurements"]
    assert m["at"] == "reference" and m["spec"]["amplitude"] == REFERENCE_AMPLITUDE == pytest.approx(0.0349066)


def test_the_help_gives_the_amplitude_defaults_the_command_and_the_dashboard_use(monkeypatch, capsys):  # noqa: ANN001
    import math

    from hopper.app.dashboard.panels.inject import AMPLITUDE
    from hopper.app.sim_cli import main

    from hopper.analysis.bench import FLIGHT_AMPLITUDE, REFERENCE_AMPLITUDE, STAND_AMPLITUDE

    monkeypatch.setenv("COLUMNS", "200")  # argparse wraps at the terminal's width
    with pytest.raises(SystemExit):
        main(["stand", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert (
        f"N m at the input (default {STAND_AMPLITUDE:g}; flight {FLIGHT_AMPLITUDE:g}), rad at the reference "
        f"(default {REFERENCE_AMPLITUDE:.4f}, {math.degrees(REFERENCE_AMPLITUDE):g} deg)"
    ) in text, text
    assert AMPLITUDE["reference"] == (pytest.approx(math.degrees(REFERENCE_AMPLITUDE)), "deg")


@pytest.mark.parametrize(
    ("flags", "said"),
    [
        (["--length", "0"], "chirp length must be in (0, 600] s, got 0"),
        (["--length", "1e9"], "chirp length must be in (0, 600] s, got 1e+09"),
        (["--f-max", "600"], "must be under the Nyquist frequency"),
        (["--amplitude", "40"], "the motor's torque limit"),
    ],
)
def test_a_bad_chirp_is_refused_in_one_line(flags: list[str], said: str):
    done = hopper_sim("stand", "--measure", *flags)
    assert done.returncode == 2
    assert said in done.stderr and done.stderr.count("\n") == 1
    assert done.stdout == ""


@pytest.mark.parametrize("flights", ["0", "1001", "100000000"])
def test_flights_beyond_their_bound_are_refused_before_any_flight(flights: str):
    done = hopper_sim("stand", "--measure", "--flight", "--flights", flights)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == f"hopper-sim: error: --flights must be in [1, 1000], got {flights}\n"


@pytest.mark.parametrize(
    ("flags", "said"),
    [
        (["--kick", "0.5"], "--kick acts on the stand, --flight measures in flight: run them one at a time"),
        (["--step", "2"], "--step acts on the stand, --flight measures in flight: run them one at a time"),
        (["--at", "reference"], "--flight measures the loop at the plant input: drop --at reference"),
        (["--legs", "free"], "--legs sets the stand, and --flight measures in flight: drop it"),  # it was ignored
        (["--settle", "2"], "--settle sets the stand, and --flight measures in flight: drop it"),
    ],
)
def test_what_flight_cannot_do_is_refused_before_any_flight(flags: list[str], said: str):
    """--kick in flight was an AttributeError traceback after the measurement; --at reference exited 1
    ("not measured") after the flights' set-up."""
    done = hopper_sim("stand", "--measure", "--flight", "--flights", "1", *flags)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith(f"hopper-sim: error: {said}") and done.stderr.count("\n") == 1, done.stderr


@pytest.mark.parametrize("action", [["--measure"], ["--kick", "0.5"]])
def test_flights_without_flight_are_refused_not_ignored(action: list[str]):
    done = hopper_sim("stand", *action, "--flights", "5")
    assert done.returncode == 2 and done.stdout == ""  # before the stand is built
    assert done.stderr == (
        "hopper-sim: error: --flights 5 is how many flights --flight averages: add --flight (on the stand one "
        "chirp is measured)\n"
    )


@pytest.mark.parametrize(
    ("flags", "said"),
    [
        (["--kp", "300", "--controller", "lqr"], "--kp is the PID's gain, which --controller lqr does not fly"),
        (["--kd", "20", "--controller", "mpc"], "--kd is the PID's gain, which --controller mpc does not fly"),
        (["--ki", "10", "--controller-param", "ki=20"], "--ki and --controller-param ki=... both set ki: give one"),
    ],
)
def test_a_gain_that_would_be_ignored_is_refused_as_run_refuses_it(flags: list[str], said: str):
    done = hopper_sim("stand", "--kick", "0.5", *flags)
    assert done.returncode == 2 and done.stdout == ""  # before the kick
    assert done.stderr.startswith("hopper-sim: error: ") and said in done.stderr and done.stderr.count("\n") == 1


def test_a_bode_figure_without_a_measurement_is_refused(tmp_path: Path):
    done = hopper_sim("stand", "--step", "2", "--bode", str(tmp_path / "bode.png"))
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == "hopper-sim: error: --bode draws the loop that --measure measures: add --measure\n"


def test_stand_without_an_action_says_what_it_takes():
    done = hopper_sim("stand")
    assert done.returncode == 2 and "--measure" in done.stderr


@pytest.mark.parametrize(("name", "said"), [("bode", "'no suffix'"), ("bode.svg", "'.svg'")])
def test_a_bode_figure_without_a_png_or_pdf_suffix_is_refused_before_any_work(tmp_path: Path, name: str, said: str):
    done = hopper_sim("stand", "--measure", "--bode", str(tmp_path / name))
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == (
        f"hopper-sim: error: argument --bode: {tmp_path / name}: cannot tell the figure's format from {said}; "
        "known: .png, .pdf\n"
    )
    assert not any(tmp_path.iterdir())
