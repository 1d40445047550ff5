"""The dashboard's stand mode (World tab): the live simulation onto the test stand and back, kicks
and reference steps on it, bad values refused with a notice while the loop runs on."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hopper.app.dashboard import viser_compat as compat
from hopper.app.dashboard.panels.inject import AMPLITUDE
from hopper.app.dashboard.probe import ProbeClient
from hopper.app.dashboard.server import Dashboard
from net import wait_until

from hopper.analysis.bench import STAND_AMPLITUDE
from hopper.analysis.frequency import MAX_LENGTH_S, REFERENCE_LIMIT
from hopper.commands import Reset
from hopper.config import WHEEL_TORQUE_LIMIT
from hopper.sim import Simulation
from hopper.stand import StandSimulation

pytestmark = pytest.mark.integration


def titles(client: ProbeClient) -> list[str]:
    return [n.get("title", "") for n in client.notifications]


def pitch(dashboard: Dashboard) -> float:
    return dashboard.sim.state().pitch


def kick_time(sim: StandSimulation) -> float | None:
    """Simulation time (s) of the first disturbance on `sim`, or None."""
    return next((e.time for e in list(sim.events) if e.kind == "disturbance"), None)


def peak_pitch_since(dashboard: Dashboard, t: float) -> float:
    """Largest |pitch| (deg) the live chart holds after simulation time `t` (s). The loop samples it,
    so a short swing is not missed between two looks from the test's thread (under load a kick's
    swing came and went between them)."""
    times, pitches = dashboard.layout.plots.window.columns()[:2]
    after = pitches[times > t]
    return float(np.abs(after).max()) if after.size else 0.0


def test_the_stand_takes_kicks_and_reference_steps_and_gives_the_robot_back(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    client.set_gui_value("Reference °", "5")  # hopping: no reference to step
    assert client.wait_for(lambda p: "Command failed" in titles(p)), titles(client)
    assert "needs the stand" in client.notifications[-1]["body"]

    client.set_gui_value("Mode", "Stand, legs locked")
    assert wait_until(lambda: isinstance(dashboard.sim, StandSimulation) and dashboard.sim.time > 0.5)
    sim = dashboard.sim
    assert sim.legs == "locked" and dashboard.mode == "stand locked"
    assert client.wait_for(lambda p: "Mode" in titles(p))
    assert abs(pitch(dashboard)) < math.radians(1.0)  # held level

    client.set_gui_value("Apply", "Pitch kick")  # the Disturb tab's kick, on the stand
    assert wait_until(lambda: kick_time(sim) is not None), "no kick on the stand"
    kicked = kick_time(sim)
    assert wait_until(lambda: peak_pitch_since(dashboard, kicked) > 2.0), "the kick never moved the torso"
    assert wait_until(lambda: abs(pitch(dashboard)) < math.radians(0.5))  # the attitude loop brings it back
    assert dashboard.sim is sim

    client.set_gui_value("Reference °", "10")
    assert wait_until(lambda: sim.reference == pytest.approx(math.radians(10.0)))
    assert wait_until(lambda: abs(pitch(dashboard) - math.radians(10.0)) < math.radians(0.5))
    assert dashboard.physics.visible and not dashboard.physics.arc.visible  # nothing ballistic on the stand

    client.set_gui_value("Reference °", "abc")
    assert client.wait_for(lambda p: "Value refused" in titles(p)), titles(client)
    client.set_gui_value("Reference °", "99")
    assert client.wait_for(lambda p: "Value clamped" in titles(p)), titles(client)
    assert wait_until(lambda: sim.reference == pytest.approx(math.radians(30.0)))
    client.set_gui_value("Reference °", "-30")  # the limit itself: taken, no notice ("outside [-30, 30]" before)
    assert wait_until(lambda: sim.reference == pytest.approx(math.radians(-30.0)))
    client.set_gui_value("Reference °", "-99")  # its notice comes after any the -30 gave (one client's order)
    assert client.wait_for(lambda p: any("-99" in n.get("body", "") for n in p.notifications)), titles(client)
    assert titles(client).count("Value clamped") == 2, [n.get("body") for n in client.notifications]
    t = sim.time
    assert wait_until(lambda: sim.time > t + 0.3)  # the loop runs on

    client.set_gui_value("Mode", "Stand, legs free")
    assert wait_until(lambda: isinstance(dashboard.sim, StandSimulation) and dashboard.sim.legs == "free")
    assert wait_until(lambda: dashboard.sim.time > 0.3)
    client.set_gui_value("Mode", "Hopping")
    assert wait_until(lambda: type(dashboard.sim) is Simulation and dashboard.mode == "hop")
    assert wait_until(lambda: len(dashboard.sim.hops) > 0), "the robot did not hop again"
    assert wait_until(lambda: dashboard.physics.arc.visible), "no flight arc once hopping again"


def test_a_chirp_injected_live_on_the_stand_is_measured_and_drawn(dashboard: Dashboard, client: ProbeClient) -> None:
    client.set_gui_value("Inject", True)  # hopping: nothing to inject into
    assert client.wait_for(lambda p: "Not on the stand" in titles(p)), titles(client)

    client.set_gui_value("Mode", "Stand, legs locked")
    assert wait_until(lambda: isinstance(dashboard.sim, StandSimulation) and dashboard.sim.time > 0.3)
    sim = dashboard.sim
    client.set_gui_value("To (Hz)", "600")  # beyond the loop's Nyquist frequency: the box refuses it
    client.set_gui_value("Inject", True)
    assert client.wait_for(lambda p: "Value refused" in titles(p)), titles(client)
    assert "Nyquist" in client.notifications[-1]["body"]
    client.set_gui_value("Length (s)", "1")  # under 2 cycles of 1 Hz: the chirp as a whole is refused
    client.set_gui_value("Inject", True)
    assert client.wait_for(lambda p: "Chirp refused" in titles(p)), titles(client)
    assert "under 2 cycles of f_min 1 Hz" in client.notifications[-1]["body"]
    assert sim.injection is None  # nothing was played

    client.set_gui_value("To (Hz)", "200")
    client.set_gui_value("From (Hz)", "250")  # said in the boxes' names, not ChirpSpec's f_min and f_max
    client.set_gui_value("Inject", True)
    said = "From (250 Hz) must be below To (200 Hz)"
    assert client.wait_for(lambda p: said in [n["body"] for n in p.notifications]), client.notifications
    client.set_gui_value("From (Hz)", "1")
    client.set_gui_value("Length (s)", "3")
    asked = sim.time  # s of simulation: the injection starts after the press and before the test sees it
    client.set_gui_value("Inject", True)
    assert wait_until(lambda: sim.injection is not None), "the injection never started"
    started = sim.time
    assert client.wait_for(lambda p: "Injection measured" in titles(p), timeout=60.0), titles(client)
    injection = sim.injection
    assert injection.stopped == "" and injection.played == 3000 and injection.length_s == pytest.approx(3.0)
    assert asked <= injection.start.time <= started
    assert "crossover" in client.notifications[-1]["body"]
    assert dashboard.layout.stand.inject.bode.visible
    assert dashboard.sim is sim and sim.time > started + 3.0  # the loop ran on through it
    log = "\n".join(dashboard.layout.events.lines)  # what was injected, as it began and as it ended
    chirp = f"a 3 s logarithmic chirp, 1-200 Hz, {STAND_AMPLITUDE:.3g} N m at the wheel torque"
    assert f"injecting {chirp}" in log and f"injection played: {chirp}" in log, log

    client.set_gui_value("Inject", True)
    assert wait_until(lambda: sim.injection is not injection and sim.injection.playing)
    client.set_gui_value("Reset robot", True)  # a reset ends it, and says so
    assert client.wait_for(lambda p: "Injection stopped" in titles(p)), titles(client)
    assert "reset" in client.notifications[-1]["body"]
    status = dashboard.layout.stand.inject.status.content
    assert "stopped after " in status and " of 3 s: " in status, status  # seconds, as the chirp's length
    stopped = "injection stopped after "
    assert wait_until(lambda: any(stopped in line for line in dashboard.layout.events.lines)), (
        dashboard.layout.events.lines
    )


def test_the_chirp_boxes_clamp_to_what_a_chirp_takes_and_say_which_limit(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    """They clamped to 10,000 whatever the number: 1e9 N m became 10,000 N m, then refused at Inject
    as over 29.5; a length of 1e9 s became 10,000 s, refused as over 600. Now each box clamps to
    ChirpSpec's own limit (hopper.analysis.frequency.chirp_limits) and the chirp is taken."""
    inject = dashboard.layout.stand.inject

    def told(title: str, body: str) -> bool:
        return client.wait_for(lambda p: (title, body) in [(n.get("title"), n.get("body")) for n in p.notifications])

    torque = "(0, 29.5] N m (the motor's torque limit)"
    client.set_gui_value("Amplitude (N m)", "1e9")
    assert told("Value clamped", f"Amplitude 1000000000 N m is outside {torque}; clamped to 29.5 N m")
    client.set_gui_value("Length (s)", "1e9")
    assert told("Value clamped", "Length 1000000000 s is outside (0, 600] s; clamped to 600 s")
    assert wait_until(lambda: (inject.amplitude.value, inject.length.value) == (29.5, 600.0))
    spec = inject.spec(None)
    assert spec is not None and (spec.amplitude, spec.length) == (WHEEL_TORQUE_LIMIT, MAX_LENGTH_S)

    # No nearest value under the Nyquist frequency, nor above 0: refused, saying why.
    client.set_gui_value("To (Hz)", "500")
    nyquist = "(0, 500) Hz (the Nyquist frequency of the 1000 Hz loop)"
    assert told("Value refused", f"To 500 Hz is outside {nyquist}; kept 300 Hz"), client.notifications
    client.set_gui_value("From (Hz)", "0")
    assert told("Value refused", "From 0 Hz is outside (0, 500) Hz; kept 1 Hz"), client.notifications

    # At the pitch reference the box is in deg, up to a quarter of the fall pitch (15 deg).
    client.set_gui_value("Inject at", "pitch reference (deg)")
    assert wait_until(lambda: inject.amplitude.value == AMPLITUDE["reference"][0])  # its default there, in deg
    box = compat.element_id(inject.amplitude.handle)  # relabelled: found by its id
    client.send({"type": "GuiUpdateMessage", "uuid": box, "updates": {"value": "1e9"}})
    quarter = "(0, 15] deg (a quarter of the fall pitch)"
    assert told("Value clamped", f"Amplitude 1000000000 deg is outside {quarter}; clamped to 15 deg")
    assert wait_until(lambda: inject.amplitude.value == 15.0)
    spec = inject.spec(None)
    assert spec is not None and spec.at == "reference" and spec.amplitude == pytest.approx(REFERENCE_LIMIT, abs=1e-15)
    assert spec.amplitude <= REFERENCE_LIMIT


def test_run_numbers_go_on_counting_across_mode_switches(dashboard: Dashboard) -> None:
    """A mode switch built a new simulation whose runs counted from 0 again: the event log said
    "run 1" after "run 2". One dashboard session is one numbering."""
    log = dashboard.layout.events

    def newest() -> str:
        return (log.lines or [""])[0]

    dashboard.submit(Reset())
    assert wait_until(lambda: "reset (user)" in newest())
    runs = [newest()]
    for mode in ("stand locked", "hop"):
        dashboard.set_mode(mode)
        reset = f"reset ({mode.split()[0]})"  # the switch's own reset, the log's newest line
        assert wait_until(lambda reset=reset: reset in newest()), newest()
        runs.append(newest())
    assert [re.search(r"run (\d+)</span>", line)[1] for line in runs] == ["1", "2", "3"], runs
    assert dashboard.sim.run_index == 3
