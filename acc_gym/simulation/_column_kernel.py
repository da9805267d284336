"""Compiled loops of :func:`~acc_gym.simulation.rollout.simulate_column`.

A column's state is three ``(B, n)`` arrays (positions, speeds, accelerations; vehicle 0
the lead); each follower's :class:`~acc_gym.drivers.base.Observation` is a function of them
(:func:`_observation`, the formulas of the per-follower loop it replaces). Two kernels:

* :func:`observe`: every follower's observation of one step into one array, its values
  checked -- the column's per-step check when some follower is not a baseline model and is
  called through its ``act`` or ``act_checked``;
* :func:`run`: the whole run of a column whose followers are all baseline models
  (:meth:`~acc_gym.drivers.baselines._Model.compiled_law`): each step every follower's
  observation (checked), its law (:func:`acc_gym.drivers._baseline_kernels.law`) on the scene
  its reaction delay ago -- read back from the recorded trajectory, which holds every past
  state, so no delay buffer is kept -- then every vehicle moves by the world's
  :func:`~acc_gym.simulation._world_kernel.advance` (Eq. (3) and the exact integration,
  checked equal to :mod:`acc_gym.vehicle`'s numpy functions).

The value check has the rules of :meth:`Observation.validate
<acc_gym.drivers.base.Observation.validate>` (the shapes are the column's own, fixed for
the run): no field NaN; speeds and accelerations finite; gaps may be ``+inf`` (nothing
ahead) but not ``-inf``; own speed ``>= 0``. A finite negative gap is a collision, recorded
in the trajectory (``Trajectory.collided``), not an invalid value, as for ``validate``. On
the first bad value (followers in order, fields in Observation's order) a kernel stops and
names the column, the follower, the field and its value in ``fault``; the caller raises naming the step.
``tests/simulation/test_column_kernel.py`` checks both kernels against the per-follower loop.
"""

from __future__ import annotations

import math
from dataclasses import fields

import numba
import numpy as np

from acc_gym.drivers import _baseline_kernels as _law
from acc_gym.drivers.base import Observation
from acc_gym.simulation._world_kernel import advance

FIELDS = tuple(f.name for f in fields(Observation))  # the rows of observe()'s output, fault[2]'s codes
_GAPS = (FIELDS.index("gap"), FIELDS.index("gap2"), FIELDS.index("stop_gap"))  # may be +inf: nothing there
_V = FIELDS.index("v")
assert FIELDS[:5] == ("v", "a", "gap", "v_lead", "a_lead") and len(FIELDS) == 9  # the order the kernels write


@numba.njit(cache=True, inline="always")
def _observation(x, v, a, lengths, sensor_range, stop, b, j):  # pragma: no cover - compiled
    """Follower ``j``'s observation in column ``b`` of the state ``(x, v, a)`` ``(B, n)``, as a tuple
    in Observation's field order. Beyond the sensor range a vehicle ahead is not seen (gap
    ``inf``); the second vehicle ahead only where the first is seen (for ``j >= 2``; else ``inf``
    and zeros); the stop gap to ``stop[b]`` [m] (without a stop position the field is None: not
    read, not checked)."""
    gap = x[b, j - 1] - lengths[j - 1] - x[b, j]  # [m] bumper to bumper
    seen = gap <= sensor_range
    gap2, v_lead2, a_lead2 = np.inf, 0.0, 0.0
    if j >= 2:
        g2 = x[b, j - 2] - lengths[j - 2] - x[b, j]
        gap2 = g2 if (seen and g2 <= sensor_range) else np.inf
        v_lead2, a_lead2 = v[b, j - 2], a[b, j - 2]
    return (v[b, j], a[b, j], gap if seen else np.inf, v[b, j - 1], a[b, j - 1], gap2, v_lead2, a_lead2,
            stop[b] - x[b, j])


@numba.njit(cache=True, inline="always")
def _first_bad(obs, j, has_stop):  # pragma: no cover - compiled
    """The index of the first field of ``obs`` that ``Observation.validate`` rejects, or -1 (the
    second vehicle ahead exists from follower 2 on, the stop gap with a stop position)."""
    for f in range(9):
        if (f >= 5 and f <= 7 and j < 2) or (f == 8 and not has_stop):
            continue  # the field is None in this follower's observation
        value = obs[f]
        if f == _GAPS[0] or f == _GAPS[1] or f == _GAPS[2]:
            if math.isnan(value) or value == -np.inf:
                return f
        elif not math.isfinite(value):
            return f
    return _V if obs[_V] < 0.0 else -1  # the sign last, as validate checks it


@numba.njit(cache=True)
def observe(x, v, a, lengths, sensor_range, stop, has_stop, out, fault):  # pragma: no cover - compiled
    """``out[j - 1, f, b]``: field ``f`` (:data:`FIELDS`) of follower ``j``'s observation in column
    ``b`` (each field of a follower contiguous). Returns False at the first bad value, with
    ``fault = (b, j, f, value)``."""
    B, n = x.shape
    for j in range(1, n):
        for b in range(B):
            obs = _observation(x, v, a, lengths, sensor_range, stop, b, j)
            f = _first_bad(obs, j, has_stop)
            if f >= 0:
                fault[0], fault[1], fault[2], fault[3] = b, j, f, obs[f]
                return False
            for i in range(9):
                out[j - 1, i, b] = obs[i]
    return True


@numba.njit(cache=True, error_model="numpy")
def run(lead_next, dt, column, laws, trace, fault):  # pragma: no cover - compiled
    """Steps ``0 .. T-1`` of a column of baseline models (``T = lead_next.shape[1]``); returns the
    number of steps done: ``T``, or the step at which an observation held a bad value (with
    ``fault = (b, j, f, value)``; rows after it are not written).

    ``lead_next`` ``(B, T)`` is the lead's profile speed at the end of each step [m/s]; ``dt``
    [s] the step. ``column``: ``(lengths, vp, sensor_range, stop, has_stop)``, the vehicles'
    lengths [m], their parameters ``(B, n, 10)`` (``VehicleParams.as_matrix``), the sensor
    range [m] and the stop positions ``(B,)`` [m] (``has_stop``). ``laws``: the followers'
    ``compiled_law()`` s, ``(kinds, params, model_dt, delays, two)`` (follower ``j`` in slot
    ``j - 1``; ``params`` ``(n-1, B, MAX_PARAMS)``, ``model_dt`` [s], ``delays`` [steps]).
    ``trace``: ``(X, V, A, A_DES, GAP)`` ``(T+1, B, n)``, the recorded trajectory, row 0 (the
    start) filled by the caller."""
    lengths, vp, sensor_range, stop, has_stop = column
    kinds, params, model_dt, delays, two = laws
    X, V, A, A_DES, GAP = trace
    T = lead_next.shape[1]
    B, n = X.shape[1], X.shape[2]
    present = np.ones((B, n), dtype=np.bool_)
    for k in range(T):
        # phase 1: every driver decides from the same snapshot, the state at the start of step k
        x, v, a = X[k], V[k], A[k]
        for b in range(B):
            A_DES[k + 1, b, 0] = (lead_next[b, k] - v[b, 0]) / dt  # [m/s^2] to the profile's next speed
            for j in range(1, n):
                now = _observation(x, v, a, lengths, sensor_range, stop, b, j)
                f = _first_bad(now, j, has_stop)
                if f >= 0:
                    fault[0], fault[1], fault[2], fault[3] = b, j, f, now[f]
                    return k
                seen = now
                back = max(k - delays[j - 1], 0)  # the step the driver perceives (its delay buffer's)
                if back < k:
                    seen = _observation(X[back], V[back], A[back], lengths, sensor_range, stop, b, j)
                A_DES[k + 1, b, j] = _law.law(kinds[j - 1], params[j - 1, b], model_dt[j - 1], two[j - 1] and j >= 2,
                                              now[0], seen[0], seen[2], seen[3], seen[4], now[5], now[6], now[7])
        # phase 2: every vehicle moves
        advance(A_DES[k + 1], present, x, v, vp, dt, X[k + 1], V[k + 1], A[k + 1], A_DES[k + 1])
        for b in range(B):
            GAP[k + 1, b, 0] = np.inf  # the lead: nothing ahead
            for j in range(1, n):
                GAP[k + 1, b, j] = X[k + 1, b, j - 1] - lengths[j - 1] - X[k + 1, b, j]
    return T
