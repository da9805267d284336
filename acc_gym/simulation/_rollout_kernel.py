"""A world with baseline drivers run for several steps in one compiled call.

:meth:`SingleLaneWorld.coast <acc_gym.simulation.single_lane.SingleLaneWorld.coast>` runs
its world this way when every surrounding driver's decision is one compiled call
(:meth:`SlotDrivers.act_world <acc_gym.drivers.slots.SlotDrivers.act_world>`'s
:func:`~acc_gym.drivers._baseline_kernels.slot_laws`: baseline models without a reaction
delay, profiles, absent vehicles): each step is
:func:`~acc_gym.drivers._baseline_kernels.decide_world` with the ego's constant desired
acceleration, then the world's :func:`~acc_gym.simulation._world_kernel.move` -- the kernels
of a Python step, in its order, so the same numbers (``tests/simulation/test_world_kernel.py``).
Imported on first use (it joins the drivers' and the world's kernels).
"""

from __future__ import annotations

import numba
import numpy as np

from acc_gym.drivers._baseline_kernels import decide_world
from acc_gym.simulation._world_kernel import move


@numba.njit(cache=True, error_model="numpy")
def coast(steps, ego_a, obs, laws, world, x, v, xs, vs):  # pragma: no cover - compiled
    """Run ``steps`` steps from the state ``x``, ``v`` (``(B, S)``) whose observation array is
    ``obs``, the ego asking for ``ego_a`` [m/s^2], the surrounding drivers deciding by ``laws``
    (:meth:`SlotDrivers.compiled_laws <acc_gym.drivers.slots.SlotDrivers.compiled_laws>`) and
    the world moving by its ``world`` record (:data:`acc_gym.simulation._world_kernel.WORLD`);
    ``xs``, ``vs`` ``(steps + 1, B, S)`` get every state's positions and speeds (row 0 the
    current one), the laws' clocks and the world's ``k`` advance by ``steps``, its collision
    flags are updated. Returns the last step's ``(F, I, obs)`` for the world to adopt
    (:meth:`SingleLaneWorld.move_buffers <acc_gym.simulation.single_lane.SingleLaneWorld.move_buffers>`'s
    layout)."""
    B, S = x.shape
    xs[0] = x
    vs[0] = v
    F = np.empty((8, B, S))
    I = np.empty((2, B, S), dtype=np.int64)
    nxt = np.empty_like(obs)
    a_des = np.empty((B, S))
    ego = np.full(B, ego_a)
    t = np.empty(B)
    for i in range(steps):
        decide_world(obs, laws, ego, a_des)
        F = np.empty((8, B, S))
        I = np.empty((2, B, S), dtype=np.int64)
        nxt = np.empty_like(obs)
        move(a_des, x, v, world, F, I, nxt, t)
        x = F[0]
        v = F[1]
        obs = nxt
        xs[i + 1] = x
        vs[i + 1] = v
    return F, I, obs
