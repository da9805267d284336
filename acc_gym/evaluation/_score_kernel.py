"""Compiled 100-point score of one episode: every number :func:`acc_gym.evaluation.scoring.score_episode` reports.

:func:`score` does in one pass over the samples (plus a short one for the speed-keeping
efficiency when it applies, and one over the lead's steady runs for the overshoot) what
the numpy oracle of the tests (``tests/score_oracle.py``) does with some hundred numpy
operations: Gapsafe and Q, the safety item (literal, or proper response: runs of Q < 0,
the grace time, responding), the transients (by the lead's identity, or without one by
appearing / disappearing vehicles and gap jumps), followable, free, candidate and
car-following samples, the band share, the closing-in rule, the efficiency ``u`` (both
branches, clipped or not), the lane items, comfort and the extra metrics of
:func:`acc_gym.evaluation.metrics.extra_metrics` (the overshoot with the same steady-run
rule as :func:`acc_gym.evaluation.metrics.speed_overshoot` and its compiled
:func:`acc_gym.evaluation.metrics._gradient`).

Every value equals the oracle's exactly: the formulas are written in numpy's
order of operations, and the three float means (``u`` over car-following samples, ``u``
of speed keeping, a steady run's lead speed) use :func:`pairwise_sum`, numpy's pairwise
summation; the other means are shares of counted samples, which numpy computes exactly
too. ``tests/evaluation/test_score_kernel.py`` compares the two on environment episodes
and on hand-made edge cases.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from acc_gym.evaluation.metrics import _gradient
from acc_gym.evaluation.trace import _columns_valid

# the config's row of score()'s parameter vector (acc_gym.evaluation.scoring._kernel_params builds it)
(P_B0, P_B1, P_BAND_WIDTH, P_STEADY_DV, P_MOVING, P_TRANSIENT, P_SENSOR, P_RESPONSE_DECEL, P_STOP_SPEED,
 P_LEAD_MARGIN, P_SPEED_TOL, P_APPROACH_DECEL, P_BAND_NEEDED, P_A_X, P_A_Y, P_LANE_CENTRED, P_STEADY_ACCEL,
 P_STEADY_TIME, P_MIN_DEVIATION, P_LITERAL_SAFETY, P_LITERAL_BAND, P_CLIP, P_ITEM_POINTS) = range(23)
N_PARAMS = 23
# score()'s outputs (counts and flags as floats; NaN: the reference's None / NaN)
(O_SCORE, O_QUALIFIED, O_R1, O_R2, O_U, O_J_X, O_J_Y,
 O_SAFE_OK, O_VIOLATIONS, O_FIRST_VIOLATION_T, O_MIN_Q, O_COLLISION,
 O_BAND_OK, O_APPLICABLE, O_SHARE, O_SAMPLES, O_APPROACHING,
 O_EDGE_OK, O_MIN_D2, O_LINE_OK, O_MIN_D3,
 O_SHARE_COMFORTABLE, O_SHARE_SAFE_SPACING, O_MIN_TTC, O_MAX_JERK, O_OVERSHOOT, O_TRANSIENTS, O_MIN_GAP,
 O_DURATION) = range(29)
N_OUT = 29


@numba.njit(cache=True, error_model="numpy")
def _block_sum(x, lo, n):  # pragma: no cover - compiled
    """numpy's pairwise sum of ``x[lo:lo + n]`` for ``n <= 128``: below 8 elements one by one
    from 0.0, else in eight interleaved accumulators combined as a tree, then the rest."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += x[i]
        return res
    r0 = x[lo]
    r1 = x[lo + 1]
    r2 = x[lo + 2]
    r3 = x[lo + 3]
    r4 = x[lo + 4]
    r5 = x[lo + 5]
    r6 = x[lo + 6]
    r7 = x[lo + 7]
    i = 8
    m = n - n % 8
    while i < m:
        k = lo + i
        r0 += x[k]
        r1 += x[k + 1]
        r2 += x[k + 2]
        r3 += x[k + 3]
        r4 += x[k + 4]
        r5 += x[k + 5]
        r6 += x[k + 6]
        r7 += x[k + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += x[lo + i]
        i += 1
    return res


@numba.njit(cache=True, error_model="numpy")
def pairwise_sum(x, lo, n):  # pragma: no cover - compiled
    """The sum of ``x[lo:lo + n]`` as numpy's ``add.reduce`` forms it (``pairwise_sum`` of
    ``numpy/_core/src/umath/loops_utils.h.src``): blocks of up to 128 by :func:`_block_sum`;
    a longer range is split in two at half its length rounded down to a multiple of 8 and
    the two sums added. numpy recurses; this walks the same tree with a stack (a recursive
    function loaded from numba's cache crashed the interpreter)."""
    if n <= 128:
        return _block_sum(x, lo, n)
    los = np.empty(128, np.int64)  # pending ranges, and how far each is done: 0 new, 1 left summed, 2 both
    ns = np.empty(128, np.int64)
    stage = np.empty(128, np.int64)
    sums = np.empty(128)  # sums of finished subranges, in order
    top = 0
    los[0] = lo
    ns[0] = n
    stage[0] = 0
    n_sums = 0
    while top >= 0:
        m = ns[top]
        if m <= 128:
            sums[n_sums] = _block_sum(x, los[top], m)
            n_sums += 1
            top -= 1
            continue
        half = m // 2
        half -= half % 8
        if stage[top] == 0:
            stage[top] = 1
            top += 1
            los[top] = los[top - 1]
            ns[top] = half
            stage[top] = 0
        elif stage[top] == 1:
            stage[top] = 2
            top += 1
            los[top] = los[top - 1] + half
            ns[top] = m - half
            stage[top] = 0
        else:
            n_sums -= 1
            sums[n_sums - 1] = sums[n_sums - 1] + sums[n_sums]
            top -= 1
    return sums[0]


@numba.njit(cache=True, error_model="numpy")
def mean(x, lo, n):  # pragma: no cover - compiled
    """``np.mean(x[lo:lo + n])`` (n >= 1): the reduction starts from add's identity 0.0."""
    return (0.0 + pairwise_sum(x, lo, n)) / n


@numba.njit(cache=True, error_model="numpy")
def _clip01(x):  # pragma: no cover - compiled
    """``np.clip(x, 0.0, 1.0)`` of a number that is not NaN."""
    x = x if x > 0.0 else 0.0
    return x if x < 1.0 else 1.0


@numba.njit(cache=True, error_model="numpy")
def _smallest(x, n, absent):  # pragma: no cover - compiled
    """The smallest of the ``n`` entries of an optional column ``x`` (``absent`` when it is empty)."""
    if x.shape[0] != n:
        return absent
    m = x[0]
    for i in range(1, n):
        if x[i] < m:
            m = x[i]
    return m


@numba.njit(cache=True, error_model="numpy")
def score(cols, p, tau1, grace, set_speed, out):  # pragma: no cover - compiled
    """Write the episode's score and every value behind it into ``out`` (:data:`N_OUT`).

    ``cols``: the :class:`~acc_gym.evaluation.trace.EgoTrace` columns ``(t, v, a, gap, v_lead,
    lead_id, a_y, d2, d3)``, the last four its optional ones (empty when absent); ``p`` the
    config's parameters (:data:`N_PARAMS`, ``P_*`` order); ``tau1`` and ``grace`` [s];
    ``set_speed`` NaN when the trace has none.
    """
    t, v, a, gap, v_lead, lead_id, a_y, d2, d3 = cols
    n = t.shape[0]
    b0 = p[P_B0]
    b1 = p[P_B1]
    bw = p[P_BAND_WIDTH]
    steady_dv = p[P_STEADY_DV]
    moving = p[P_MOVING]
    transient = p[P_TRANSIENT]
    sensor = p[P_SENSOR]
    resp_decel = -p[P_RESPONSE_DECEL]
    stop_speed = p[P_STOP_SPEED]
    a_x_comfort = p[P_A_X]
    literal_safety = p[P_LITERAL_SAFETY] != 0.0
    literal_band = p[P_LITERAL_BAND] != 0.0
    clip = p[P_CLIP] != 0.0
    has_set = not math.isnan(set_speed)
    fast_limit = set_speed + p[P_LEAD_MARGIN] + p[P_SPEED_TOL]  # a lead above it is faster than the set speed
    cruise_limit = set_speed - steady_dv
    far_edge = 1.0 + bw
    two_decel = 2.0 * p[P_APPROACH_DECEL]
    two_b0 = 2.0 * b0
    two_b1 = 2.0 * b1
    by_id = lead_id.shape[0] == n

    ubuf = np.empty(n)  # u_t of the car-following samples, in order
    free_m = np.empty(n, np.bool_)
    cand_m = np.empty(n, np.bool_)

    collision = False
    n_bad = 0
    first_bad = np.nan
    n_seen = 0
    n_safe = 0
    min_q = np.inf
    neg_prev = False
    run_start_t = t[0]
    last_event = t[0]
    ident_prev = 0.0
    has_prev = False
    n_cand = 0
    n_follow = 0
    n_band = 0
    all_closing = True
    n_comf = 0
    max_ax = 0.0
    min_ttc = np.inf
    max_jerk = -np.inf
    min_gap = np.inf
    for i in range(n):
        ti = t[i]
        vi = v[i]
        ai = a[i]
        g = gap[i]
        has = math.isfinite(g)
        v0 = v_lead[i] if has else 0.0
        gs = vi * tau1 + vi * vi / two_b1 - v0 * v0 / two_b0
        q = g - gs if has else np.inf

        # safety
        coll = has and g <= 0.0
        if coll:
            collision = True
        neg = has and q < 0.0
        if neg and not neg_prev:
            run_start_t = ti
        neg_prev = neg
        if literal_safety:
            bad = neg
        else:
            responding = ai <= resp_decel or vi <= stop_speed
            bad = (neg and ti - run_start_t > grace and not responding) or coll
        if bad:
            if n_bad == 0:
                first_bad = ti
            n_bad += 1
        if has:
            n_seen += 1
            if q < min_q:
                min_q = q
            if q >= 0.0:
                n_safe += 1

        # transients: a new vehicle ahead (by identity, else appearing / disappearing or a gap jump)
        if by_id:
            ident = lead_id[i] if has else -1.0
            if i > 0 and ident != ident_prev:
                last_event = ti
            ident_prev = ident
        elif i > 0:
            if has != has_prev:
                last_event = ti
            elif has:
                expected = (v_lead[i - 1] - v[i - 1]) * (ti - t[i - 1])
                if abs((g - gap[i - 1]) - expected) > 3.0:
                    last_event = ti
        has_prev = has
        settled = ti - last_event >= transient

        # car-following samples, the band and u_t
        too_fast = has_set and v0 > fast_limit
        followable = has and v0 > moving and not too_fast
        free_m[i] = (not (has and g <= sensor)) or (has and too_fast)
        if literal_band:
            cand = has and gs > 0.0
            follow = cand
        else:
            cand = followable and settled
            follow = cand and vi > moving and v0 > moving and abs(v0 - vi) <= steady_dv and gs > 0.0
        cand_m[i] = cand
        if cand:
            n_cand += 1
            if not literal_band and all_closing:  # the closing-in rule (scoring._closing_in)
                dv = vi - v0
                braking_phase = dv * dv >= two_decel * (g - far_edge * gs)
                cruising = has_set and vi >= cruise_limit
                if not (dv > steady_dv and (cruising or braking_phase)):
                    all_closing = False
        if follow:
            if q > 0.0 and q < bw * gs:
                n_band += 1
            u_t = q / (bw * gs)
            ubuf[n_follow] = _clip01(u_t) if clip else u_t
            n_follow += 1

        # extra metrics
        abs_a = abs(ai)
        if abs_a > max_ax:
            max_ax = abs_a
        if abs_a <= a_x_comfort:
            n_comf += 1
        if has:  # indicators.time_to_collision: 0 in contact, D1 / closing speed while closing in
            closing = vi - v_lead[i]
            if g <= 0.0:
                min_ttc = 0.0
            elif closing > 0.0:
                ttc = g / closing
                if ttc < min_ttc:
                    min_ttc = ttc
        if i > 0:
            jerk = abs(ai - a[i - 1]) / (ti - t[i - 1])
            if jerk > max_jerk:
                max_jerk = jerk
        if g < min_gap:
            min_gap = g

    # safety item
    safe_ok = n_bad == 0 and (literal_safety or not collision)

    # band item
    applicable = n_cand > 0
    approaching = False
    if not applicable:
        band_ok = True
        share = np.nan
    elif n_follow == 0:
        share = 0.0
        approaching = not literal_band and all_closing
        band_ok = approaching
    else:
        share = n_band / n_follow
        band_ok = share >= p[P_BAND_NEEDED] - 1e-12

    # efficiency
    if n_follow > 0:
        u = mean(ubuf, 0, n_follow)
    elif has_set and (approaching or not applicable):
        denom = bw * set_speed
        k = 0
        for i in range(n):
            if free_m[i] or (approaching and cand_m[i]):
                x = (set_speed - v[i]) / denom
                ubuf[k] = _clip01(x) if clip else x
                k += 1
        u = mean(ubuf, 0, k) if k > 0 else np.nan
    else:
        u = np.nan
    r1 = 0.0 if math.isnan(u) else (1.0 - u) * 20.0

    # lane items
    min_d2 = _smallest(d2, n, p[P_LANE_CENTRED])
    min_d3 = _smallest(d3, n, p[P_LANE_CENTRED])
    edge_ok = min_d2 > 0.0
    line_ok = min_d3 > 0.0

    # comfort
    j_x = max_ax / a_x_comfort
    max_ay = 0.0
    if a_y.shape[0] == n:
        for i in range(n):
            if abs(a_y[i]) > max_ay:
                max_ay = abs(a_y[i])
    j_y = max_ay / p[P_A_Y]
    if clip:
        j_x = min(j_x, 1.0)
        j_y = min(j_y, 1.0)
    r2 = (1.0 - j_x) * 10.0 + (1.0 - j_y) * 10.0

    n_qualified = int(safe_ok) + int(band_ok) + int(edge_ok) + int(line_ok)
    qualified = n_qualified == 4
    total = 60.0 + r1 + r2 if qualified else p[P_ITEM_POINTS] * n_qualified

    # speed overshoot after the lead's steady runs (metrics.speed_overshoot)
    dv0 = _gradient(v_lead, t)
    steady_accel = p[P_STEADY_ACCEL]
    worst = np.nan
    n_transients = 0
    i = 0
    while i < n:
        j = i
        while j < n and math.isfinite(gap[j]) and abs(dv0[j]) <= steady_accel and v_lead[j] > 0.5:
            j += 1
        if j == i:
            i += 1
            continue
        if not t[j - 1] - t[i] < p[P_STEADY_TIME]:
            v_star = mean(v_lead, i, j - i)
            dev0 = v_star - v[i]
            if not abs(dev0) < p[P_MIN_DEVIATION]:
                sign = 1.0 if dev0 > 0.0 else -1.0
                past = -np.inf
                for k in range(i, j):
                    x = sign * (v[k] - v_star)
                    if x > past:
                        past = x
                os = (0.0 if 0.0 > past else past) / abs(dev0)
                if math.isnan(worst) or os > worst:
                    worst = os
                n_transients += 1
        i = j

    out[O_SCORE] = total
    out[O_QUALIFIED] = 1.0 if qualified else 0.0
    out[O_R1] = r1
    out[O_R2] = r2
    out[O_U] = u
    out[O_J_X] = j_x
    out[O_J_Y] = j_y
    out[O_SAFE_OK] = 1.0 if safe_ok else 0.0
    out[O_VIOLATIONS] = n_bad
    out[O_FIRST_VIOLATION_T] = first_bad
    out[O_MIN_Q] = min_q if n_seen > 0 else np.nan
    out[O_COLLISION] = 1.0 if collision else 0.0
    out[O_BAND_OK] = 1.0 if band_ok else 0.0
    out[O_APPLICABLE] = 1.0 if applicable else 0.0
    out[O_SHARE] = share
    out[O_SAMPLES] = n_follow
    out[O_APPROACHING] = 1.0 if approaching else 0.0
    out[O_EDGE_OK] = 1.0 if edge_ok else 0.0
    out[O_MIN_D2] = min_d2
    out[O_LINE_OK] = 1.0 if line_ok else 0.0
    out[O_MIN_D3] = min_d3
    out[O_SHARE_COMFORTABLE] = n_comf / n
    out[O_SHARE_SAFE_SPACING] = n_safe / n_seen if n_seen > 0 else np.nan
    out[O_MIN_TTC] = min_ttc
    out[O_MAX_JERK] = max_jerk
    out[O_OVERSHOOT] = worst
    out[O_TRANSIENTS] = n_transients
    out[O_MIN_GAP] = min_gap
    out[O_DURATION] = t[n - 1] - t[0]


@numba.njit(cache=True, error_model="numpy")
def score_record(rec, n, p, tau1, grace, set_speed, out):  # pragma: no cover - compiled
    """:func:`score` of the first ``n`` samples of a record whose rows are the
    :class:`~acc_gym.evaluation.trace.EgoTrace` columns in their order (``t, v, a, gap,
    v_lead, a_lead, lead_id, a_y, d2, d3``, the environments' episode record), read where
    they are, when they pass the trace's column checks as given
    (:func:`acc_gym.evaluation.trace._columns_valid`). Returns whether they did; when not,
    nothing is written (the caller makes the trace, whose checks convert or raise)."""
    t = rec[0, :n]
    v = rec[1, :n]
    a = rec[2, :n]
    gap = rec[3, :n]
    v_lead = rec[4, :n]
    lead_id = rec[6, :n]
    a_y = rec[7, :n]
    d2 = rec[8, :n]
    d3 = rec[9, :n]
    if not _columns_valid(t, v, a, gap, v_lead, rec[5, :n], lead_id, a_y, d2, d3):
        return False
    score((t, v, a, gap, v_lead, lead_id, a_y, d2, d3), p, tau1, grace, set_speed, out)
    return True
