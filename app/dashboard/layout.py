"""Where the panels go: controls docked right, live plots, hops and events docked left."""

from __future__ import annotations

import dataclasses

import viser
from hopper.app.dashboard import assets
from hopper.app.dashboard.panels import PanelContext
from hopper.app.dashboard.panels.analysis import AnalysisPanel, build_analysis_panel
from hopper.app.dashboard.panels.controller import ControllerPanel, build_controller_panel
from hopper.app.dashboard.panels.disturbances import DisturbancesPanel, build_disturbances_panel
from hopper.app.dashboard.panels.events import EventLog, build_event_log
from hopper.app.dashboard.panels.gains import GainsPanel, build_gains_panel
from hopper.app.dashboard.panels.help import build_help_button
from hopper.app.dashboard.panels.hops import HopTable, build_hop_table
from hopper.app.dashboard.panels.logreplay import LogReplayPanel, build_logreplay_panel
from hopper.app.dashboard.panels.record import RecordPanel, build_record_panel
from hopper.app.dashboard.panels.replay import ReplayHost, ReplayPanel, build_replay_panel
from hopper.app.dashboard.panels.simulation import SimulationPanel, build_simulation_panel
from hopper.app.dashboard.panels.stand import StandPanel, build_stand_panel
from hopper.app.dashboard.panels.status import StatusPanel, build_status_panel
from hopper.app.dashboard.panels.terrain import TerrainPanel, build_terrain_panel
from hopper.app.dashboard.panels.view import ViewPanel, build_view_panel
from hopper.app.dashboard.physics import PhysicsView
from hopper.app.dashboard.plots import LivePlots, LogReplayPlots, ReflyPlots
from hopper.app.dashboard.recording import Recorder
from hopper.app.dashboard.scene import CameraFollow, GhostRobot, RobotView, Trail

from hopper.config import Gains, GaitParams
from hopper.robot import PACKAGED, Robot


@dataclasses.dataclass
class Layout:
    """Every panel's handles, for the loop to update and for tests to drive."""

    status: StatusPanel
    simulation: SimulationPanel
    gains: GainsPanel
    analysis: AnalysisPanel
    disturbances: DisturbancesPanel
    terrain: TerrainPanel
    view: ViewPanel
    record: RecordPanel
    plots: LivePlots
    hops: HopTable
    events: EventLog
    control: viser.GuiFolderHandle  # each client's own role widgets go in here (app/dashboard/roles.py)
    viewer_safe: tuple[viser.GuiButtonHandle, ...]  # inputs a viewer may use: they change nothing shared
    replay: ReplayPanel | None = None  # re-fly, history scrubber, keyframes
    controller: ControllerPanel | None = None  # which law flies the wheel, its params
    logreplay: LogReplayPanel | None = None  # a log replayed beside the simulation
    stand: StandPanel | None = None  # hop, or the test stand (World tab)


def configure_theme(server: viser.ViserServer) -> None:
    """Colours from static/theme.json; the stylesheet rides along in an invisible HTML element."""
    theme = assets.theme()
    server.gui.configure_theme(
        dark_mode=theme.dark_mode,
        brand_color=theme.brand_color,
        control_width=theme.control_width,  # type: ignore[arg-type]
        show_logo=False,
        show_share_button=False,
    )
    server.gui.set_panel_label(None)


def build_layout(
    server: viser.ViserServer,
    ctx: PanelContext,
    *,
    gains: Gains,
    sensing: bool,
    seed: int,
    terrain: str,
    gravity: float,
    speed: float,
    recorder: Recorder,
    camera: CameraFollow,
    trail: Trail,
    robot: RobotView,
    replay_host: ReplayHost | None = None,
    ghost: GhostRobot | None = None,
    physics: PhysicsView | None = None,
    controller: str = "pid",
    controller_choices: tuple[str, ...] = (),
    flown: Robot = PACKAGED,
    gait: GaitParams | None = None,  # the flown gait (None: the default one)
    lighting: str = "full",
) -> Layout:
    configure_theme(server)
    gui, theme = server.gui, assets.theme()
    gui.add_html(f"<style>{assets.stylesheet()}</style>")
    gui.add_html(f"<div class='hd-logo'><img src='{assets.logo_data_uri()}' alt='lunar hopper' height='44'></div>")
    status = build_status_panel(server)
    control = gui.add_folder("Control")
    with gui.add_folder("Simulation"):
        simulation = build_simulation_panel(gui, ctx, speed)
    tabs = gui.add_tab_group()
    with tabs.add_tab("Gains", viser.Icon.ADJUSTMENTS):
        controller_panel = build_controller_panel(gui, ctx, controller, controller_choices)
        gains_panel = build_gains_panel(gui, ctx, gains, sensing=sensing)
        controller_panel.pid_handles = (
            *gains_panel.sliders.values(),
            *(e.handle for e in gains_panel.entries.values()),
        )
        controller_panel.pid_handles += (gains_panel.reset_button,)
        analysis = build_analysis_panel(
            gui, gains, lambda g, source: gains_panel.apply(source=source, kp=g.kp, ki=g.ki, kd=g.kd), flown
        )
    with tabs.add_tab("Disturb", viser.Icon.BOLT):
        disturbances = build_disturbances_panel(gui, ctx)
    with tabs.add_tab("World", viser.Icon.PLANET):
        terrain_panel = build_terrain_panel(gui, ctx, seed, terrain, gravity, flown, gait)
        with gui.add_folder("Test stand"):
            stand = build_stand_panel(gui, ctx)
        view = build_view_panel(gui, server.scene, camera, trail, robot, physics, lighting)
    with tabs.add_tab("Record", viser.Icon.PLAYER_RECORD):
        record = build_record_panel(gui, recorder)
    replay = logreplay = None
    if replay_host is not None and ghost is not None:
        with tabs.add_tab("Replay", viser.Icon.HISTORY):
            replay = build_replay_panel(gui, ctx, replay_host, None, ghost)
            logreplay = build_logreplay_panel(gui, server.scene, replay_host)
    help_button = build_help_button(gui, assets.help_markdown())
    server.gui.main_panel.dock_right()
    server.gui.main_panel.set_width(theme.right_panel_width)

    live = gui.add_panel()
    with live.add_tab("Live", viser.Icon.CHART_LINE):
        plots = LivePlots(server, flown)
        with gui.add_folder("Hops"):
            hops = build_hop_table(gui)
        with gui.add_folder("Events"):
            events = build_event_log(gui)
        if replay is not None:
            with gui.add_folder("Re-fly: before / after"):
                replay.plots = ReflyPlots(gui)
        if logreplay is not None:
            with gui.add_folder("Log replay: simulated − logged"):
                logreplay.plots = LogReplayPlots(gui)
    live.dock_left()
    live.set_width(theme.left_panel_width)
    return Layout(
        status,
        simulation,
        gains_panel,
        analysis,
        disturbances,
        terrain_panel,
        view,
        record,
        plots,
        hops,
        events,
        control=control,
        viewer_safe=(help_button, view.home),
        replay=replay,
        controller=controller_panel,
        logreplay=logreplay,
        stand=stand,
    )
