"""The safety-margin features an ACC computes from its radar, derived from the observation.

Paper 003's score judges following by the safety margin ``Q = D1 - Gapsafe`` and its band
``0 < Q < 0.2 Gapsafe``, with ``Gapsafe = v tau1 + v^2 / (2 b1) - v_lead^2 / (2 b0)`` a
quadratic of what the radar measures: about 4 m wide at 60 km/h, and the policy has to
find it inside a 200 m gap. An ACC computes such margins itself (ISO 15622's time gap,
time to collision, the required deceleration); they are part of the observation from the
``-v1`` environment ids on. This module computes them from the observation's
own fields, so they add nothing the controller could not compute, and they are the same
for one env, a vector env and a batch of stored observations.

For each vehicle ahead (the first; with ``v2v`` also the second), from the ego's speed
``v``, the gap ``d``, the relative speed ``dv = v_lead - v``, the in-range flag and the
nominal time gap ``tau`` (observation fields 0, 2, 3, 4 and 6; 8, 9, 10 for the second):

========================  =================================================  ========  ============
feature                   definition                                          unit      bounds
========================  =================================================  ========  ============
``gap_safe``              ``(v tau + v^2 / (2 b1) - v_lead^2 / (2 b0)) / R``  -         [-1, 2]
``q``                     ``(d - Gapsafe) / R``                               -         [-2, 1]
``q_over_gap_safe``       ``(d - Gapsafe) / max(Gapsafe, 1 m)``               -         [-1, 5]
``time_headway``          ``d / max(v, 0.1 m/s)``                             s         [0, 10]
``inverse_ttc``           ``-dv / max(d, 0.1 m)`` (> 0 closing)               1/s       [-2, 2]
``a_req``                 ``-dv^2 / (2 max(d, 0.1 m))`` closing, else 0       m/s^2     [-20, 0]
========================  =================================================  ========  ============

``R`` is the sensor range (200 m by default): gaps and margins as a fraction of what the
radar can see, so that every feature is of order one and an unnormalised MLP can use
them. ``Q / Gapsafe`` is where the ego is in the score's band (0 to 0.2 inside it; the
score's efficiency ``u_t`` is 5 times it there). ``a_req`` is paper 001's required
deceleration (Eq. 10): the constant deceleration that matches the lead's speed at the
lead's bumper. ``b0 = b1 = 8 m/s^2`` (paper 003's, the scoring defaults).

**Decided: nothing in range.** The observation shows a vehicle that is not in range as
one at the sensor range moving at the ego's speed (gap ``R``, relative speed 0), and the
features are those of that vehicle: ``Gapsafe = v tau``, ``Q = R - v tau``, the headway
``R / v``, no closing (``inverse_ttc = a_req = 0``). They change continuously as a vehicle
comes into range at the range's edge at the ego's speed, and a policy needs no special
case. The in-range flag stays in the observation for the policies that want one.

Every feature is clipped to its bounds (the observation space's), as the other fields are.
"""

from __future__ import annotations

import math

import numba
import numpy as np

FEATURES = ("gap_safe", "q", "q_over_gap_safe", "time_headway", "inverse_ttc", "a_req")
LOW = (-1.0, -2.0, -1.0, 0.0, -2.0, -20.0)
HIGH = (2.0, 1.0, 5.0, 10.0, 2.0, 0.0)
B0 = 8.0  # [m/s^2] the vehicle ahead's assumed braking (paper 003; ScoringConfig.b0)
B1 = 8.0  # [m/s^2] the ego's (ScoringConfig.b1)
GAP_SAFE_FLOOR = 1.0  # [m] Q / Gapsafe divides by at least this
SPEED_FLOOR = 0.1  # [m/s] the headway divides by at least this
GAP_FLOOR = 0.1  # [m] the inverse TTC and a_req divide by at least this
# the v0 observation's fields each vehicle's features are computed from: (gap, v_rel, in range)
_FIELDS = ((2, 3, 4), (8, 9, 10))


def feature_names(v2v: bool) -> tuple[str, ...]:
    """The appended fields' names, in order (``*_2`` for the second vehicle ahead)."""
    return FEATURES + (tuple(f"{name}_2" for name in FEATURES) if v2v else ())


def feature_bounds(v2v: bool) -> tuple[np.ndarray, np.ndarray]:
    k = 2 if v2v else 1
    return np.array(LOW * k, dtype=float), np.array(HIGH * k, dtype=float)


@numba.njit(cache=True, error_model="numpy")
def _one(v, gap, v_rel, tau, sensor_range, b0, b1, out, j):  # pragma: no cover - compiled
    v_lead = v + v_rel
    gs = v * tau + v * v / (2.0 * b1) - v_lead * v_lead / (2.0 * b0)
    q = gap - gs
    d = max(gap, GAP_FLOOR)
    out[j] = gs / sensor_range
    out[j + 1] = q / sensor_range
    out[j + 2] = q / max(gs, GAP_SAFE_FLOOR)
    out[j + 3] = gap / max(v, SPEED_FLOOR)
    out[j + 4] = -v_rel / d
    out[j + 5] = -v_rel * v_rel / (2.0 * d) if v_rel < 0.0 else 0.0


@numba.njit(cache=True, error_model="numpy")
def append_features(obs, sensor_range, b0, b1, low, high, out):  # pragma: no cover - compiled
    """``out[:, :m] = obs``, then the features of each vehicle ahead (``obs`` ``(n, m)``, m = 7
    or 11 with V2V), each clipped to ``[low, high]`` (the features' bounds)."""
    n, m = obs.shape
    vehicles = 2 if m == 11 else 1
    row = np.empty(6 * vehicles)
    for i in range(n):
        for j in range(m):
            out[i, j] = obs[i, j]
        v = obs[i, 0]
        tau = obs[i, 6]
        for k in range(vehicles):
            gi = 2 if k == 0 else 8
            _one(v, obs[i, gi], obs[i, gi + 1], tau, sensor_range, b0, b1, row, 6 * k)
        for j in range(6 * vehicles):
            out[i, m + j] = min(max(row[j], low[j]), high[j])


def margin_features(obs, sensor_range: float = 200.0, b0: float = B0, b1: float = B1) -> np.ndarray:
    """The observation ``obs`` (``(m,)`` or ``(n, m)``, m = 7 or 11: the ``-v0`` fields) with
    the safety-margin features appended (``(m + 6)`` or ``(m + 12)`` columns, the module
    table's order, clipped to its bounds); ``sensor_range`` [m] is the env's. A pure
    function of its arguments: the same for an env, a vector env and stored observations."""
    x = np.asarray(obs, dtype=float)
    squeeze = x.ndim == 1
    x2 = np.atleast_2d(x)
    if x2.ndim != 2 or x2.shape[1] not in (7, 11):
        raise ValueError(f"obs must have 7 or 11 fields (the -v0 observation, 11 with v2v), got shape {x.shape}")
    if not (isinstance(sensor_range, (int, float)) and math.isfinite(sensor_range) and sensor_range > 0):
        raise ValueError(f"sensor_range must be a finite number > 0 [m], got {sensor_range!r}")
    for name, b in (("b0", b0), ("b1", b1)):
        if not (isinstance(b, (int, float)) and math.isfinite(b) and b > 0):
            raise ValueError(f"{name} must be a finite deceleration > 0 [m/s^2], got {b!r}")
    if not np.all(np.isfinite(x2)):
        raise ValueError("obs must be finite")
    low, high = feature_bounds(x2.shape[1] == 11)
    out = np.empty((x2.shape[0], x2.shape[1] + low.size))
    append_features(np.ascontiguousarray(x2), float(sensor_range), float(b0), float(b1), low, high, out)
    return out[0] if squeeze else out
