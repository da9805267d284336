"""Extra metrics against hand computations."""

import math

import numpy as np
import pytest

from acc_gym.evaluation import EgoTrace, ScoringConfig, damping_ratio, score_episode, speed_overshoot


def test_ttc_jerk_comfort_and_safe_spacing_by_hand():
    t = np.arange(5.0)
    v = np.array([20.0, 20.0, 18.0, 16.0, 16.0])
    v_lead = np.array([15.0, 15.0, 15.0, 16.0, 16.0])
    gap = np.array([50.0, 45.0, 22.0, 25.0, np.inf])
    a = np.array([0.0, 0.0, -2.0, -3.5, 0.0])
    r = score_episode(EgoTrace(t=t, v=v, a=a, gap=gap, v_lead=v_lead), ScoringConfig(tau1=1.0))
    m = r.metrics
    assert m["min_ttc"] == pytest.approx(min(50 / 5, 45 / 5, 22 / 3))  # closing only at samples 0-2
    assert m["max_jerk"] == pytest.approx(3.5)  # |0 - (-3.5)| / 1 s
    assert m["share_comfortable"] == pytest.approx(4 / 5)  # |a| <= 3 except -3.5
    # Gapsafe = v1 + (v1^2 - v0^2)/16 = 20+10.9, 20+10.9, 18+6.2, 16: Q >= 0 at samples 0, 1, 3 of 4
    gs = v[:4] + (v[:4] ** 2 - v_lead[:4] ** 2) / 16
    assert m["share_safe_spacing"] == pytest.approx(np.mean(gap[:4] - gs >= 0)) == pytest.approx(0.75)
    assert m["min_gap"] == 22.0 and not m["collision"]


def test_overshoot_of_a_second_order_step_gives_its_damping_ratio():
    zeta, wn = 0.3, 0.8
    t = np.arange(0, 40, 0.05)
    wd = wn * math.sqrt(1 - zeta ** 2)
    # the ego settles from 15 to the lead's new steady 20 m/s like an underdamped second-order system
    step = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    v = 15 + 5 * step
    v_lead = np.full(t.size, 20.0)
    os, n = speed_overshoot(t, v, v_lead, np.ones(t.size, bool))
    assert n == 1
    assert os == pytest.approx(math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2)), rel=1e-3)
    assert damping_ratio(os) == pytest.approx(zeta, rel=1e-2)
    # a critically damped approach has no overshoot
    v = 20 - 5 * (1 + wn * t) * np.exp(-wn * t)
    os, n = speed_overshoot(t, v, v_lead, np.ones(t.size, bool))
    assert os == pytest.approx(0.0, abs=1e-12) and damping_ratio(os) == 1.0


def test_no_lead_transient_gives_nan_damping():
    t = np.arange(0, 20, 0.2)
    os, n = speed_overshoot(t, np.full(t.size, 20.0), np.full(t.size, 20.0), np.ones(t.size, bool))
    assert n == 0 and math.isnan(os) and math.isnan(damping_ratio(os))


def test_compiled_gradient_equals_numpy_gradient_bit_for_bit():
    """``metrics.gradient`` (what speed_overshoot uses) equals ``np.gradient(f, x)``: uniform grids
    (exactly equal steps), the environments' ``k dt`` times (steps equal only up to rounding),
    irregular times, two samples; other inputs go to numpy itself."""
    from acc_gym.evaluation.metrics import _gradient, gradient

    rng = np.random.default_rng(0)
    grids = [lambda n: np.arange(n) * 0.2, lambda n: np.arange(n) * 0.25, lambda n: np.arange(n, dtype=float),
             lambda n: np.cumsum(rng.uniform(0.05, 0.5, n))]
    for k in range(800):
        n = int(rng.integers(2, 150))
        x = grids[k % 4](n)
        f = rng.normal(0.0, 10.0, n)
        assert np.array_equal(_gradient(f, x).view(np.int64), np.gradient(f, x).view(np.int64)), (k, n)
    assert not np.all(np.diff(np.arange(100) * 0.2) == 0.2)  # the k dt grid is not exactly uniform
    assert np.array_equal(gradient([1.0, 2.0, 4.0], [0.0, 1.0, 2.0]), np.gradient([1.0, 2.0, 4.0], [0.0, 1.0, 2.0]))
