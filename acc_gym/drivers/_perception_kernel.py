"""The compiled step of :class:`acc_gym.drivers.perception.Perception` (the formulas are in
that module's docstring): the odometer, the reaction-time delay as a ring of the last
``k + 1`` scenes ahead, HDM's anticipation and the estimation errors' scaling, for every
driver in one pass. The error processes' draws stay in Python (each group's own generator)."""

from __future__ import annotations

import math

import numba


@numba.njit(cache=True, error_model="numpy")
def perceive(v, a, gap, v_lead, a_lead, hist, push, motion, w, params, out):
    """Write the perceived ``(v, a, gap, v_lead, a_lead)`` of ``n`` drivers into ``out[:5]``.

    ``hist`` ``(k + 1, 4, n)``: the ring of the scenes ahead (gap, v_lead, a_lead, odometer),
    ``push`` the number of scenes pushed so far (0: the run's first, which fills the ring, as
    the scene before the first ``k`` steps is the start's); ``motion`` ``(2, n)``: the own
    speed of the step before [m/s] and the distance driven [m], updated in place; ``w`` ``(2,
    n)`` the error processes now; ``params``: the delay ``k`` [steps], ``dt`` [s], the gap's
    relative error and the approach rate's error [1/s]."""
    k, dt, gap_error, rate_error = int(params[0]), params[1], params[2], params[3]
    v_prev = motion[0]
    odo = motion[1]
    n = v.shape[0]
    d1 = hist.shape[0]
    slot = push % d1
    for i in range(n):
        if push == 0:
            odo[i] = 0.0
        else:
            odo[i] = odo[i] + 0.5 * (v_prev[i] + v[i]) * dt
        v_prev[i] = v[i]
        if push == 0:
            for r in range(d1):
                hist[r, 0, i], hist[r, 1, i], hist[r, 2, i], hist[r, 3, i] = gap[i], v_lead[i], a_lead[i], odo[i]
        else:
            hist[slot, 0, i], hist[slot, 1, i], hist[slot, 2, i], hist[slot, 3, i] = gap[i], v_lead[i], a_lead[i], odo[i]
    old = (slot + 1) % d1  # the scene k steps ago (the oldest of the ring)
    tau = k * dt
    for i in range(n):
        gap_d, v_lead_d, a_lead_d, odo_d = hist[old, 0, i], hist[old, 1, i], hist[old, 2, i], hist[old, 3, i]
        out[0, i] = v[i]
        out[1, i] = a[i]
        if math.isfinite(gap[i]) and math.isfinite(gap_d):
            s = gap_d + tau * v_lead_d - (odo[i] - odo_d)
            s_est = s * math.exp(gap_error * w[0, i])
            out[2, i] = s_est if (s_est >= 0.0 or s_est != s_est) else 0.0  # numpy's maximum(., 0)
            s_pos = s if (s >= 0.0 or s != s) else 0.0
            v_lead_est = v_lead_d - rate_error * s_pos * w[1, i]
            out[3, i] = v_lead_est if (v_lead_est >= 0.0 or v_lead_est != v_lead_est) else 0.0
            out[4, i] = a_lead_d
        else:  # nothing ahead now or then: as given
            out[2, i], out[3, i], out[4, i] = gap[i], v_lead[i], a_lead[i]
    return out
