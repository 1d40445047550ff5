"""Dashboard panels and their feedback: notices, typed numbers, charts, camera; no browser.

Browser input is stood in for by `ProbeClient`, which speaks viser's real websocket protocol.
"""

from __future__ import annotations

import contextlib
import dataclasses
import html
import logging
import math
import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import viser
from calls import Call
from hopper.app.dashboard import feedback
from hopper.app.dashboard import viser_compat as compat
from hopper.app.dashboard.config import DashboardConfig
from hopper.app.dashboard.feedback import Refused, format_number, notify, parse_number
from hopper.app.dashboard.panels.entry import QUIET_S, UNFINISHED_QUIET_S, NumberEntry
from hopper.app.dashboard.panels.simulation import SPEEDS
from hopper.app.dashboard.plots import LivePlots
from hopper.app.dashboard.probe import ProbeClient
from hopper.app.dashboard.scene import LOOK_OFFSET
from hopper.app.dashboard.server import Dashboard
from net import free_port, wait_until

from hopper import keyframes
from hopper.commands import Reset, SetWheel
from hopper.config import GAIN_RANGES, GRAVITY_PRESETS, MOON_GRAVITY, WHEEL_NO_LOAD_SPEED, WHEEL_TORQUE_LIMIT
from hopper.events import Event
from hopper.metrics import RAD_S_TO_RPM
from hopper.sim import Simulation

pytestmark = pytest.mark.integration  # servers, processes or pools (conftest: the suite in parts)


def bodies(client: ProbeClient, title: str) -> list[str]:
    return [n.get("body", "") for n in client.notifications if n.get("title") == title]


# -- notices ---------------------------------------------------------------------------------------
def test_clamp_notices_give_the_range_with_units_and_whole_numbers_as_such(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    # Both at once: a handler must not put back the other slider before that one's handler has run.
    client.set_gui_value("Ki", 900.0)
    client.set_gui_value("Kd", -3.0)
    assert client.wait_for(lambda p: len(bodies(p, "Gain clamped")) == 2), client.notifications
    assert sorted(bodies(client, "Gain clamped")) == [
        "Kd -3 N m s/rad is outside [0, 100] N m s/rad; clamped to 0 N m s/rad",
        "Ki 900 N m/(rad s) is outside [0, 500] N m/(rad s); clamped to 500 N m/(rad s)",
    ]
    client.set_gui_value("Seed", "20000000000000000000")  # above 2^64 - 1, the seeds hopper-sim takes
    assert client.wait_for(lambda p: bodies(p, "Value clamped")), client.notifications
    assert bodies(client, "Value clamped") == [
        "Seed 20000000000000000000 is outside [0, 18446744073709551615]; clamped to 18446744073709551615"
    ]


def test_numbers_in_notices() -> None:
    assert [format_number(v) for v in (2**31 - 1, 500.0, -5.0, 0.0, 12.5, 1 / 3, 1e20, -2.5e-7)] == [
        "2147483647",
        "500",
        "-5",
        "0",
        "12.5",
        "0.333333",
        "1e+20",
        "-2.5e-07",
    ]


class FakeClient:
    """Records what would be shown."""

    def __init__(self) -> None:
        self.shown: list[tuple[str, str]] = []

    def add_notification(self, title: str, body: str, **_: Any) -> None:
        self.shown.append((title, body))


def test_a_notification_still_on_screen_is_not_shown_again(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [100.0]
    monkeypatch.setattr(feedback, "_clock", lambda: now[0])
    monkeypatch.setattr(feedback, "page_may_close", lambda _: contextlib.nullcontext())  # no connection here
    a, b = FakeClient(), FakeClient()
    notify(a, "The robot fell", "pitch -60°", "warning")
    notify(a, "The robot fell", "pitch -60°", "warning")  # still on screen: dropped
    notify(a, "The robot fell", "pitch +60°", "warning")  # another body: shown
    notify(b, "The robot fell", "pitch -60°", "warning")  # another client: shown
    assert a.shown == [("The robot fell", "pitch -60°"), ("The robot fell", "pitch +60°")]
    assert b.shown == [("The robot fell", "pitch -60°")]
    now[0] += feedback.AUTO_CLOSE_S["warning"] + 0.1  # closed on its own by now
    notify(a, "The robot fell", "pitch -60°", "warning")
    assert a.shown[-1] == ("The robot fell", "pitch -60°") and len(a.shown) == 3


def test_a_replayed_fall_shows_one_toast(tmp_path: Path) -> None:
    """After the auto reset the simulation replays the same fall: same pitch, same time, same text."""
    d = Dashboard(DashboardConfig(port=free_port(), speed=4.0, sessions_dir=tmp_path), verbose=False).start()
    try:
        probe = ProbeClient(d.url)
        assert wait_until(lambda: len(d.server.get_clients()) == 1)
        walls: list[float] = []

        class FallClock:
            def tick(self, sim: Simulation) -> None:
                pass

            def event(self, sim: Simulation, event: Event) -> None:
                if event.kind == "fall":
                    walls.append(time.monotonic())

        # Both runs from a reset with the wheel already off (one drain applies both, in order), so no
        # tick of the first run has the wheel on (how many would depends on the machine's load).
        d.set_paused(True)
        d.sim.submit(Call(lambda sim: sim.listeners.append(FallClock())))
        d.sim.submit(SetWheel(False))  # with the wheel off it tumbles in its first flight
        d.sim.submit(Reset("test"))
        assert wait_until(lambda: any(e.kind == "reset" and e.payload.reason == "test" for e in list(d.sim.events)))
        d.set_paused(False)
        assert wait_until(lambda: len(walls) >= 2, timeout=40), "the robot did not fall twice"
        falls = [e for e in list(d.sim.events) if e.kind == "fall"][:2]
        # The same toast text (pitch to the degree, time to 10 ms): only the last digits of the pitch differ.
        assert [f"{e.payload.pitch_deg:+.0f} {e.time:.2f}" for e in falls] == [f"-60 {falls[0].time:.2f}"] * 2
        assert walls[1] - walls[0] < feedback.AUTO_CLOSE_S["warning"], "the first toast had closed already"

        # The auto reset after the second fall comes after the loop has handled that fall; a marker
        # sent then reaches the probe after any toast for it (one connection keeps its order).
        def resets_after_falls() -> int:
            return sum(e.kind == "reset" and e.payload.reason == "after fall" for e in list(d.sim.events))

        assert wait_until(lambda: resets_after_falls() >= 2, timeout=20)
        feedback.notify_all(d.server, "marker", "")
        assert probe.wait_for(lambda p: bodies(p, "marker"))
        assert len(bodies(probe, "The robot fell")) == 1, bodies(probe, "The robot fell")
        probe.close()
    finally:
        d.stop()


def test_a_gravity_whose_hop_the_legs_cap_tells_every_client_and_how_to_size_the_robot(dashboard: Dashboard) -> None:
    probes = [ProbeClient(dashboard.url)]
    try:
        assert wait_until(lambda: dashboard.roles.operator is not None)  # the first to connect operates
        probes.append(ProbeClient(dashboard.url))  # and the second watches
        assert wait_until(lambda: len(dashboard.server.get_clients()) == 2)
        probes[0].set_gui_value("Gravity", "Earth")
        for probe in probes:  # the one who chose it and the viewer
            assert probe.wait_for(lambda p: bodies(p, "Legs at their limit")), probe.notifications
            (body,) = bodies(probe, "Legs at their limit")
            assert body.startswith("At 9.81 m/s² this robot's 30 N m legs cap the hop at 0.09 m of the 0.25 m asked")
            assert "hopper-sim size --gravity 9.81 --out FILE" in body and "hopper-dashboard --model FILE" in body
        # Mars's gravity asks no more of the legs than they give: the loop has it, then a marker, and
        # no second notice came before the marker (one connection keeps its order).
        probes[0].set_gui_value("Gravity", "Mars")
        assert wait_until(lambda: dashboard.sim.config.gravity == GRAVITY_PRESETS["mars"])
        feedback.notify_all(dashboard.server, "marker", "")
        assert probes[0].wait_for(lambda p: bodies(p, "marker"))
        assert len(bodies(probes[0], "Legs at their limit")) == 1, probes[0].notifications
    finally:
        for probe in probes:
            probe.close()


def test_a_gravity_the_legs_cannot_hold_the_robot_at_is_refused_and_the_control_shows_what_flies(
    start: Any, tmp_path: Path
) -> None:
    from hopper.model import MODEL_XML

    weak = tmp_path / "weak.xml"  # 10 N m legs: enough on the Moon, not on Earth
    weak.write_text(MODEL_XML.read_text().replace('ctrlrange="-30 30"', 'ctrlrange="-10 10"'))
    d = start(model=str(weak))
    probe = ProbeClient(d.url)
    try:
        assert wait_until(lambda: d.roles.operator is not None)
        gravity = probe.set_gui_value("Gravity", "Earth")
        assert probe.wait_for(lambda p: bodies(p, "Command failed")), probe.notifications
        assert bodies(probe, "Command failed") == [
            "SetGravity failed: ValueError: the legs cannot hold the robot at 9.81 m/s^2 (crouched, 10 N m)"
        ]
        assert probe.wait_for(lambda p: (gravity, {"value": "Moon"}) in p.gui_log), "the control still shows Earth"
        assert d.sim.config.gravity == MOON_GRAVITY and d.sim.model.opt.gravity[2] == -MOON_GRAVITY
        now = d.sim.time
        assert wait_until(lambda: d.sim.time > now + 0.5), "the simulation stopped"
    finally:
        probe.close()


PICKY = """
from hopper.controllers import ControllerError, Param


class Picky:
    \"\"\"A PD whose kd refuses what the wheel cannot take (its setter raises ControllerError).\"\"\"

    params = (Param("kp", 300.0, (0.0, 2000.0), "N m/rad"), Param("kd", 25.0, (0.0, 100.0), "N m s/rad"))

    @property
    def kd(self):
        return self._kd

    @kd.setter
    def kd(self, value):
        if value > 50.0:
            raise ControllerError("over 50 the wheel rings at the motor's delay")
        self._kd = value

    def __call__(self, obs):
        return self.kp * obs.pitch + self.kd * obs.rate
"""


def test_a_param_value_the_controller_refuses_is_one_line_and_the_slider_and_box_show_the_value_in_use(
    start: Any, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """It was 'SetControllerParam failed: ControllerError: ...' with a traceback in the log."""
    picky = tmp_path / "picky.py"
    picky.write_text(PICKY)
    spec = f"{picky}:Picky"
    d = start(controller_choice=(spec,))
    probe = ProbeClient(d.url)
    try:
        assert wait_until(lambda: d.roles.operator is not None)
        probe.set_gui_value("Controller", spec)
        panel = d.layout.controller
        assert wait_until(lambda: "kd" in panel.entries, timeout=60), "Picky's params were never shown"
        box, slider = panel.entries["kd"].handle, panel.sliders["kd"]
        assert probe.wait_for(lambda p: compat.element_id(box) in p.gui), "the page never got the kd box"
        said = "Picky refused kd = 80 N m s/rad: over 50 the wheel rings at the motor's delay"

        probe.send({"type": "GuiUpdateMessage", "uuid": compat.element_id(box), "updates": {"value": "80"}})
        assert probe.wait_for(lambda p: bodies(p, "Value refused") == [said]), probe.notifications
        assert probe.wait_for(lambda p: (compat.element_id(box), {"value": "25"}) in p.gui_log), "the box kept 80"
        assert d.sim.law.values["kd"] == 25.0 and panel.entries["kd"].value == 25.0 and slider.value == 25.0

        probe.send({"type": "GuiUpdateMessage", "uuid": compat.element_id(slider), "updates": {"value": 60.0}})
        assert probe.wait_for(lambda p: (compat.element_id(slider), {"value": 25.0}) in p.gui_log), "slider kept 60"
        assert d.sim.law.values["kd"] == 25.0 and not bodies(probe, "Command failed"), probe.notifications
        refused = [r for r in caplog.records if "refused" in r.getMessage()]
        assert refused and all(r.levelno == logging.WARNING and not r.exc_info for r in refused), caplog.text
        assert not [r for r in caplog.records if r.exc_info], "a refused value logged a traceback"
    finally:
        probe.close()


def test_a_controllers_params_are_flown_again_when_it_is_chosen_again(start: Any) -> None:
    """MPC's pitch_tol set to 7, then LQR, then MPC: it came back at its default 5, where the PID's
    gains survive a switch (the Gains panel keeps them)."""
    d = start()
    probe = ProbeClient(d.url)
    try:
        assert wait_until(lambda: d.roles.operator is not None)
        panel = d.layout.controller
        probe.set_gui_value("Controller", "mpc")
        assert wait_until(lambda: "pitch_tol" in panel.entries, timeout=60), "MPC's params were never shown"
        box = panel.entries["pitch_tol"].handle
        assert probe.wait_for(lambda p: compat.element_id(box) in p.gui), "the page never got the box"
        probe.send({"type": "GuiUpdateMessage", "uuid": compat.element_id(box), "updates": {"value": "7"}})
        assert wait_until(lambda: d.sim.law.spec == "mpc" and d.sim.law.values["pitch_tol"] == 7.0, timeout=60)
        # The panel learns it from the simulation's ControllerChanged, on the loop's thread, after the law has it.
        assert wait_until(lambda: panel.remembered.get("mpc", {}).get("pitch_tol") == 7.0, timeout=60)
        for spec in ("lqr", "mpc"):
            probe.set_gui_value("Controller", spec)
            assert wait_until(lambda spec=spec: d.sim.law.spec == spec, timeout=60), spec
        assert d.sim.law.values["pitch_tol"] == 7.0
        assert wait_until(
            lambda: panel.entries.get("pitch_tol") is not None and panel.entries["pitch_tol"].value == 7.0
        )
    finally:
        probe.close()


def test_the_flying_law_shown_again_does_not_undo_a_pick_on_its_way(start: Any) -> None:
    """A param applied to LQR comes back as ControllerChanged(lqr); shown after the operator's pick of
    MPC had set the selector and before that pick's callback ran, it put LQR back in the selector, the
    callback read LQR, took it for no change and MPC never flew (CI failed so, once in about 30 runs)."""
    d = start()
    probe = ProbeClient(d.url)
    try:
        assert wait_until(lambda: d.roles.operator is not None)
        panel = d.layout.controller
        probe.set_gui_value("Controller", "lqr")
        assert wait_until(lambda: panel.flying == "lqr", timeout=60), "LQR never flew"
        lqr = d.sim.law
        with panel._lock:  # the panel shows no other law meanwhile: LQR is the one in flight for it
            probe.set_gui_value("Controller", "mpc")
            assert wait_until(lambda: panel.choice.value == "mpc"), "the pick never reached the selector"
            panel.show(lqr)  # the loop shows LQR's values again: a param applied meanwhile
            assert panel.choice.value == "mpc", "showing the law in flight undid the pick"
        assert wait_until(lambda: d.sim.law.spec == "mpc" and panel.flying == "mpc", timeout=60), "the pick was lost"
        assert panel.choice.value == "mpc"
    finally:
        probe.close()


def test_a_controller_that_cannot_fly_is_refused_and_the_selector_shows_what_flies(start: Any, tmp_path: Path) -> None:
    broken = tmp_path / "broken.py"
    broken.write_text(
        "class Broken:\n"
        "    def __init__(self):\n"
        "        raise RuntimeError('no wheel model for this robot')\n"
        "    def __call__(self, obs):\n"
        "        return 0.0\n"
    )
    spec = f"{broken}:Broken"
    d = start(controller_choice=(spec,))
    probe = ProbeClient(d.url)
    try:
        assert wait_until(lambda: d.roles.operator is not None)
        choice = probe.set_gui_value("Controller", spec)
        assert probe.wait_for(lambda p: bodies(p, "Command failed")), probe.notifications
        assert "no wheel model for this robot" in bodies(probe, "Command failed")[0]
        assert probe.wait_for(lambda p: (choice, {"value": "pid"}) in p.gui_log), "the selector still shows Broken"
        assert d.layout.controller.choice.value == "pid" and d.sim.law.spec == "pid"
    finally:
        probe.close()


# -- typed numbers ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text, value",
    [("800", 800.0), ("1e3", 1000.0), ("12.5", 12.5), (" -2.5 ", -2.5), ("+.5", 0.5), ("5.", 5.0), ("1E-2", 0.01)],
)
def test_typed_numbers_that_parse(text: str, value: float) -> None:
    assert parse_number("Kp", text, -2000.0, 2000.0, "N m/rad") == (value, None)


@pytest.mark.parametrize(
    "text, why",
    [
        ("1,5", "a point"),
        ("abc", "not a number"),
        ("NaN", "not a number"),
        ("inf", "not a number"),
        ("-Infinity", "not a number"),
        ("", "empty"),
        ("1e", "not a number"),
        ("0x10", "not a number"),
        ("1_000", "not a number"),
        ("1e999", "too large"),
    ],
)
def test_typed_text_that_is_refused(text: str, why: str) -> None:
    with pytest.raises(Refused, match=why):
        parse_number("Kp", text, 0.0, 2000.0, "N m/rad")


def test_typed_numbers_are_clamped_with_the_range_and_units() -> None:
    low, high, unit = GAIN_RANGES["ki"]
    assert parse_number("Ki", "900", low, high, unit) == (
        500.0,
        "Ki 900 N m/(rad s) is outside [0, 500] N m/(rad s); clamped to 500 N m/(rad s)",
    )
    assert parse_number("Seed", "1e3", 0, 2**31 - 1, integer=True) == (1000, None)
    # Digits are read exactly: as a float, 2^64 - 2 would be 2^64 and clamped.
    assert parse_number("Seed", "18446744073709551614", 0, 2**64 - 1, integer=True) == (2**64 - 2, None)
    with pytest.raises(Refused, match="whole number"):
        parse_number("Seed", "12.5", 0, 2**31 - 1, integer=True)


class _Box:
    """A text box as NumberEntry uses it: a value, and the callback viser calls when it changes."""

    def __init__(self) -> None:
        self.value = ""
        self.changed: Any = None

    def on_update(self, callback: Any) -> None:
        self.changed = callback


def test_a_word_the_box_takes_stands_for_its_value_and_its_start_waits_as_a_half_typed_number() -> None:
    """Speed's box shows Max and takes it typed in any case; text that is neither a number nor the word
    is refused and the box shows the value in use; "ma" waits before it is read as long as "1e" does."""
    box, applied = _Box(), []
    entry = NumberEntry(
        box, "Speed", 0.1, 64.0, "x", value=1.0, words={"Max": math.inf}, on_apply=lambda v, _: applied.append(v)
    )  # type: ignore[arg-type]
    assert box.value == "1"
    box.value = "mAX"
    assert entry.commit() == math.inf and box.value == "Max" and applied == [math.inf]
    box.value = "abc"
    assert entry.commit() is None and box.value == "Max" and entry.value == math.inf
    entry.show(4.0)
    assert box.value == "4" and applied == [math.inf]  # shown, not applied
    for text, wait in (("ma", UNFINISHED_QUIET_S), ("1e", UNFINISHED_QUIET_S), ("max", QUIET_S), ("2", QUIET_S)):
        box.value = text
        box.changed(viser.GuiEvent(client=object(), client_id=0, target=box))  # type: ignore[arg-type]
        timer = entry._timer
        assert timer is not None
        timer.cancel()
        assert timer.interval == wait, text


# -- charts ----------------------------------------------------------------------------------------
def test_the_torque_and_speed_charts_draw_the_wheel_limits() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        plots = LivePlots(server)
        rpm_limit = WHEEL_NO_LOAD_SPEED * RAD_S_TO_RPM
        specs = {spec.uuid: spec for spec in plots.feed.charts}
        for chart, limit in ((plots.torque, WHEEL_TORQUE_LIMIT), (plots.rpm, rpm_limit)):
            spec = specs[chart._impl.uuid]
            # The feed sends a limit line as its one value (chart_feed: a constant column).
            lines = [
                (s, column)
                for s, column in zip(chart.series, spec.columns, strict=True)
                if "limit" in str(s.get("label", ""))
            ]
            assert len(lines) == 2, chart.series
            assert sorted(column for _, column in lines) == pytest.approx([-limit, limit], abs=1e-3)
            assert all(isinstance(column, float) for _, column in lines)
            for series, _ in lines:
                assert series.get("dash") and series["stroke"] == "#e5484d"
        assert math.isclose(rpm_limit, 400.0)
    finally:
        server.stop()


# -- camera ----------------------------------------------------------------------------------------
def test_side_view_looks_at_the_robot_where_it_is_shown_with_follow_off(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    import mujoco

    client.set_gui_value("Pause", True)
    client.set_gui_value("Follow robot", False)
    assert wait_until(lambda: dashboard.pacer.paused and not dashboard.camera.enabled)

    def carry_forward(sim: Simulation) -> None:  # 2.5 m along the strip, as after a few hops
        sim.data.joint("root_x").qpos[0] += 2.5
        mujoco.mj_forward(sim.model, sim.data)

    x_before = dashboard.sim.state().x
    dashboard.sim.submit(Call(carry_forward))

    def shown_torso() -> np.ndarray:
        return np.asarray(dashboard.robot.torso_position) + np.asarray(dashboard.camera.world.position)

    assert wait_until(lambda: dashboard.robot.torso_position[0] > x_before + 2.4), "the moved robot was not drawn"
    assert shown_torso()[0] > 2.0, "with follow off the world frame must not have followed"
    client.set_gui_value("Side view", True)
    (handle,) = dashboard.server.get_clients().values()

    def aimed() -> bool:  # the whole move: viser's position setter shifts look_at too, then look_at is set
        aim = np.asarray(handle.camera.look_at) - LOOK_OFFSET
        return bool(np.linalg.norm(aim - shown_torso()) < 0.03)

    assert wait_until(aimed), (handle.camera.look_at, shown_torso())
    assert np.allclose(np.asarray(handle.camera.position) - handle.camera.look_at, [0.0, -4.4, 1.9])


def _strip(**changes: object):
    from hopper.app.dashboard.panels.status import Status

    status = Status(
        phase="flight", time=3.0, rtf=1.0, speed=1.0, paused=False, behind=False, hops=2, pitch_deg=0.4,
        wheel_rpm=-200.0, saturation=0.5, capacity=-0.5, capacity_nms=2.0, gravity=1.625, recording=False,
    )  # fmt: skip
    return dataclasses.replace(status, **changes)


def _text(strip: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", strip))


def test_the_status_strip_shows_the_wheels_momentum_as_a_share_of_its_capacity() -> None:
    from hopper.app.dashboard.panels.status import status_html

    text = _text(status_html(_strip()))
    assert "capacity-50 % · -1.00 N m s" in text and "wheel-200 rpm" in text  # cells run together
    still = _text(status_html(_strip(wheel_rpm=-0.3, pitch_deg=-0.04, capacity=-0.001)))
    assert "wheel+0 rpm" in still and "pitch+0.0°" in still and "capacity+0 % · +0.00 N m s" in still  # no "-0"


def test_the_momentum_gauge_fills_from_the_centre_toward_the_wheels_side() -> None:
    from hopper.app.dashboard.panels.status import status_html

    back = status_html(_strip(capacity=-0.5))  # half the capacity spent backward: the fill is the left quarter
    assert "hd-gauge-fill hd-warn' data-v='8' style='left:25.0%;width:25.0%'" in back
    ahead = status_html(_strip(capacity=0.9))
    assert "hd-gauge-fill hd-bad' data-v='8' style='left:50.0%;width:45.0%'" in ahead
    assert "hd-ok" in status_html(_strip(capacity=0.1))
    assert "width:50.0%" in status_html(_strip(capacity=-3.0))  # clipped at the capacity


class _Element:
    """A stand-in for viser's HTML handle that counts what is sent."""

    def __init__(self) -> None:
        self._content, self.sent = "", []

    @property
    def content(self) -> str:
        return self._content

    @content.setter
    def content(self, value: str) -> None:
        self._content = value
        self.sent.append(value)


def test_the_status_table_is_sent_on_a_new_layout_and_its_values_alone_otherwise() -> None:
    from hopper.app.dashboard.panels.status import FIELDS, StatusPanel, decode_values, status_html, values

    panel = StatusPanel(frame=_Element(), carrier=_Element())  # type: ignore[arg-type]
    for i in range(10):  # time, pitch and wheel move: values only
        panel.show(_strip(time=3.0 + 0.2 * i, pitch_deg=0.1 * i, wheel_rpm=-200.0 + 10 * i))
    assert len(panel.frame.sent) == 1 and len(panel.carrier.sent) == 10
    assert decode_values(panel.carrier.content) == dict(zip(FIELDS, values(panel.status), strict=True))
    assert decode_values(panel.carrier.content)["time"] == "4.80"
    assert panel.shown == status_html(panel.status) and "4.80" not in panel.frame.content  # the page writes it
    panel.show(_strip(time=4.8, pitch_deg=0.9, wheel_rpm=-110.0))  # nothing new: nothing sent
    assert len(panel.frame.sent) == 1 and len(panel.carrier.sent) == 10
    for change in ({"paused": True}, {"recording": True}, {"speed": math.inf}, {"behind": True}, {"gravity": 9.81}):
        panel.show(_strip(**change))  # a new layout: the table again, with the values in it
        assert panel.frame.sent[-1] == status_html(panel.status), change
    assert len(panel.frame.sent) == 6
    panel.show(_strip(phase="landing"))  # a phase is a value: its badge is written by the page
    assert len(panel.frame.sent) == 7 and decode_values(panel.carrier.content)["phase"] == "landing"
    panel.show(_strip(phase="stance"))
    assert len(panel.frame.sent) == 7 and decode_values(panel.carrier.content)["phase"] == "stance"


def test_the_status_values_survive_quotes_and_markup_in_their_carrier() -> None:
    from hopper.app.dashboard.panels.status import decode_values, values_html

    shown = ("a'b", "<i>", "&amp;", '"', "·", "5", "6", "7", "8")
    assert list(decode_values(values_html(shown)).values()) == list(shown)
    assert decode_values("<div>no values</div>") is None


def test_a_gravity_given_at_start_is_flown_shown_and_the_default_the_reset_goes_back_to(tmp_path: Path) -> None:
    earth = GRAVITY_PRESETS["earth"]
    config = DashboardConfig(port=free_port(), sessions_dir=tmp_path / "s", gravity=earth)
    dashboard = Dashboard(config, verbose=False)
    try:
        terrain = dashboard.layout.terrain
        assert dashboard.sim.config.gravity == earth and terrain.gravity.value == "Earth"
        terrain.gravity.value = "Mars"
        terrain.reset()
        assert terrain.gravity.value == "Earth"
    finally:
        dashboard.stop()
    with pytest.raises(ValueError, match=r"gravity must be one of the presets \(moon 1.625, mars 3.72"):
        DashboardConfig(gravity=9.8)


@pytest.mark.parametrize(
    ("controller", "shown"), [("policy", "Policy is not a linear law"), ("lqr", "LQR as state feedback")]
)
def test_a_controller_given_at_start_gets_its_own_loop_analysis(tmp_path: Path, controller: str, shown: str) -> None:
    """Not the PID's: the analysis followed only a switch in the page (seen with --controller policy)."""
    config = DashboardConfig(port=free_port(), sessions_dir=tmp_path / "s", controller=controller)
    with Dashboard(config, verbose=False) as dashboard:
        assert shown in dashboard.layout.analysis.note
        assert wait_until(lambda: shown in dashboard.layout.analysis.html.content), (
            dashboard.layout.analysis.html.content
        )


# -- trail -----------------------------------------------------------------------------------------
def test_the_trail_creates_each_node_once_then_sends_only_its_points() -> None:
    """A growing or recycled chunk is one points update, not a new node; the page draws the whole path,
    also when fast-forward samples several chunks between two publishes."""
    from hopper.app.dashboard.scene import TRAIL_CHUNK, TRAIL_CHUNKS, TRAIL_SAMPLE_S, Trail

    step = 2.0 ** math.ceil(math.log2(TRAIL_SAMPLE_S))  # s between samples: exact, so none is skipped
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    probe = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
    try:
        trail = Trail(server.scene)
        path = [(0.01 * k, 0.3 + 0.1 * math.sin(0.2 * k)) for k in range(3 * TRAIL_CHUNK * TRAIL_CHUNKS + 7)]
        burst = 4 * TRAIL_CHUNK  # the last samples come between two publishes, as at 64x
        for k, (x, z) in enumerate(path):
            trail.sample(k * step, x, z)
            if k % 4 == 3 and k < len(path) - burst:  # 4 samples a publish, as at 1x
                trail.publish()
        trail.publish()
        segments = len(path) - 1
        newest = (segments - 1) // TRAIL_CHUNK  # the chunk the last segment is in
        names = [f"/world/trail/{c % TRAIL_CHUNKS}" for c in range(newest - TRAIL_CHUNKS + 1, newest + 1)]
        last = np.float32(path[-1][0])

        def arrived() -> bool:
            shown = probe.scene_points.get(names[-1])
            return shown is not None and bool((shown[:, 1, 0] == last).any())

        assert wait_until(arrived), "the newest point never reached the page"
        assert all(probe.scene_counts["LineSegmentsMessage", name] == 1 for name in names)  # created once each
        chunks = [probe.scene_points[name] for name in names]
        assert all(chunk.shape == (TRAIL_CHUNK, 2, 3) for chunk in chunks)
        drawn = np.concatenate(chunks)
        drawn = drawn[np.linalg.norm(drawn[:, 1] - drawn[:, 0], axis=1) > 0]  # the newest chunk's unreached ones
        assert len(drawn) == (TRAIL_CHUNKS - 1) * TRAIL_CHUNK + (segments - 1) % TRAIL_CHUNK + 1
        expected = np.array([(x, 0.0, z) for x, z in path], np.float32)[-len(drawn) - 1 :]
        assert np.array_equal(drawn[:, 0], expected[:-1]) and np.array_equal(drawn[:, 1], expected[1:])
    finally:
        probe.close()
        server.stop()


def trail_drawn(probe: ProbeClient) -> set[tuple[float, ...]]:
    """The trail segments (x0, z0, x1, z1) the page draws: the trail nodes' shown and not collapsed."""
    return {
        (float(a[0]), float(a[2]), float(b[0]), float(b[2]))
        for name, points in probe.scene_points.items()
        if name.startswith("/world/trail/") and probe.scene_visible.get(name)
        for a, b in points
        if (a != b).any()
    }


def test_a_rewound_trail_ends_at_the_moment_shown_until_the_run_goes_on_from_there() -> None:
    """Scrubbed back, the robot stood behind the end of its own trail: the path ahead of it was still
    drawn. It ends at the moment shown now; a later moment brings the path back while paused, and once
    the run goes on from the moment the path it left is dropped (as the history after it is)."""
    from hopper.app.dashboard.scene import TRAIL_CHUNK, TRAIL_SAMPLE_S, Trail

    step = 2.0 ** math.ceil(math.log2(TRAIL_SAMPLE_S))  # s between samples: exact, so none is skipped
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    probe = ProbeClient(f"http://127.0.0.1:{server.get_port()}")

    def drawn_to() -> float:
        """The largest x (m) the page draws a trail segment to."""
        return max((x1 for _, _, x1, _ in trail_drawn(probe)), default=-1.0)

    def shows_to(x: float) -> bool:
        return probe.wait_for(lambda p: drawn_to() == np.float32(x), timeout=20)

    def shows_the_path() -> bool:
        f = np.float32
        path = [(float(f(x)), float(f(z))) for x, z in trail.points]
        segments = {(*a, *b) for a, b in zip(path[:-1], path[1:], strict=True)}
        return probe.wait_for(lambda p: trail_drawn(probe) == segments, timeout=20)

    try:
        trail = Trail(server.scene)
        path = [(0.01 * k, 0.3) for k in range(5 * TRAIL_CHUNK + 3)]  # six chunks
        for k, (x, z) in enumerate(path):
            trail.sample(k * step, x, z)
        trail.publish()
        assert shows_to(path[-1][0])
        cut, later = 2 * TRAIL_CHUNK + 4, 4 * TRAIL_CHUNK + 1
        trail.rewind(cut * step, *path[cut])
        trail.publish()
        assert shows_to(path[cut][0]), drawn_to()
        assert trail.points == path[: cut + 1]
        trail.rewind(later * step, *path[later])  # still paused: a later moment of the same path
        trail.publish()
        assert shows_to(path[later][0]), drawn_to()
        trail.rewind(cut * step, *path[cut])
        # The run goes on from there another way, before the next publish (a restore while running):
        # the cut chunk comes back to its length with other points.
        for k in range(cut + 1, later + 1):
            trail.sample(k * step, path[k][0], 0.5)
        trail.publish()
        regrown = path[: cut + 1] + [(x, 0.5) for x, _ in path[cut + 1 : later + 1]]
        assert trail.points == regrown and shows_the_path(), sorted(trail_drawn(probe))
        trail.rewind(len(path) * step, *regrown[-1])
        assert trail.points == regrown  # the path it left is gone
        # A moment older than the path's oldest point (the path is kept as far back as the history
        # reaches, but not before the run): nothing drawn there, and the path is there again at a
        # later moment (it was not forgotten).
        trail.rewind(-1.0, *regrown[0])
        trail.publish()
        assert trail.points == [] and probe.wait_for(lambda p: drawn_to() == -1.0, timeout=20)
        trail.rewind(cut * step, *regrown[cut])
        trail.publish()
        assert trail.points == regrown[: cut + 1] and shows_the_path(), sorted(trail_drawn(probe))
        trail.rewind(cut * step, 50.0, 0.3)  # a moment the path does not lead to (a keyframe from elsewhere)
        trail.publish()
        assert trail.points == [] and probe.wait_for(lambda p: drawn_to() == -1.0, timeout=20)
    finally:
        probe.close()
        server.stop()


def test_a_moment_put_back_further_than_the_trail_shows_is_drawn_with_the_path_that_led_to_it() -> None:
    """The trail showed 15 s and kept no more, and the history reaches 40 s back: a moment 30 s ago
    was shown with no trail at all. The path is kept as far back as the history reaches, and the
    15 s before the moment shown are drawn."""
    from hopper.app.dashboard.scene import TRAIL_CHUNK, TRAIL_CHUNKS, TRAIL_SAMPLE_S, Trail

    from hopper.history import RING_SPAN_S

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    probe = ProbeClient(f"http://127.0.0.1:{server.get_port()}")
    f = np.float32

    try:
        trail = Trail(server.scene)
        step = 2.0 ** math.ceil(math.log2(TRAIL_SAMPLE_S))  # s between samples: exact, so none is skipped
        n = round(60.0 / step)  # a minute of path
        path = [(0.01 * k, float(f(0.3 + 0.001 * (k % 7)))) for k in range(n)]
        for k, (x, z) in enumerate(path):
            trail.sample(k * step, x, z)
            if k % 4 == 3:
                trail.publish()
        back = n - 1 - round(30.0 / step)  # 30 s ago: within the history, beyond the 15 s shown
        assert RING_SPAN_S > 30.0
        trail.rewind(back * step, *path[back])
        trail.publish()
        shown = trail.points
        assert shown[-1] == path[back] and len(shown) > (TRAIL_CHUNKS - 1) * TRAIL_CHUNK  # 29 to 30 chunks of it
        assert shown == path[back + 1 - len(shown) : back + 1]
        want = {(float(f(a[0])), a[1], float(f(b[0])), b[1]) for a, b in zip(shown[:-1], shown[1:], strict=True)}
        assert probe.wait_for(lambda p: trail_drawn(probe) == want, timeout=20), len(trail_drawn(probe) ^ want)
    finally:
        probe.close()
        server.stop()


def test_a_history_further_back_than_it_reaches_is_clamped_with_a_notice(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    """Typed into the History's Back box, 100 s was taken without a word (and showed the newest
    moment), and -100 s showed the oldest while its line said 100 s back: both are clamped with a
    notice, the box and the line show the moment shown."""
    assert wait_until(lambda: dashboard.history.span >= 1.0, timeout=60)
    client.set_gui_value("Back (s)", 100.0)
    assert client.wait_for(lambda p: bodies(p, "Back clamped")), client.notifications
    assert bodies(client, "Back clamped") == ["Back 100 s is outside [-40, 0] s; clamped to 0 s"]
    client.set_gui_value("Back (s)", -100.0)
    assert client.wait_for(lambda p: len(bodies(p, "Back clamped")) == 2), client.notifications
    body = bodies(client, "Back clamped")[1]
    # The slider's -100 is its -40 first (no page sends past a slider's end), then the history's span.
    assert body.startswith("Back 40 s: the history holds ") and body.endswith(" s; showing its oldest moment")
    held = float(body.removeprefix("Back 40 s: the history holds ").split(" s;")[0])
    replay = dashboard.layout.replay
    assert wait_until(lambda: replay.scrubbed is not None)
    assert replay.scrub.value == pytest.approx(-held, abs=0.051)  # the box shows it (to the line's 0.1 s)
    assert f"({held:.1f} s back of " in replay.scrub_info.content
    # Typed, one notice, with what was typed: the box clamped to 40 s first, then the history to 39.9.
    client.set_gui_value("s back", "1000")
    assert client.wait_for(lambda p: len(bodies(p, "Back clamped")) == 3), client.notifications
    assert bodies(client, "Back clamped")[2].startswith("Back 1000 s: the history holds ")
    assert not bodies(client, "Value clamped"), client.notifications


def test_back_is_typed_in_seconds_ago_and_the_log_tells_each_restore_and_resume(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    """The Back box took -40 to 0 s: 5, meaning 5 s ago, was clamped to live and the line read
    "-0.0 s back". It takes seconds ago (a minus sign is dropped); the slider stays a timeline, the
    past to the left. Restores and resumes left no line in the event log; each has one, and the
    trail ends at the robot shown."""
    replay, log = dashboard.layout.replay, dashboard.layout.events

    def newest() -> str:
        return html.unescape((log.lines or [""])[0])

    assert wait_until(lambda: dashboard.history.span >= 8.0, timeout=90)
    client.set_gui_value("s back", "5")
    assert wait_until(lambda: replay.scrubbed is not None and dashboard.sim.time == replay.scrubbed.time, timeout=30)
    ring, snap = list(dashboard.history.ring), replay.scrubbed
    # 50 ring entries back from the newest when it was picked, and those the loop added before it
    # applied the pause: as many as the machine's load delays it, so no upper bound.
    assert len(ring) - 1 - ring.index(snap) >= 50
    assert replay.back.value == 5.0 and replay.scrub.value == -5.0
    # The panel writes its line after it asks for the restore, on viser's thread: the loop may restore first.
    assert wait_until(lambda: "(5.0 s back of " in replay.scrub_info.content), replay.scrub_info.content
    assert wait_until(lambda: "restored the moment 5.0 s back" in newest()), newest()
    torso = dashboard.sim.state()
    assert wait_until(lambda: math.dist(dashboard.trail.points[-1], (torso.x, torso.z)) < 0.1)

    client.set_gui_value("s back", "-3")  # as the box took it before: 3 s back
    assert wait_until(lambda: "(3.0 s back of " in replay.scrub_info.content), replay.scrub_info.content
    assert replay.back.value == 3.0 and client.wait_for(lambda p: p.shown_value("s back") == "3")
    client.set_gui_value("s back", "0")
    assert wait_until(lambda: "(0.0 s back of " in replay.scrub_info.content), replay.scrub_info.content
    assert wait_until(lambda: "restored the moment 0.0 s back" in newest()), newest()
    assert "-0.0" not in replay.scrub_info.content + "".join(log.lines)
    client.set_gui_value("Resume from here", True)
    assert wait_until(lambda: "resumed from the moment restored" in newest()), newest()
    assert not bodies(client, "Value clamped"), client.notifications

    client.set_gui_value("Save keyframe", True)
    assert wait_until(lambda: "keyframe 1" in replay.keyframes)
    client.set_gui_value("Restore keyframe", True)  # while running: it goes on at once, no resume line
    assert wait_until(lambda: "restored keyframe 'keyframe 1'" in newest()), newest()
    later = dashboard.sim.time + 0.5
    assert wait_until(lambda: dashboard.sim.time > later)
    assert "resumed" not in newest()


def test_a_keyframe_saved_or_imported_under_a_taken_name_is_kept_beside_the_first(
    dashboard: Dashboard, client: ProbeClient
) -> None:
    """Save pressed twice under the box's name, or a file imported twice, replaced the first keyframe
    without a word. Both are kept: the second is "name (2)", and the notice says so."""
    replay = dashboard.layout.replay
    client.set_gui_value("Save keyframe", True)
    assert wait_until(lambda: list(replay.keyframes) == ["keyframe 1"])
    first = replay.keyframes["keyframe 1"]
    client.set_gui_value("Save keyframe", True)
    # The selector shows the new one just after the list has it (the panel's lock is not the test's).
    both = ["keyframe 1", "keyframe 1 (2)"]
    assert wait_until(lambda: list(replay.keyframes) == both and replay.choice.value == both[1]), replay.choice.value
    assert replay.keyframes["keyframe 1"] is first
    assert client.wait_for(lambda p: len(bodies(p, "Keyframe saved")) == 2), client.notifications
    assert bodies(client, "Keyframe saved")[1].endswith("('keyframe 1' is taken: both are kept)")
    text = keyframes.to_json(first).encode()
    for _ in range(2):
        replay.import_file(text, None)
    assert list(replay.keyframes)[2:] == ["keyframe 1 (3)", "keyframe 1 (4)"]


@pytest.mark.parametrize(
    "label, refusal",
    [
        ("× real time", "Speed: {!r} is not a number (or Max); kept 1 x"),
        ("s back", "Back: {!r} is not a number; kept 0 s"),
    ],
)
def test_text_in_the_speed_or_back_box_is_refused_and_the_box_shows_the_value_in_use_again(
    dashboard: Dashboard, client: ProbeClient, label: str, refusal: str
) -> None:
    """NaN or abc typed into viser's number box left it blank and sent nothing: no notice, no value.
    The boxes are text now: the server refuses the text, says why, and sends the value in use back."""
    uuid = client.input_uuid(label)
    kept = client.shown_value(label)

    def refills(p: ProbeClient) -> int:
        """How often the page was sent the value in use for the box."""
        return sum(1 for u, update in p.gui_log if u == uuid and update.get("value") == kept)

    for n, text in enumerate(("NaN", "abc"), start=1):
        before = refills(client)
        client.set_gui_value(label, text)
        assert client.wait_for(lambda p, n=n: len(bodies(p, "Value refused")) == n), client.notifications
        assert bodies(client, "Value refused")[-1] == refusal.format(text)
        assert client.wait_for(lambda p, b=before: refills(p) == b + 1), "the page was not sent the value in use"
    assert dashboard.pacer.speed == 1.0 and dashboard.layout.replay.scrubbed is None


def test_the_speed_sliders_marks_read_its_range(dashboard: Dashboard, client: ProbeClient) -> None:
    """The lowest mark read 1 at the left end of a 0.1-64 slider: the marks the page gets start at
    0.1 and end at 64, each reading its own value, in order."""
    slider = client.gui[client.input_uuid("Speed ×")]["props"]
    marks = [(m["value"], m["label"]) for m in slider["_marks"]]
    assert [float(label) for _, label in marks] == [value for value, _ in marks], marks
    assert marks[0][0] == slider["min"] == 0.1 and marks[-1][0] == slider["max"] == 64.0, marks
    assert [v for v, _ in marks] == sorted({v for v, _ in marks}), marks


def test_every_speed_button_is_a_value_the_speed_box_can_show(dashboard: Dashboard) -> None:
    """The ¼× button showed 0.3 in the box: the slider's 0.1 step rounded it. Each finite preset is a
    whole number of steps."""
    slider = dashboard.layout.simulation.speed
    for speed in (s for s in SPEEDS.values() if math.isfinite(s)):
        assert abs(speed / slider.step - round(speed / slider.step)) < 1e-9, (speed, slider.step)
