"""Ticks back to back in compiled code: the control kernel and MuJoCo's mj_step with no Python between.

A Python tick costs the kernel's dispatch (~1.2 us for its five arrays), the step wrapper and
mj_step's binding (~1.5 us together), about a tenth of a bare mj_step. `burst` runs the same two
calls in a compiled loop (hopper.mujoco_compat: libmujoco's own mj_step) while nothing in Python is
due, and hands the tick that needs Python back to hopper.sim. It holds no GIL: a front end's
threads run beside it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from hopper.control import KERNEL_SOURCES, drop_stale_compiled
from hopper.control.kernel import control_tick
from hopper.mujoco_compat import MJ_STEP

# _burst inlines the control kernel: its cache is stale when any of the kernel's sources changed,
# though numba would reload it while this file is unchanged.
_HERE = Path(__file__)
drop_stale_compiled((*KERNEL_SOURCES, _HERE), _HERE.parent / "__pycache__", "stepping.*.nb[ic]", "numba-stepping.sha1")


@intrinsic
def _call(typingctx, function, model, data):  # noqa: ANN001, ANN202 (numba's typing)
    """Call the C function `void f(void*, void*)` at address `function` on the addresses `model`, `data`.

    The address comes in as an argument, not a global, so that numba can cache what calls it.
    """

    def codegen(context, builder, signature, args):  # noqa: ANN001, ANN202
        pointer = ir.IntType(8).as_pointer()
        kind = ir.FunctionType(ir.VoidType(), [pointer, pointer])
        target = builder.inttoptr(args[0], kind.as_pointer())
        builder.call(target, [builder.inttoptr(args[1], pointer), builder.inttoptr(args[2], pointer)])
        return context.get_dummy_value()

    return types.void(function, model, data), codegen


@njit(nogil=True, cache=True)
def _burst(
    ticks: int,
    before: float,
    after: float,
    qpos: np.ndarray,
    qvel: np.ndarray,
    sensors: np.ndarray,
    ctrl: np.ndarray,
    mem: np.ndarray,
    step: int,
    model: int,
    data: int,
    pitch: np.ndarray,
    torque: np.ndarray,
    count: np.ndarray,
    q_pitch: int,
    s_torque: int,
) -> tuple[int, int]:
    m = mem[0]
    for i in range(ticks):
        if m.clock >= before or m.clock + m.dt >= after:
            return i, 0
        events = control_tick(qpos, qvel, sensors, ctrl, mem)
        if events:
            return i, events
        _call(step, model, data)
        if q_pitch >= 0:  # a flight recorded (hopper.history): what its tick() would have stored
            n = count[0]
            if n < len(pitch):
                pitch[n], torque[n] = qpos[q_pitch], sensors[s_torque]
                count[0] = n + 1
    return ticks, 0


def burst(
    count: int,
    before: float,
    after: float,
    arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    model: int,
    data: int,
    trace: tuple[np.ndarray, np.ndarray, np.ndarray, int, int] | None = None,
) -> tuple[int, int]:
    """Step up to `count` ticks: (ticks stepped, the EV_* bits of the kernel's run on the next one).

    `arrays` are the kernel's (qpos, qvel, sensordata, ctrl, memory), `model` and `data` the
    structs' addresses (hopper.mujoco_compat.address). It stops before a tick that Python must take
    part in: one that starts at or after `before` (s, a pending action's time, compared as
    hopper.sim compares data.time), that ends at or after `after` (s, when a listener wants the
    tick), or whose kernel run reports events: that tick's kernel has run (its bits are returned,
    nonzero), its mj_step has not. The kernel's clock is data.time exactly (it adds the same
    timestep the same way). With `trace` (pitch, torque, count, q index, s index: History.flight_trace)
    each tick appends qpos[q index] and sensordata[s index] after its step, at most len(pitch).
    """
    return _burst(count, before, after, *arrays, MJ_STEP, model, data, *(trace or NO_TRACE))


NO_TRACE = (np.empty(0), np.empty(0), np.zeros(1, np.int64), -1, -1)
