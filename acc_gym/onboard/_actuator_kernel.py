"""The actuators' step as one compiled call over named records (:mod:`acc_gym.onboard.actuators`
says what it does; this is its only implementation). The per-vehicle record is a numpy
structured array (:data:`VEHICLE`), as the radar's (:mod:`acc_gym.onboard._radar_kernel`)."""

from __future__ import annotations

import numba
import numpy as np

#: one vehicle's actuator (one record per vehicle)
VEHICLE = np.dtype([
    ("m", "i8"),  # whole steps of dead time
    ("f", "f8"),  # the fraction of a step beyond them
    ("alpha", "f8"),  # the lag's share of the difference closed in one step (1: no lag)
], align=True)


@numba.njit(cache=True)
def command(vehicles, hist, head, u, a_prev, out):  # pragma: no cover - compiled
    """This step's commands ``u`` in, what the vehicles are asked to realise into ``out``:
    ``vehicles`` (n,) :data:`VEHICLE`, ``hist`` (H, n) the last commands with the newest at
    ``head[0]``, ``a_prev`` what they realised over the last step."""
    size = hist.shape[0]
    h = (head[0] + 1) % size
    head[0] = h
    for i in range(u.shape[0]):
        hist[h, i] = u[i]
        v = vehicles[i]
        delayed = hist[(h - v.m) % size, i]
        if v.f != 0.0:
            delayed = (1.0 - v.f) * delayed + v.f * hist[(h - v.m - 1) % size, i]
        out[i] = delayed if v.alpha == 1.0 else a_prev[i] + v.alpha * (delayed - a_prev[i])
