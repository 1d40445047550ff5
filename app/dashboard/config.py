"""The dashboard's command-line configuration, validated on construction."""

from __future__ import annotations

import dataclasses
import ipaddress
import math
import os
import tempfile
from pathlib import Path
from typing import Literal, get_args

from hopper.app.cli_common import missing_folder
from hopper.app.dashboard.access import AUTO, check_token, generate_token, is_loopback
from hopper.app.dashboard.pacing import MAX, MAX_SPEED, MIN_SPEED

from hopper.config import GRAVITY_PRESETS, MOON_GRAVITY, Gains, InvalidConfig, SimConfig
from hopper.controllers import load_class, with_controller
from hopper.controllers.loading import canonical

_DEFAULT_GAINS = Gains()
MIN_PART_MB = 2.0  # MB: a part starts with ~1.1 MB of terrain and robot meshes
MIN_PART_MIN = 0.05  # min (3 s of simulation)
# The scene's lighting, lightest last (hopper.app.dashboard.scene.configure_lighting). A software
# (GPU-less) WebGL renderer drew the crater scene at 5 frames/s with the environment map and
# shadows, 8.7 without shadows and about 20 with simple, in headless Chromium on a 2-core machine.
Lighting = Literal["full", "no-shadows", "simple"]
LIGHTING: tuple[str, ...] = get_args(Lighting)


@dataclasses.dataclass(frozen=True, kw_only=True)
class DashboardConfig:
    """Live dashboard for the lunar reaction-wheel hopper: simulate in real time and tune it in a browser."""

    host: str = "127.0.0.1"
    """Address to serve on (loopback by default)."""
    port: int = 8080
    """Port to serve on; refused if already in use."""
    seed: int = 0
    """Terrain seed."""
    terrain: Literal["crater", "flat"] = "crater"
    """Terrain kind."""
    sensing: Literal["ideal", "realistic"] = "ideal"
    """What the controller reads: the true pitch, or a simulated IMU's estimate with a motor delay."""
    gravity: float = MOON_GRAVITY
    """m/s^2 at start: one of GRAVITY_PRESETS' (the Gravity control offers those)."""
    kp: float = _DEFAULT_GAINS.kp
    """Wheel PID proportional gain, N m/rad."""
    ki: float = _DEFAULT_GAINS.ki
    """Wheel PID integral gain, N m/(rad s)."""
    kd: float = _DEFAULT_GAINS.kd
    """Wheel PID derivative gain, N m s/rad."""
    speed: float = 1.0
    """Simulation speed, x real time; MAX (inf): as fast as the machine allows."""
    rrd: Path | None = None
    """Record the whole session to this .rrd file from the start."""
    rerun_viewer: Literal["spawn", "serve", "off"] = "off"
    """Stream the recording to a rerun viewer: spawn one, serve one on loopback, or neither."""
    sessions_dir: Path = Path("sessions")
    """Folder for recordings started with the Record button."""
    token: str | None = dataclasses.field(default=None, repr=False)  # never in a repr, hence never in a log
    """Access token every client must present; required off loopback; 'auto' generates one."""
    public_view: bool = False
    """Clients without the token may watch (read-only) instead of being refused."""
    idle_timeout: float = 300.0
    """s without input after which the operator's control passes to a viewer."""
    rrd_max_mb: float | None = None
    """Roll recordings over into numbered parts of about this many MB (1e6 bytes) each."""
    rrd_max_min: float | None = None
    """Roll recordings over into numbered parts of this many minutes of simulation each."""
    rrd_flush_s: float = 1.0
    """Wall seconds between recording flushes: at most this much is lost if the process is killed."""
    controller: str = "pid"
    """The flight's wheel law: pid, lqr, mpc, FILE.py:Class, module:Class or tcp://127.0.0.1:PORT."""
    controller_param: tuple[tuple[str, float], ...] = ()
    """The controller's declared params, (NAME, VALUE) pairs (for pid: kp, ki, kd)."""
    controller_choice: tuple[str, ...] = ()
    """More controllers the Gains tab's selector offers (the built-ins always are)."""
    lighting: Lighting = "full"
    """The scene's lighting: simple (no environment light, no shadows) for browsers without a GPU."""
    model: str | None = None
    """A user's MJCF of the robot (absolute path; README: Your own model), or None: the packaged one."""

    def __post_init__(self) -> None:
        try:
            ipaddress.ip_address(self.host)
        except ValueError:
            if self.host != "localhost":
                raise InvalidConfig(f"host must be an IP address or 'localhost', got {self.host!r}") from None
        if self.token == AUTO:
            object.__setattr__(self, "token", generate_token())  # frozen: settled once, here
        if self.token is not None:
            check_token(self.token)
        elif not is_loopback(self.host):
            raise InvalidConfig(
                f"serving on {self.host}, which is not a loopback address, needs an access token: "
                "add --token auto (or --token TOKEN)"
            )
        if self.public_view and self.token is None:
            raise InvalidConfig("--public-view needs --token: without a token every client may already operate")
        if not (isinstance(self.idle_timeout, (int, float)) and 0 < self.idle_timeout < float("inf")):
            raise InvalidConfig(f"idle-timeout must be a positive number of seconds, got {self.idle_timeout!r}")
        if not isinstance(self.port, int) or not 1 <= self.port <= 65535:
            raise InvalidConfig(f"port must be an integer in [1, 65535], got {self.port!r}")
        if self.lighting not in LIGHTING:
            raise InvalidConfig(f"lighting must be one of {', '.join(LIGHTING)}, got {self.lighting!r}")
        if not (self.speed == MAX or MIN_SPEED <= self.speed <= MAX_SPEED):
            raise InvalidConfig(
                f"speed must be in [{MIN_SPEED:g}, {MAX_SPEED:g}] x real time, or max, got {self.speed!r}"
            )
        if self.gravity not in GRAVITY_PRESETS.values():
            presets = ", ".join(f"{name} {g:g}" for name, g in GRAVITY_PRESETS.items())
            raise InvalidConfig(f"gravity must be one of the presets ({presets} m/s^2), got {self.gravity!r}")
        self.sim_config()  # validates seed, terrain and gains with the core's own messages
        object.__setattr__(self, "controller_choice", tuple(canonical(c) for c in self.controller_choice))
        for spec in self.controller_choice:
            load_class(spec)  # ControllerError naming what is wrong with it
        if self.rrd is not None and self.rrd.suffix != ".rrd":
            raise InvalidConfig(f"--rrd must name a .rrd file, got {str(self.rrd)!r}")
        if self.rrd_max_mb is not None and not MIN_PART_MB <= self.rrd_max_mb < math.inf:
            raise InvalidConfig(f"--rrd-max-mb must be at least {MIN_PART_MB:g} MB, got {self.rrd_max_mb!r}")
        if self.rrd_max_min is not None and not MIN_PART_MIN <= self.rrd_max_min < math.inf:
            raise InvalidConfig(f"--rrd-max-min must be at least {MIN_PART_MIN:g} min, got {self.rrd_max_min!r}")
        if not 0.05 <= self.rrd_flush_s <= 60:
            raise InvalidConfig(f"--rrd-flush-s must be in [0.05, 60] s, got {self.rrd_flush_s!r}")
        if self.rolls_over and self.rerun_viewer != "off":
            raise InvalidConfig("--rrd-max-mb and --rrd-max-min cannot be combined with --rerun-viewer")
        if self.sessions_dir.exists() and not self.sessions_dir.is_dir():
            raise InvalidConfig(f"sessions-dir {str(self.sessions_dir)!r} exists and is not a folder")

    @property
    def rolls_over(self) -> bool:
        return self.rrd_max_mb is not None or self.rrd_max_min is not None

    @property
    def gains(self) -> Gains:
        return Gains(kp=self.kp, ki=self.ki, kd=self.kd)

    def sim_config(self) -> SimConfig:
        """The simulation this dashboard starts with."""
        config = SimConfig(
            seed=self.seed,
            terrain=self.terrain,
            gains=self.gains,
            sensing=self.sensing,
            gravity=self.gravity,
            model=self.model,
        )
        return with_controller(config, self.controller, self.controller_param)


def check_sessions_dir(folder: Path) -> Path:
    """`folder`, made if missing and proven writable by a probe file; InvalidConfig in one line if not.

    Only the last folder is made, in one that exists, as every output of hopper-sim (cli_common.
    missing_folder): a mistyped parent is refused, never created. Checked at start-up so that a bad
    folder fails there, not at the first press of Record. The probe is really written: permission
    bits say little for root, /proc or read-only mounts. `~` is expanded, as the Record button does.
    """
    path = folder.expanduser()
    missing = missing_folder(path)
    if missing:
        raise InvalidConfig(f"cannot use sessions folder {str(folder)!r}: {missing}")
    try:
        path.mkdir(exist_ok=True)
        handle, probe = tempfile.mkstemp(prefix=".hopper-probe-", dir=path)
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        raise InvalidConfig(f"cannot use sessions folder {str(folder)!r}: {exc.strerror or exc}") from None
    return folder
