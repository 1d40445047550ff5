"""Lunar reaction-wheel hopper: model, controller, phases, metrics and telemetry (no UI)."""

import os

# Nothing here renders through MuJoCo's OpenGL (the scene is viser's, in the browser), yet on Linux
# `import mujoco` loads glfw, which probes its library in a Python subprocess: 0.1 s per process,
# and a pool worker stopped during its import left that probe behind to print a BrokenPipeError
# into the command's stderr after a clean Ctrl-C. Who sets MUJOCO_GL (egl, osmesa) keeps it.
os.environ.setdefault("MUJOCO_GL", "disable")
