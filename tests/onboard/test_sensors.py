"""The radar model: errors, dropouts, track coasting, latency and beams as declared."""

import math

import numpy as np
import pytest

from acc_gym.onboard import SENSOR_PRESETS, Radar, SensorConfig

DT = 0.2
R = 200.0


def _truth(n, gap1=50.0, v1=20.0, lat1=0.0, gap2=np.inf, v2=0.0, lat2=np.inf, v=20.0) -> tuple:
    """A world of ``n`` scenes: the ego (slot 0), the vehicle ahead at ``gap1`` with its nearest edge
    ``lat1`` off the ego's centre line (slot 1; none for an infinite gap), the second at ``gap2``."""
    full = lambda x: np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()  # noqa: E731
    obs = np.zeros((8, n))
    obs[0], obs[2], obs[3], obs[5], obs[6] = full(v), full(gap1), full(v1), full(gap2), full(v2)
    width = np.full((n, 3), 1.8)
    y = np.zeros((n, 3))
    y[:, 1] = np.where(np.isfinite(full(lat1)), full(lat1) + 0.9, 0.0)
    y[:, 2] = np.where(np.isfinite(full(lat2)), full(lat2) + 0.9, 0.0)
    lead = np.full((n, 3), -1, dtype=np.int64)
    lead2 = np.full((n, 3), -1, dtype=np.int64)
    lead[:, 0] = np.where(np.isfinite(obs[2]), 1, -1)
    lead2[:, 0] = np.where(np.isfinite(obs[5]), 2, -1)
    return obs, y, width, lead, lead2


def _radar(cfg, n=1, seed=0):
    radar = Radar(cfg, n, DT, R)
    rngs = [np.random.default_rng([seed, j]) for j in range(n)]
    first = radar.reset(np.arange(n), rngs, _truth(n))
    return radar, first


def _ks_normal(x: np.ndarray, mean: float, sd: float) -> float:
    """Kolmogorov-Smirnov distance of the sample ``x`` from N(mean, sd^2)."""
    x = np.sort((x - mean) / sd)
    cdf = 0.5 * (1.0 + np.vectorize(math.erf)(x / math.sqrt(2.0)))
    n = x.size
    return float(max(np.max(np.arange(1, n + 1) / n - cdf), np.max(cdf - np.arange(n) / n)))


def test_10000_gap_and_rate_errors_follow_the_declared_normal_laws():
    cfg = SensorConfig(gap_sd=0.3, gap_bias=0.5, rate_sd=0.2, rate_bias=-0.1)
    radar, _ = _radar(cfg)
    out = np.array([radar.sense(_truth(1, gap1=50.0, v1=18.0))[0] for _ in range(10_000)])
    gap_err, rate_err = out[:, 0] - 50.0, out[:, 1] - (18.0 - 20.0)
    crit = 1.95 / math.sqrt(10_000)  # the KS test's 0.1 % critical distance
    assert _ks_normal(gap_err, 0.5, 0.3) < crit and _ks_normal(rate_err, -0.1, 0.2) < crit
    assert gap_err.mean() == pytest.approx(0.5, abs=4 * 0.3 / 100) and gap_err.std() == pytest.approx(0.3, rel=0.03)
    assert abs(np.corrcoef(gap_err, rate_err)[0, 1]) < 0.04  # independent draws
    assert abs(np.corrcoef(gap_err[1:], gap_err[:-1])[0, 1]) < 0.04  # and independent in time
    assert np.all(out[:, 2] == 1.0)


def test_dropout_bursts_follow_the_declared_two_state_chain():
    cfg = SensorConfig(dropout_share=0.2, dropout_burst=0.6)  # r = 1/3 per step, p = r / 4
    radar, _ = _radar(cfg)
    seen = np.array([radar.sense(_truth(1))[0, 2] for _ in range(40_000)])
    dropped = seen == 0.0
    assert dropped.mean() == pytest.approx(0.2, abs=0.015)
    edges = np.flatnonzero(np.diff(np.r_[0, dropped.astype(int), 0]))
    lengths = edges[1::2] - edges[::2]  # every burst's length in steps
    r = DT / 0.6
    assert lengths.mean() == pytest.approx(1.0 / r, rel=0.06)
    # geometric: P(length = k) = r (1 - r)^(k - 1)
    for k in (1, 2, 3, 4):
        assert np.mean(lengths == k) == pytest.approx(r * (1 - r) ** (k - 1), abs=0.025)
    # and the chain, not independent steps: a dropped step is followed by another with 1 - r
    assert np.mean(dropped[1:][dropped[:-1]]) == pytest.approx(1 - r, abs=0.02)


def test_a_latency_of_k_steps_delays_the_observation_by_exactly_k_steps():
    gaps = 30.0 + 5.0 * np.sin(np.arange(60) * 0.3)
    for latency, k in ((0.0, 0), (0.1, 1), (0.2, 1), (0.4, 2), (0.5, 3)):
        cfg = SensorConfig(latency=latency, far_range=1e4)  # not ideal, nothing else modelled
        radar = Radar(cfg, 1, DT, R)
        assert cfg.latency_steps(DT) == k
        first = radar.reset([0], [np.random.default_rng(1)], _truth(1, gap1=gaps[0]))
        out = [first[0, 0]] + [radar.sense(_truth(1, gap1=g))[0, 0] for g in gaps[1:]]
        expected = np.r_[np.full(k, gaps[0]), gaps[:len(gaps) - k]]  # the first track fills the buffer
        assert np.array_equal(np.array(out), expected)


def test_the_track_coasts_at_its_relative_speed_through_a_dropout_then_is_dropped():
    cfg = SensorConfig(coast=0.6, far_range=1e4)
    radar, _ = _radar(cfg)
    radar.sense(_truth(1, gap1=40.0, v1=18.0))  # closing at 2 m/s
    gone = _truth(1, gap1=np.inf)
    out = np.array([radar.sense(gone)[0] for _ in range(5)])
    assert out[:3, 0] == pytest.approx([39.6, 39.2, 38.8])  # 0.6 s of constant-velocity prediction
    assert np.all(out[:3, 1] == pytest.approx(-2.0)) and np.all(out[:3, 2] == 1.0)
    assert np.all(out[3:, 2] == 0.0) and np.all(out[3:, 0] == R) and np.all(out[3:, 1] == 0.0)


def test_a_cut_in_is_acquired_when_it_enters_the_beam_and_the_old_target_is_kept_until_then():
    far_only = SensorConfig(far_range=200.0, far_fov=18.0)
    radar, _ = _radar(far_only)
    # a vehicle 8 m ahead whose nearest edge is 1.5 m off the centre line: tan(9 deg) 8 m = 1.27 m
    out = radar.sense(_truth(1, gap1=8.0, v1=15.0, lat1=1.5, gap2=40.0, v2=22.0, lat2=0.0))
    assert out[0].tolist() == pytest.approx([40.0, 2.0, 1.0])  # still the vehicle it tracked
    out = radar.sense(_truth(1, gap1=8.0, v1=15.0, lat1=1.2, gap2=40.0, v2=22.0, lat2=0.0))
    assert out[0].tolist() == pytest.approx([8.0, -5.0, 1.0])
    # a near beam (+-45 deg to 70 m) sees it at once
    both = SensorConfig(far_range=200.0, far_fov=18.0, near_range=70.0, near_fov=90.0)
    radar, _ = _radar(both)
    out = radar.sense(_truth(1, gap1=8.0, v1=15.0, lat1=1.5, gap2=40.0, v2=22.0, lat2=0.0))
    assert out[0].tolist() == pytest.approx([8.0, -5.0, 1.0])
    # and the range: at 150 m a 120 m radar sees nothing
    radar, _ = _radar(SensorConfig(far_range=120.0))
    assert radar.sense(_truth(1, gap1=150.0))[0].tolist() == [R, 0.0, 0.0]


def test_scenes_draw_from_their_own_generators_and_the_same_seed_gives_the_same_draws():
    cfg = SENSOR_PRESETS["degraded"]
    a, _ = _radar(cfg, n=3, seed=5)
    b, _ = _radar(cfg, n=3, seed=5)
    one = Radar(cfg, 1, DT, R)
    one.reset([0], [np.random.default_rng([5, 1])], _truth(1))  # scene 1 alone, the same generator
    for _ in range(300):  # past a block of draws
        x, y, z = a.sense(_truth(3)), b.sense(_truth(3)), one.sense(_truth(1))
        assert np.array_equal(x, y) and np.array_equal(x[1], z[0])
    assert not np.array_equal(x[0], x[1]) or not np.array_equal(x[1], x[2])


def test_configs_are_validated_naming_the_field_and_value():
    for kwargs, match in (({"gap_sd": -1.0}, "SensorConfig.gap_sd .* got -1.0"),
                          ({"far_fov": 0.0}, "SensorConfig.far_fov .* got 0.0"),
                          ({"dropout_share": 1.0}, "SensorConfig.dropout_share .* got 1.0"),
                          ({"latency": float("inf")}, "SensorConfig.latency .* got inf"),
                          ({"dropout_share": 0.1}, "dropout_burst must be > 0"),
                          ({"coast": "1"}, "SensorConfig.coast .* got '1'")):
        with pytest.raises(ValueError, match=match):
            SensorConfig(**kwargs)
    assert SensorConfig().ideal and not SENSOR_PRESETS["typical"].ideal
