"""Build the MuJoCo model from config: gravity, timestep, terrain, and the wheel switch."""

from __future__ import annotations

import math
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from hopper import terrain
from hopper.config import SimConfig
from hopper.errors import ModelError
from hopper.layout import check_names
from hopper.robot import WHEEL_ACTUATOR_GROUP, Robot

MODEL_XML = resources.files("hopper.models") / "hopper.xml"  # models/hopper.xml, installed or not
MJCF_SUFFIX = ".xml"  # the one MjSpec.from_file reads (MuJoCo 4: not .XML, .mjcf nor none; from_xml_path reads any)


def terrain_window(config: SimConfig) -> terrain.Window:
    """The config's endless terrain (seeded, so repeatable), its window at the start."""
    params = config.craters
    field = terrain.FlatField(params) if config.terrain == "flat" else terrain.CraterField(params, config.seed)
    return terrain.Window(field, params)


def terrain_heights(config: SimConfig) -> np.ndarray:
    """The config's terrain under the start window in metres, shape (nrow, ncol)."""
    return terrain_window(config).heights


Derive = Callable[[mujoco.MjSpec], None]  # edits the model's spec before it compiles (hopper.stand)


def build_model(
    config: SimConfig, window: terrain.Window | None = None, derive: Derive | None = None
) -> mujoco.MjModel:
    """Compile models/hopper.xml with the config's gravity, timestep and terrain (`window`, by
    default the start window of the config's), edited by `derive` if given: a variant of the robot
    (the test stand) is derived from the one model, not kept as a second XML."""
    if window is None:
        window = terrain_window(config)
    spec = model_spec(config)
    params = config.craters
    field = spec.hfield("terrain")
    field.nrow, field.ncol = window.heights.shape
    data, elevation, offset = terrain.to_hfield(window.heights, window.field.vertical_range)
    # Base depth under the lowest point only matters for rendering; keep it a thin slab.
    field.size = [params.length / 2, params.width / 2, elevation, 0.1]
    field.userdata = data.ravel().tolist()
    geom = spec.geom("terrain")
    geom.pos = [window.x0 + params.length / 2, 0.0, offset]
    spec.option.gravity = [0.0, 0.0, -config.gravity]
    spec.option.timestep = config.timestep
    if derive is not None:
        derive(spec)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise ModelError(f"model {model_source(config)}: {_one_line(exc)}") from None
    set_terrain(model, window)  # the compiler rescales hfield data to span [0, 1]; the field's scale is fixed
    set_wheel_enabled(model, config.wheel)
    return model


def robot_of(config: SimConfig) -> Robot:
    """The robot of the config's model, as built (ModelError in one line if the product cannot fly it)."""
    return Robot.of(build_model(config), model_source(config))


def model_source(config: SimConfig) -> str:
    """How messages name the config's model: its path, or models/hopper.xml."""
    return config.model if config.model is not None else "models/hopper.xml"


def model_spec(config: SimConfig) -> mujoco.MjSpec:
    """The config's MJCF as an MjSpec, its names checked (layout.NAMES); ModelError in one line for
    a file not found, not MJCF, or missing a name the product needs."""
    if config.model is None:
        spec = mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))
        check_names(spec, model_source(config))
        return spec
    path = Path(config.model)
    if not path.is_file():
        raise ModelError(f"model {config.model}: no such file")
    if path.suffix != MJCF_SUFFIX:  # MjSpec.from_file picks its decoder by the name alone
        raise ModelError(
            f"model {config.model}: MuJoCo reads an MJCF file only if its name ends in {MJCF_SUFFIX}: rename it"
        )
    try:  # from_file: includes, meshes and textures resolve next to the file
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise ModelError(f"model {config.model}: not a valid MJCF file ({_one_line(exc)})") from None
    check_names(spec, config.model)
    return spec


def _one_line(exc: Exception) -> str:
    """MuJoCo's parser errors span lines: one line of them."""
    return " ".join(str(exc).split())


def set_terrain(model: mujoco.MjModel, window: terrain.Window) -> None:
    """Write the window into a compiled model's heightfield in place (same grid shape) and move the
    terrain geom under it, with the bounds the compiler derives from them: a new terrain, or the
    window moved along its field.

    The terrain geom's size, bounding sphere and boxes follow its elevation; left at the old
    terrain's, a higher new terrain could be missed by the broad phase. These are MuJoCo's compile
    rules for an hfield geom (size z = size[2]/4 + base/2; box from -base to size[2]); the tests
    check the swapped model against a freshly compiled one, array by array. The field's scale is
    fixed (its vertical_range), so a moved window's float32 data decode to the same heights.
    """
    hid = model.hfield("terrain").id
    nrow, ncol = model.hfield_nrow[hid], model.hfield_ncol[hid]
    if window.heights.shape != (nrow, ncol):
        raise ValueError(f"terrain shape {window.heights.shape} does not match the model's ({nrow}, {ncol})")
    data, elevation, offset = terrain.to_hfield(window.heights, window.field.vertical_range)
    adr = model.hfield_adr[hid]
    model.hfield_data[adr : adr + nrow * ncol] = data.ravel()
    model.hfield_size[hid, 2] = elevation
    geom = model.geom("terrain").id
    sx = model.hfield_size[hid, 0]
    model.geom_pos[geom] = (window.x0 + sx, 0.0, offset)
    if model.geom_sameframe[geom] == mujoco.mjtSameFrame.mjSAMEFRAME_BODY:  # compiled at the origin
        model.geom_sameframe[geom] = mujoco.mjtSameFrame.mjSAMEFRAME_BODYROT  # or kinematics ignores geom_pos
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
