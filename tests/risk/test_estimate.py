"""The estimator on toy failure regions whose probability is known in closed form."""

import math

import numpy as np
import pytest
from scipy.special import ndtr

from acc_gym.risk.episodes import draw_episodes
from acc_gym.risk.estimate import crude_episodes, estimate, upper_bound
from acc_gym.risk.proposal import Proposal
from acc_gym.risk.run import search
from acc_gym.scenarios.distributions import Laplace, LogNormal, Normal


def _toy(laws: dict, fail_margin):
    """A simulation without a simulator: ``S = fail_margin(params)`` (failure when S <= 0)."""

    def simulate(rnd, prop, size, seed=0):
        draws, lw = draw_episodes(prop, seed, rnd, 0, size)
        s = fail_margin({n: np.array([d[0][n] for d in draws]) for n in prop.names})
        return [{"params": d[0], "nominal": d[1], "log_w": float(lw[i]), "S": float(s[i])}
                for i, d in enumerate(draws)]

    return Proposal.nominal_only(laws), simulate, lambda recs: np.array([r["S"] for r in recs])


GAUSS = {"x": Normal(0.0, 1.0, low=-10.0, high=10.0)}
P_GAUSS = float(ndtr(-4.0) - ndtr(-10.0))  # P(X > 4) of the truncated law (mass ~ 1)


def _run(laws, margin, budget=6000, seed=0, rhw=0.1):
    prop, sim, perf = _toy(laws, margin)
    return search(prop, lambda r, p, n: sim(r, p, n, seed), perf, budget=budget, round_size=512, max_rounds=8,
                  target_rhw=rhw)


def _final(pooled, perf):
    s = perf(pooled)
    return estimate(np.array([r["log_w"] for r in pooled]), s <= 0, nominal=np.array([r["nominal"] for r in pooled]))


def test_gaussian_tail_is_estimated_within_its_interval_and_the_proposal_concentrates():
    prop, pooled, rounds, stop = _run(GAUSS, lambda x: 4.0 - x["x"])
    est = _final(pooled, lambda recs: np.array([r["S"] for r in recs]))
    assert stop == "target reached"
    assert abs(est.p - P_GAUSS) < 1.5 * (est.ci_high - est.p)  # within 3 standard errors (the coverage of the
    assert abs(est.p / P_GAUSS - 1) < 0.15                     # 95 % interval is measured over repetitions below)
    g = prop.tilted["x"]
    assert 3.8 < g.mu < 5.0 and g.sigma == 1.0  # shifted to the tail (mean ~4.2), never narrowed
    assert [r["kind"] for r in rounds].count("adaptive") >= 2  # it took levels to get there
    used = sum(r["episodes"] for r in rounds)
    assert crude_episodes(est.p, est.rhw) / used > 100  # crude needs ~ 1.96^2 / (3.2e-5 x 0.01) ~ 1.2e7


def test_product_of_laws_with_a_corner_failure_region():
    laws = {"a": LogNormal(math.log(10.0), 0.3, low=2.0, high=60.0), "b": Laplace(0.0, 1.0, low=-12.0, high=12.0)}
    a0, b0 = 20.0, -3.0
    pa = float((ndtr(-(math.log(a0) - math.log(10.0)) / 0.3) - ndtr(-(math.log(60.0) - math.log(10.0)) / 0.3))
               / (ndtr((math.log(60.0) - math.log(10.0)) / 0.3) - ndtr((math.log(2.0) - math.log(10.0)) / 0.3)))
    pb = (0.5 * math.exp(b0) - 0.5 * math.exp(-12.0)) / (1.0 - math.exp(-12.0))
    truth = pa * pb  # ~ 1.0e-3

    def margin(x):  # fails when a > a0 and b < b0: the distance to that corner
        return np.maximum((a0 - x["a"]) / 5.0, (x["b"] - b0))

    prop, pooled, _, _ = _run(laws, margin, budget=8000, rhw=0.1)
    est = _final(pooled, lambda recs: np.array([r["S"] for r in recs]))
    assert abs(est.p - truth) < 1.5 * (est.ci_high - est.p)  # within 3 standard errors
    assert prop.tilted["a"].M > math.log(a0) - 0.2 and prop.tilted["b"].mu < b0 + 0.5


def test_unbiased_and_covering_over_repetitions_with_a_fitted_proposal():
    """With the proposal the search fitted, 300 independent estimates of 400 draws each: their
    mean is within 3 standard errors of the truth and the 95 % interval covers it in 93-97 %
    of them (binomial noise of 300 runs allowed: 90-99 %)."""
    prop, _, _, _ = _run(GAUSS, lambda x: 4.0 - x["x"])
    rng = np.random.default_rng(2024)
    ests, covered = [], 0
    for _ in range(300):
        draws = [prop.sample(rng) for _ in range(400)]
        x = np.array([d[0]["x"] for d in draws])
        est = estimate(prop.log_weight({"x": x}), x >= 4.0)
        ests.append(est.p)
        covered += est.ci_low <= P_GAUSS <= est.ci_high
    ests = np.array(ests)
    se = ests.std(ddof=1) / math.sqrt(ests.size)
    assert abs(ests.mean() - P_GAUSS) < 3 * se
    assert 0.90 <= covered / 300 <= 0.99


def test_every_episode_failing_gives_one_exactly():
    rng = np.random.default_rng(0)
    est = estimate(rng.normal(0, 0.7, 300), np.ones(300, bool))
    assert (est.p, est.ci_low, est.ci_high) == (1.0, 1.0, 1.0)


def test_crude_estimate_is_the_plain_frequency_with_its_normal_interval():
    f = np.zeros(1000, bool)
    f[:25] = True
    est = estimate(np.zeros(1000), f)
    half = 1.959963984540054 * math.sqrt(0.025 * 0.975 * 1000 / 999 / 1000)
    assert est.p == pytest.approx(0.025, abs=1e-15)
    assert est.ci_high - est.p == pytest.approx(half, rel=1e-12)
    assert est.acceleration == pytest.approx(crude_episodes(0.025, half / 0.025) / 1000)
    assert est.acceleration == pytest.approx(1.0, rel=1e-3)  # crude is its own baseline


def test_no_failure_gives_an_exact_upper_bound_not_zero():
    # 2500 draws from mixtures holding 10 % of the nominal law, then 500 nominal ones
    est = estimate(np.zeros(500), np.zeros(500, bool), episodes_total=3000, exposure=0.1 * 2500 + 500)
    assert est.p == 0.0 and est.upper_bound == pytest.approx(-math.log(0.05) / 750)
    assert est.ci_high == est.upper_bound and est.acceleration is None
    assert any("too few failures" in w for w in est.warnings)
    assert upper_bound(1000) == pytest.approx(2.9957 / 1000, rel=1e-4)  # the rule of three
    assert estimate(np.zeros(1000), np.zeros(1000, bool)).upper_bound == upper_bound(1000)


def test_diagnostics_flag_degenerate_weights_and_a_missed_region():
    lw = np.log(np.full(2000, 0.5))
    f = np.zeros(2000, bool)
    f[:12] = True
    lw[0] = math.log(10.0)  # one failure drawn by the nominal component with the largest weight
    nominal = np.zeros(2000, bool)
    nominal[0] = True
    est = estimate(lw, f, nominal=nominal)
    text = " ".join(est.warnings)
    assert "one episode carries" in text and "misses part of the failure region" in text
    assert "weights average" in text  # mean(w) ~ 0.5: not a valid proposal's weights


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="at least 2 episodes"):
        estimate(np.zeros(1), np.ones(1, bool))
    with pytest.raises(ValueError, match="not finite"):
        estimate(np.array([0.0, -np.inf]), np.array([True, False]))
    with pytest.raises(ValueError, match="one length"):
        estimate(np.zeros(3), np.zeros(4, bool))
