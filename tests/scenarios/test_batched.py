"""The counter-based, batched scenario sampler (:mod:`acc_gym.scenarios.batched`, issue 35).

* its generator is Philox4x32-10 (the Random123 known-answer vectors);
* a scenario's draws are a pure function of (id, seed): the same whatever the batch, its
  size, the scenario's place in it or the order of the calls;
* the laws are the declared ones: Kolmogorov-Smirnov tests on 10,000 draws per law (one
  per seed 0..9,999; fixed, so the verdicts are deterministic) against the truncated
  law's exact CDF, and for the bivariate normal and the surrounding drivers against large
  samples of the numpy samplers that define them (two-sample tests).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from acc_gym.drivers.population import sample_driver_values
from acc_gym.scenarios import batched as B
from acc_gym.scenarios.distributions import BivariateNormal, Constant, LogNormal, Normal
from acc_gym.scenarios.registry import list_scenarios, scenario_type

N = 10_000
ALPHA = 1e-3  # KS tests' level: a correct sampler fails one law in a thousand (the seeds are fixed)

# the Random123 distribution's tests/kat_vectors, "philox4x32 10" lines: counter, key, output
KAT = [((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
       ((0xFFFFFFFF,) * 4, (0xFFFFFFFF,) * 2, (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
       ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
        (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1))]


@pytest.mark.parametrize("counter, key, expected", KAT)
def test_the_generator_is_philox4x32_10(counter, key, expected):
    assert tuple(int(w) for w in B.philox4x32(*counter, *key)) == expected


def test_uniforms_are_inside_the_unit_interval_and_uniform():
    u = B.uniforms(123, 456, 7, 100_001)
    assert u.shape == (100_001,) and 0.0 < u.min() and u.max() < 1.0
    assert stats.kstest(u, "uniform").pvalue > ALPHA
    assert not np.array_equal(u[:50], B.uniforms(123, 456, 8, 50))  # another stream
    assert not np.array_equal(u[:50], B.uniforms(123, 457, 7, 50))  # another key


def test_the_normal_inverse_cdf_is_scipys():
    from scipy.special import ndtri

    p = np.concatenate([np.linspace(1e-6, 1 - 1e-6, 20_001), np.geomspace(1e-300, 0.03, 2_000),
                        1.0 - np.geomspace(1e-15, 0.03, 1_000)])
    got = np.array([B._ndtri(x) for x in p])
    assert np.allclose(got, ndtri(p), rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("sid", ["singlelane/3/lane-change+cut-in", "singlelane/2/car-following", "carfollowing/varied",
                                 "carfollowing/emergency", "stopandgo"])
def test_a_scenarios_parameters_are_a_function_of_its_id_and_seed_alone(sid):
    stype = scenario_type(sid)
    seeds = list(range(40, 90))
    whole = B.draw_params(stype, seeds)
    one_by_one = [B.draw_params(stype, [s])[0] for s in seeds]
    backwards = B.draw_params(stype, seeds[::-1])[::-1]
    halves = B.draw_params(stype, seeds[25:]) + B.draw_params(stype, seeds[:25])
    assert whole == one_by_one == backwards == halves[25:] + halves[:25]
    assert set(whole[0]) == set(stype.parameter_names)
    assert len({tuple(p.values()) for p in whole}) > 1 or all(isinstance(law, Constant)
                                                              for law in stype.parameters.values())


def test_driver_draws_are_a_function_of_key_and_vehicle_alone():
    keys = np.array([B.key_of("stopandgo", s) for s in range(30)])
    speeds = np.linspace(3.0, 38.0, 30)
    whole = B.draw_drivers("typical", speeds, keys, 0)
    assert whole == [B.draw_drivers("typical", speeds[i:i + 1], keys[i:i + 1], 0)[0] for i in range(30)]
    assert B.draw_drivers("typical", speeds[::-1], keys[::-1], 0)[::-1] == whole
    assert B.draw_drivers("typical", speeds, keys, 1) != whole  # the POV2 draws on its own stream


def _truncated_cdf(law):
    """The exact CDF of a truncated univariate law, from scipy."""
    if isinstance(law, Normal):
        base = stats.norm(law.mu, law.sigma)
    elif isinstance(law, LogNormal):
        base = stats.lognorm(law.S, scale=math.exp(law.M))
    else:
        base = stats.laplace(law.mu, law.b)
    lo, hi = base.cdf(law.low), base.cdf(law.high)
    return lambda x: (base.cdf(x) - lo) / (hi - lo)


def _laws():
    """Every distinct univariate and bivariate law of the scenario catalogue, with a type declaring it."""
    seen = {}
    for sid in list_scenarios():
        for key, law in scenario_type(sid).parameters.items():
            if not isinstance(law, Constant):
                seen.setdefault(law, (sid, key))
    return list(seen.items())


LAWS = _laws()


def _draws(sid, key):
    stype = scenario_type(sid)
    params = B.draw_params(stype, range(N))
    names = key if isinstance(key, tuple) else (key,)
    return np.array([[p[n] for n in names] for p in params])


@pytest.mark.parametrize("law, where", [(law, w) for law, w in LAWS if not isinstance(law, BivariateNormal)],
                         ids=lambda x: repr(x) if not isinstance(x, tuple) else f"{x[0]}:{x[1]}")
def test_univariate_laws_follow_their_declared_cdf(law, where):
    x = _draws(*where)[:, 0]
    assert law.low <= x.min() and x.max() <= law.high
    assert stats.kstest(x, _truncated_cdf(law)).pvalue > ALPHA


@pytest.mark.parametrize("law, where", [(law, w) for law, w in LAWS if isinstance(law, BivariateNormal)],
                         ids=lambda x: repr(x) if not isinstance(x, tuple) else f"{x[0]}:{x[1]}")
def test_bivariate_laws_follow_their_declared_law(law, where):
    x = _draws(*where)
    ref = law.sample(np.random.default_rng(0), 200_000)
    assert np.all((x >= law.low) & (x <= law.high))
    for j in range(2):
        assert stats.ks_2samp(x[:, j], ref[:, j]).pvalue > ALPHA
    # the dependence: the correlation within 4 standard errors of the reference's
    r, r_ref = np.corrcoef(x.T)[0, 1], np.corrcoef(ref.T)[0, 1]
    assert abs(r - r_ref) < 4 * (1 - r_ref ** 2) / math.sqrt(N)


@pytest.mark.parametrize("kind", sorted(B.DRIVER_KINDS))
@pytest.mark.parametrize("speed", [6.0, 27.0])
def test_surrounding_drivers_follow_the_population_sampler(kind, speed):
    keys = np.array([B.key_of("singlelane/2/car-following", s) for s in range(N)])
    got = B.draw_drivers(kind, np.full(N, speed), keys, 0)
    rng = np.random.default_rng(1)
    ref = [sample_driver_values(rng, speed, kind) for _ in range(40_000)]
    assert set(got[0]) == set(ref[0])
    for name in got[0]:
        x, y = np.array([d[name] for d in got]), np.array([d[name] for d in ref])
        if np.ptp(y) == 0.0:
            assert np.all(x == y[0]), name
        else:
            assert stats.ks_2samp(x, y).pvalue > ALPHA, name


def test_the_builders_generator_is_the_registrys():
    from acc_gym.scenarios.registry import scenario_rngs

    for sid, seed in (("stopandgo", 0), ("singlelane/2/cut-in", 2 ** 31 - 2), ("carfollowing/varied", 77)):
        a, b = B.builder_rng(sid, seed), scenario_rngs(sid, seed)[1]
        assert a.bit_generator.state == b.bit_generator.state and np.array_equal(a.random(8), b.random(8))
