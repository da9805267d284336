"""Compiled inner loops of :class:`~acc_gym.simulation.single_lane.SingleLaneWorld`.

The world's state is a handful of ``(B, S)`` arrays; one step touches each of them a few
times. Written as numpy expressions that is some hundred small array operations per step,
whose fixed cost (about a microsecond each) dwarfs the arithmetic for the few vehicles of
a scene. These kernels do the same arithmetic in one pass per phase:

* :func:`advance`: Eq. (3) of the vehicle model (``clip(a_des, a_L(v), a_U(v))``, no
  braking at standstill) and the exact zero-order-hold integration with stopping inside
  the step -- the same formulas as :func:`acc_gym.vehicle.applied_acceleration` and
  :func:`acc_gym.vehicle.integrate`, compiled from the same physics functions;
* :func:`refresh`: the scripted lateral positions and accelerations (half-cosine moves),
  then *who is ahead* by lane-corridor overlap (the nearest and second-nearest vehicle
  whose front bumper is ahead and whose contour overlaps the corridor; ties go to the
  lower slot, as a stable sort would), and the sticky collision flags;
* :func:`mark_passed`: a collision inside a step that the end-of-step gaps miss (a fast
  vehicle driving into and past a slow one within one step);
* :func:`observe_all`: every slot's :class:`~acc_gym.drivers.base.Observation` fields at
  once (sensor range applied), as ``(S, 8, B)`` so each field of a slot is contiguous.

The numpy formulations stay in :mod:`acc_gym.simulation.single_lane` and
:mod:`acc_gym.vehicle` as the reference; ``tests/simulation/test_world_kernel.py``
checks the kernels against them.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.core import types
from numba.experimental import structref

from acc_gym.vehicle import accel_lower_core, accel_upper_core

_upper = numba.njit(cache=True, error_model="numpy")(accel_upper_core)
_lower = numba.njit(cache=True, error_model="numpy")(accel_lower_core)

# rows of observe_all's output, in Observation's field order
OBS_FIELDS = ("v", "a", "gap", "v_lead", "a_lead", "gap2", "v_lead2", "a_lead2")


@structref.register
class WorldRecordType(types.StructRef):
    """numba's type of a :data:`WORLD_FIELDS` record (a structref: named fields, one argument)."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


class WorldRecord(structref.StructRefProxy):
    """What a world's move reads besides its state, as one record for the compiled kernels
    (made by :meth:`SingleLaneWorld.kernel_record
    <acc_gym.simulation.single_lane.SingleLaneWorld.kernel_record>`; its arrays are the world's
    own, shared, so what the world writes in place the kernels see)."""


structref.define_boxing(WorldRecordType, WorldRecord)
_F1, _F2, _F3 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1]
_B2, _I1 = types.bool_[:, ::1], types.int64[::1]
# the fields, their types ((B, S) arrays unless noted) and units
WORLD_FIELDS = (
    ("present", _B2),  # which vehicles exist
    ("vp", _F3),  # (B, S, 10) the vehicle parameters in VEHICLE_COLUMNS order
    ("dt", types.float64),  # [s] the step
    ("k", _I1),  # (B,) each scene's step count
    ("y0", _F2), ("y1", _F2), ("t_start", _F2), ("duration", _F2),  # the lateral plan [m], [m], [s], [s]
    ("lengths", _F2),  # [m]
    ("width", _F2),  # [m]
    ("lane_width", types.float64),  # [m]
    ("collided", _B2),  # sticky: ever gap <= 0
    ("sensor_range", types.float64),  # [m] vehicles further ahead are not seen
)
WORLD = WorldRecordType(list(WORLD_FIELDS))


@numba.njit(cache=True)
def make_world(f):  # pragma: no cover - compiled
    """A :data:`WORLD` record of the values ``f``, in :data:`WORLD_FIELDS` order."""
    r = structref.new(WORLD)
    r.present, r.vp, r.dt, r.k, r.y0, r.y1, r.t_start = f[0], f[1], f[2], f[3], f[4], f[5], f[6]
    r.duration, r.lengths, r.width, r.lane_width, r.collided, r.sensor_range = f[7], f[8], f[9], f[10], f[11], f[12]
    return r


@numba.njit(cache=True, error_model="numpy")
def advance(a_des, present, x, v, vp, dt, x_out, v_out, a_out, a_des_out):  # pragma: no cover - compiled
    """Apply Eq. (3) and integrate one step; absent vehicles ask for and get 0."""
    B, S = x.shape
    for b in range(B):
        for s in range(S):
            if not present[b, s]:
                a_des_out[b, s] = 0.0
                x_out[b, s] = x[b, s]
                v_out[b, s] = v[b, s]
                a_out[b, s] = 0.0
                continue
            ad = a_des[b, s]
            a_des_out[b, s] = ad
            vv = v[b, s]
            p = vp[b, s]
            lo = _lower(vv, p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[9])
            hi = _upper(vv, p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8])
            a = min(max(ad, lo), hi)  # np.clip(a_des, lo, hi)
            if vv <= 0.0 and a < 0.0:
                a = 0.0
            v_end = vv + a * dt
            if v_end < 0.0:
                x_out[b, s] = x[b, s] + vv * vv / (-2.0 * a)
                v_out[b, s] = 0.0
            else:
                x_out[b, s] = x[b, s] + (vv * dt + 0.5 * a * dt * dt)
                v_out[b, s] = v_end
            a_out[b, s] = a


@numba.njit(cache=True, error_model="numpy")
def refresh(t, world, x, y, a_y, lead, gap, lead2, gap2, mark):  # pragma: no cover - compiled
    """Lateral positions at each scene's time ``t`` (by ``world``'s lateral plan, a
    :data:`WORLD` record), then neighbours of the positions ``x`` into ``lead``, ``gap``,
    ``lead2``, ``gap2``; with ``mark``, set the sticky collision flag (``world.collided``) of
    every vehicle whose gap is <= 0 (after a step, not at a start)."""
    y0, y1, t_start, duration = world.y0, world.y1, world.t_start, world.duration
    lengths, present, width, lane_width, collided = world.lengths, world.present, world.width, world.lane_width, world.collided
    B, S = x.shape
    for b in range(B):
        for s in range(S):
            d = duration[b, s]
            ph = (t[b] - t_start[b, s]) / d
            ph = min(max(ph, 0.0), 1.0)
            dy = y1[b, s] - y0[b, s]
            c = math.cos(math.pi * ph)
            y[b, s] = y0[b, s] + dy * 0.5 * (1.0 - c)
            if ph > 0.0 and ph < 1.0:
                a_y[b, s] = dy * 0.5 * (math.pi / d) ** 2 * c
            else:
                a_y[b, s] = 0.0
        for i in range(S):
            g1 = np.inf
            j1 = -1
            g2 = np.inf
            j2 = -1
            if present[b, i]:
                for j in range(S):
                    if not present[b, j] or not (x[b, j] > x[b, i]):
                        continue
                    if not (abs(y[b, j] - y[b, i]) < 0.5 * (lane_width + width[b, j])):
                        continue
                    g = (x[b, j] - lengths[b, j]) - x[b, i]
                    if g < g1:
                        g2, j2 = g1, j1
                        g1, j1 = g, j
                    elif g < g2:
                        g2, j2 = g, j
            lead[b, i] = j1
            gap[b, i] = g1
            lead2[b, i] = j2
            gap2[b, i] = g2
            if mark and g1 <= 0.0:
                collided[b, i] = True


@numba.njit(cache=True, error_model="numpy")
def mark_passed(x_prev, x, lengths, present, y, width, lane_width, lead, gap, collided):  # pragma: no cover
    """Collisions inside a step that the end-of-step gaps cannot see: a vehicle ``j`` whose rear
    was ahead of ``i``'s front before the step (gap > 0), is in ``i``'s lane corridor now and
    whose rear is now behind ``i``'s front (gap <= 0) without its front still being ahead --
    ``i`` drove into and past it within one step (at 0.2 s that takes a closing speed above
    ``L_j / dt``, 23.5 m/s for a 4.7 m car). Decided: it is a collision like any other -- ``i``'s
    lead becomes ``j`` with that (negative) gap, so every reader of the gaps (the env's
    termination, the metrics, the traces) sees it, and the sticky flag is set. Vehicles that
    are ahead by the usual rule are left to :func:`refresh`."""
    B, S = x.shape
    for b in range(B):
        for i in range(S):
            if not present[b, i] or gap[b, i] <= 0.0:
                continue
            for j in range(S):
                if j == i or not present[b, j] or x[b, j] > x[b, i]:
                    continue
                if not (abs(y[b, j] - y[b, i]) < 0.5 * (lane_width + width[b, j])):
                    continue
                g = (x[b, j] - lengths[b, j]) - x[b, i]
                if (x_prev[b, j] - lengths[b, j]) - x_prev[b, i] > 0.0 and g <= 0.0 and g < gap[b, i]:
                    lead[b, i] = j
                    gap[b, i] = g
                    collided[b, i] = True


@numba.njit(cache=True, error_model="numpy")
def observe_all(v, a, lead, gap, lead2, gap2, sensor_range, out):  # pragma: no cover - compiled
    """``out[s, f, b]``: field ``f`` (:data:`OBS_FIELDS`) of slot ``s``'s vehicle in scene ``b``."""
    B, S = v.shape
    for s in range(S):
        for b in range(B):
            out[s, 0, b] = v[b, s]
            out[s, 1, b] = a[b, s]
            g = gap[b, s]
            seen = g <= sensor_range
            out[s, 2, b] = g if seen else np.inf
            j = lead[b, s]
            out[s, 3, b] = v[b, j] if j >= 0 else 0.0
            out[s, 4, b] = a[b, j] if j >= 0 else 0.0
            g2 = gap2[b, s]
            out[s, 5, b] = g2 if (seen and g2 <= sensor_range) else np.inf
            j2 = lead2[b, s]
            out[s, 6, b] = v[b, j2] if j2 >= 0 else 0.0
            out[s, 7, b] = a[b, j2] if j2 >= 0 else 0.0


@numba.njit(cache=True, error_model="numpy")
def slot_rows(obs, rows):  # pragma: no cover - compiled
    """The surrounding slots' observations as driver rows: ``rows[f, (s - 1) B + b] = obs[s, f, b]``
    for ``s >= 1`` (``obs`` ``(S, 8, B)``, :func:`observe_all`'s; ``rows`` ``(8, (S - 1) B)``),
    the layout of a :class:`~acc_gym.drivers.slots.SlotDrivers` holding every surrounding slot."""
    S, m, B = obs.shape
    for s in range(1, S):
        for f in range(m):
            for b in range(B):
                rows[f, (s - 1) * B + b] = obs[s, f, b]


@numba.njit(cache=True, error_model="numpy")
def put_slots(out, a_des):  # pragma: no cover - compiled
    """The drivers' outputs by row back into the world's layout: ``a_des[b, s] = out[(s - 1) B + b]``
    for ``s >= 1`` (:func:`slot_rows`'s inverse for ``a_des`` ``(B, S)``)."""
    B, S = a_des.shape
    for s in range(1, S):
        for b in range(B):
            a_des[b, s] = out[(s - 1) * B + b]


@numba.njit(cache=True, error_model="numpy")
def move(a_des, x, v, world, F, I, obs, t):  # pragma: no cover - compiled
    """:meth:`~acc_gym.simulation.single_lane.SingleLaneWorld.move` and the next state's
    :func:`observe_all` in one call, from the state ``x``, ``v`` and the rest of the world
    (``world``, a :data:`WORLD` record): :func:`advance`, ``k += 1``, the times ``t = k dt``,
    :func:`refresh` with collision marking, :func:`mark_passed`. Outputs in ``F`` (x, v, a,
    a_des, y, a_y, gap, gap2), ``I`` (lead, lead2), ``obs`` and ``t`` (see
    ``SingleLaneWorld.move_buffers``)."""
    w = world
    advance(a_des, w.present, x, v, w.vp, w.dt, F[0], F[1], F[2], F[3])
    k = w.k
    for b in range(k.shape[0]):
        k[b] += 1
        t[b] = k[b] * w.dt
    refresh(t, w, F[0], F[4], F[5], I[0], F[6], I[1], F[7], True)
    mark_passed(x, F[0], w.lengths, w.present, F[4], w.width, w.lane_width, I[0], F[6], w.collided)
    observe_all(F[1], F[2], I[0], F[6], I[1], F[7], w.sensor_range, obs)


@numba.njit(cache=True, error_model="numpy")
def place(rows, new, initial, world, x, v, a, a_des):  # pragma: no cover - compiled
    """Start scenes ``rows`` afresh (the body of ``SingleLaneWorld.reset_rows`` for inputs
    already shaped ``(len(rows), S)``): ``new`` the rows' ``(x0, v0, a0, present, lengths,
    width, y0, y1, t_start, duration)``. First checks every initial position, speed,
    acceleration, length and width is finite and every speed >= 0 and returns False, changing
    nothing, if not (the caller then takes the reference path, which names the bad value);
    else writes the scenes' rows of the world's initial state ``initial`` (``(x0, v0, a0)``),
    of its ``world`` record (presence, sizes, lateral plan, clocks, collision flags) and of the
    state ``x``, ``v``, ``a``, ``a_des``, and returns True."""
    x0, v0, a0, present, lengths, width, y0, y1, t_start, duration = new
    X0, V0, A0 = initial
    PRESENT, LENGTHS, WIDTH, k, collided = world.present, world.lengths, world.width, world.k, world.collided
    LY0, LY1, LT, LD = world.y0, world.y1, world.t_start, world.duration
    m, S = x0.shape
    for r in range(m):
        for s in range(S):
            if not (math.isfinite(x0[r, s]) and math.isfinite(v0[r, s]) and v0[r, s] >= 0.0
                    and math.isfinite(a0[r, s]) and math.isfinite(lengths[r, s]) and math.isfinite(width[r, s])):
                return False
    for r in range(m):
        b = rows[r]
        k[b] = 0
        for s in range(S):
            X0[b, s] = x0[r, s]
            V0[b, s] = v0[r, s]
            A0[b, s] = a0[r, s]
            PRESENT[b, s] = present[r, s]
            LENGTHS[b, s] = lengths[r, s]
            WIDTH[b, s] = width[r, s]
            LY0[b, s] = y0[r, s]
            LY1[b, s] = y1[r, s]
            LT[b, s] = t_start[r, s]
            LD[b, s] = duration[r, s]
            x[b, s] = x0[r, s]
            v[b, s] = v0[r, s] if present[r, s] else 0.0
            a[b, s] = a0[r, s] if present[r, s] else 0.0
            a_des[b, s] = np.nan
            collided[b, s] = False
    return True


@numba.njit(cache=True, error_model="numpy")
def first_overlap(rows, x, y, present, width, lengths, lane_width):  # pragma: no cover - compiled
    """``(r, i, j)`` of the first pair of vehicles (in row-major order over ``rows``, ``i``,
    ``j``) that share a lane corridor and overlap lengthwise, or ``(-1, -1, -1)``: the test
    of ``SingleLaneWorld._check_apart``, which then raises naming them."""
    S = x.shape[1]
    for r in range(rows.shape[0]):
        b = rows[r]
        for i in range(S):
            for j in range(S):
                if i == j or not (present[b, i] and present[b, j]):
                    continue
                if not (abs(y[b, j] - y[b, i]) < 0.5 * (lane_width + width[b, j])):
                    continue
                rear_i = x[b, i] - lengths[b, i]
                rear_j = x[b, j] - lengths[b, j]
                if rear_i < x[b, j] and rear_j < x[b, i]:
                    return r, i, j
    return -1, -1, -1
