"""Build the MuJoCo model from config: gravity, timestep, terrain, and the wheel switch."""

from __future__ import annotations

import math
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
    """Hot-swap the heightfield in a compiled model (same grid shape), with the bounds the compiler
    derives from it.

    The terrain geom's size, bounding sphere and boxes follow its elevation; left at the old
    terrain's, a higher new terrain could be missed by the broad phase. These are MuJoCo's compile
    rules for an hfield geom (size z = size[2]/4 + base/2; box from -base to size[2]); the tests
    check the swapped model against a freshly compiled one, array by array.
    """
    hid = model.hfield("terrain").id
    nrow, ncol = model.hfield_nrow[hid], model.hfield_ncol[hid]
    if heights.shape != (nrow, ncol):
        raise ValueError(f"terrain shape {heights.shape} does not match the model's ({nrow}, {ncol})")
    data, elevation, offset = terrain.to_hfield(heights)
    adr = model.hfield_adr[hid]
    model.hfield_data[adr : adr + nrow * ncol] = data.ravel()
    model.hfield_size[hid, 2] = elevation
    geom = model.geom("terrain").id
    model.geom_pos[geom, 2] = offset
    sx, sy, top, base = model.hfield_size[hid]
    model.geom_size[geom] = (sx, sy, 0.25 * top + 0.5 * base)
    model.geom_aabb[geom] = (0.0, 0.0, 0.5 * (top - base), sx, sy, 0.5 * (top + base))
    model.geom_rbound[geom] = math.sqrt(sx * sx + sy * sy + max(top, base) ** 2)
    body = model.geom_bodyid[geom]
    if model.body_bvhnum[body] != 1:  # the world body holds more than the terrain: not this model
        raise ValueError("set_terrain expects the terrain to be the world body's only geom")
    aabb = model.geom_aabb[geom]
    model.bvh_aabb[model.body_bvhadr[body]] = (*(model.geom_pos[geom] + aabb[:3]), *aabb[3:])


def set_wheel_enabled(model: mujoco.MjModel, enabled: bool) -> None:
    """Wheel off disables the wheel's actuator group: zero torque, the wheel spins freely."""
    bit = 1 << WHEEL_ACTUATOR_GROUP
    model.opt.disableactuator = (model.opt.disableactuator & ~bit) | (0 if enabled else bit)
