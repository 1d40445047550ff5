"""Configuration dataclasses, validated on construction, with units and sources."""

from __future__ import annotations

import dataclasses
import math
from typing import Literal, NamedTuple

from hopper.errors import HopperError
from hopper.terrain import CraterParams

MOON_GRAVITY = 1.625  # m/s^2, paper Table I
GRAVITY_PRESETS: dict[str, float] = {  # m/s^2, PHYSICS.md
    "moon": MOON_GRAVITY,
    "mars": 3.72,
    "ceres": 0.28,
    "earth": 9.81,
}
GRAVITY_LIMITS = (0.05, 30.0)  # m/s^2, the gravities a simulation accepts (every front end checks against these)
TIMESTEP = 0.001  # s, 1 kHz physics and control, paper Table I

# The packaged robot's constants (they mirror models/hopper.xml). What flies reads them from the model
# it flies (hopper.robot.Robot.of, equal to these for the packaged one); hopper.robot.PACKAGED holds them.
TOTAL_MASS = 8.2  # kg, Table I
WHEEL_INERTIA = 0.03375  # kg m^2, 3 kg disc of radius 0.15 m
WHEEL_ARMATURE = 0.0045  # kg m^2, reflected rotor inertia N^2 J_m (models/hopper.xml): adds to the spin
WHEEL_GEAR = 30.0  # Table I
WHEEL_TORQUE_LIMIT = 29.5  # N m at the wheel, Table I
WHEEL_NO_LOAD_SPEED = 400 * 2 * math.pi / 60  # rad/s at the wheel (12000 rpm motor / 30), ours
LEG_TORQUE_LIMIT = 30.0  # N m per leg joint, ours (models/hopper.xml)
THIGH_LENGTH = 0.5  # m, Table I
SHANK_LENGTH = 0.5  # m, Table I
HIP_OFFSET_Z = -0.18  # m, hips below the torso CoM (models/hopper.xml)
FOOT_RADIUS = 0.04  # m, Table I
SATURATION_FRACTION = 0.98  # of the torque limit counts as saturated, paper Sec. V-D
STANDARD_GRAVITY = 9.80665  # m/s^2, the "g" of datasheet units (mg, ug), not any body's gravity
MAX_MOTOR_DELAY_TICKS = 16  # length of the kernel's wheel-command delay line (hopper.control.memory)
MAX_SEED = 2**64 - 1  # the IMU's draws are seeded from SimConfig.seed as a uint64 (hopper.control.memory)

# The motors' electrical figures, for their energy (hopper.control.energy); the simulation never reads them.
# The paper gives neither k_t nor R. Every motor is a maxon EC 45 flat, 43.5 mm, brushless, 70 W, 24 V
# winding: torque constant 40.4 mN m/A, terminal resistance 0.573 ohm phase to phase, speed constant
# 236 rpm/V, stall torque 1.69 N m and stall current 42 A at 24 V, rotor inertia 181 g cm^2, max speed
# 10,000 rpm (maxon's catalogue page, data marked provisional, read from a stored copy of it, no web
# access; not checked against maxon's current datasheet). Against the model: the wheel's 0.983 N m
# stall torque is 24.3 A (the drive's current limit; the winding takes 42 A) and its 12,000 rpm no-load
# speed is 50.8 V of back-EMF (a 48 V bus reaches 11,300 rpm). The XML's back-EMF slope, 0.9833 N m over
# 1256.6 rad/s, would be a weaker motor (R / k_t^2 of 1278 against this one's 351 W/(N m)^2): its copper
# losses would be 3.6x these. Iron and friction losses (the no-load current) and the gearbox's are left out.
MOTOR_TORQUE_CONSTANT = 0.0404  # N m/A, EC 45 flat 70 W, 24 V winding (above)
MOTOR_RESISTANCE = 0.573  # ohm, phase to phase, the same winding
# The legs' motors drive their joints through 30:1, as the wheel's does: the XML's leg actuators act
# on the joints directly (gear 1, ctrl in N m), and 30 N m there is 1.0 N m, 24.8 A, at the motor.
LEG_MOTOR_GEAR = 30.0  # joint torque / motor torque, ours
# Whether the drives recover braking energy: False, a motor's negative electrical power (generating,
# when the mechanical power it absorbs exceeds its copper loss) is burnt in its own drive (a brake
# resistor) and counts as zero; True, it is returned to the battery, without loss, and counts negative.
REGENERATIVE_DRIVES = False


# Model mismatch (hopper.mismatch applies it): what each factor scales, x nominal.
MISMATCH_FACTORS = {
    "torso_mass": "the torso's mass and pitch inertia together",
    "wheel_inertia": "the wheel's spin inertia and the motor's reflected rotor inertia",
    "motor_torque": "the wheel motor's torque constant k_t (stall torque x k, back-EMF damping x k^2)",
    "leg_mass": "thighs' and shanks' masses and inertias",
    "friction": "the ground's and the feet's sliding friction",
    # One quantity each (the Monte Carlo's, hopper.experiments.uncertainty), where torso_mass and
    # leg_mass scale a body's mass and inertia together (a denser body).
    "mass_torso": "the torso's mass alone",
    "mass_wheel": "the wheel's mass alone",
    "mass_thigh": "both thighs' masses alone",
    "mass_shank": "both shanks' masses alone",
    "inertia_torso": "the torso's inertia alone (every principal moment)",
    "inertia_thigh": "both thighs' inertias alone",
    "inertia_shank": "both shanks' inertias alone",
}
MISMATCH_RANGE = (0.2, 5.0)  # x nominal
# Offsets of the torso's centre of mass from the wheel axis (its frame's origin), m, added to body_ipos.
MISMATCH_OFFSETS = {
    "com_x": "the torso's centre of mass, forward of the wheel axis (m)",
    "com_z": "the torso's centre of mass, above the wheel axis (m)",
}
COM_OFFSET_LIMIT = 0.18  # m: the torso's box half size (models/hopper.xml), the CoM stays inside it


def check_mismatch(mismatch: tuple[tuple[str, float], ...]) -> tuple[tuple[str, float], ...]:
    """(name, value) pairs: factors (MISMATCH_FACTORS) within MISMATCH_RANGE, offsets (MISMATCH_OFFSETS)
    within +-COM_OFFSET_LIMIT m; InvalidConfig if not."""
    out = []
    for item in mismatch:
        try:
            name, value = str(item[0]), float(item[1])
        except (TypeError, ValueError, IndexError):
            raise InvalidConfig(f"mismatch entries are (name, value) pairs, got {item!r}") from None
        if name in MISMATCH_OFFSETS:
            if not -COM_OFFSET_LIMIT <= value <= COM_OFFSET_LIMIT:
                raise InvalidConfig(f"mismatch {name} = {value:g} m is outside +-{COM_OFFSET_LIMIT:g} m")
        elif name in MISMATCH_FACTORS:
            low, high = MISMATCH_RANGE
            if not low <= value <= high:
                raise InvalidConfig(f"mismatch {name} = {value:g} is outside [{low:g}, {high:g}] x nominal")
        else:
            known = ", ".join((*MISMATCH_FACTORS, *MISMATCH_OFFSETS))
            raise InvalidConfig(f"unknown mismatch {name!r}; choose from {known}")
        out.append((name, value))
    return tuple(out)


class GainRange(NamedTuple):
    """The one allowed range of a flight gain: the core validates it, the CLIs and the dashboard show it."""

    low: float
    high: float
    unit: str


# Wide enough to reach a visibly unstable or saturating loop (PHYSICS.md's LQR range is kp 340 to
# 850, kd 17 to 31), narrow enough for a slider.
GAIN_RANGES: dict[str, GainRange] = {
    "kp": GainRange(0.0, 2000.0, "N m/rad"),
    "ki": GainRange(0.0, 500.0, "N m/(rad s)"),
    "kd": GainRange(0.0, 100.0, "N m s/rad"),
}


class InvalidConfig(HopperError, ValueError):
    """A configuration value outside its allowed range."""


def require_finite(name: str, value: float, low: float = -math.inf, high: float = math.inf, unit: str = "") -> None:
    """Raise InvalidConfig unless low <= value <= high and value is finite."""
    if not isinstance(value, (int, float)) or not math.isfinite(value) or not low <= value <= high:
        u = f" {unit}" if unit else ""
        raise InvalidConfig(f"{name} must be a finite number in [{low:g}, {high:g}]{u}, got {value!r}")


def check_seed(seed: int) -> int:
    """`seed`, or InvalidConfig unless it is an integer in [0, MAX_SEED]."""
    if not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise InvalidConfig(f"seed must be a non-negative integer below 2^64, got {seed!r}")
    return seed


@dataclasses.dataclass(frozen=True, kw_only=True)
class Gains:
    """Flight PID gains for the wheel: torque on the torso = -kp theta - kd theta_dot - ki int theta.

    Defaults place the closed-loop poles at wn = 30 rad/s, zeta = 1 for the effective inertia
    I_locked - I_w ~ 0.5 kg m^2 (PHYSICS.md's LQR range: kp 340 to 850, kd 17 to 31); ki only trims
    model error, as there is no gravity torque in flight.
    """

    kp: float = 450.0  # N m / rad
    ki: float = 50.0  # N m / (rad s)
    kd: float = 30.0  # N m s / rad

    def __post_init__(self) -> None:
        for name, (low, high, unit) in GAIN_RANGES.items():
            require_finite(name, getattr(self, name), low, high, unit)


@dataclasses.dataclass(frozen=True, kw_only=True)
class GaitParams:
    """The hop cycle's targets. Lengths are hip heights above the feet, in metres."""

    apex_height: float = 0.25  # m above the liftoff height; v_z = sqrt(2 g h)
    forward_speed: float = 0.4  # m/s at liftoff on the Moon; sqrt(g) elsewhere (hopper.control.gait)
    stand_height: float = 0.85  # m
    crouch_height: float = 0.68  # m
    push_length: float = 0.96  # m, leg length where the push stops
    flight_length: float = 0.86  # m, leg length held in flight for landing, after the apex
    tuck_length: float = 0.75  # m, leg length while rising, for clearance over rims ahead
    foot_spread: float = 0.36  # m between the feet at landing, a support base for stance pitch
    crouch_lean: float = 0.1  # m, torso CoM ahead of the feet midpoint before the push
    stance_time: float = 0.25  # s, minimum stabilisation time before the crouch
    friction: float = 0.7  # friction coefficient the stance forces assume (model: 0.8)
    # The paper's flight (hopper.scenarios "paper"): right after liftoff both legs swing back from
    # their liftoff angle by sweep_angle in sweep_time (constant speed between short ramps), then
    # forward to the landing pose along a minimum-jerk path in sweep_return_time, their swing servo
    # sweep_stiffness times as fast; the torso takes the reaction. 0 deg: no sweep, the legs tuck
    # while rising (the default).
    sweep_angle: float = 0.0  # deg, world angle of the hip-to-foot line, backward
    sweep_time: float = 0.0  # s
    sweep_return_time: float = 0.0  # s
    sweep_stiffness: float = 1.0  # x the swing servo's natural frequency (hopper.control.legs)

    def __post_init__(self) -> None:
        require_finite("apex_height", self.apex_height, 0.02, 3.0)
        require_finite("forward_speed", self.forward_speed, -2.0, 2.0)
        require_finite("crouch_height", self.crouch_height, 0.45, self.stand_height)
        require_finite("stand_height", self.stand_height, 0.5, 0.98)
        require_finite("push_length", self.push_length, self.stand_height, 0.99)
        require_finite("sweep_angle", self.sweep_angle, 0.0, 60.0, "deg")
        require_finite("sweep_time", self.sweep_time, 0.0, 2.0, "s")
        require_finite("sweep_return_time", self.sweep_return_time, 0.0, 2.0, "s")
        require_finite("sweep_stiffness", self.sweep_stiffness, 0.5, 4.0)


@dataclasses.dataclass(frozen=True, kw_only=True)
class SensingParams:
    """The realistic sensing mode: a MEMS IMU's errors, the attitude estimator's gains, the motor delay.

    IMU figures are a Bosch BMI088's (PHYSICS.md quotes its datasheet); noise densities become
    per-sample standard deviations density / sqrt(dt) at the 1 kHz control rate (gyro 0.44 deg/s,
    accelerometer 0.054 m/s^2 = 3.3 % of lunar g per sample). Draws are seeded by SimConfig.seed.
    """

    # Gyro (pitch axis).
    gyro_noise_density: float = 0.014  # deg/s/sqrt(Hz), BMI088 datasheet (PHYSICS.md)
    # Bias random walk: the bias wanders by the datasheet's 2 deg/h bias stability (5.6e-4 deg/s)
    # in about 100 s, where a MEMS gyro's Allan deviation typically turns from its flat bias-
    # instability floor to rate random walk. Ours; temperature drift is not modelled.
    gyro_bias_walk: float = 5.6e-5  # deg/s/sqrt(s)
    # Turn-on bias, drawn anew at each power-on (reset): magnitude uniform in [0.5, 1] x this,
    # random sign. PHYSICS.md's example (0.5 deg/s drifts 0.6 deg over a lunar flight); the
    # BMI088 datasheet's zero-rate offset spread is of the order of 1 deg/s.
    gyro_turn_on_bias: float = 0.5  # deg/s
    # Known parts of the turn-on biases, added to the seeded draws above: a Monte Carlo sample
    # (hopper.experiments.uncertainty) sets them, with the draws' scales at 0, to fly one IMU exactly.
    gyro_bias_fixed: float = 0.0  # deg/s
    accel_bias_fixed_x: float = 0.0  # mg
    accel_bias_fixed_z: float = 0.0  # mg
    # Accelerometer (x and z axes of the torso).
    accel_noise_density: float = 175.0  # ug/sqrt(Hz), BMI088 datasheet (PHYSICS.md)
    # Residual zero-g offset after a factory/6-position calibration, per axis uniform in [-1, 1] x
    # this. Ours (the untrimmed offset is tens of mg). It is unobservable and tilts the estimated
    # vertical by offset / g: 1 mg is 0.35 deg on the Moon, 2 deg on Ceres.
    accel_bias: float = 1.0  # mg
    # Power-on: the robot stands still this long before a run while the estimator averages the
    # gyro (its bias: the true rate is zero) and the accelerometer (the direction of gravity).
    calibration_time: float = 1.0  # s
    # Attitude estimator (hopper.control.sensing): the gyro integral corrected by the horizontal
    # specific force in the estimated world frame, a PI loop with this natural frequency and
    # damping. Slow on purpose: on the Moon a 0.1 m/s^2 body acceleration looks like a 3.5 deg tilt,
    # and only its long-run average (zero: velocity stays bounded) tells the vertical. A change of
    # speed dv shifts the estimate by 2 zeta wn dv / g: 0.56 deg between stance and flight at 0.4 m/s
    # on the Moon. Measured over 30 hops (100 s): worst error 1.3 deg at 0.02 rad/s, 1.5 at 0.01,
    # and 1.9 deg with no correction at all (the calibration's residual bias drifting).
    tilt_wn: float = 0.02  # rad/s
    tilt_zeta: float = 1.0
    # Wheel command latency: one bus cycle at 1 kHz to get the command to the driver (CAN/EtherCAT
    # frame, sent in the cycle after it is computed), one driver cycle to latch it into the current
    # loop, and ~1 ms for the current (torque) to rise through the winding's L/R. Ours.
    motor_delay_ticks: int = 3  # control ticks (1 ms each at 1 kHz)

    def __post_init__(self) -> None:
        require_finite("gyro_noise_density", self.gyro_noise_density, 0.0, 1.0, "deg/s/sqrt(Hz)")
        require_finite("gyro_bias_walk", self.gyro_bias_walk, 0.0, 0.1, "deg/s/sqrt(s)")
        require_finite("gyro_turn_on_bias", self.gyro_turn_on_bias, 0.0, 10.0, "deg/s")
        require_finite("accel_noise_density", self.accel_noise_density, 0.0, 5000.0, "ug/sqrt(Hz)")
        require_finite("accel_bias", self.accel_bias, 0.0, 100.0, "mg")
        require_finite("gyro_bias_fixed", self.gyro_bias_fixed, -10.0, 10.0, "deg/s")
        require_finite("accel_bias_fixed_x", self.accel_bias_fixed_x, -100.0, 100.0, "mg")
        require_finite("accel_bias_fixed_z", self.accel_bias_fixed_z, -100.0, 100.0, "mg")
        require_finite("calibration_time", self.calibration_time, 0.0, 60.0, "s")
        require_finite("tilt_wn", self.tilt_wn, 0.0, 10.0, "rad/s")
        require_finite("tilt_zeta", self.tilt_zeta, 0.1, 5.0)
        delay = self.motor_delay_ticks
        if not isinstance(delay, int) or isinstance(delay, bool) or not 0 <= delay <= MAX_MOTOR_DELAY_TICKS:
            raise InvalidConfig(
                f"motor_delay_ticks must be an integer in [0, {MAX_MOTOR_DELAY_TICKS}] ticks, got {delay!r}"
            )


@dataclasses.dataclass(frozen=True, kw_only=True)
class SimConfig:
    """Everything that defines one simulation run."""

    seed: int = 0
    terrain: Literal["crater", "flat"] = "crater"
    gravity: float = MOON_GRAVITY  # m/s^2, magnitude
    timestep: float = TIMESTEP  # s
    gains: Gains = dataclasses.field(default_factory=Gains)
    gait: GaitParams = dataclasses.field(default_factory=GaitParams)
    wheel: bool = True  # False: zero wheel torque, wheel free to spin
    craters: CraterParams = dataclasses.field(default_factory=CraterParams)
    # "ideal": the controller reads the true pitch and the noise-free gyro, the wheel acts at once.
    # "realistic": a noisy, biased IMU, an attitude estimate, and a delayed wheel command (sensor).
    sensing: Literal["ideal", "realistic"] = "ideal"
    sensor: SensingParams = dataclasses.field(default_factory=SensingParams)
    # The flight's wheel law (hopper.controllers.loading reads the spec) and its declared params;
    # the PID's params are `gains` (hopper.controllers.law.with_controller).
    controller: str = "pid"
    controller_params: tuple[tuple[str, float], ...] = ()
    # The robot simulated differs from the nominal one by these (name, factor) pairs (hopper.mismatch).
    mismatch: tuple[tuple[str, float], ...] = ()
    # A user's MJCF of the robot (`--model`; hopper.robot reads its constants), or None: the packaged
    # models/hopper.xml. An absolute path, so that workers in other folders find the same file.
    model: str | None = None

    def __post_init__(self) -> None:
        if self.model is not None and (not isinstance(self.model, str) or not self.model.strip()):
            raise InvalidConfig(f"model must be the path of an MJCF file or None, got {self.model!r}")
        if not isinstance(self.controller, str) or not self.controller.strip():
            raise InvalidConfig(f"controller must be a non-empty spec, got {self.controller!r}")
        try:  # JSON gives lists: hold (name, value) tuples so that the config stays hashable
            params = tuple((str(name), float(value)) for name, value in self.controller_params)
        except (TypeError, ValueError):
            raise InvalidConfig(
                f"controller_params must be (name, value) pairs, got {self.controller_params!r}"
            ) from None
        object.__setattr__(self, "controller_params", params)
        object.__setattr__(self, "mismatch", check_mismatch(self.mismatch))
        if self.terrain not in ("crater", "flat"):
            raise InvalidConfig(f"terrain must be 'crater' or 'flat', got {self.terrain!r}")
        if self.sensing not in ("ideal", "realistic"):
            raise InvalidConfig(f"sensing must be 'ideal' or 'realistic', got {self.sensing!r}")
        check_seed(self.seed)
        require_finite("gravity", self.gravity, *GRAVITY_LIMITS, "m/s^2")
        require_finite("timestep", self.timestep, 1e-4, 5e-3)

    @property
    def command_delay_ticks(self) -> int:
        """Ticks (1 ms) from a wheel command to the motor: the sensor's delay line runs under
        realistic sensing only."""
        return self.sensor.motor_delay_ticks if self.sensing == "realistic" else 0


# The unit of each number of a SimConfig, by its dotted name as a report's settings table shows it
# ("" for a pure number); tests/test_report.py checks that every number of SimConfig has one.
SETTING_UNITS: dict[str, str] = {
    "gravity": "m/s^2",
    "timestep": "s",
    "gains.kp": "N m/rad",
    "gains.ki": "N m/(rad s)",
    "gains.kd": "N m s/rad",
    **{f"gait.{name}": "m" for name in ("apex_height", "stand_height", "crouch_height", "push_length")},
    **{f"gait.{name}": "m" for name in ("flight_length", "tuck_length", "foot_spread", "crouch_lean")},
    "gait.forward_speed": "m/s",
    "gait.stance_time": "s",
    "gait.friction": "",
    "gait.sweep_angle": "deg",
    "gait.sweep_time": "s",
    "gait.sweep_return_time": "s",
    "gait.sweep_stiffness": "x the swing servo's natural frequency",
    **{f"craters.{name}": "m" for name in ("length", "width", "x0", "cell", "tile", "diameter_range")},
    **{f"craters.{name}": "m" for name in ("roughness", "roughness_scale", "clear_radius")},
    "craters.density": "craters/m^2",
    "craters.depth_ratio_range": "depth/diameter",
    "craters.rim_ratio_range": "rim height/diameter",
    "sensor.gyro_noise_density": "deg/s/sqrt(Hz)",
    "sensor.gyro_bias_walk": "deg/s/sqrt(s)",
    "sensor.gyro_turn_on_bias": "deg/s",
    "sensor.gyro_bias_fixed": "deg/s",
    "sensor.accel_bias_fixed_x": "mg",
    "sensor.accel_bias_fixed_z": "mg",
    "sensor.accel_noise_density": "ug/sqrt(Hz)",
    "sensor.accel_bias": "mg",
    "sensor.calibration_time": "s",
    "sensor.tilt_wn": "rad/s",
    "sensor.tilt_zeta": "",
    "sensor.motor_delay_ticks": "ticks",
}


def unit_of(key: str) -> str:
    """The unit of a setting by its dotted name ('gains.kp'), or by its last part where that names
    one setting only (a sweep's 'values.kp', a recording's 'kp'); '' if none is known."""
    if key in SETTING_UNITS:
        return SETTING_UNITS[key]
    leaf = key.rpartition(".")[2]
    units = {unit for name, unit in SETTING_UNITS.items() if name.rpartition(".")[2] == leaf}
    return units.pop() if len(units) == 1 else ""
