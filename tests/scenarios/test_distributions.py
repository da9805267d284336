"""Scenario-parameter laws (van Tongeren et al. 2007, Eqs. 6-9): sampling, densities, truncation, serialisation.

Moment checks use N = 200,000 draws and a tolerance of 4 standard errors (SE), stated per test.
"""

import json
import math
import re
from dataclasses import fields

import numpy as np
import pytest
from scipy import stats
from scipy.integrate import trapezoid

from acc_gym.scenarios.distributions import (
    BivariateNormal,
    Constant,
    Laplace,
    LogNormal,
    Normal,
    from_dict,
)

N = 200_000
E = math.e


def _span(law):
    """A range holding all but a negligible part (< 1e-30) of the untruncated law."""
    if isinstance(law, Normal):
        return law.mu - 12 * law.sigma, law.mu + 12 * law.sigma
    if isinstance(law, Laplace):
        return law.mu - 80 * law.b, law.mu + 80 * law.b
    return math.exp(law.M - 12 * law.S), math.exp(law.M + 12 * law.S)


def _grid(law, n=400_001):
    a, b = _span(law)
    a, b = max(a, law.low), min(b, law.high)
    return np.geomspace(a, b, n) if isinstance(law, LogNormal) else np.linspace(a, b, n)


def _truncated(dist, low, high):
    """scipy reference log-density of ``dist`` renormalised to [low, high]."""
    log_mass = math.log(dist.cdf(high) - dist.cdf(low))
    return lambda x: np.where((x >= low) & (x <= high), dist.logpdf(x) - log_mass, -np.inf)


# (law, scipy reference logpdf)
LAWS = [
    (Normal(3.0, 2.0), stats.norm(3.0, 2.0).logpdf),
    (Normal(3.0, 2.0, low=0.0, high=5.0), stats.truncnorm(-1.5, 1.0, loc=3.0, scale=2.0).logpdf),
    (Normal(0.0, 1.0, low=6.0), stats.truncnorm(6.0, np.inf).logpdf),  # far upper tail
    (LogNormal(1.0, 0.5), stats.lognorm(s=0.5, scale=E).logpdf),
    (LogNormal(1.0, 0.5, low=2.0, high=6.0), _truncated(stats.lognorm(s=0.5, scale=E), 2.0, 6.0)),
    (Laplace(-2.0, 1.5), stats.laplace(-2.0, 1.5).logpdf),
    (Laplace(-2.0, 1.5, low=-1.0, high=4.0), _truncated(stats.laplace(-2.0, 1.5), -1.0, 4.0)),  # above the median
    (Laplace(-2.0, 1.5, high=-4.0), _truncated(stats.laplace(-2.0, 1.5), -np.inf, -4.0)),  # lower tail
]
IDS = [repr(law) for law, _ in LAWS]
TRUNCATED = [law for law, _ in LAWS if math.isfinite(law.low) or math.isfinite(law.high)]


def test_normal_sample_moments():
    x = Normal(3.0, 2.0).sample(np.random.default_rng(1), N)
    assert x.shape == (N,)
    assert abs(x.mean() - 3.0) < 4 * 2.0 / math.sqrt(N)  # SE of the mean: sigma / sqrt(N) = 0.0045
    assert abs(x.std() - 2.0) < 4 * 2.0 / math.sqrt(2 * N)  # SE of the std: sigma / sqrt(2N) = 0.0032


def test_lognormal_sample_moments_of_log():
    x = LogNormal(1.0, 0.5).sample(np.random.default_rng(2), N)
    assert np.all(x > 0)
    assert abs(np.log(x).mean() - 1.0) < 4 * 0.5 / math.sqrt(N)  # SE 0.0011
    assert abs(np.log(x).std() - 0.5) < 4 * 0.5 / math.sqrt(2 * N)  # SE 0.0008
    assert LogNormal(1.0, 0.5).mean == pytest.approx(math.exp(1.125))
    assert abs(x.mean() / math.exp(1.125) - 1) < 0.01


def test_laplace_sample_median_and_mean_absolute_deviation():
    x = Laplace(-2.0, 1.5).sample(np.random.default_rng(3), N)
    med = np.median(x)
    # SE of the median: 1 / (2 f(mu) sqrt(N)) = b / sqrt(N) = 0.0034; |X - mu| ~ Exp(b), SE of its mean b / sqrt(N)
    assert abs(med + 2.0) < 4 * 1.5 / math.sqrt(N)
    assert abs(np.mean(np.abs(x - med)) - 1.5) < 4 * 1.5 / math.sqrt(N)
    assert abs(x.std() - 1.5 * math.sqrt(2)) < 0.01  # std of the Laplace law: b sqrt 2


@pytest.mark.parametrize("law,ref", LAWS, ids=IDS)
def test_logpdf_integrates_to_one_and_matches_scipy(law, ref):
    x = _grid(law)
    assert trapezoid(np.exp(law.logpdf(x)), x) == pytest.approx(1.0, abs=1e-6)
    a, b = _span(law)
    pts = np.concatenate([x[::20_000], [a - 1.0, law.low - 0.5, law.high + 0.5, b + 1.0]])
    pts = pts[np.isfinite(pts) & (pts > (0 if isinstance(law, LogNormal) else -np.inf))]
    ours, theirs = law.logpdf(pts), ref(pts)
    assert np.array_equal(np.isneginf(ours), np.isneginf(theirs))
    fin = np.isfinite(theirs)
    np.testing.assert_allclose(ours[fin], theirs[fin], rtol=1e-9, atol=1e-12)
    assert isinstance(law.logpdf(float(x[len(x) // 2])), float)


def test_lognormal_logpdf_is_minus_infinity_off_its_support_and_nan_stays_nan():
    law = LogNormal(0.0, 1.0)
    assert np.all(np.isneginf(law.logpdf([-1.0, 0.0])))
    assert math.isnan(law.logpdf(math.nan))
    assert math.isnan(Normal(0.0, 1.0, low=0.0).logpdf(math.nan))


@pytest.mark.parametrize("law", TRUNCATED, ids=repr)
def test_truncated_samples_follow_the_renormalised_density(law):
    x = law.sample(np.random.default_rng(4), N)
    assert np.all((x >= law.low) & (x <= law.high))
    # moments of the truncated law by numerical integration of its (renormalised) logpdf
    g = _grid(law)
    f = np.exp(law.logpdf(g))
    mean = trapezoid(g * f, g)
    sd = math.sqrt(trapezoid((g - mean) ** 2 * f, g))
    assert abs(x.mean() - mean) < 4 * sd / math.sqrt(N)  # 4 SE
    # histogram on 40 bins against bin probabilities integrated from the pdf (max |z| of the counts <= 4.5)
    k = (len(g) - 1) // 40
    cell = 0.5 * (f[1:] + f[:-1]) * np.diff(g)
    p = np.add.reduceat(cell, np.arange(0, len(cell), k))
    counts, _ = np.histogram(x, g[::k])
    z = (counts - N * p) / np.sqrt(N * p * (1 - p) + 1e-300)
    assert np.max(np.abs(z[N * p > 5])) < 4.5


def test_far_tail_truncation_is_exact():
    # E[X | X > 6] for X ~ N(0, 1) is phi(6) / (1 - Phi(6)) = 6.15828...; rejection would need ~1e9 draws
    x = Normal(0.0, 1.0, low=6.0).sample(np.random.default_rng(5), N)
    tail_mean = stats.norm.pdf(6.0) / stats.norm.sf(6.0)
    assert x.min() >= 6.0
    assert abs(x.mean() - tail_mean) < 0.001


ALL_LAWS = [law for law, _ in LAWS] + [
    Constant(1.5),
    BivariateNormal((25.0, 40.0), ((16.0, 33.6), (33.6, 144.0))),
    BivariateNormal((25.0, 40.0), ((16.0, 33.6), (33.6, 144.0)), low=(20.0, None), high=(30.0, 60.0)),
]


@pytest.mark.parametrize("law", ALL_LAWS, ids=repr)
def test_same_seed_same_samples_different_seed_different(law):
    a = law.sample(np.random.default_rng(42), 1000)
    assert np.array_equal(a, law.sample(np.random.default_rng(42), 1000))
    if not isinstance(law, Constant):
        assert not np.array_equal(a, law.sample(np.random.default_rng(43), 1000))
    one = law.sample(np.random.default_rng(42))
    if isinstance(law, BivariateNormal):
        assert one.shape == (2,) and law.sample(np.random.default_rng(0), (3, 4)).shape == (3, 4, 2)
    else:
        assert isinstance(one, float) and law.sample(np.random.default_rng(0), (3, 4)).shape == (3, 4)


@pytest.mark.parametrize("law", ALL_LAWS, ids=repr)
def test_json_round_trip(law):
    d = law.to_dict()
    back = from_dict(json.loads(json.dumps(d, allow_nan=False)))  # allow_nan=False: no inf/NaN in the JSON
    assert back == law and type(back) is type(law) and hash(back) == hash(law)
    if hasattr(law, "low") and not isinstance(law, BivariateNormal):
        assert (d["low"] is None) == math.isinf(law.low) and (d["high"] is None) == math.isinf(law.high)


def test_global_numpy_rng_is_rejected():
    with pytest.raises(TypeError, match="Generator"):
        Normal(0.0, 1.0).sample(np.random)


def test_constant():
    law, rng = Constant(2.5), np.random.default_rng(0)
    state = rng.bit_generator.state
    assert law.sample(rng) == 2.5 and np.all(law.sample(rng, 4) == 2.5)
    assert rng.bit_generator.state == state  # draws nothing
    assert law.mean == 2.5
    assert law.logpdf(2.5) == 0.0 and np.isneginf(law.logpdf(2.4))


COV = ((16.0, 0.7 * 4 * 12), (0.7 * 4 * 12, 144.0))


def test_bivariate_sample_moments_logpdf_and_normalisation():
    law = BivariateNormal((25.0, 40.0), COV)
    assert law.correlation == pytest.approx(0.7, rel=1e-12)
    x = law.sample(np.random.default_rng(6), N)
    assert x.shape == (N, 2)
    np.testing.assert_array_less(np.abs(x.mean(0) - [25.0, 40.0]), 4 * np.array([4.0, 12.0]) / math.sqrt(N))
    np.testing.assert_array_less(np.abs(x.std(0) - [4.0, 12.0]), 4 * np.array([4.0, 12.0]) / math.sqrt(2 * N))
    assert abs(np.corrcoef(x.T)[0, 1] - 0.7) < 4 * (1 - 0.7**2) / math.sqrt(N)  # SE of r: (1 - rho^2) / sqrt(N)
    pts = x[:50].reshape(5, 10, 2)
    lp = law.logpdf(pts)
    assert lp.shape == (5, 10)
    np.testing.assert_allclose(lp, stats.multivariate_normal([25.0, 40.0], COV).logpdf(pts), rtol=1e-12)
    g0, g1 = np.linspace(25 - 32, 25 + 32, 1601), np.linspace(40 - 96, 40 + 96, 1601)  # +-8 sd
    f = np.exp(law.logpdf(np.stack(np.meshgrid(g0, g1, indexing="ij"), -1)))
    assert trapezoid(trapezoid(f, g1, axis=1), g0) == pytest.approx(1.0, abs=1e-6)


def test_bivariate_truncated_by_rejection():
    law = BivariateNormal((25.0, 40.0), COV, low=(20.0, None), high=(30.0, 50.0))
    g0, g1 = np.linspace(20.0, 30.0, 1001), np.linspace(40 - 96, 50.0, 2001)
    G = np.stack(np.meshgrid(g0, g1, indexing="ij"), -1)
    untrunc = np.exp(BivariateNormal((25.0, 40.0), COV).logpdf(G))
    mass = trapezoid(trapezoid(untrunc, g1, axis=1), g0)
    assert law.box_probability == pytest.approx(mass, rel=1e-6)
    f = np.exp(law.logpdf(G))
    assert trapezoid(trapezoid(f, g1, axis=1), g0) == pytest.approx(1.0, abs=1e-6)
    assert np.isneginf(law.logpdf([31.0, 45.0])) and np.isneginf(law.logpdf([25.0, 51.0]))
    x = law.sample(np.random.default_rng(7), N)
    assert np.all((x[:, 0] >= 20) & (x[:, 0] <= 30) & (x[:, 1] <= 50))
    marg = [trapezoid(f, g1, axis=1), trapezoid(f, g0, axis=0)]
    for i, (g, m) in enumerate(zip((g0, g1), marg)):
        mean = trapezoid(g * m, g)
        sd = math.sqrt(trapezoid((g - mean) ** 2 * m, g))
        assert abs(x[:, i].mean() - mean) < 4 * sd / math.sqrt(N)  # 4 SE


def test_bivariate_tail_box_probability_matches_scipy():
    law = BivariateNormal((25.0, 40.0), COV, low=(33.0, 64.0))  # both coordinates beyond +2 sd
    ref = stats.multivariate_normal.cdf([np.inf, np.inf], [25.0, 40.0], COV, lower_limit=[33.0, 64.0],
                                        abseps=1e-12, releps=1e-8)
    assert law.box_probability == pytest.approx(ref, rel=1e-5)


def test_bivariate_rejection_gives_up_on_an_empty_box():
    law = BivariateNormal((0.0, 0.0), ((1.0, 0.0), (0.0, 1.0)), low=(10.0, 10.0))
    with pytest.raises(RuntimeError, match=re.escape("low=(10.0, 10.0), high=(inf, inf)")):
        law.sample(np.random.default_rng(0), 10)


BAD = [
    (lambda: Normal(0.0, -1.0), "Normal.sigma must be > 0, got -1.0"),
    (lambda: Normal(math.nan, 1.0), "Normal.mu must be finite, got nan"),
    (lambda: Normal(0.0, math.inf), "Normal.sigma must be finite, got inf"),
    (lambda: Normal(0.0, 1.0, low=2.0, high=2.0), "Normal.low must be < Normal.high, got low=2.0, high=2.0"),
    (lambda: Normal(0.0, 1.0, low=math.nan), "Normal.low must be a number or None, got nan"),
    (lambda: LogNormal(0.0, 0.0), "LogNormal.S must be > 0, got 0.0"),
    (lambda: LogNormal(0.0, 1.0, high=-1.0), "zero probability mass"),
    (lambda: Laplace(0.0, -2.0), "Laplace.b must be > 0, got -2.0"),
    (lambda: Laplace("0", 1.0), "Laplace.mu must be a real number, got '0'"),
    (lambda: Constant(math.nan), "Constant.value must be finite, got nan"),
    (lambda: BivariateNormal((0.0, 0.0), ((1.0, 2.0), (2.0, 1.0))), "BivariateNormal.cov must be positive definite"),
    (lambda: BivariateNormal((0.0, 0.0), ((1.0, 0.5), (0.4, 1.0))), "BivariateNormal.cov must be symmetric"),
    (lambda: BivariateNormal((0.0, 0.0), ((1.0, math.nan), (0.0, 1.0))), "BivariateNormal.cov[0][1] must be finite"),
    (lambda: BivariateNormal((0.0, 0.0), ((1.0, 0.0),)), "BivariateNormal.cov must be a 2x2 matrix"),
    (lambda: BivariateNormal((0.0, math.nan), ((1.0, 0.0), (0.0, 1.0))), "BivariateNormal.mean[1] must be finite"),
    (lambda: BivariateNormal((0.0,), ((1.0, 0.0), (0.0, 1.0))), "BivariateNormal.mean must be a pair"),
    (lambda: BivariateNormal((0.0, 0.0), ((1.0, 0.0), (0.0, 1.0)), low=(0.0, 3.0), high=(1.0, 2.0)),
     "BivariateNormal.low must be < BivariateNormal.high elementwise"),
    (lambda: from_dict({"kind": "gamma", "k": 1.0}), "unknown law kind 'gamma'"),
    (lambda: from_dict({"mu": 0.0, "sigma": 1.0}), "missing key 'kind'"),
    (lambda: from_dict({"kind": "normal", "mu": 0.0}), "missing key(s) ['sigma']"),
    (lambda: from_dict({"kind": "normal", "mu": 0.0, "sigma": 1.0, "foo": 2}), "unexpected key(s) ['foo']"),
    (lambda: from_dict({"kind": "bivariate_normal", "mean": [0, 0]}), "missing key(s) ['cov']"),
    (lambda: from_dict({"kind": "normal", "mu": 0.0, "sigma": -3}), "Normal.sigma must be > 0, got -3.0"),
]


@pytest.mark.parametrize("make,message", BAD, ids=[m for _, m in BAD])
def test_bad_parameters_raise_naming_the_field(make, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        make()


def test_sampling_with_cached_truncation_bounds_equals_the_fresh_formula():
    """``sample`` maps uniforms through ``[F(a), F(b)]`` cached per (frozen) law: the draws equal
    the formula with the bounds recomputed each time, and the cache does not touch equality."""
    from acc_gym.scenarios.distributions import Laplace, LogNormal, Normal

    laws = [Normal(27.0, 4.0, low=8.0, high=40.0), Normal(0.0, 1.0, low=1.5), LogNormal(np.log(12.0), 0.35, 6.0, 40.0),
            Laplace(2.0, 0.5, high=1.0), Normal(3.0, 1.0)]
    for law in laws:
        fresh = type(law)(*[getattr(law, f.name) for f in fields(law)])
        for size in (None, 7):
            a, b, flip = law._z_bounds()
            ua, ub = law._std.cdf(a), law._std.cdf(b)
            r1, r2 = np.random.default_rng(5), np.random.default_rng(5)
            z = law._std.ppf(ua + (ub - ua) * r1.random(size))
            ref = np.clip(law._from_z(-z if flip else z), law.low, law.high)
            got = law.sample(r2, size)
            assert np.array_equal(np.asarray(got), np.asarray(ref))
        assert law == fresh and hash(law) == hash(fresh)


@pytest.mark.parametrize("law", [Normal(27.0, 4.0, 8.0, 40.0), Normal(0.0, 1.0), LogNormal(math.log(6.0), 0.45, 1.0, 20.0),
                                 LogNormal(math.log(80.0), 0.35, 30.0, 180.0), Laplace(0.0, 0.8, -4.0, 4.0),
                                 Laplace(1.0, 2.0), Normal(10.0, 1.0, 12.0, 13.0)],
                         ids=["normal", "normal-free", "lognormal", "lognormal-gap", "laplace", "laplace-free", "tail"])
def test_one_draw_equals_the_array_draw(law):
    """A single draw (``size=None``, a float: the scenario builders' case) is the same number
    as the array path gives from the same generator state, inside the bounds."""
    for seed in range(200):
        one = law.sample(np.random.default_rng(seed))
        arr = law.sample(np.random.default_rng(seed), size=1)
        assert type(one) is float and one == arr[0]
        assert law.low <= one <= law.high


def test_episodes_run_without_scipy_integrate():
    """scipy.integrate (about 0.5 s of every process start: leaderboard controllers,
    campaign workers, CLI calls) is imported only by the bivariate law's box mass
    (``pdf``/``logpdf``/calibration), never by drawing scenarios or stepping an env."""
    import subprocess
    import sys

    code = ("import sys\n"
            "sys.modules['scipy.integrate'] = None  # importing it now fails\n"
            "import gymnasium as gym, acc_gym\n"
            "env = gym.make('acc_gym/SingleLane-v1', default_scenarios={'singlelane/3/lane-change+cut-in': 1.0})\n"
            "env.reset(seed=3)\n"
            "done = False\n"
            "while not done:\n"
            "    obs, r, term, trunc, info = env.step(env.action_space.sample() * 0)\n"
            "    done = term or trunc\n"
            "print(info['score'] >= 0)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert out.returncode == 0 and out.stdout.split()[-1] == "True", out.stderr[-2000:]


@pytest.mark.parametrize("law", [
    BivariateNormal((27.0, 40.0), ((16.0, 28.8), (28.8, 144.0)), low=(8.0, 8.0), high=(40.0, 120.0)),  # SPEED_GAP
    BivariateNormal((25.0, 40.0), COV, low=(30.0, 50.0)),  # a tail box: the first rows are mostly outside
    BivariateNormal((0.0, 0.0), ((1.0, 0.5), (0.5, 1.0)), low=(3.0, 3.2)),  # acceptance ~1e-4: several rounds
], ids=["speed-gap", "tail", "rare"])
def test_one_bivariate_pair_equals_the_rejection_loop(law):
    """One pair (``size=None``: a scenario's draw, searched row by row in Python floats) is the
    pair the general rejection loop gives from the same generator state, bit for bit, inside
    the box, and leaves the generator in the same state (the parameters drawn after it are
    the same)."""
    for seed in range(60):
        r1, r2 = np.random.default_rng(seed), np.random.default_rng(seed)
        one = law.sample(r1)
        ref = law._rejection(r2, 1)[0]
        assert one.shape == (2,) and np.array_equal(one, ref)
        assert r1.bit_generator.state == r2.bit_generator.state
        assert all(lo <= v <= hi for v, lo, hi in zip(one, law.low, law.high))


def test_one_bivariate_pair_gives_up_on_an_empty_box_as_the_loop_does():
    law = BivariateNormal((0.0, 0.0), ((1.0, 0.0), (0.0, 1.0)), low=(10.0, 10.0))
    with pytest.raises(RuntimeError, match=re.escape("low=(10.0, 10.0), high=(inf, inf): acceptance 0 < 1e-06")):
        law.sample(np.random.default_rng(0))


def test_laplace_inverse_cdf_of_a_number_equals_the_array_formula():
    """The standard Laplace inverse CDF of one number (a scenario's draw) takes the branch the
    array formula's ``np.where`` takes, with the same bits, over uniforms across (0, 1)."""
    from acc_gym.scenarios.distributions import _laplace_ppf

    rng = np.random.default_rng(11)
    u = np.concatenate([rng.random(20_000), [0.5, np.nextafter(0.5, 0.0), np.nextafter(0.5, 1.0), 1e-300,
                                             np.nextafter(1.0, 0.0)]])
    ref = _laplace_ppf(u)
    got = np.array([_laplace_ppf(float(x)) for x in u])
    assert np.array_equal(got, ref)
