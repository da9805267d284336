"""Compiled loops of :mod:`acc_gym.simulation.ring`: the gap of each vehicle to its leader (the
ring's one definition of it, :func:`gap_to_leader`) and the snapshot a step's drivers decide
from, in one pass."""

from __future__ import annotations

import numba


@numba.njit(cache=True, inline="always")
def gap_to_leader(s_i, s_lead, length_lead, lap):
    """[m] A vehicle's bumper-to-bumper gap to its leader: the leader's unwrapped position
    ``s_lead`` plus ``lap`` (the ring's length for the first vehicle, whose leader is the last,
    one lap ahead; else 0), minus its own ``s_i`` and the leader's length ``length_lead``
    (scalars: numba's array arguments cost more than this arithmetic)."""
    lead = s_lead + lap if lap != 0.0 else s_lead
    return lead - s_i - length_lead


@numba.njit(cache=True)
def gaps(s, lengths, length, out):
    """``out[b, i]``: :func:`gap_to_leader` for every row and vehicle of ``s`` ``(R, N)``."""
    n = s.shape[1]
    for b in range(s.shape[0]):
        for i in range(n):
            j = i - 1 if i > 0 else n - 1
            out[b, i] = gap_to_leader(s[b, i], s[b, j], lengths[j], length if i == 0 else 0.0)


@numba.njit(cache=True)
def snapshot(s, v, a, lengths, length, ahead, cells_b, cells_j, rows):
    """``ahead`` ``(3, R, N)``: each vehicle's gap [m] to its leader, the leader's speed [m/s]
    and acceleration [m/s^2]; ``rows`` ``(5, M)``: ``v, a, gap, v_lead, a_lead`` of the cells
    ``(cells_b[m], cells_j[m])``."""
    R, N = s.shape
    for b in range(R):
        for i in range(N):
            j = i - 1 if i > 0 else N - 1
            ahead[0, b, i] = gap_to_leader(s[b, i], s[b, j], lengths[j], length if i == 0 else 0.0)
            ahead[1, b, i] = v[b, j]
            ahead[2, b, i] = a[b, j]
    for m in range(cells_b.shape[0]):
        b, i = cells_b[m], cells_j[m]
        rows[0, m] = v[b, i]
        rows[1, m] = a[b, i]
        rows[2, m] = ahead[0, b, i]
        rows[3, m] = ahead[1, b, i]
        rows[4, m] = ahead[2, b, i]
