"""Paper 003's per-sample indicators as pure array functions (any shape, broadcasting).

    D1      = centre distance - (l_TV + l_BV) / 2 = the bumper-to-bumper gap
    Gapsafe = v1 tau1 + v1^2 / (2 b1) - v0^2 / (2 b0)
    Q = G   = D1 - Gapsafe
    u_t     = (D1 - Gapsafe) / (0.2 Gapsafe)
    j_x     = max |a_x| / a_x,comfort;   j_y likewise

``v1`` is the ego's (TV's) speed, ``v0`` the speed of the vehicle ahead (BV), ``b0``/``b1``
their maximum decelerations (> 0), ``tau1`` the ego's reaction time.
"""

from __future__ import annotations

import numpy as np

from acc_gym._validation import check_positive


def centre_to_gap(centre_distance, length_ego, length_lead):
    """Paper 003's D1 from the centre-to-centre distance and the two lengths [m]."""
    return np.asarray(centre_distance, float) - 0.5 * (np.asarray(length_ego, float) + np.asarray(length_lead, float))


def gap_safe(v1, v0, tau1: float, b0: float, b1: float):
    """Gapsafe [m]: reaction distance plus the difference of the two braking distances."""
    check_positive("tau1", tau1)
    check_positive("b0", b0)
    check_positive("b1", b1)
    v1 = np.asarray(v1, float)
    v0 = np.asarray(v0, float)
    return v1 * tau1 + v1 ** 2 / (2.0 * b1) - v0 ** 2 / (2.0 * b0)


def safety_q(d1, gapsafe):
    """Q = D1 - Gapsafe [m] (also the car-following indicator G)."""
    return np.asarray(d1, float) - np.asarray(gapsafe, float)


def in_band(g, gapsafe, width: float = 0.2):
    """``0 < G < width * Gapsafe`` (False where Gapsafe <= 0)."""
    g = np.asarray(g, float)
    gs = np.asarray(gapsafe, float)
    return (gs > 0) & (g > 0) & (g < width * gs)


def efficiency_u(g, gapsafe, width: float = 0.2, clip: bool = True):
    """u_t = G / (width Gapsafe), NaN where Gapsafe <= 0; clipped to [0, 1] if ``clip``."""
    g = np.asarray(g, float)
    gs = np.asarray(gapsafe, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(gs > 0, g / (width * np.where(gs > 0, gs, 1.0)), np.nan)
    return np.clip(u, 0.0, 1.0) if clip else u


def comfort_j(acceleration, comfort_max: float, clip: bool = True) -> float:
    """j = max |a| / a_comfort_max over the samples (0 for an empty series); clipped to [0, 1] if ``clip``."""
    check_positive("comfort_max", comfort_max)
    a = np.abs(np.asarray(acceleration, float))
    j = float(a.max() / comfort_max) if a.size else 0.0
    return min(max(j, 0.0), 1.0) if clip else j


def time_to_collision(d1, v1, v0):
    """D1 / (v1 - v0) where the ego closes in, 0 where D1 <= 0 (in contact: the collision has
    happened, whatever the speeds then), inf elsewhere [s]."""
    d1 = np.asarray(d1, float)
    closing = np.asarray(v1, float) - np.asarray(v0, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where((closing > 0) & np.isfinite(d1), np.maximum(d1, 0.0) / np.where(closing > 0, closing, 1.0),
                       np.inf)
    return np.where(d1 <= 0.0, 0.0, ttc)
