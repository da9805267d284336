"""Sensors and actuators in the environments (``gym.make(id, sensors=..., actuators=...)``):
ideal is no model at all, the radar changes only what the controller sees, the actuators
what the vehicle realises, seeded, and the vector env equals single envs with them."""

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.config import EnvConfig
from acc_gym.evaluation.runner import load_controller
from acc_gym.onboard import ACTUATOR_PRESETS, SENSOR_PRESETS, ActuatorConfig, SensorConfig

DT = 0.2
IDS = ("acc_gym/CarFollowing-v1", "acc_gym/SingleLane-v1", "acc_gym/NCAP-v1", "acc_gym/StopAndGo-v1")


def _drive(env, seed, policy=None, scenario=None, steps=None):
    obs, _ = env.reset(seed=seed, options=None if scenario is None else {"scenario": scenario})
    out = {"obs": [obs], "a": [], "gap": [], "reward": []}
    core = env.unwrapped.core
    done, k = False, 0
    while not done and (steps is None or k < steps):
        action = policy.predict(obs, deterministic=True)[0] if policy is not None else np.array([0.3 * np.sin(k / 4)])
        obs, r, term, trunc, info = env.step(np.asarray(action, dtype=np.float32).reshape(1))
        out["obs"].append(obs)
        out["a"].append(info["a_applied"])
        out["gap"].append(core.world.neighbours.gap[0, 0])
        out["reward"].append(r)
        done, k = term or trunc, k + 1
    out["info"] = info
    return {k: (np.array(v) if isinstance(v, list) else v) for k, v in out.items()}


def test_the_ideal_presets_are_no_model_and_give_the_default_trajectories():
    assert EnvConfig(sensors="ideal", actuators="ideal") == EnvConfig()
    for env_id in IDS:
        plain = _drive(gym.make(env_id), 3, steps=60)
        env = gym.make(env_id, sensors="ideal", actuators={"lag": 0.0})
        assert env.unwrapped.core.car is None
        ideal = _drive(env, 3, steps=60)
        assert np.array_equal(plain["obs"], ideal["obs"]) and np.array_equal(plain["reward"], ideal["reward"])


@pytest.mark.parametrize("env_id", IDS)
def test_the_radar_changes_what_the_controller_sees_not_the_world(env_id):
    plain = _drive(gym.make(env_id), 4)
    noisy = _drive(gym.make(env_id, sensors=SensorConfig(gap_sd=0.5, rate_sd=0.2)), 4)
    # an open-loop command: the same world, the same episode, the same true gaps and accelerations
    assert np.array_equal(plain["a"], noisy["a"]) and np.array_equal(plain["gap"], noisy["gap"])
    assert plain["info"]["score"] == noisy["info"]["score"]
    seen = plain["obs"][:, 4] == 1.0
    assert seen.sum() > 10 and np.array_equal(seen, noisy["obs"][:, 4] == 1.0)
    err = (noisy["obs"][:, 2] - plain["obs"][:, 2])[seen & (plain["obs"][:, 2] > 2.0)]
    assert 0.3 < err.std() < 0.7
    # the -v1 features are those of what the radar reports
    if env_id.endswith("-v1"):
        from acc_gym.envs.observation import margin_features

        m0 = 7
        again = margin_features(noisy["obs"][:, :m0].astype(float), 200.0).astype(np.float32)
        assert np.allclose(again[:, m0:], noisy["obs"][:, m0:], atol=1e-5)
    # the same seed, the same draws
    again = _drive(gym.make(env_id, sensors=SensorConfig(gap_sd=0.5, rate_sd=0.2)), 4)
    assert np.array_equal(again["obs"], noisy["obs"])


def test_the_actuators_realise_the_command_through_their_lag_and_dead_time():
    cfg = ActuatorConfig(lag=0.4, dead_time=0.4)  # two steps late, then the lag
    env = gym.make("acc_gym/SingleLane-v1", actuators=cfg)
    env.reset(seed=0)
    a = [env.step(np.array([0.1], dtype=np.float32))[4]["a_applied"] for _ in range(12)]  # 0.3 m/s^2
    alpha = 1 - np.exp(-0.2 / 0.4)
    k = np.arange(12)
    expected = np.where(k >= 2, 0.3 * (1 - (1 - alpha) ** (k - 1)), 0.0)
    assert np.allclose(a, expected, atol=1e-9)


def test_a_cut_in_is_acquired_later_by_a_narrow_beam_and_the_episode_scores_worse():
    acc = load_controller("acc")
    runs = {fov: _drive(gym.make("acc_gym/SingleLane-v1", sensors=SensorConfig(far_fov=fov)), 1, acc,
                        "singlelane/2/cut-in") for fov in (180.0, 6.0, 2.0)}
    first = {fov: int(np.argmax(r["obs"][:, 4] == 1.0)) for fov, r in runs.items()}
    assert first[180.0] < first[6.0] < first[2.0]
    assert runs[2.0]["info"]["score"] < runs[180.0]["info"]["score"] - 20


def test_the_vector_env_equals_single_envs_with_sensors_and_actuators():
    kw = {"sensors": "degraded", "actuators": "typical", "randomise": {"lag": [0, 0.8], "noise": [0, 3]}}
    vec = gym.make_vec("acc_gym/SingleLane-v1", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    singles = [gym.make("acc_gym/SingleLane-v1", **kw) for _ in range(3)]
    vo, _ = vec.reset(seed=11)
    so = np.stack([e.reset(seed=11 + i)[0] for i, e in enumerate(singles)])
    assert np.array_equal(vo, so)
    rng = np.random.default_rng(0)
    for k in range(120):  # through the autoresets of ended episodes
        act = rng.uniform(-0.5, 0.5, (3, 1)).astype(np.float32)
        vo, vr, vt, vtr, _ = vec.step(act)
        for i, e in enumerate(singles):
            if getattr(e, "_done", False):
                o, _ = e.reset()
                e._done = False
                r, t, tr = 0.0, False, False
            else:
                o, r, t, tr, _ = e.step(act[i])
                e._done = t or tr
            assert np.array_equal(vo[i], o), f"step {k} env {i}"
            assert vr[i] == r


def test_settings_name_their_bad_values():
    with pytest.raises(ValueError, match="unknown sensors preset 'perfect'"):
        gym.make("acc_gym/CarFollowing-v1", sensors="perfect")
    with pytest.raises(ValueError, match=r"unknown SensorConfig setting\(s\) \['noise'\]"):
        gym.make("acc_gym/CarFollowing-v1", sensors={"noise": 1.0})
    with pytest.raises(ValueError, match="ActuatorConfig.lag"):
        gym.make("acc_gym/CarFollowing-v1", actuators={"lag": -1})
    assert EnvConfig(sensors="typical").sensors == SENSOR_PRESETS["typical"]
    assert EnvConfig.from_dict(EnvConfig(actuators="degraded").to_dict()).actuators == ACTUATOR_PRESETS["degraded"]


def test_the_car_s_draws_leave_the_scenarios_alone():
    plain = gym.make("acc_gym/SingleLane-v1")
    car = gym.make("acc_gym/SingleLane-v1", sensors="degraded", randomise={"lag": [0, 1], "dead_time": [0, 1]})
    seen = [[], []]
    for env, out in zip((plain, car), seen):
        _, info = env.reset(seed=5)
        out.append((info["scenario"], info["scenario_seed"]))
        for _ in range(6):
            _, info = env.reset()
            out.append((info["scenario"], info["scenario_seed"]))
    assert seen[0] == seen[1]


def test_randomisation_draws_each_episode_s_car_within_its_ranges():
    env = gym.make("acc_gym/CarFollowing-v1", sensors="typical",
                   randomise={"lag": [0.1, 0.7], "dead_time": [0.0, 0.5], "noise": [0.5, 2.0]})
    core = env.unwrapped.core
    cars = []
    env.reset(seed=2)
    for _ in range(40):
        lag = -DT / np.log(1.0 - core.car.actuators.alpha[0])
        dead = (core.car.actuators.m[0] + core.car.actuators.f[0]) * DT
        env.step(np.zeros(1, dtype=np.float32))  # the radar starts at the first observation or step
        cars.append((lag, dead, core.car.radar.scenes["scale"][0]))
        env.reset()
    cars = np.array(cars)
    for (lo, hi), col in zip(((0.1, 0.7), (0.0, 0.5), (0.5, 2.0)), cars.T):
        assert np.all((col >= lo - 1e-9) & (col <= hi + 1e-9)) and col.std() > 0.1 * (hi - lo)
    again = gym.make("acc_gym/CarFollowing-v1", sensors="typical",
                     randomise={"lag": [0.1, 0.7], "dead_time": [0.0, 0.5], "noise": [0.5, 2.0]})
    again.reset(seed=2)
    assert -DT / np.log(1.0 - again.unwrapped.core.car.actuators.alpha[0]) == pytest.approx(cars[0, 0])
    with pytest.raises(ValueError, match=r"Randomisation.lag must be \[low, high\] .* got \[0.5, 0.1\]"):
        gym.make("acc_gym/CarFollowing-v1", randomise={"lag": [0.5, 0.1]})
