"""The radar's step as one compiled call over named records (:mod:`acc_gym.onboard.sensors` says
what a step does; this is its only implementation).

The records are numpy structured arrays: a field is read by name (``radar.far_reach``,
``scenes[r].gap``), and a whole record passes to the compiled call as one argument (numba
unboxes a structured array in about a microsecond, a named tuple of arrays in about one per
array)."""

from __future__ import annotations

import math

import numba
import numpy as np

#: the radar's constants at one step length, and the clock of its latency buffer (one record)
RADAR = np.dtype([
    ("far_reach", "f8"),  # [m] the far beam's range (within the observation's)
    ("far_tan", "f8"),  # tan of the far beam's half azimuth (inf: the half plane ahead)
    ("near_reach", "f8"),  # [m] the near beam's (0: none)
    ("near_tan", "f8"),
    ("gap_sd", "f8"),  # [m] (each scene's errors: these times its scale)
    ("gap_bias", "f8"),  # [m]
    ("rate_sd", "f8"),  # [m/s]
    ("rate_bias", "f8"),  # [m/s]
    ("p_end", "f8"),  # per step: a dropout ends
    ("coast", "f8"),  # [s]
    ("dt", "f8"),  # [s]
    ("obs_range", "f8"),  # [m] the observation's gap for nothing in range
    ("latency", "i8"),  # [steps]
    ("head", "i8"),  # the newest row of the reports buffer
], align=True)

#: one scene's radar (one record per scene)
SCENE = np.dtype([
    ("gap", "f8"),  # [m] the track
    ("rate", "f8"),  # [m/s]
    ("age", "f8"),  # [s] since the track's last detection
    ("scale", "f8"),  # the scene's multiple of the errors
    ("share", "f8"),  # its long-run dropped share (the chain's start)
    ("p_start", "f8"),  # its per-step probability that a dropout starts
    ("alive", "?"),  # a track is held
    ("dropped", "?"),  # the dropout chain's state
    ("pos", "i8"),  # the scene's next draw in its block
], align=True)


@numba.njit(cache=True, inline="always")
def _in_beam(gap, lateral, reach, tan):  # pragma: no cover - compiled
    if not gap <= reach:  # (a NaN or inf gap is not)
        return False
    return tan == math.inf or lateral <= max(gap, 0.0) * tan


@numba.njit(cache=True)
def _visible(p, gap, j, r, y, width):  # pragma: no cover - compiled
    """Whether vehicle ``j`` of scene ``r`` at ``gap`` is in range and in a beam (its nearest edge's
    lateral offset from the ego's centre line against the beam's width there)."""
    if j < 0:
        return False
    lateral = max(abs(y[r, j] - y[r, 0]) - 0.5 * width[r, j], 0.0)
    return _in_beam(gap, lateral, p.far_reach, p.far_tan) or (
        p.near_reach > 0.0 and _in_beam(gap, lateral, p.near_reach, p.near_tan))


@numba.njit(cache=True)
def sense(radar, scenes, reports, draws, obs, y, width, lead, lead2, rows, start, out):  # pragma: no cover
    """One step of the radars of scenes ``rows``, their reports into ``out`` ``(len(rows), 3)``.

    ``radar`` (1,) :data:`RADAR`; ``scenes`` (n,) :data:`SCENE`; ``reports`` (latency + 1, n, 3)
    the reported (gap, relative speed, in range) of the last steps; ``draws`` (n, BLOCK, 3) each
    scene's next draws (uniform, normal, normal); the world: ``obs`` (8, n) the egos' true
    observation rows (v, a, gap, v_lead, a_lead, gap2, v_lead2, a_lead2), ``y`` and ``width``
    (n, S) [m], ``lead`` and ``lead2`` (n, S) the vehicles ahead of each slot (-1: none).
    ``start``: the scenes start (the chain in its long-run distribution, no track, every row of
    the latency's buffer this step's report); else every scene steps. Returns the largest next
    draw position among ``rows`` after the step (a block is used up at ``BLOCK``)."""
    p = radar[0]
    pos_max = 0
    n_rows = reports.shape[0]
    if not start:
        radar[0].head = (p.head + 1) % n_rows
    head = radar[0].head
    for i in range(rows.shape[0]):
        r = rows[i]
        s = scenes[r]
        k = s.pos
        u, z_gap, z_rate = draws[r, k, 0], draws[r, k, 1], draws[r, k, 2]
        s.pos = k + 1
        pos_max = max(pos_max, k + 1)
        if start:
            s.dropped = u < s.share
            s.alive = False
            s.age = 0.0
        elif s.dropped:
            s.dropped = u >= p.p_end
        else:
            s.dropped = u < s.p_start
        det = False
        g_true = v_target = 0.0
        if not s.dropped:
            if _visible(p, obs[2, r], lead[r, 0], r, y, width):
                det, g_true, v_target = True, obs[2, r], obs[3, r]
            elif _visible(p, obs[5, r], lead2[r, 0], r, y, width):  # the old target, until the one ahead is seen
                det, g_true, v_target = True, obs[5, r], obs[6, r]
        age = s.age + p.dt
        if det:
            s.gap = g_true + s.scale * (p.gap_bias + p.gap_sd * z_gap)
            s.rate = v_target - obs[0, r] + s.scale * (p.rate_bias + p.rate_sd * z_rate)
            s.age = 0.0
            s.alive = True
        elif s.alive and age <= p.coast + 1e-9:  # coasting at the track's relative speed
            s.gap += s.rate * p.dt
            s.age = age
        else:
            s.alive = False
            s.age = age
        if s.alive:
            g, rate, seen = min(max(s.gap, 0.0), p.obs_range), s.rate, 1.0
        else:
            g, rate, seen = p.obs_range, 0.0, 0.0
        lo, hi = (0, n_rows) if start else (head, head + 1)
        for m in range(lo, hi):
            reports[m, r, 0], reports[m, r, 1], reports[m, r, 2] = g, rate, seen
        late = (head - p.latency) % n_rows
        out[i, 0], out[i, 1], out[i, 2] = reports[late, r, 0], reports[late, r, 1], reports[late, r, 2]
    return pos_max
