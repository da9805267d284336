"""Compiled laws of the baseline drivers (:mod:`acc_gym.drivers.baselines`), one call per batch.

Each kernel writes, for the rows ``rows`` only, what the model's ``act`` gives: its law
(the array functions of :mod:`~acc_gym.drivers.baselines`, ``gipps_speed``, ``idm_accel``,
..., entry by entry with the same operations), then NaN -> ``A_FLOOR``, clipped to
``[A_FLOOR, A_CEIL]`` (which also maps the infinities as ``nan_to_num`` would). Own speed
``v`` is the current one; the other observation fields are as perceived (delayed) where
the model has a reaction delay, as in the models' ``_law``. Parameters are float arrays of
one value per row or one value for all rows (:func:`_at`).

``tests/drivers/test_baselines.py`` checks every kernel against its array function to 1e-12
(``np.power``/``np.exp`` and the compiled ``pow``/``exp`` may differ in the last bit).
"""

from __future__ import annotations

import math

import numba
import numpy as np

A_FLOOR = -20.0  # [m/s^2] (baselines.A_FLOOR)
A_CEIL = 10.0  # [m/s^2] (baselines.A_CEIL)


@numba.njit(cache=True, inline="always")
def _at(p, r):  # pragma: no cover - compiled
    return p[r] if p.size > 1 else p[0]


@numba.njit(cache=True, inline="always")
def _finish(x):  # pragma: no cover - compiled
    """``clip(nan_to_num(x, nan=A_FLOOR, posinf=A_CEIL, neginf=A_FLOOR), A_FLOOR, A_CEIL)``."""
    if math.isnan(x):
        return A_FLOOR
    return min(max(x, A_FLOOR), A_CEIL)


@numba.njit(cache=True, inline="always")
def _free(v, v_desired, k_free, a_max):  # pragma: no cover - compiled
    """``free_accel``: ``clip(k_free (v_desired - v), -a_max, a_max)``."""
    return min(max(k_free * (v_desired - v), -a_max), a_max)


@numba.njit(cache=True)
def idm_rows(v, gap, v_seen, v_lead, a, b, time_gap, s0, v_desired, delta, rows, out):  # pragma: no cover
    """IDM: ``idm_accel(v, gap, v_lead - v_seen, ...)``."""
    for r in rows:
        ar = _at(a, r)
        vr = v[r]
        free = 1.0 - (max(vr, 0.0) / _at(v_desired, r)) ** _at(delta, r)
        g = gap[r]
        inter = 0.0
        if math.isfinite(g):
            dv = v_lead[r] - v_seen[r]
            s_star = _at(s0, r) + max(0.0, vr * _at(time_gap, r) - vr * dv / (2.0 * math.sqrt(ar * _at(b, r))))
            q = s_star / max(g, 1e-3)
            inter = q * q
        out[r] = _finish(ar * (free - inter))


@numba.njit(cache=True)
def gipps_rows(v_now, v, gap, v_lead, a, b, b_hat, tau, theta, v_desired, s0, dt, rows, out):  # pragma: no cover
    """Gipps: ``(gipps_speed(v, gap, v_lead, ...) - v_now) / dt``; ``theta`` NaN is ``None`` (tau / 2)."""
    for r in rows:
        vr, ar, br, taur = v[r], _at(a, r), _at(b, r), _at(tau, r)
        th = _at(theta, r)
        if math.isnan(th):
            th = 0.5 * taur
        ratio = vr / _at(v_desired, r)
        free = vr + 2.5 * ar * taur * (1.0 - ratio) * math.sqrt(max(0.025 + ratio, 0.0))
        h = 0.5 * taur + th
        g = gap[r]
        if math.isfinite(g):
            vl = v_lead[r]
            arg = br * br * h * h - br * (2.0 * (g - _at(s0, r)) - vr * taur - vl * vl / _at(b_hat, r))
            safe = br * h + math.sqrt(max(arg, 0.0)) if arg >= 0.0 else 0.0
            safe = max(safe, 0.0)
        else:
            safe = np.inf
        out[r] = _finish((max(min(free, safe), 0.0) - v_now[r]) / dt)


@numba.njit(cache=True)
def gm_rows(v_now, gap, v_seen, v_lead, c, m, l, v_desired, k_free, a_max, length_ahead, rows, out):  # pragma: no cover
    """GM: ``gm_accel(v_now, gap + length_ahead, v_lead - v_seen, ...)`` with nothing ahead ``inf``,
    min the free-road law."""
    for r in rows:
        vn = v_now[r]
        a = np.inf
        if math.isfinite(gap[r]):
            d = gap[r] + _at(length_ahead, r)
            if math.isfinite(d):
                a = _at(c, r) * max(vn, 0.0) ** _at(m, r) * (v_lead[r] - v_seen[r]) / max(d, 1e-3) ** _at(l, r)
            else:
                a = 0.0
        out[r] = _finish(min(a, _free(vn, _at(v_desired, r), _at(k_free, r), _at(a_max, r))))


@numba.njit(cache=True)
def fuzzy_rows(v_now, v, gap, v_lead, a_lead, T, gamma, s0, h, level_width, max_level, step, v_desired, k_free, a_max,
               rows, out):  # pragma: no cover
    """Fuzzy: ``fuzzy_accel`` on the perceived scene (nothing ahead ``inf``), min the free-road law."""
    for r in rows:
        a = np.inf
        g = gap[r]
        if math.isfinite(g):
            ml = _at(max_level, r)
            level = min(max(np.rint((g - (_at(s0, r) + _at(h, r) * v[r])) / _at(level_width, r)), -ml), ml)
            a = (v_lead[r] - v[r] + a_lead[r] * _at(T, r)) / _at(gamma, r) + _at(step, r) * level
        out[r] = _finish(min(a, _free(v_now[r], _at(v_desired, r), _at(k_free, r), _at(a_max, r))))


@numba.njit(cache=True)
def pipes_rows(v_now, v, gap, v_lead, c, v_desired, k_free, a_max, rows, out):  # pragma: no cover
    """Pipes: ``c (v_lead - v)`` on the perceived scene (nothing ahead ``inf``), min the free-road law."""
    for r in rows:
        a = _at(c, r) * (v_lead[r] - v[r]) if math.isfinite(gap[r]) else np.inf
        out[r] = _finish(min(a, _free(v_now[r], _at(v_desired, r), _at(k_free, r), _at(a_max, r))))


@numba.njit(cache=True)
def newell_rows(v_now, gap, c, r_min, v_desired, dt, rows, out):  # pragma: no cover
    """Newell: ``(newell_speed(gap, ...) - v_now) / dt``."""
    for r in rows:
        vd = _at(v_desired, r)
        g = gap[r]
        speed = max(vd * (1.0 - math.exp(-_at(c, r) * (g - _at(r_min, r)) / vd)), 0.0) if math.isfinite(g) else vd
        out[r] = _finish((speed - v_now[r]) / dt)


@numba.njit(cache=True)
def tyler_rows(v_now, v, gap, v_lead, c_v, c_s, c_t, s0, v_desired, k_free, a_max, rows, out):  # pragma: no cover
    """Tyler: ``tyler_accel`` on the perceived scene (nothing ahead ``inf``), min the free-road law."""
    for r in rows:
        a = np.inf
        g = gap[r]
        if math.isfinite(g):
            a = _at(c_v, r) * (v_lead[r] - v[r]) + _at(c_s, r) * (g - _at(s0, r) - _at(c_t, r) * v[r])
        out[r] = _finish(min(a, _free(v_now[r], _at(v_desired, r), _at(k_free, r), _at(a_max, r))))


@numba.njit(cache=True, inline="always")
def _acc_law(v, gap, v_lead, a_lead, k1, k2, k3, time_gap, s0):  # pragma: no cover - compiled
    if not math.isfinite(gap):
        return np.inf
    return k3 * a_lead + k2 * (v_lead - v) + k1 * (gap - (s0 + time_gap * v))


@numba.njit(cache=True)
def acc_rows(v, gap, v_lead, a_lead, gap2, v_lead2, a_lead2, two, k1, k2, k3, time_gap, s0, v_set, k_cruise, a_max,
             vehicle_length, rows, out):  # pragma: no cover
    """ACC / CACC (``acc_accel``), with ``two`` the minimum over the second vehicle ahead (Eq. 3:
    doubled ``s0`` and time gap plus one length), min the set-speed controller."""
    for r in rows:
        k1r, k2r, k3r, hr, s0r = _at(k1, r), _at(k2, r), _at(k3, r), _at(time_gap, r), _at(s0, r)
        a = _acc_law(v[r], gap[r], v_lead[r], a_lead[r], k1r, k2r, k3r, hr, s0r)
        if two:
            a = min(a, _acc_law(v[r], gap2[r], v_lead2[r], a_lead2[r], k1r, k2r, k3r, 2.0 * hr,
                                2.0 * s0r + _at(vehicle_length, r)))
        out[r] = _finish(min(a, _free(v[r], _at(v_set, r), _at(k_cruise, r), _at(a_max, r))))
