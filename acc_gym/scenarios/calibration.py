"""Fitting the scenario-parameter laws of :mod:`acc_gym.scenarios.distributions` to data.

* :func:`fit_normal`, :func:`fit_lognormal`, :func:`fit_laplace`: closed-form maximum
  likelihood for one law; :func:`fit_ml` dispatches on the law's kind name.
* :func:`fit_best`: fits several families and keeps the one with the lowest Akaike
  information criterion, AIC = 2 k - 2 ln L (k = 2 parameters for each family here).
* :func:`fit_bivariate_em`: maximum likelihood for a correlated pair by expectation
  maximisation, using rows where one of the two quantities is missing (NaN) -- a radar
  log loses the second quantity when the target is out of range.

Estimates carry the unit of the data (log-normal M and S: of ln x, dimensionless).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from acc_gym.scenarios.distributions import BivariateNormal, Laplace, LogNormal, Normal

UnivariateLaw = Normal | LogNormal | Laplace
_LOG_2PI = math.log(2.0 * math.pi)


def _sample(x: Any, name: str = "x") -> np.ndarray:
    """``x`` as a 1-D float array of at least 2 finite values, else ``ValueError``."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"{name} must be finite, got {float(arr[bad[0]])!r} at index {bad[0]} "
                         f"({bad.size} non-finite value(s))")
    if arr.size < 2:
        raise ValueError(f"{name} needs at least 2 samples, got {arr.size}")
    return arr


def _spread(value: float, what: str, arr: np.ndarray) -> float:
    if not value > 0:
        raise ValueError(f"{what} of x is {value!r} (all samples equal {float(arr[0])!r}); cannot fit a scale")
    return float(value)


def fit_normal(x: Any) -> Normal:
    """ML normal law: mu = sample mean, sigma = sample std with divisor n (ddof=0, biased)."""
    arr = _sample(x)
    return Normal(float(arr.mean()), _spread(arr.std(), "the standard deviation", arr))


def fit_lognormal(x: Any) -> LogNormal:
    """ML log-normal law: M and S are the mean and the ddof=0 std of ln x; needs x > 0."""
    arr = _sample(x)
    bad = np.flatnonzero(arr <= 0)
    if bad.size:
        raise ValueError(f"fit_lognormal needs x > 0, got x[{bad[0]}] = {float(arr[bad[0]])!r} "
                         f"({bad.size} non-positive value(s))")
    ln = np.log(arr)
    return LogNormal(float(ln.mean()), _spread(ln.std(), "the standard deviation of ln x", arr))


def fit_laplace(x: Any) -> Laplace:
    """ML Laplace law: mu = sample median, b = mean absolute deviation from that median."""
    arr = _sample(x)
    mu = float(np.median(arr))
    return Laplace(mu, _spread(np.mean(np.abs(arr - mu)), "the mean absolute deviation", arr))


_FITTERS: dict[str, Callable[[Any], UnivariateLaw]] = {
    "normal": fit_normal, "lognormal": fit_lognormal, "laplace": fit_laplace}


def fit_ml(x: Any, kind: str) -> UnivariateLaw:
    """The ML law of family ``kind`` ("normal", "lognormal" or "laplace") for samples ``x``."""
    if kind not in _FITTERS:
        raise ValueError(f"unknown law kind {kind!r}; expected one of {sorted(_FITTERS)}")
    return _FITTERS[kind](x)


@dataclass(frozen=True)
class FitResult:
    """One candidate of :func:`fit_best`: the ML law, its log-likelihood ln L, AIC = 4 - 2 ln L and n."""

    law: UnivariateLaw
    log_likelihood: float
    aic: float
    n: int

    @property
    def kind(self) -> str:
        return self.law.kind


def fit_best(x: Any, kinds: Sequence[str] = ("normal", "lognormal", "laplace")) -> tuple[FitResult, list[FitResult]]:
    """Fit each family in ``kinds`` by ML and return (lowest-AIC result, all results by ascending AIC).

    The log-normal family is skipped when some x <= 0 (its likelihood is zero there).
    """
    arr = _sample(x)
    if isinstance(kinds, str):
        kinds = (kinds,)
    results = []
    for kind in kinds:
        if kind == "lognormal" and np.any(arr <= 0):
            continue
        law = fit_ml(arr, kind)
        ll = float(np.sum(law.logpdf(arr)))
        results.append(FitResult(law, ll, 2.0 * 2 - 2.0 * ll, int(arr.size)))
    if not results:
        raise ValueError(f"no family of {list(kinds)} can be fitted (log-normal needs x > 0)")
    results.sort(key=lambda r: r.aic)
    return results[0], results


# --------------------------------------------------------------------------------- EM
@dataclass(frozen=True)
class EMResult:
    """Outcome of :func:`fit_bivariate_em`.

    ``log_likelihood`` is the observed-data log-likelihood of ``law``; ``history`` holds
    it at the initial estimate and after each of the ``n_iter`` EM updates.
    """

    law: BivariateNormal
    log_likelihood: float
    n_iter: int
    converged: bool
    history: tuple[float, ...] = ()


def _observed_loglik(xc: np.ndarray, a: np.ndarray, b: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> float:
    """ln L of complete rows ``xc`` (n, 2), first-only values ``a`` and second-only values ``b``."""
    c00, c01, c11 = cov[0, 0], cov[0, 1], cov[1, 1]
    det = c00 * c11 - c01 * c01
    d0, d1 = xc[:, 0] - mean[0], xc[:, 1] - mean[1]
    ll = -0.5 * np.sum(c11 * d0 * d0 - 2.0 * c01 * d0 * d1 + c00 * d1 * d1) / det - len(xc) * (
        _LOG_2PI + 0.5 * math.log(det))
    for v, m, c in ((a, mean[0], c00), (b, mean[1], c11)):
        ll += -0.5 * np.sum((v - m) ** 2) / c - 0.5 * len(v) * (_LOG_2PI + math.log(c))
    return float(ll)


def _em_step(xc: np.ndarray, a: np.ndarray, b: np.ndarray, mean: np.ndarray,
             cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One EM update: fill each missing coordinate with its conditional mean given the observed one
    (E-step), then take mean and covariance of the filled rows plus the conditional variances (M-step)."""
    c00, c01, c11 = cov[0, 0], cov[0, 1], cov[1, 1]
    filled = np.concatenate([
        xc,
        np.column_stack([a, mean[1] + c01 / c00 * (a - mean[0])]),
        np.column_stack([mean[0] + c01 / c11 * (b - mean[1]), b]),
    ])
    new_mean = filled.mean(axis=0)
    d = filled - new_mean
    s = d.T @ d
    s[0, 0] += len(b) * (c00 - c01 * c01 / c11)  # Var(x0 | x1) of the rows missing x0
    s[1, 1] += len(a) * (c11 - c01 * c01 / c00)  # Var(x1 | x0) of the rows missing x1
    s /= len(filled)
    s[1, 0] = s[0, 1]
    return new_mean, s


def fit_bivariate_em(X: Any, n_iter: int = 500, tol: float = 1e-9) -> EMResult:
    """ML bivariate normal from rows of ``X`` (n, 2) in which either coordinate may be NaN (missing).

    Rows missing both coordinates are ignored. EM starts from the mean and ddof=0
    covariance of the complete rows (at least 3 needed) and stops when an update raises
    the observed-data log-likelihood by less than ``tol`` (absolute), or after ``n_iter``
    updates. Without missing values the result is the closed-form ML estimate.
    """
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"X must have shape (n, 2), got {X.shape}")
    if np.any(np.isinf(X)):
        raise ValueError("X must not contain infinity (NaN marks a missing value)")
    if isinstance(n_iter, bool) or not isinstance(n_iter, numbers.Integral) or n_iter < 0:
        raise ValueError(f"n_iter must be an integer >= 0, got {n_iter!r}")
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be finite and > 0, got {tol!r}")
    miss = np.isnan(X)
    xc = X[~miss.any(axis=1)]
    a = X[miss[:, 1] & ~miss[:, 0], 0]
    b = X[miss[:, 0] & ~miss[:, 1], 1]
    if len(xc) < 3:
        raise ValueError(f"X needs at least 3 complete rows (no NaN) to initialise EM, got {len(xc)}")
    mean = xc.mean(axis=0)
    d = xc - mean
    cov = d.T @ d / len(xc)
    cov[1, 0] = cov[0, 1]
    if not cov[0, 0] * cov[1, 1] - cov[0, 1] ** 2 > 0:
        raise ValueError(f"the complete rows of X are collinear (covariance {cov.tolist()}); cannot initialise EM")
    ll = _observed_loglik(xc, a, b, mean, cov)
    history = [ll]
    converged, it = False, 0
    for it in range(1, int(n_iter) + 1):
        mean, cov = _em_step(xc, a, b, mean, cov)
        new = _observed_loglik(xc, a, b, mean, cov)
        history.append(new)
        converged, ll = new - ll < tol, new
        if converged:
            break
    law = BivariateNormal((float(mean[0]), float(mean[1])),
                          ((float(cov[0, 0]), float(cov[0, 1])), (float(cov[0, 1]), float(cov[1, 1]))))
    return EMResult(law, ll, it, converged, tuple(history))
