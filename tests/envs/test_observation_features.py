"""The safety-margin features (acc_gym.envs.observation) against values computed by hand on
fixed states: closing, opening, nothing in range (and a vehicle beyond the range, which
the observation shows the same way), standstill, a faster lead (Gapsafe < 0) and the
clipping bounds; the second vehicle's features with V2V; the wrapper on a real env."""

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.observation import (B0, B1, FEATURES, GAP_FLOOR, GAP_SAFE_FLOOR, SPEED_FLOOR, feature_bounds,
                                     feature_names, margin_features)
from acc_gym.wrappers import MarginObservation


def reference_features(v, gap, v_rel, tau, sensor_range=200.0, b0=B0, b1=B1) -> dict[str, float]:
    """The module table's definitions for one vehicle ahead, written out in plain Python
    (unclipped): the oracle the compiled features are compared with."""
    v_lead = v + v_rel
    gs = v * tau + v ** 2 / (2 * b1) - v_lead ** 2 / (2 * b0)
    q = gap - gs
    return {"gap_safe": gs / sensor_range, "q": q / sensor_range, "q_over_gap_safe": q / max(gs, GAP_SAFE_FLOOR),
            "time_headway": gap / max(v, SPEED_FLOOR), "inverse_ttc": -v_rel / max(gap, GAP_FLOOR),
            "a_req": -v_rel ** 2 / (2 * max(gap, GAP_FLOOR)) if v_rel < 0 else 0.0}

R = 200.0  # [m] the default sensor range


def obs(v, gap, v_rel, seen, tau, set_speed=30.0, a=0.0):
    return np.array([v, a, gap, v_rel, seen, set_speed, tau])


def features(o, sensor_range=R):
    out = margin_features(o, sensor_range)
    assert np.array_equal(out[:o.size], o)  # the v0 fields come first, unchanged
    return dict(zip(FEATURES, out[o.size:]))


CASES = {
    # v = 20 m/s behind a lead at 15 m/s, 30 m ahead, tau 1.5 s:
    # Gapsafe = 20*1.5 + 20^2/16 - 15^2/16 = 30 + 25 - 14.0625 = 40.9375 m; Q = 30 - 40.9375 = -10.9375 m
    "closing": (obs(20.0, 30.0, -5.0, 1.0, 1.5),
                {"gap_safe": 40.9375 / 200, "q": -10.9375 / 200, "q_over_gap_safe": -10.9375 / 40.9375,
                 "time_headway": 1.5, "inverse_ttc": 5.0 / 30.0, "a_req": -25.0 / 60.0}),
    # v = 20 behind a lead at 24, 40 m ahead, tau 1.2: Gapsafe = 24 + 25 - 576/16 = 13 m; Q = 27 m
    "opening": (obs(20.0, 40.0, 4.0, 1.0, 1.2),
                {"gap_safe": 13.0 / 200, "q": 27.0 / 200, "q_over_gap_safe": 27.0 / 13.0, "time_headway": 2.0,
                 "inverse_ttc": -0.1, "a_req": 0.0}),
    # nothing in range: gap = R, v_rel = 0 (v = 25, tau 1.5): Gapsafe = 37.5 m, Q = 162.5 m, headway 8 s
    "no lead": (obs(25.0, 200.0, 0.0, 0.0, 1.5),
                {"gap_safe": 37.5 / 200, "q": 162.5 / 200, "q_over_gap_safe": 162.5 / 37.5, "time_headway": 8.0,
                 "inverse_ttc": 0.0, "a_req": 0.0}),
    # standstill 5 m behind a stopped car: Gapsafe = 0 (divided by its 1 m floor), headway 5 / 0.1 = 50 s
    # -> clipped to 10 s, Q / Gapsafe 5 -> at its bound 5
    "standstill": (obs(0.0, 5.0, 0.0, 1.0, 1.5),
                   {"gap_safe": 0.0, "q": 5.0 / 200, "q_over_gap_safe": 5.0, "time_headway": 10.0,
                    "inverse_ttc": 0.0, "a_req": 0.0}),
    # a lead 10 m/s faster 8 m ahead (v = 10, tau 1.5): Gapsafe = 15 + 100/16 - 400/16 = -3.75 m,
    # Q = 11.75 m, Q / max(Gapsafe, 1 m) = 11.75 -> 5; headway 0.8 s; opening at 10/8 = 1.25 /s
    "faster lead": (obs(10.0, 8.0, 10.0, 1.0, 1.5),
                    {"gap_safe": -3.75 / 200, "q": 11.75 / 200, "q_over_gap_safe": 5.0, "time_headway": 0.8,
                     "inverse_ttc": -1.25, "a_req": 0.0}),
    # closing at 20 m/s 5 m ahead (v = 30): a_req = -400/10 = -40 -> -20; 1/TTC = 4 -> 2;
    # Gapsafe = 45 + 900/16 - 100/16 = 95 m, Q = -90 m, Q / Gapsafe = -0.947
    "about to hit": (obs(30.0, 5.0, -20.0, 1.0, 1.5),
                     {"gap_safe": 95.0 / 200, "q": -90.0 / 200, "q_over_gap_safe": -90.0 / 95.0,
                      "time_headway": 5.0 / 30.0, "inverse_ttc": 2.0, "a_req": -20.0}),
}


@pytest.mark.parametrize("case", CASES)
def test_features_equal_hand_computed_values(case):
    o, expected = CASES[case]
    got = features(o)
    for name in FEATURES:
        assert got[name] == pytest.approx(expected[name], rel=1e-12, abs=1e-12), (case, name)


def test_a_vehicle_beyond_the_range_looks_like_nothing_in_range():
    """The observation shows a vehicle beyond the sensor range as gap = R, v_rel = 0, flag 0
    (whatever its true speed): the features are those of 'nothing in range', and continuous
    with a vehicle at the range's edge at the ego's speed."""
    beyond = features(obs(25.0, 200.0, 0.0, 0.0, 1.5))
    edge = features(obs(25.0, 199.999, 0.0, 1.0, 1.5))
    assert beyond == pytest.approx(features(CASES["no lead"][0]))
    for name in FEATURES:
        assert beyond[name] == pytest.approx(edge[name], abs=1e-4), name


def test_features_agree_with_the_written_out_definitions_on_random_states():
    rng = np.random.default_rng(3)
    low, high = feature_bounds(False)
    for _ in range(500):
        v, gap, v_rel, tau = rng.uniform(0, 45), rng.uniform(0.05, 200), rng.uniform(-30, 30), rng.uniform(0.8, 3)
        got = features(obs(v, gap, v_rel, 1.0, tau))
        ref = reference_features(v, gap, v_rel, tau)
        for j, name in enumerate(FEATURES):
            assert got[name] == pytest.approx(min(max(ref[name], low[j]), high[j]), rel=1e-12, abs=1e-12)


def test_the_second_vehicle_gets_the_same_features_with_v2v():
    o = np.concatenate([CASES["closing"][0], [0.5, 60.0, -3.0, 1.0]])  # a_lead, gap2, v_rel2, seen2
    out = margin_features(o)
    assert out.shape == (11 + 12,) and len(feature_names(True)) == 12
    second = dict(zip(FEATURES, out[17:]))
    ref = reference_features(20.0, 60.0, -3.0, 1.5)
    for name in FEATURES:
        assert second[name] == pytest.approx(ref[name], rel=1e-12), name
    assert np.array_equal(out[11:17], margin_features(CASES["closing"][0])[7:])


def test_batches_and_bad_input():
    batch = np.stack([c[0] for c in CASES.values()])
    out = margin_features(batch)
    assert out.shape == (len(CASES), 13)
    for row, (o, _) in zip(out, CASES.values()):
        assert np.array_equal(row, margin_features(o))
    assert features(CASES["closing"][0], 100.0)["gap_safe"] == pytest.approx(40.9375 / 100)
    with pytest.raises(ValueError, match="7 or 11"):
        margin_features(np.zeros(8))
    with pytest.raises(ValueError, match="finite"):
        margin_features(obs(np.nan, 30.0, 0.0, 1.0, 1.5))
    with pytest.raises(ValueError, match="sensor_range.*-5"):
        margin_features(CASES["closing"][0], -5.0)


@pytest.mark.filterwarnings("ignore:.*is different from the unwrapped version")  # check_env on a wrapper
@pytest.mark.parametrize("v2v", [False, True])
def test_the_wrapper_appends_them_to_a_real_episode(v2v):
    from gymnasium.utils.env_checker import check_env

    env = MarginObservation(gym.make("acc_gym/CarFollowing-v0", v2v=v2v))
    m = 11 if v2v else 7
    assert env.observation_space.shape == (m + (12 if v2v else 6),)
    check_env(env.unwrapped, skip_render_check=True)
    check_env(env, skip_render_check=True, skip_close_check=True)
    o, _ = env.reset(seed=4)
    raw = env.unwrapped._obs()
    assert np.array_equal(o, margin_features(raw).astype(np.float32))
    for _ in range(30):
        o, *_, info = env.step(np.array([0.1], dtype=np.float32))
        assert env.observation_space.contains(o)
        # Q and Gapsafe from the features (fractions of the 200 m range) are the env's own (info)
        assert o[m + 1] * 200.0 == pytest.approx(info["q"], abs=2e-3)
        assert o[m] * 200.0 == pytest.approx(info["gap_safe"], abs=2e-3)
