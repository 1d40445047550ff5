"""Build the MuJoCo model from config: gravity, timestep, terrain, and the wheel switch."""

from __future__ import annotations

from importlib import resources

import mujoco
import numpy as np

from hopper import terrain
from hopper.config import SimConfig

MODEL_XML = resources.files("hopper.models") / "hopper.xml"  # models/hopper.xml, installed or not
WHEEL_ACTUATOR_GROUP = 1  # models/hopper.xml: disabling this group turns the wheel off


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
