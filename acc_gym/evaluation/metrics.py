"""Extra per-episode metrics (paper 004 Section V.C and common ACC practice).

* ``collision``: the gap to the vehicle ahead reached 0 (D1 <= 0).
* ``share_comfortable``: share of samples with ``|a_x| <= a_x,comfort`` (the same 3 m/s^2
  as paper 003's comfort indicator).
* ``share_safe_spacing``: share of samples with a vehicle ahead (within sensor range)
  where Q >= 0; NaN if there is never one.
* ``min_ttc`` [s]: smallest time-to-collision D1 / (v1 - v0) while closing in, 0 once in
  contact (D1 <= 0, so every collision has 0, however the speeds were then recorded), inf if
  never closing in (:func:`acc_gym.evaluation.indicators.time_to_collision`).
* ``max_jerk`` [m/s^3]: largest |da/dt| between consecutive samples.
* ``speed_overshoot`` and ``damping_ratio``: how the ego's speed settles after a lead
  transient. Each time the lead holds a steady speed ``v*`` (|dv0/dt| <= 0.15 m/s^2 for at
  least 5 s) while the ego starts that period at least 1 m/s away from ``v*``, the
  overshoot is how far the ego's speed goes past ``v*`` on the other side, relative to the
  initial deviation (0: no overshoot). ``speed_overshoot`` is the largest over the
  episode (NaN if there was no such transient) and ``damping_ratio`` the second-order
  damping ratio with that overshoot, ``-ln(OS) / sqrt(pi^2 + ln(OS)^2)`` (1 for OS = 0,
  0 for OS >= 1).
"""

from __future__ import annotations

import numba
import numpy as np

from acc_gym.evaluation.indicators import time_to_collision

STEADY_ACCEL = 0.15  # [m/s^2] the lead counts as steady below this |dv0/dt|
STEADY_TIME = 5.0  # [s] for at least this long
MIN_DEVIATION = 1.0  # [m/s] ego-lead speed difference at the start of a steady period that counts


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index ranges where ``mask`` is True."""
    m = np.concatenate([[False], mask, [False]]).astype(int)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


@numba.njit(cache=True)
def _gradient(f, x):  # pragma: no cover - compiled
    """``np.gradient(f, x)`` for 1-D float arrays (``edge_order=1``), compiled: numpy's own
    formulas in its order of operations (a uniform spacing when every step of ``x`` is
    exactly the first, else the second-order non-uniform stencil; one-sided edges), so
    the same values exactly, without its dozen temporaries (``tests/evaluation/test_metrics.py``)."""
    n = f.shape[0]
    out = np.empty(n)
    d0 = x[1] - x[0]
    uniform = True
    for i in range(1, n - 1):
        if not (x[i + 1] - x[i]) == d0:
            uniform = False
            break
    for i in range(1, n - 1):
        if uniform:
            out[i] = (f[i + 1] - f[i - 1]) / (2.0 * d0)
        else:
            dx1 = x[i] - x[i - 1]
            dx2 = x[i + 1] - x[i]
            a = -dx2 / (dx1 * (dx1 + dx2))
            b = (dx2 - dx1) / (dx1 * dx2)
            c = dx1 / (dx2 * (dx1 + dx2))
            out[i] = a * f[i - 1] + b * f[i] + c * f[i + 1]
    out[0] = (f[1] - f[0]) / d0
    out[n - 1] = (f[n - 1] - f[n - 2]) / (d0 if uniform else x[n - 1] - x[n - 2])
    return out


def gradient(f, x) -> np.ndarray:
    """``np.gradient(f, x)``; float64 1-D inputs of one length (>= 2) take :func:`_gradient`."""
    if (type(f) is np.ndarray and type(x) is np.ndarray and f.dtype == np.float64 and x.dtype == np.float64
            and f.ndim == 1 and x.shape == f.shape and f.shape[0] >= 2):
        return _gradient(f, x)
    return np.gradient(f, x)


def speed_overshoot(t, v, v_lead, has_lead) -> tuple[float, int]:
    """(largest relative overshoot, number of transients evaluated)."""
    t = np.asarray(t, float)
    dv0 = gradient(np.asarray(v_lead, float), t)
    steady = has_lead & (np.abs(dv0) <= STEADY_ACCEL) & (np.asarray(v_lead) > 0.5)
    worst, count = np.nan, 0
    for i, j in _runs(steady):
        if t[j - 1] - t[i] < STEADY_TIME:
            continue
        v_star = float(np.mean(v_lead[i:j]))
        dev0 = v_star - v[i]
        if abs(dev0) < MIN_DEVIATION:
            continue
        past = np.sign(dev0) * (v[i:j] - v_star)  # > 0 once the ego has gone past v*
        os = max(float(past.max()), 0.0) / abs(dev0)
        worst = os if np.isnan(worst) else max(worst, os)
        count += 1
    return worst, count


def damping_ratio(overshoot: float) -> float:
    if np.isnan(overshoot):
        return np.nan
    if overshoot <= 0:
        return 1.0
    if overshoot >= 1:
        return 0.0
    ln = np.log(overshoot)
    return float(-ln / np.sqrt(np.pi ** 2 + ln ** 2))


def extra_metrics(trace, q, seen, a_x_comfort: float) -> dict:
    """The metrics above for an :class:`~acc_gym.evaluation.trace.EgoTrace` with per-sample Q."""
    has = trace.has_lead
    dt = np.diff(trace.t)
    jerk = np.abs(np.diff(trace.a)) / dt
    os, n_tr = speed_overshoot(trace.t, trace.v, trace.v_lead, has)
    ttc = time_to_collision(np.where(has, trace.gap, np.inf), trace.v, trace.v_lead)
    return {
        "collision": bool(np.any(has & (trace.gap <= 0.0))),
        "share_comfortable": float(np.mean(np.abs(trace.a) <= a_x_comfort)),
        "share_safe_spacing": float(np.mean(q[seen] >= 0.0)) if np.any(seen) else np.nan,
        "min_ttc": float(np.min(ttc)) if ttc.size else np.inf,
        "max_jerk": float(jerk.max()) if jerk.size else 0.0,
        "speed_overshoot": os,
        "damping_ratio": damping_ratio(os),
        "transients": n_tr,
        "min_gap": float(np.min(np.where(has, trace.gap, np.inf))),
        "duration": float(trace.t[-1] - trace.t[0]),
    }
