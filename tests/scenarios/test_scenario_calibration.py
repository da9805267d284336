"""Fitting scenario-parameter laws: closed-form ML, AIC selection and EM with missing values.

Parameter recovery uses n = 20,000 draws and a tolerance of 3 standard errors (SE), stated per test.
"""

import math
import re

import numpy as np
import pytest
from scipy import stats

from acc_gym.scenarios.calibration import (
    EMResult,
    FitResult,
    fit_best,
    fit_bivariate_em,
    fit_laplace,
    fit_lognormal,
    fit_ml,
    fit_normal,
)
from acc_gym.scenarios.distributions import BivariateNormal, Laplace, LogNormal, Normal

N = 20_000


def _loglik(law, x):
    return float(np.sum(law.logpdf(x)))


def test_fit_normal_recovers_parameters():
    x = np.random.default_rng(11).normal(3.0, 2.0, N)
    law = fit_normal(x)
    assert isinstance(law, Normal)
    assert abs(law.mu - 3.0) < 3 * 2.0 / math.sqrt(N)  # SE(mu) = sigma / sqrt(n) = 0.014
    assert abs(law.sigma - 2.0) < 3 * 2.0 / math.sqrt(2 * N)  # SE(sigma) = sigma / sqrt(2n) = 0.010
    assert law.mu == pytest.approx(x.mean(), rel=1e-14) and law.sigma == pytest.approx(x.std(ddof=0), rel=1e-14)
    np.testing.assert_allclose([law.mu, law.sigma], stats.norm.fit(x), rtol=1e-12)


def test_fit_lognormal_recovers_parameters():
    x = np.random.default_rng(12).lognormal(1.0, 0.5, N)
    law = fit_lognormal(x)
    assert isinstance(law, LogNormal)
    assert abs(law.M - 1.0) < 3 * 0.5 / math.sqrt(N)  # SE(M) = S / sqrt(n) = 0.0035
    assert abs(law.S - 0.5) < 3 * 0.5 / math.sqrt(2 * N)  # SE(S) = S / sqrt(2n) = 0.0025
    s, _, scale = stats.lognorm.fit(x, floc=0.0)
    np.testing.assert_allclose([law.M, law.S], [math.log(scale), s], rtol=1e-10)


def test_fit_laplace_recovers_parameters():
    x = np.random.default_rng(13).laplace(-2.0, 1.5, N)
    law = fit_laplace(x)
    assert isinstance(law, Laplace)
    assert abs(law.mu + 2.0) < 3 * 1.5 / math.sqrt(N)  # SE(median) = 1 / (2 f(mu) sqrt(n)) = b / sqrt(n) = 0.011
    assert abs(law.b - 1.5) < 3 * 1.5 / math.sqrt(N)  # |X - mu| ~ Exp(b): SE(b) = b / sqrt(n) = 0.011
    np.testing.assert_allclose([law.mu, law.b], stats.laplace.fit(x), rtol=1e-12)


@pytest.mark.parametrize("kind,x", [
    ("normal", np.random.default_rng(21).normal(3.0, 2.0, 2000)),
    ("lognormal", np.random.default_rng(22).lognormal(1.0, 0.5, 2000)),
    ("laplace", np.random.default_rng(23).laplace(-2.0, 1.5, 2000)),
])
def test_fit_is_a_local_maximum_of_the_likelihood(kind, x):
    law = fit_ml(x, kind)
    assert law.kind == kind
    best = _loglik(law, x)
    d = law.to_dict()
    for name in [k for k in d if k not in ("kind", "low", "high")]:
        for step in (0.99, 1.01):
            other = type(law)(**{**{k: v for k, v in d.items() if k != "kind"}, name: d[name] * step})
            assert _loglik(other, x) < best


@pytest.mark.parametrize("truth", [Normal(10.0, 2.0), LogNormal(1.0, 0.5), Laplace(20.0, 1.5)], ids=repr)
def test_fit_best_picks_the_generating_family(truth):
    x = truth.sample(np.random.default_rng(31), 5000)
    best, table = fit_best(x)
    assert best.law.kind == truth.kind
    assert [r.law.kind for r in table].count(truth.kind) == 1 and len(table) == 3
    assert best is table[0] and [r.aic for r in table] == sorted(r.aic for r in table)
    for r in table:
        assert isinstance(r, FitResult) and r.n == 5000
        assert r.log_likelihood == pytest.approx(_loglik(r.law, x), rel=1e-12)
        assert r.aic == pytest.approx(2 * 2 - 2 * r.log_likelihood, rel=1e-12)
    # the winner is clear: the runner-up is > 10 AIC units behind
    assert table[1].aic - best.aic > 10


def test_fit_best_skips_lognormal_on_non_positive_data():
    x = np.random.default_rng(32).normal(0.0, 1.0, 1000)
    best, table = fit_best(x)
    assert {r.kind for r in table} == {"normal", "laplace"} and best.kind == "normal"
    with pytest.raises(ValueError, match="no family"):
        fit_best(x, kinds=("lognormal",))


@pytest.mark.parametrize("fit", [fit_normal, fit_lognormal, fit_laplace])
def test_input_errors(fit):
    with pytest.raises(ValueError, match=re.escape("got nan at index 1")):
        fit([1.0, math.nan, 2.0])
    with pytest.raises(ValueError, match=re.escape("got inf at index 2")):
        fit([1.0, 2.0, math.inf])
    with pytest.raises(ValueError, match="at least 2 samples, got 1"):
        fit([1.0])
    with pytest.raises(ValueError, match="1-D"):
        fit([[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(ValueError, match="all samples equal"):
        fit([2.0, 2.0, 2.0])


def test_lognormal_fit_names_the_non_positive_value():
    with pytest.raises(ValueError, match=re.escape("x > 0, got x[2] = -0.5")):
        fit_lognormal([1.0, 2.0, -0.5, 0.0])


def test_fit_ml_unknown_kind():
    with pytest.raises(ValueError, match="unknown law kind 'gamma'"):
        fit_ml([1.0, 2.0, 3.0], "gamma")


# ------------------------------------------------------------------------------------ EM
MEAN, SD, RHO = np.array([25.0, 40.0]), np.array([4.0, 12.0]), 0.7
COV = np.array([[SD[0] ** 2, RHO * SD[0] * SD[1]], [RHO * SD[0] * SD[1], SD[1] ** 2]])


@pytest.fixture(scope="module")
def radar_log():
    """n = 20,000 pairs; 30 % of the rows miss the second quantity, 10 % the first (at random)."""
    rng = np.random.default_rng(2007)
    X = rng.multivariate_normal(MEAN, COV, N)
    u = rng.random(N)
    X[u < 0.3, 1] = np.nan
    X[(u >= 0.3) & (u < 0.4), 0] = np.nan
    return X


def _observed_loglik(X, mean, cov):
    """Independent reference: scipy densities of whatever each row observes."""
    miss = np.isnan(X)
    full, only0, only1 = ~miss.any(1), miss[:, 1] & ~miss[:, 0], miss[:, 0] & ~miss[:, 1]
    return float(stats.multivariate_normal(mean, cov).logpdf(X[full]).sum()
                 + stats.norm(mean[0], math.sqrt(cov[0][0])).logpdf(X[only0, 0]).sum()
                 + stats.norm(mean[1], math.sqrt(cov[1][1])).logpdf(X[only1, 1]).sum())


def test_em_recovers_the_law_from_incomplete_rows(radar_log):
    res = fit_bivariate_em(radar_log)
    assert isinstance(res, EMResult) and isinstance(res.law, BivariateNormal)
    assert res.converged and 1 < res.n_iter < 500
    m, c = np.array(res.law.mean), np.array(res.law.cov)
    # mean: SE ~ sd / sqrt(observed rows) = 0.03 and 0.10 -> 3 SE
    assert abs(m[0] - MEAN[0]) < 0.09 and abs(m[1] - MEAN[1]) < 0.3
    # sds: relative SE ~ 1 / sqrt(2 n_obs) = 0.6 % -> 2 %; correlation: SE (1 - rho^2) / sqrt(12,000) = 0.005 -> 0.015
    np.testing.assert_array_less(np.abs(np.sqrt(np.diag(c)) / SD - 1), 0.02)
    assert abs(res.law.correlation - RHO) < 0.015
    assert res.log_likelihood == pytest.approx(_observed_loglik(radar_log, m, c), rel=1e-12)


def test_em_log_likelihood_never_decreases_and_ends_at_a_maximum(radar_log):
    res = fit_bivariate_em(radar_log)
    h = np.array(res.history)
    assert len(h) == res.n_iter + 1 and h[-1] == res.log_likelihood
    assert np.all(np.diff(h) >= -1e-8)  # EM's monotonicity, up to rounding of a sum of 20,000 terms
    assert h[-1] > h[0]  # EM improved on its complete-rows start
    assert h[-1] - h[-2] < 1e-9
    # a local maximum: moving any of the 5 parameters lowers the observed-data likelihood
    m, c = np.array(res.law.mean), np.array(res.law.cov)
    sd, r = np.sqrt(np.diag(c)), res.law.correlation
    for i in range(5):
        for step in (-1e-3, 1e-3):
            p = np.array([*m, *np.log(sd), np.arctanh(r)])
            p[i] += step
            s, rr = np.exp(p[2:4]), np.tanh(p[4])
            cov = [[s[0] ** 2, rr * s[0] * s[1]], [rr * s[0] * s[1], s[1] ** 2]]
            assert _observed_loglik(radar_log, p[:2], cov) < res.log_likelihood


def test_em_iteration_limit(radar_log):
    res = fit_bivariate_em(radar_log, n_iter=1)
    assert res.n_iter == 1 and not res.converged and len(res.history) == 2
    assert res.history[1] > res.history[0]
    assert res.log_likelihood < fit_bivariate_em(radar_log).log_likelihood


def test_em_ignores_rows_missing_both(radar_log):
    padded = np.vstack([radar_log, np.full((500, 2), np.nan)])
    assert fit_bivariate_em(padded).law == fit_bivariate_em(radar_log).law


def test_em_without_missing_values_is_the_closed_form():
    X = np.random.default_rng(5).multivariate_normal(MEAN, COV, N)
    res = fit_bivariate_em(X)
    assert res.converged
    np.testing.assert_allclose(res.law.mean, X.mean(0), rtol=1e-10, atol=0)
    np.testing.assert_allclose(res.law.cov, np.cov(X.T, ddof=0), rtol=1e-10, atol=0)


def test_em_input_errors():
    X = np.array([[1.0, 2.0], [2.0, 1.0], [np.nan, 3.0], [4.0, np.nan], [5.0, np.nan]])
    with pytest.raises(ValueError, match="at least 3 complete rows"):
        fit_bivariate_em(X)
    with pytest.raises(ValueError, match=re.escape("shape (n, 2), got (5,)")):
        fit_bivariate_em(np.ones(5))
    with pytest.raises(ValueError, match="collinear"):
        fit_bivariate_em([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    with pytest.raises(ValueError, match="infinity"):
        fit_bivariate_em([[1.0, 2.0], [2.0, np.inf], [3.0, 1.0], [0.0, 0.0]])
