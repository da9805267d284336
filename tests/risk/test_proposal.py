"""Proposals: weights from the generator's own densities, checked against independent formulas."""

import math

import numpy as np
import pytest
from scipy import stats

from acc_gym.risk.episodes import episode_draw
from acc_gym.risk.proposal import DEFENSIVE, Proposal, tilted_keys
from acc_gym.scenarios.distributions import BivariateNormal, Constant, Laplace, LogNormal, Normal
from acc_gym.scenarios.registry import scenario_type


def _scipy_logpdf(law, x):
    """The truncated density written independently with scipy.stats."""
    x = np.asarray(x, dtype=float)
    if isinstance(law, Normal):
        a, b = (law.low - law.mu) / law.sigma, (law.high - law.mu) / law.sigma
        return stats.truncnorm.logpdf(x, a, b, loc=law.mu, scale=law.sigma)
    if isinstance(law, LogNormal):
        base = stats.lognorm(s=law.S, scale=math.exp(law.M))
        mass = base.cdf(law.high) - base.cdf(law.low)
        return base.logpdf(x) - math.log(mass)
    if isinstance(law, Laplace):
        base = stats.laplace(loc=law.mu, scale=law.b)
        return base.logpdf(x) - math.log(base.cdf(law.high) - base.cdf(law.low))
    raise TypeError(law)


def test_cut_in_tilts_every_random_parameter_but_the_duration():
    st = scenario_type("singlelane/2/cut-in")
    keys = tilted_keys(st.parameters)
    assert set(keys) == {"v_sv", "gap", "v_rel", "t_lc", "lc_duration"}
    assert not isinstance(st.parameters["time_gap"], Normal) and isinstance(st.parameters["time_gap"], Constant)


def test_log_weights_equal_independent_densities_on_random_draws():
    st = scenario_type("singlelane/2/cut-in")
    nominal = dict(st.parameters)
    tilted = {"v_sv": Normal(33.0, 2.0, low=8.0, high=40.0),
              "gap": LogNormal(math.log(9.0), 0.2, low=5.0, high=60.0),
              "v_rel": Normal(-6.0, 1.0, low=-8.0, high=6.0),
              "t_lc": nominal["t_lc"], "lc_duration": Normal(3.0, 0.5, low=2.5, high=7.0)}
    prop = Proposal(nominal, tilted, 0.2)
    rng = np.random.default_rng(3)
    draws = [prop.sample(rng)[0] for _ in range(500)]
    x = {n: np.array([d[n] for d in draws]) for n in prop.names}
    log_p = sum(_scipy_logpdf(nominal[k], x[k]) for k in tilted)
    log_g = sum(_scipy_logpdf(tilted[k], x[k]) for k in tilted)
    expected = log_p - np.log(0.2 * np.exp(log_p) + 0.8 * np.exp(log_g))
    np.testing.assert_allclose(prop.log_weight(x), expected, rtol=0, atol=1e-9)
    assert np.all(np.exp(prop.log_weight(x)) <= 1 / 0.2 + 1e-12)  # the defensive bound


def test_the_generator_samples_the_density_the_weights_use():
    """What ScenarioType.build draws is distributed as the law whose logpdf weighs it."""
    st = scenario_type("singlelane/2/cut-in")
    rng = np.random.default_rng(11)
    gaps = np.array([st.sample_params(rng)["gap"] for _ in range(20000)])
    law = st.parameters["gap"]
    edges = np.quantile(gaps, np.linspace(0, 1, 21))
    grid = [np.linspace(lo, hi, 201) for lo, hi in zip(edges[:-1], edges[1:])]
    mass = np.array([np.trapezoid(np.exp(law.logpdf(g)), g) for g in grid])
    np.testing.assert_allclose(mass, 0.05, atol=0.006)  # each empirical 5 % bin holds 5 % of the density


def test_nominal_proposal_gives_weight_one_exactly():
    st = scenario_type("singlelane/2/approach")
    prop = Proposal.nominal_only(st.parameters)
    rng = np.random.default_rng(0)
    draws = [prop.sample(rng)[0] for _ in range(200)]
    lw = prop.log_weight({n: np.array([d[n] for d in draws]) for n in prop.names})
    assert np.all(lw == 0.0)


def test_bivariate_pair_is_tilted_jointly_and_weighted_by_its_box_density():
    st = scenario_type("singlelane/2/car-following")
    nominal = dict(st.parameters)
    assert ("v_sv", "gap") in tilted_keys(nominal)
    pair = nominal[("v_sv", "gap")]
    g = BivariateNormal((32.0, 15.0), ((4.0, 1.0), (1.0, 9.0)), low=pair.low, high=pair.high)
    prop = Proposal(nominal, {("v_sv", "gap"): g}, DEFENSIVE)
    x = {"v_sv": np.array([30.0, 35.0]), "gap": np.array([12.0, 20.0])}
    pts = np.stack([x["v_sv"], x["gap"]], axis=1)
    r = g.logpdf(pts) - pair.logpdf(pts)
    np.testing.assert_allclose(prop.log_weight(x), -np.log(DEFENSIVE + (1 - DEFENSIVE) * np.exp(r)), rtol=1e-12)


def test_draws_depend_only_on_seed_round_and_episode():
    st = scenario_type("singlelane/2/cut-in")
    prop = Proposal.nominal_only(st.parameters)
    a = episode_draw(prop, 7, 2, 130)
    assert a == episode_draw(prop, 7, 2, 130)
    assert a != episode_draw(prop, 7, 2, 131) and a != episode_draw(prop, 7, 3, 130)


def test_cross_entropy_fit_moves_towards_the_elite_and_keeps_kind_and_support():
    st = scenario_type("singlelane/2/cut-in")
    prop = Proposal.nominal_only(st.parameters)
    n = 50
    x = {"v_sv": np.full(n, 35.0), "gap": np.linspace(6, 8, n), "v_rel": np.linspace(-7.5, -6.5, n),
         "t_lc": np.full(n, 3.0), "lc_duration": np.full(n, 4.0)}
    new = prop.fit(x, np.ones(n))
    gap = new.tilted["gap"]
    assert isinstance(gap, LogNormal) and (gap.low, gap.high) == (5.0, 60.0)
    assert gap.M < st.parameters["gap"].M and new.tilted["v_rel"].mu < -4.0
    assert new.tilted["v_sv"].sigma == st.parameters["v_sv"].sigma  # never narrower than nominal


def test_bad_proposals_are_named():
    st = scenario_type("singlelane/2/cut-in")
    with pytest.raises(ValueError, match="'nope'"):
        Proposal(dict(st.parameters), {"nope": Normal(0, 1)})
    with pytest.raises(ValueError, match="same kind"):
        Proposal(dict(st.parameters), {"gap": Normal(10, 1, low=5, high=60)})
    with pytest.raises(ValueError, match="beta"):
        Proposal(dict(st.parameters), {}, 0.0)
    with pytest.raises(ValueError, match="positive, finite weights"):
        Proposal.nominal_only(st.parameters).fit({"v_sv": np.ones(2)}, np.array([np.nan, 1.0]))


def test_proposal_round_trips_through_json():
    import json

    st = scenario_type("singlelane/2/car-following")
    prop = Proposal.nominal_only(st.parameters)
    back = Proposal.from_dict(st.parameters, json.loads(json.dumps(prop.to_dict())))
    assert back == prop
