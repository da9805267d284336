"""The importance-sampling estimate of a failure probability, its interval and its diagnostics.

From ``n`` episodes drawn from the proposal ``q``, with weights ``w_i = p(x_i) / q(x_i)``
and failure indicators ``f_i``, ``y_i = w_i f_i``. The plain importance-sampling estimate
``mean(y)`` is unbiased (``E_q[w f] = E_p[f] = p``); we also know ``E_q[w] = 1`` exactly, so
the weights are their own control variate (the regression estimator, Owen 2013, ch. 9.9):

    b       = cov(y, w) / var(w)                 (0 when every weight is equal: crude Monte Carlo)
    p_hat   = mean(y) - b (mean(w) - 1)
    var_hat = sum_i (y_i - mean(y) - b (w_i - mean(w)))^2 / ((n - 2) n)
    95 % interval  p_hat +- 1.96 sqrt(var_hat), clipped to [0, 1]
    relative half-width  rhw = 1.96 sqrt(var_hat) / p_hat

Decided: its variance is never larger than the plain estimate's (to first order) and it
is exact where the plain one is not -- when every episode fails ``y = w``, ``b = 1`` and
``p_hat = 1`` exactly with a zero-width interval, where ``mean(w)`` would be 1 only on
average. The price is a bias of order ``1/n`` from estimating ``b`` on the same episodes,
far below the standard error at the sample sizes used (the coverage study measures the
whole: ``tests/risk``, ``benchmarks/bench_risk.py``). Crude Monte Carlo (``w = 1``) is the
plain mean. **No failure**: ``p_hat = 0`` says little, so the
estimate reports an exact one-sided 95 % upper bound instead. Every proposal here is a
defensive mixture with a share ``beta_i`` of the nominal law (``beta_i`` = 1 for a draw
from the nominal law itself), so draw ``i`` fails with probability at least ``beta_i p``;
draws without a failure then have probability at most ``exp(-p E)``, ``E = sum_i beta_i``
(the run's *exposure*, adaptive rounds included), and ``p <= -ln(0.05) / E`` at 95 %:
the rule of three when every draw is nominal.

**Acceleration** against crude Monte Carlo: crude sampling needs
``n_crude = 1.96^2 (1 - p) / (p rhw^2)`` episodes for the same relative half-width at the
same ``p``; the factor is ``n_crude / episodes used`` (adaptive rounds included).

**Diagnostics** (:func:`diagnose`; each is a sentence in ``warnings``, never a silent fix):

* *too few failures*: fewer than ``MIN_FAILURES`` (10) failing episodes: the normal
  interval is not to be trusted;
* *weight degeneracy*: the failures' effective number ``(sum w f)^2 / sum (w f)^2`` is
  below a quarter of their count, or one episode carries more than half of ``p_hat``;
* *proposal misses part of the failure region*: failures drawn by the nominal component
  carry most of the estimate (the fitted ``g`` does not cover where they are);
* *weights do not average to 1*: ``mean(w)`` is more than 4 standard errors from 1
  (``E_q[w] = 1`` for any valid proposal: a density that disagrees with the sampler shows here).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

Z95 = 1.959963984540054
MIN_FAILURES = 10


@dataclass(frozen=True)
class Estimate:
    """One probability's estimate (``p`` is 0 and ``upper_bound`` set when nothing failed)."""

    event: str
    p: float
    ci_low: float
    ci_high: float
    rhw: float  # relative half-width (inf when p is 0)
    failures: int
    episodes: int  # in the estimation round
    episodes_total: int  # adaptive rounds included
    ess: float  # effective sample size of all weights
    ess_failures: float  # effective number of failures
    mean_weight: float
    acceleration: float | None  # crude episodes for the same rhw / episodes_total (None without failures)
    upper_bound: float | None = None  # exact 95 % bound when no episode failed
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in asdict(self).items()}


def crude_episodes(p: float, rhw: float) -> float:
    """Episodes crude Monte Carlo needs for relative half-width ``rhw`` at probability ``p``."""
    if not (0.0 < p < 1.0) or not rhw > 0:
        return math.nan
    return Z95 ** 2 * (1.0 - p) / (p * rhw ** 2)


def upper_bound(exposure: float, level: float = 0.95) -> float:
    """Exact one-sided upper bound on ``p`` after draws without a failure whose nominal shares
    add up to ``exposure`` (``N`` draws from the nominal law: ``N``; from a mixture holding a
    share ``beta``: ``beta N``)."""
    if exposure <= 0:
        return 1.0
    return min(1.0, -math.log(1.0 - level) / exposure)


def estimate(log_w: np.ndarray, failed: np.ndarray, *, event: str = "collision", episodes_total: int | None = None,
             exposure: float | None = None, nominal: np.ndarray | None = None) -> Estimate:
    """The estimate of ``P(failed)`` from an estimation round's log-weights and failure flags
    (``nominal``: which draws came from the nominal component, for the diagnostics;
    ``exposure``: the run's, for the bound when nothing failed -- default: as many as the
    episodes, every one nominal)."""
    log_w = np.asarray(log_w, dtype=float)
    f = np.asarray(failed, dtype=bool)
    if log_w.shape != f.shape or log_w.ndim != 1:
        raise ValueError(f"log_w and failed must be 1-D arrays of one length, got {log_w.shape} and {f.shape}")
    n = int(f.size)
    if n < 2:
        raise ValueError(f"an estimate needs at least 2 episodes, got {n}")
    if not np.all(np.isfinite(log_w)):
        raise ValueError("a log-weight is not finite: a draw outside the nominal law's support")
    total = n if episodes_total is None else int(episodes_total)
    w = np.exp(log_w)
    y = w * f
    p, se = _regression(y, w)
    half = Z95 * se
    ess = float(np.sum(w) ** 2 / np.sum(w * w))
    k = int(f.sum())
    ess_f = float(np.sum(y) ** 2 / np.sum(y * y)) if k else 0.0
    mean_w = float(np.mean(w))
    if k == 0:
        bound = upper_bound(total if exposure is None else exposure)
        est = Estimate(event, 0.0, 0.0, bound, math.inf, 0, n, total, ess, 0.0, mean_w, None, bound)
    else:
        rhw = half / p if p > 0 else math.inf
        need = crude_episodes(p, rhw)
        est = Estimate(event, p, max(p - half, 0.0), min(p + half, 1.0), rhw, k, n, total, ess, ess_f, mean_w,
                       (need / total) if math.isfinite(need) else None)
    return _with_warnings(est, w, y, f, nominal)


def _regression(y: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """The regression estimate of ``E[y]`` with ``w`` as control variate (``E[w] = 1``) and its
    standard error (see the module docstring)."""
    n = y.size
    dw = w - np.mean(w)
    dy = y - np.mean(y)
    vw = float(np.dot(dw, dw))
    if vw <= 0.0 or n < 3:  # equal weights (crude Monte Carlo): the plain mean
        return float(np.mean(y)), float(np.std(y, ddof=1) / math.sqrt(n))
    b = float(np.dot(dy, dw)) / vw
    resid = dy - b * dw
    p = float(np.mean(y - b * w)) + b
    se = math.sqrt(float(np.dot(resid, resid)) / (n - 2) / n)
    return min(max(p, 0.0), 1.0), se


def _with_warnings(est: Estimate, w: np.ndarray, y: np.ndarray, f: np.ndarray, nominal) -> Estimate:
    est.warnings.extend(diagnose(w, y, f, nominal))
    return est


def diagnose(w: np.ndarray, y: np.ndarray, f: np.ndarray, nominal=None) -> list[str]:
    """The warnings of the module docstring that apply."""
    out = []
    k = int(f.sum())
    if k < MIN_FAILURES:
        out.append(f"too few failures: {k} (< {MIN_FAILURES}); the interval is not reliable"
                   + ("; the upper bound is exact" if k == 0 else ""))
    if k:
        ess_f = float(np.sum(y) ** 2 / np.sum(y * y))
        top = float(np.max(y) / np.sum(y))
        if k >= 2 and ess_f < 0.25 * k:
            out.append(f"weight degeneracy: the {k} failures count as {ess_f:.1f} effective failures")
        if k >= 2 and top > 0.5:
            out.append(f"weight degeneracy: one episode carries {top:.0%} of the estimate")
        if nominal is not None:
            nom = np.asarray(nominal, dtype=bool)
            share = float(np.sum(y[nom]) / np.sum(y))
            if share > 0.5 and np.any(f & nom) and not np.all(nom):
                out.append(f"the proposal misses part of the failure region: failures drawn from the nominal law "
                           f"carry {share:.0%} of the estimate")
    n = w.size
    se_w = float(np.std(w, ddof=1) / math.sqrt(n))
    if se_w > 0 and abs(float(np.mean(w)) - 1.0) > 4.0 * se_w:
        out.append(f"weights average {float(np.mean(w)):.3f}, more than 4 standard errors ({se_w:.3f}) from 1: "
                   "the proposal's density and its sampler disagree")
    return out
