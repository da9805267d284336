"""Driver model 6's perception (acc_gym.drivers.perception) and the model registry: the reaction
time with HDM's anticipation against a hand computation, the error processes' statistics, each
group's own randomness, the emergency reflex, and the following rule."""

import math

import numpy as np
import pytest

from acc_gym.drivers import MPCDriver, MPCSettings, sample_drivers
from acc_gym.drivers._mpc_kernel import ACCELERATE, EMERGENCY
from acc_gym.drivers.base import Observation
from acc_gym.drivers.mpc import DRIVER_MODELS, ENV_DRIVER_MODEL, MODEL_VERSION, driver_model, human_drivers
from acc_gym.drivers.perception import HumanPerception, Perception

DT = 0.2


def rows(v, a, gap, v_lead, a_lead):
    return np.array([np.atleast_1d(np.asarray(x, float)) for x in (v, a, gap, v_lead, a_lead)])


def exact(reaction_time=0.8, n=1):
    return Perception(HumanPerception(reaction_time=reaction_time, gap_error=0.0, rate_error=0.0), n, DT,
                      [(np.random.default_rng(0), n)])


def test_the_scene_ahead_is_seen_a_reaction_time_late_and_extrapolated_with_the_own_motion_known():
    p = exact(0.8)  # 4 steps
    scenes = [rows(10.0 + 0.1 * k, 0.5, 20.0 - k, 9.0 - 0.2 * k, -1.0 * k) for k in range(8)]
    out = [p.perceive(s) for s in scenes]
    speeds = [s[0, 0] for s in scenes]
    odo = np.concatenate([[0.0], np.cumsum([0.5 * (a + b) * DT for a, b in zip(speeds[:-1], speeds[1:])])])
    for k in range(8):
        j = max(k - 4, 0)
        d = scenes[j]  # before T' has passed: the scene at the start
        v_now = scenes[k][0, 0]
        s_hand = d[2, 0] + 0.8 * d[3, 0] - (odo[k] - odo[j])  # s' = s_d + T' v_lead,d - distance driven since
        assert out[k][2, 0] == pytest.approx(s_hand, abs=1e-12)
        assert out[k][3, 0] == pytest.approx(d[3, 0], abs=1e-12)  # the lead at its speed T' ago
        assert out[k][4, 0] == pytest.approx(d[4, 0], abs=1e-12)  # the lead's acceleration T' ago
        assert out[k][0, 0] == v_now and out[k][1, 0] == scenes[k][1, 0]  # own speed and acceleration now


def test_nothing_ahead_passes_through_and_perceived_values_stay_physical():
    p = exact(0.4, n=2)
    for _ in range(3):
        out = p.perceive(rows([5.0, 5.0], [0.0, 0.0], [np.inf, 0.5], [0.0, 0.0], [0.0, 0.0]))
    assert out[2, 0] == np.inf  # nothing ahead
    assert out[2, 1] == 0.0 and out[3, 1] == 0.0  # extrapolated into contact: gap 0, lead speed >= 0


def test_the_estimation_errors_are_unit_ornstein_uhlenbeck_processes_scaled_as_hdm():
    n, steps = 400, 3000
    hp = HumanPerception(reaction_time=0.0, gap_error=0.1, rate_error=0.01, correlation_time=20.0)
    p = Perception(hp, n, DT, [(np.random.default_rng(1), n)])
    gap, v, vl = 50.0, 10.0, 9.0
    ws, wl = np.empty((steps, n)), np.empty((steps, n))
    for k in range(steps):
        out = p.perceive(rows(np.full(n, v), np.zeros(n), np.full(n, gap), np.full(n, vl), np.zeros(n)))
        ws[k] = np.log(out[2] / gap) / hp.gap_error  # s_est = s exp(V_s w_s)
        wl[k] = -(out[3] - vl) / (hp.rate_error * gap)  # v_lead,est = v_lead - r_c s w_l
    for w in (ws, wl):
        assert np.var(w) == pytest.approx(1.0, abs=0.08)  # stationary unit variance from the first step
        assert np.mean(w) == pytest.approx(0.0, abs=0.06)
        lag = 50  # 10 s
        r = np.mean(w[lag:] * w[:-lag]) / np.var(w)
        assert r == pytest.approx(math.exp(-lag * DT / 20.0), abs=0.06)
    assert abs(np.corrcoef(ws.ravel(), wl.ravel())[0, 1]) < 0.05  # two independent processes


def test_each_group_draws_its_own_errors_whatever_shares_the_batch():
    hp = HumanPerception(gap_error=0.1, rate_error=0.01)
    alone = Perception(hp, 3, DT, [(np.random.default_rng(7), 3)])
    shared = Perception(hp, 8, DT, [(np.random.default_rng(7), 3), (np.random.default_rng(8), 5)])
    for k in range(300):  # past the block of pre-drawn normals
        r = rows(np.full(8, 8.0), np.zeros(8), np.full(8, 12.0 + k % 5), np.full(8, 7.5), np.zeros(8))
        np.testing.assert_array_equal(alone.perceive(r[:, :3]), shared.perceive(r)[:, :3])


def test_bad_perception_input_is_named():
    with pytest.raises(ValueError, match="reaction_time"):
        HumanPerception(reaction_time=float("nan"))
    with pytest.raises(ValueError, match="correlation_time"):
        HumanPerception(correlation_time=0.0)
    with pytest.raises(ValueError, match=r"serve \[2\] rows, not 3"):
        Perception(HumanPerception(gap_error=0.1), 3, DT, [(np.random.default_rng(0), 2)])
    with pytest.raises(ValueError, match="unknown driver model 7"):
        driver_model(7)
    with pytest.raises(ValueError, match="groups="):
        Perception(HumanPerception(gap_error=0.1), 3, DT)


def test_the_registry_names_each_model_and_model_5_is_the_plain_mpc_driver():
    assert MODEL_VERSION == max(DRIVER_MODELS) == 6
    assert DRIVER_MODELS[6].perception.reaction_time == 1.0 and not DRIVER_MODELS[6].perception.noisy
    # the environments (and so every suite and leaderboard) drive model 5: MPCDriver's defaults
    assert ENV_DRIVER_MODEL == 5 and DRIVER_MODELS[5].settings == MPCSettings()
    from acc_gym.leaderboard.run import versions
    assert versions()["driver_model"] == ENV_DRIVER_MODEL
    assert DRIVER_MODELS[5].perception is None and not DRIVER_MODELS[5].settings.follow_in_range
    assert DRIVER_MODELS[6].perception == HumanPerception() and DRIVER_MODELS[6].settings.follow_in_range
    params = sample_drivers(np.random.default_rng(3), 6, 15.0, "naturalistic")
    a, b = MPCDriver(params), human_drivers(params, 5)
    obs = Observation(v=np.full(6, 15.0), a=np.zeros(6), gap=np.linspace(15, 60, 6), v_lead=np.full(6, 12.0),
                      a_lead=np.zeros(6))
    for _ in range(20):
        np.testing.assert_array_equal(a.act(obs), b.act(obs))


def test_a_true_emergency_is_seen_at_once_the_rest_a_reaction_time_late():
    params = sample_drivers(np.random.default_rng(4), 1, 10.0, "typical")
    d = human_drivers(params, 6)
    calm = Observation(v=np.array([10.0]), a=np.zeros(1), gap=np.array([40.0]), v_lead=np.array([10.0]),
                       a_lead=np.zeros(1))
    for _ in range(10):
        d.act(calm)
    assert d.mode[0] == ACCELERATE
    # the lead brakes at 8 m/s^2 from 10 m ahead: braking at the driver's own a_min cannot keep x_min
    danger = Observation(v=np.array([10.0]), a=np.zeros(1), gap=np.array([10.0]), v_lead=np.array([10.0]),
                         a_lead=np.array([-8.0]))
    u = d.act(danger)
    assert d.mode[0] == EMERGENCY and u[0] < params.a_min[0]
    # a milder change (the lead 4 m/s slower at 40 m: no emergency) is seen only after T' = 1 s (5 steps)
    p = Perception(DRIVER_MODELS[6].perception, 1, DT, [(np.random.default_rng(0), 1)])
    perceived = [p.perceive(rows(10.0, 0.0, 40.0, 10.0 if k < 2 else 6.0, 0.0))[3, 0] for k in range(8)]
    assert all(x == 10.0 for x in perceived[:7])  # the step at k = 2 is seen from k = 7 on
    assert perceived[7] == 6.0


def settle(settings, lead_speed=2.0, steps=1500):
    params = sample_drivers(np.random.default_rng(5), 6, 8.33, "naturalistic")
    d = MPCDriver(params, settings=settings)
    n = d.n
    v, gap, a = np.full(n, lead_speed), np.full(n, 20.0), np.zeros(n)
    for _ in range(steps):
        a = d.act(Observation(v=v, a=a, gap=gap, v_lead=np.full(n, lead_speed), a_lead=np.zeros(n)))
        vn = np.maximum(v + a * DT, 0.0)
        gap = gap + (lead_speed - 0.5 * (v + vn)) * DT
        v = vn
    return params, gap


def test_model_6_follows_a_slow_vehicle_at_its_own_time_gap():
    params, gap6 = settle(DRIVER_MODELS[6].settings)
    np.testing.assert_allclose(gap6, params.x_min + params.c_tg * 2.0, atol=0.1)  # e_x = 0
    _, gap5 = settle(DRIVER_MODELS[5].settings)
    assert np.all(gap5 > gap6 + 3.0)  # model 5: the free law held back by its constraints, far behind
