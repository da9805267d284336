"""Compiled laws of the baseline drivers (:mod:`acc_gym.drivers.baselines`), one call per batch.

Each kernel writes, for the rows ``rows`` only, what the model's ``act`` gives: its law
(the array functions of :mod:`~acc_gym.drivers.baselines`, ``gipps_speed``, ``idm_accel``,
..., entry by entry with the same operations), then NaN -> ``A_FLOOR``, clipped to
``[A_FLOOR, A_CEIL]`` (which also maps the infinities as ``nan_to_num`` would). Own speed
``v`` is the current one; the other observation fields are as perceived (delayed) where
the model has a reaction delay, as in the models' ``_law``. Parameters are float arrays of
one value per row or one value for all rows (:func:`_at`).

Each law is written once, as a function of one vehicle's numbers (``idm``, ``gipps``, ...);
:func:`law` picks it by the model's code (:data:`KINDS`), for :func:`law_rows` over a batch's
rows (a model's ``act``) and for the compiled loops that step several models (the column
simulation's, :mod:`acc_gym.simulation._column_kernel`; a world's surrounding slots,
:func:`slot_laws`).

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


# ---------------------------------------------------------------------------------------
# One vehicle's law: own speed now ``v_now``; ``v``, ``gap``, ``v_lead``, ``a_lead`` as perceived
# ---------------------------------------------------------------------------------------

@numba.njit(cache=True, inline="always")
def idm(v_now, gap, v, v_lead, a, b, time_gap, s0, v_desired, delta):  # pragma: no cover - compiled
    """IDM: ``idm_accel(v_now, gap, v_lead - v, ...)``."""
    free = 1.0 - (max(v_now, 0.0) / v_desired) ** delta
    inter = 0.0
    if math.isfinite(gap):
        dv = v_lead - v
        s_star = s0 + max(0.0, v_now * time_gap - v_now * dv / (2.0 * math.sqrt(a * b)))
        q = s_star / max(gap, 1e-3)
        inter = q * q
    return _finish(a * (free - inter))


@numba.njit(cache=True, inline="always")
def gipps(v_now, v, gap, v_lead, a, b, b_hat, tau, theta, v_desired, s0, dt):  # pragma: no cover - compiled
    """Gipps: ``(gipps_speed(v, gap, v_lead, ...) - v_now) / dt``; ``theta`` NaN is ``None`` (tau / 2)."""
    if math.isnan(theta):
        theta = 0.5 * tau
    ratio = v / v_desired
    free = v + 2.5 * a * tau * (1.0 - ratio) * math.sqrt(max(0.025 + ratio, 0.0))
    h = 0.5 * tau + theta
    if math.isfinite(gap):
        arg = b * b * h * h - b * (2.0 * (gap - s0) - v * tau - v_lead * v_lead / b_hat)
        safe = b * h + math.sqrt(max(arg, 0.0)) if arg >= 0.0 else 0.0
        safe = max(safe, 0.0)
    else:
        safe = np.inf
    return _finish((max(min(free, safe), 0.0) - v_now) / dt)


@numba.njit(cache=True, inline="always")
def gm(v_now, gap, v, v_lead, c, m, l, v_desired, k_free, a_max, length_ahead):  # pragma: no cover - compiled
    """GM: ``gm_accel(v_now, gap + length_ahead, v_lead - v, ...)`` with nothing ahead ``inf``,
    min the free-road law."""
    a = np.inf
    if math.isfinite(gap):
        d = gap + length_ahead
        if math.isfinite(d):
            a = c * max(v_now, 0.0) ** m * (v_lead - v) / max(d, 1e-3) ** l
        else:
            a = 0.0
    return _finish(min(a, _free(v_now, v_desired, k_free, a_max)))


@numba.njit(cache=True, inline="always")
def fuzzy(v_now, v, gap, v_lead, a_lead, p):  # pragma: no cover - compiled
    """Fuzzy: ``fuzzy_accel`` on the perceived scene (nothing ahead ``inf``), min the free-road law;
    ``p``: ``(T, gamma, s0, h, level_width, max_level, step, v_desired, k_free, a_max)``."""
    T, gamma, s0, h, level_width, max_level, step, v_desired, k_free, a_max = (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9])
    a = np.inf
    if math.isfinite(gap):
        level = min(max(np.rint((gap - (s0 + h * v)) / level_width), -max_level), max_level)
        a = (v_lead - v + a_lead * T) / gamma + step * level
    return _finish(min(a, _free(v_now, v_desired, k_free, a_max)))


@numba.njit(cache=True, inline="always")
def pipes(v_now, v, gap, v_lead, c, v_desired, k_free, a_max):  # pragma: no cover - compiled
    """Pipes: ``c (v_lead - v)`` on the perceived scene (nothing ahead ``inf``), min the free-road law."""
    a = c * (v_lead - v) if math.isfinite(gap) else np.inf
    return _finish(min(a, _free(v_now, v_desired, k_free, a_max)))


@numba.njit(cache=True, inline="always")
def newell(v_now, gap, c, r_min, v_desired, dt):  # pragma: no cover - compiled
    """Newell: ``(newell_speed(gap, ...) - v_now) / dt``."""
    speed = max(v_desired * (1.0 - math.exp(-c * (gap - r_min) / v_desired)), 0.0) if math.isfinite(gap) else v_desired
    return _finish((speed - v_now) / dt)


@numba.njit(cache=True, inline="always")
def tyler(v_now, v, gap, v_lead, c_v, c_s, c_t, s0, v_desired, k_free, a_max):  # pragma: no cover - compiled
    """Tyler: ``tyler_accel`` on the perceived scene (nothing ahead ``inf``), min the free-road law."""
    a = np.inf
    if math.isfinite(gap):
        a = c_v * (v_lead - v) + c_s * (gap - s0 - c_t * v)
    return _finish(min(a, _free(v_now, v_desired, k_free, a_max)))


@numba.njit(cache=True, inline="always")
def _acc_law(v, gap, v_lead, a_lead, k1, k2, k3, time_gap, s0):  # pragma: no cover - compiled
    if not math.isfinite(gap):
        return np.inf
    return k3 * a_lead + k2 * (v_lead - v) + k1 * (gap - (s0 + time_gap * v))


@numba.njit(cache=True, inline="always")
def acc(v, gap, v_lead, a_lead, gap2, v_lead2, a_lead2, two, p):  # pragma: no cover - compiled
    """ACC / CACC (``acc_accel``) on the current scene, with ``two`` the minimum over the second
    vehicle ahead (Eq. 3: doubled ``s0`` and time gap plus one length), min the set-speed
    controller; ``p``: ``(k1, k2, k3, time_gap, s0, v_set, k_cruise, a_max, vehicle_length)``."""
    k1, k2, k3, time_gap, s0, v_set, k_cruise, a_max, vehicle_length = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]
    a = _acc_law(v, gap, v_lead, a_lead, k1, k2, k3, time_gap, s0)
    if two:
        a = min(a, _acc_law(v, gap2, v_lead2, a_lead2, k1, k2, k3, 2.0 * time_gap, 2.0 * s0 + vehicle_length))
    return _finish(min(a, _free(v, v_set, k_cruise, a_max)))


# ---------------------------------------------------------------------------------------
# Any model by its code, for a loop that steps several (the column simulation)
# ---------------------------------------------------------------------------------------

# the models' codes in law(): a model class's ``_kernel_kind`` (acc_gym.drivers.baselines)
IDM, GIPPS, GM, FUZZY, PIPES, NEWELL, TYLER, ACC = range(8)
KINDS = {"idm": IDM, "gipps": GIPPS, "gm": GM, "fuzzy": FUZZY, "pipes": PIPES, "newell": NEWELL, "tyler": TYLER,
         "acc": ACC}
MAX_PARAMS = 10  # the longest parameter list of a law (fuzzy's); law()'s p has this many rows


@numba.njit(cache=True)
def law(kind, p, dt, two, v_now, v, gap, v_lead, a_lead, gap2, v_lead2, a_lead2):  # pragma: no cover - compiled
    """The output of the model with code ``kind`` for one vehicle: ``p`` its parameters in the
    order of the model's ``_kernel_fields`` (a float array of at least that many entries), ``dt``
    [s] the model's step (Gipps, Newell), ``two`` whether ACC takes the second vehicle ahead
    too. ``v``, ``gap``, ``v_lead``, ``a_lead`` are as perceived (the scene its reaction delay
    ago; ACC has none), ``v_now`` the current own speed; ``gap2``, ``v_lead2``, ``a_lead2`` the
    current second vehicle ahead (ACC only)."""
    if kind == IDM:
        return idm(v_now, gap, v, v_lead, p[0], p[1], p[2], p[3], p[4], p[5])
    if kind == GIPPS:
        return gipps(v_now, v, gap, v_lead, p[0], p[1], p[2], p[3], p[4], p[5], p[6], dt)
    if kind == GM:
        return gm(v_now, gap, v, v_lead, p[0], p[1], p[2], p[3], p[4], p[5], p[6])
    if kind == FUZZY:
        return fuzzy(v_now, v, gap, v_lead, a_lead, p)
    if kind == PIPES:
        return pipes(v_now, v, gap, v_lead, p[0], p[1], p[2], p[3])
    if kind == NEWELL:
        return newell(v_now, gap, p[0], p[1], p[2], dt)
    if kind == TYLER:
        return tyler(v_now, v, gap, v_lead, p[0], p[1], p[2], p[3], p[4], p[5], p[6])
    return acc(v, gap, v_lead, a_lead, gap2, v_lead2, a_lead2, two, p)


@numba.njit(cache=True)
def law_rows(kind, params, dt, two, fields, rows, out):  # pragma: no cover - compiled
    """:func:`law` of the model with code ``kind`` over a batch's ``rows`` (a model's ``act``):
    ``params`` its parameters in :func:`law`'s order, a tuple of float arrays of one value per
    row or one for all (:func:`_at`); ``fields`` the observation's ``(v_now, v, gap, v_lead,
    a_lead, gap2, v_lead2, a_lead2)`` arrays, as :func:`law` reads them."""
    v_now, v, gap, v_lead, a_lead, gap2, v_lead2, a_lead2 = fields
    p = np.empty(MAX_PARAMS)
    for r in rows:
        for i in range(len(params)):
            p[i] = _at(params[i], r)
        out[r] = law(kind, p, dt, two, v_now[r], v[r], gap[r], v_lead[r], a_lead[r], gap2[r], v_lead2[r], a_lead2[r])


# ---------------------------------------------------------------------------------------
# Every surrounding slot of a world's step at once (acc_gym.drivers.slots.SlotDrivers.act_world)
# ---------------------------------------------------------------------------------------

PROFILE, BASELINE = 2, 3  # SlotDrivers.kind's codes this kernel runs (0 no driver: 0; 1, an MPC driver, it does not)


@numba.njit(cache=True)
def slot_laws(obs, laws, a_des):  # pragma: no cover - compiled
    """The desired accelerations of every surrounding vehicle of a world's step into
    ``a_des[:, 1:]`` (``(B, S)`` [m/s^2]), read from the world's observation array ``obs``
    (``(S, 8, B)``, :func:`acc_gym.simulation._world_kernel.observe_all`); slot ``s`` of scene
    ``b`` is driver row ``r = (s - 1) B + b``. ``laws``: :meth:`SlotDrivers.compiled_laws
    <acc_gym.drivers.slots.SlotDrivers.compiled_laws>`' tuple (the rows' kinds, laws, parameters,
    switches, the step [s], the profiles and the clocks). By ``slot_kind[r]``: :data:`BASELINE`, the
    baseline model ``law_kind[r]`` (:data:`KINDS`) with parameters ``params[r]`` and ``two[r]``
    (:func:`law`, no reaction delay: the scene as it is now); :data:`PROFILE`, the speed
    profile row ``profile[r]`` played to its next sample ``min(clock[r] + 1, end)``, ``(that
    speed - v) / dt``; anything else (no driver) 0. The same numbers as each model's ``act`` and
    :meth:`SlotDrivers._play_profiles <acc_gym.drivers.slots.SlotDrivers._play_profiles>`
    (``tests/drivers/test_slots.py``). Then every row's clock advances by one."""
    slot_kind, law_kind, params, two, dt, profile, clock = laws
    S = obs.shape[0]
    B = obs.shape[2]
    last = profile.shape[1] - 1
    for s in range(1, S):
        for b in range(B):
            r = (s - 1) * B + b
            kind = slot_kind[r]
            v = obs[s, 0, b]
            if kind == BASELINE:
                a_des[b, s] = law(law_kind[r], params[r], dt, two[r], v, v, obs[s, 2, b], obs[s, 3, b], obs[s, 4, b],
                                  obs[s, 5, b], obs[s, 6, b], obs[s, 7, b])
            elif kind == PROFILE:
                a_des[b, s] = (profile[r, min(clock[r] + 1, last)] - v) / dt
            else:
                a_des[b, s] = 0.0
    for r in range(clock.shape[0]):
        clock[r] += 1


@numba.njit(cache=True)
def decide_world(obs, laws, ego_a, a_des):  # pragma: no cover - compiled
    """A world's whole decision when its surrounding drivers are :func:`slot_laws`'s: their
    accelerations into ``a_des[:, 1:]``, the ego's desired accelerations ``ego_a`` (``(B,)``
    [m/s^2]) into ``a_des[:, 0]``, and every row's clock advanced by one -- what
    :meth:`SingleLaneWorld.decide <acc_gym.simulation.single_lane.SingleLaneWorld.decide>`
    does with :meth:`SlotDrivers.act_world <acc_gym.drivers.slots.SlotDrivers.act_world>`, for
    a compiled caller that steps such a world (:func:`acc_gym.simulation._rollout_kernel.coast`)."""
    slot_laws(obs, laws, a_des)
    for b in range(a_des.shape[0]):
        a_des[b, 0] = ego_a[b]

