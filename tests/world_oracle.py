"""A world's move as the separate kernels it is made of: the oracle the one compiled move
(:meth:`acc_gym.simulation.single_lane.SingleLaneWorld.move`) is compared with."""

from __future__ import annotations

import numpy as np

from acc_gym.simulation import _world_kernel as _K


def move_by_parts(world, a_des: np.ndarray) -> None:
    """:meth:`SingleLaneWorld.move` of ``world`` as separate calls: :func:`~acc_gym.simulation._world_kernel.advance`,
    then the world's refresh and :func:`~acc_gym.simulation._world_kernel.mark_passed` (observations made
    on first use)."""
    w = world
    x, v, a, applied_des = np.empty((4, w.B, w.S))  # fresh arrays (one allocation): callers may keep the old
    _K.advance(a_des, w.present, w.x, w.v, w._vp, w.dt, x, v, a, applied_des)
    x_prev = w.x
    w.x, w.v, w.a, w.a_des = x, v, a, applied_des
    w.k += 1
    w._refresh(mark=True)
    nb = w.neighbours
    _K.mark_passed(x_prev, w.x, w.lengths, w.present, w.y, w.width, float(w.road.lane_width), nb.lead, nb.gap,
                   w.collided)
