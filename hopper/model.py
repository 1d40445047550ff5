"""Build the MuJoCo model from config, and the named accessors the controller reads."""

from __future__ import annotations

from importlib import resources

import mujoco
import numpy as np

from hopper import terrain
from hopper.config import SimConfig

MODEL_XML = resources.files("hopper.models") / "hopper.xml"  # models/hopper.xml, installed or not
WHEEL_ACTUATOR_GROUP = 1  # models/hopper.xml: disabling this group turns the wheel off
LEG_JOINTS = ("hip_L", "knee_L", "hip_R", "knee_R")
# Named indices into qpos and qvel (nq == nv here) and sensordata; Physics checks the layout.
Q_X, Q_Z, Q_PITCH, Q_WHEEL, Q_HIP_L, Q_KNEE_L, Q_HIP_R, Q_KNEE_R = range(8)
S_PITCH, S_GYRO_X, S_GYRO_Y, S_GYRO_Z, S_WHEEL_SPEED, S_FOOT_L, S_FOOT_R, S_WHEEL_TORQUE = range(8)


def terrain_heights(config: SimConfig) -> np.ndarray:
    """The config's terrain in metres, shape (nrow, ncol); seeded, so repeatable."""
    if config.terrain == "flat":
        return terrain.flat(config.craters)
    return terrain.generate(config.craters, np.random.default_rng(config.seed))


def build_model(config: SimConfig, heights: np.ndarray | None = None) -> mujoco.MjModel:
    """Compile models/hopper.xml with the config's gravity, timestep and terrain."""
    if heights is None:
        heights = terrain_heights(config)
    spec = mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))
    params = config.craters
    field = spec.hfield("terrain")
    field.nrow, field.ncol = heights.shape
    data, elevation, offset = terrain.to_hfield(heights)
    # Base depth under the lowest point only matters for rendering; keep it a thin slab.
    field.size = [params.length / 2, params.width / 2, elevation, 0.1]
    field.userdata = data.ravel().tolist()
    geom = spec.geom("terrain")
    geom.pos = [params.x0 + params.length / 2, 0.0, offset]
    spec.option.gravity = [0.0, 0.0, -config.gravity]
    spec.option.timestep = config.timestep
    model = spec.compile()
    set_wheel_enabled(model, config.wheel)
    return model


def set_terrain(model: mujoco.MjModel, heights: np.ndarray) -> None:
    """Hot-swap the heightfield in a compiled model (same grid shape)."""
    hid = model.hfield("terrain").id
    nrow, ncol = model.hfield_nrow[hid], model.hfield_ncol[hid]
    if heights.shape != (nrow, ncol):
        raise ValueError(f"terrain shape {heights.shape} does not match the model's ({nrow}, {ncol})")
    data, elevation, offset = terrain.to_hfield(heights)
    adr = model.hfield_adr[hid]
    model.hfield_data[adr : adr + nrow * ncol] = data.ravel()
    model.hfield_size[hid, 2] = elevation
    model.geom_pos[model.geom("terrain").id, 2] = offset


def set_wheel_enabled(model: mujoco.MjModel, enabled: bool) -> None:
    """Wheel off disables the wheel's actuator group: zero torque, the wheel spins freely."""
    bit = 1 << WHEEL_ACTUATOR_GROUP
    model.opt.disableactuator = (model.opt.disableactuator & ~bit) | (0 if enabled else bit)


class Physics:
    """Named, cheap reads of the robot's state; `refresh()` once per control tick.

    Plain float attributes (read from MuJoCo's arrays in one `tolist()` each) so a 1 kHz
    controller in Python pays for a few list reads, not dozens of numpy scalar lookups.
    """

    # The model's coordinate and sensor layout, checked against models/hopper.xml at construction,
    # so that refresh() can unpack whole arrays instead of indexing them one by one.
    QPOS = ("root_x", "root_z", "pitch", "wheel", "hip_L", "knee_L", "hip_R", "knee_R")
    SENSORS = ("imu_pitch", "imu_gyro", "wheel_speed", "foot_L", "foot_R", "wheel_torque")

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.model, self.data = model, data
        if [model.joint(n).qposadr[0] for n in self.QPOS] != list(range(8)) or model.nv != 8:
            raise ValueError("models/hopper.xml: joints must be ordered as Physics.QPOS")
        if [model.sensor(n).adr[0] for n in self.SENSORS] != [0, 1, 4, 5, 6, 7]:
            raise ValueError("models/hopper.xml: sensors must be ordered as Physics.SENSORS")
        self.wheel_gear = float(model.actuator("wheel").gear[0])
        # Slide joints measure from the torso's pose in the XML; add it back for world x, z.
        self._x0, _, self._z0 = model.body("torso").pos.tolist()
        # MjData's array properties build a new numpy view on every access (~1 us each): keep them.
        self._qpos, self._qvel, self._sensors = data.qpos, data.qvel, data.sensordata
        self.refresh()

    def refresh(self) -> None:
        """Copy the current state into named attributes (SI units, angles in rad)."""
        self.time: float = self.data.time
        x, z, self.pitch, self.wheel_angle, self.hip_L, self.knee_L, self.hip_R, self.knee_R = self._qpos.tolist()
        self.x, self.z = x + self._x0, z + self._z0  # torso CoM, world frame
        (
            self.vx,
            self.vz,
            _,
            self.wheel_speed,  # wheel angle and speed are relative to the torso
            self.hip_L_rate,
            self.knee_L_rate,
            self.hip_R_rate,
            self.knee_R_rate,
        ) = self._qvel.tolist()
        # IMU pitch rate is the gyro's body-y axis; foot forces are touch-sensor normal forces (N).
        _, _, self.pitch_rate, _, _, self.foot_force_L, self.foot_force_R, torque = self._sensors.tolist()
        self.wheel_torque = torque * self.wheel_gear  # N m at the wheel, as applied

    def angular_momentum(self) -> float:
        """Total pitch angular momentum about the whole robot's CoM (kg m^2/s)."""
        mujoco.mj_subtreeVel(self.model, self.data)
        return float(self.data.subtree_angmom[self.model.body("torso").id, 1])
