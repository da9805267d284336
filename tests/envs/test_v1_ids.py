"""The -v1 ids (issue 33): the observation is the v0 one with the safety-margin features
appended, the default reward is MarginReward, CarFollowing-v1 trains on varied traffic,
and the native vector env gives what the single env gives."""

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.acc_env import ACCEnv
from acc_gym.envs.config import EnvConfig
from acc_gym.envs.observation import FEATURES, margin_features
from acc_gym.envs.registration import CARFOLLOWING_V1
from acc_gym.envs.reward import CriteriaReward, MarginReward

V1 = ["acc_gym/CarFollowing-v1", "acc_gym/SingleLane-v1", "acc_gym/NCAP-v1", "acc_gym/StopAndGo-v1"]


@pytest.mark.parametrize("env_id", V1)
def test_a_v1_step_is_the_v0_fields_then_their_features(env_id):
    env = gym.make(env_id)
    assert env.unwrapped.config.version == 1 and isinstance(env.unwrapped.core.reward_fn, MarginReward)
    assert env.observation_space.shape == (13,)
    obs, _ = env.reset(seed=3)
    for k in range(60):
        assert env.observation_space.contains(obs)
        # exactly the features of the emitted float32 fields (what a -v1 policy computes from -v0 ones)
        assert np.array_equal(obs, margin_features(obs[:7]).astype(np.float32))
        obs, r, term, trunc, info = env.step(np.array([0.3 * np.sin(0.1 * k)], dtype=np.float32))
        assert set(info["rewards"]) == set(MarginReward.TERMS)
        assert r == pytest.approx(sum(info["rewards"].values()))
        if term or trunc:
            break
    env.close()


def test_v1_is_v0_underneath():
    """Same seed, same actions: the v1 observation's first fields are v0's observation, and
    v0's rewards are v0's own; only the appended features and the reward differ."""
    v0, v1 = gym.make("acc_gym/SingleLane-v0"), gym.make("acc_gym/SingleLane-v1")
    o0, _ = v0.reset(seed=11)
    o1, _ = v1.reset(seed=11)
    for k in range(80):
        assert np.array_equal(o0, o1[:7])
        a = np.array([0.5 * np.cos(0.05 * k)], dtype=np.float32)
        o0, r0, t0, u0, i0 = v0.step(a)
        o1, r1, t1, u1, i1 = v1.step(a)
        assert (t0, u0) == (t1, u1) and i0["q"] == i1["q"]
        assert set(i0["rewards"]) == set(CriteriaReward().__class__.__dataclass_fields__) - {"jerk_scale"}
        if t0 or u0:
            break


def test_carfollowing_v1_draws_its_training_mixture():
    env = gym.make("acc_gym/CarFollowing-v1")
    cfg = env.unwrapped.config
    assert cfg.drivers == "naturalistic"
    assert "carfollowing/varied" in cfg.scenarios and "stopandgo" in cfg.scenarios
    p = dict(zip(cfg.scenarios, cfg.probabilities))
    assert p["carfollowing/varied"] == pytest.approx(CARFOLLOWING_V1["carfollowing/varied"])
    assert sum(p[f"carfollowing/{k}"] for k in (60, 90, 120)) == pytest.approx(CARFOLLOWING_V1["carfollowing"])
    seen, speeds = set(), []
    for seed in range(60):
        env.reset(seed=seed)
        sc = env.unwrapped.scenario
        seen.add(sc.id)
        if sc.id == "carfollowing/varied":
            speeds.append(sc.params["speed_limit"])
    assert seen <= set(cfg.scenarios)
    assert {"carfollowing/varied", "stopandgo", "singlelane/2/car-following"} <= seen
    assert min(speeds) < 65 and max(speeds) > 105 and all(40 <= s <= 130 for s in speeds)
    # the v0 id still draws only paper 003's test
    assert set(gym.make("acc_gym/CarFollowing-v0").unwrapped.config.scenarios) == {
        "carfollowing/60", "carfollowing/90", "carfollowing/120"}


def test_v2v_adds_the_second_vehicles_features():
    from acc_gym.evaluation.runner import load_controller

    env, acc = gym.make("acc_gym/StopAndGo-v1", v2v=True), load_controller("acc")
    assert env.observation_space.shape == (11 + 12,)
    obs, _ = env.reset(seed=0)
    for _ in range(40):
        obs, _, term, trunc, _ = env.step(acc.predict(obs[:11], deterministic=True)[0])
        assert not (term or trunc)
    np.testing.assert_allclose(obs, margin_features(obs[:11].astype(float)), rtol=1e-5, atol=1e-5)
    second = dict(zip(FEATURES, obs[17:]))
    assert second["time_headway"] > dict(zip(FEATURES, obs[11:17]))["time_headway"]  # the second is further


def test_the_vector_env_gives_the_single_envs_v1_observations():
    vec = gym.make_vec("acc_gym/SingleLane-v1", num_envs=3, vectorization_mode="vector_entry_point")
    single = [gym.make("acc_gym/SingleLane-v1") for _ in range(3)]
    obs, _ = vec.reset(seed=[5, 6, 7])
    for i, env in enumerate(single):
        o, _ = env.reset(seed=5 + i)
        np.testing.assert_array_equal(obs[i], o)
    a = np.full((3, 1), 0.1, dtype=np.float32)
    for _ in range(20):
        obs, rew, term, trunc, _ = vec.step(a)
        for i, env in enumerate(single):
            o, r, *_ = env.step(a[i])
            np.testing.assert_allclose(obs[i], o, rtol=1e-6, atol=1e-6)
            assert rew[i] == pytest.approx(r)
    vec.close()


def test_a_bad_version_is_named():
    with pytest.raises(ValueError, match="version.*7"):
        EnvConfig(version=7)
    with pytest.raises(ValueError, match="version"):
        ACCEnv(version=True)


def test_worker_shards_give_the_same_v1_steps():
    a = gym.make_vec("acc_gym/SingleLane-v1", num_envs=4, vectorization_mode="vector_entry_point")
    b = gym.make_vec("acc_gym/SingleLane-v1", num_envs=4, vectorization_mode="vector_entry_point", workers=2)
    try:
        oa, _ = a.reset(seed=3)
        ob, _ = b.reset(seed=3)
        assert oa.shape == (4, 13) and np.array_equal(oa, ob)
        act = np.full((4, 1), 0.1, dtype=np.float32)
        for _ in range(30):
            oa, ra, *_ = a.step(act)
            ob, rb, *_ = b.step(act)
            assert np.array_equal(oa, ob) and np.array_equal(ra, rb)
    finally:
        b.close()
        a.close()
