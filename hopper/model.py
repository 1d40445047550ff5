"""Build the MuJoCo model from config, and the named accessors the controller reads."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

import terrain
from hopper.config import SimConfig

MODEL_PATH = Path(__file__).resolve().parent.parent / "models" / "hopper.xml"
WHEEL_ACTUATOR_GROUP = 1  # models/hopper.xml: disabling this group turns the wheel off
LEG_JOINTS = ("hip_L", "knee_L", "hip_R", "knee_R")


def terrain_heights(config: SimConfig) -> np.ndarray:
    """The config's terrain in metres, shape (nrow, ncol); seeded, so repeatable."""
    if config.terrain == "flat":
        return terrain.flat(config.craters)
    return terrain.generate(config.craters, np.random.default_rng(config.seed))


def build_model(config: SimConfig, heights: np.ndarray | None = None) -> mujoco.MjModel:
    """Compile models/hopper.xml with the config's gravity, timestep and terrain."""
    if heights is None:
        heights = terrain_heights(config)
    spec = mujoco.MjSpec.from_file(str(MODEL_PATH))
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

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.model, self.data = model, data
        self._qpos = {n: model.joint(n).qposadr[0] for n in ("root_x", "root_z", "pitch", "wheel", *LEG_JOINTS)}
        self._qvel = {n: model.joint(n).dofadr[0] for n in self._qpos}
        self._sensor = {n: model.sensor(n).adr[0] for n in ("foot_L", "foot_R", "imu_gyro", "wheel_torque")}
        self.wheel_gear = float(model.actuator("wheel").gear[0])
        # Slide joints measure from the torso's pose in the XML; add it back for world x, z.
        self._x0, _, self._z0 = model.body("torso").pos.tolist()
        self.refresh()

    def refresh(self) -> None:
        """Copy the current state into named attributes (SI units, angles in rad)."""
        q, v, s = self.data.qpos.tolist(), self.data.qvel.tolist(), self.data.sensordata.tolist()
        a, b, c = self._qpos, self._qvel, self._sensor
        self.time: float = self.data.time
        self.x, self.z = q[a["root_x"]] + self._x0, q[a["root_z"]] + self._z0  # torso CoM, world
        self.pitch = q[a["pitch"]]
        self.vx, self.vz = v[b["root_x"]], v[b["root_z"]]
        self.pitch_rate: float = s[c["imu_gyro"] + 1]  # IMU gyro, body y axis
        self.wheel_angle, self.wheel_speed = q[a["wheel"]], v[b["wheel"]]  # relative to the torso
        self.hip_L, self.knee_L = q[a["hip_L"]], q[a["knee_L"]]
        self.hip_R, self.knee_R = q[a["hip_R"]], q[a["knee_R"]]
        self.hip_L_rate, self.knee_L_rate = v[b["hip_L"]], v[b["knee_L"]]
        self.hip_R_rate, self.knee_R_rate = v[b["hip_R"]], v[b["knee_R"]]
        self.foot_force_L, self.foot_force_R = s[c["foot_L"]], s[c["foot_R"]]  # N, normal
        self.wheel_torque: float = s[c["wheel_torque"]] * self.wheel_gear  # N m at the wheel, applied

    def angular_momentum(self) -> float:
        """Total pitch angular momentum about the whole robot's CoM (kg m^2/s)."""
        mujoco.mj_subtreeVel(self.model, self.data)
        return float(self.data.subtree_angmom[self.model.body("torso").id, 1])

    def leg_torques(self) -> tuple[float, float, float, float]:
        """Applied leg joint torques (hip_L, knee_L, hip_R, knee_R), N m."""
        f = self.data.actuator_force
        return tuple(float(f[self.model.actuator(n).id]) for n in LEG_JOINTS)  # type: ignore[return-value]
