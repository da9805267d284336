"""Confidence intervals for a campaign's summary (all deterministic: no random numbers).

* :func:`poisson_rate_ci`: exact (Garwood) interval for a Poisson count ``k`` over an
  exposure -- collisions per hour of traffic.
* :func:`wilson_ci`: Wilson score interval for a binomial share -- share of episodes qualified.
* :func:`mean_ci`: Student-t interval for a mean -- mean score, mean overshoot, damping.
* :func:`weighted_share_ci`: a share of *time* pooled over episodes (``sum w_i s_i / sum
  w_i`` with ``w_i`` the episode's duration), with the ratio-estimator (cluster-robust)
  standard error and a t quantile: episodes are the independent units, samples within one
  are not -- share of comfortable acceleration, share of safe spacing.

An interval that cannot be formed (no data, one observation, zero spread with a t
interval is fine) is ``(nan, nan)``; the summary turns NaN into ``None`` in JSON.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats


def _check_confidence(confidence: float) -> float:
    if not (isinstance(confidence, (int, float)) and 0.0 < confidence < 1.0):
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    return float(confidence)


def poisson_rate_ci(count: int, exposure: float, confidence: float = 0.95) -> tuple[float, float, float]:
    """``(rate, low, high)`` of ``count`` events over ``exposure`` (exact Garwood interval)."""
    alpha = 1.0 - _check_confidence(confidence)
    if count < 0 or int(count) != count:
        raise ValueError(f"count must be a non-negative integer, got {count!r}")
    if not exposure > 0:
        return math.nan, math.nan, math.nan
    low = 0.0 if count == 0 else stats.chi2.ppf(alpha / 2, 2 * count) / 2
    high = stats.chi2.ppf(1 - alpha / 2, 2 * count + 2) / 2
    return count / exposure, float(low) / exposure, float(high) / exposure


def wilson_ci(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float, float]:
    """``(share, low, high)``: Wilson score interval of ``successes`` out of ``n``."""
    confidence = _check_confidence(confidence)
    if n <= 0:
        return math.nan, math.nan, math.nan
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be within [0, n={n}], got {successes!r}")
    z = stats.norm.ppf(0.5 + confidence / 2)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return p, max(0.0, centre - half), min(1.0, centre + half)


def mean_ci(values, confidence: float = 0.95, bounds: tuple[float, float] = (-math.inf, math.inf)) \
        -> tuple[float, float, float]:
    """``(mean, low, high)``: Student-t interval of the mean of ``values`` (NaNs dropped), clipped to
    ``bounds`` (the range the quantity can take, e.g. [0, 1] for a damping ratio)."""
    confidence = _check_confidence(confidence)
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return math.nan, math.nan, math.nan
    m = float(x.mean())
    if x.size == 1:
        return m, math.nan, math.nan
    half = stats.t.ppf(0.5 + confidence / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return m, float(max(bounds[0], m - half)), float(min(bounds[1], m + half))


def weighted_share_ci(shares, weights, confidence: float = 0.95) -> tuple[float, float, float]:
    """``(share, low, high)``: ``sum w s / sum w`` over episodes (NaN shares dropped) with a
    cluster-robust t interval, clipped to [0, 1]."""
    confidence = _check_confidence(confidence)
    s = np.asarray(shares, dtype=float)
    w = np.asarray(weights, dtype=float)
    keep = ~np.isnan(s)
    s, w = s[keep], w[keep]
    if s.size == 0 or w.sum() <= 0:
        return math.nan, math.nan, math.nan
    est = float(np.sum(w * s) / np.sum(w))
    n = s.size
    if n == 1:
        return est, math.nan, math.nan
    se = math.sqrt(n / (n - 1) * np.sum((w * (s - est)) ** 2)) / float(w.sum())
    half = stats.t.ppf(0.5 + confidence / 2, n - 1) * se
    return est, max(0.0, est - half), min(1.0, est + half)
