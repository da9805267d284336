"""acc_gym/Ring-v1 (acc_gym.envs.ring_env.RingEnv): seeding, one path with simulate_ring, wrap-around,
the reward's terms by hand, collisions, bad actions and Gymnasium's checker."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.acc_env import observation_space
from acc_gym.envs.config import EnvConfig
from acc_gym.evaluation.scoring import score_episode
from acc_gym.evaluation.trace import EgoTrace
from acc_gym.evaluation.waves import speed_sd
from acc_gym.simulation.ring import SUGIYAMA_SPEED, ring_layout, simulate_ring
from acc_gym_agents.controllers import FollowerStopper

ID = "acc_gym/Ring-v1"


def _run(env, act, seed, options=None):
    obs, info = env.reset(seed=seed, options=options)
    out = {"obs": [obs], "rewards": [], "infos": []}
    while True:
        obs, r, term, trunc, info = env.step(act(obs))
        out["obs"].append(obs)
        out["rewards"].append(r)
        out["infos"].append(info)
        if term or trunc:
            out["term"], out["trunc"] = term, trunc
            return out


def test_the_same_seed_gives_the_same_episode_and_only_the_envs_generator_draws():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.3, size=(200, 1)).astype(np.float32)
    runs = []
    for _ in range(2):
        np.random.seed(len(runs))  # the global generator plays no part
        env = gym.make(ID, warmup=10.0, horizon=20.0)
        it = iter(actions)
        runs.append((_run(env, lambda o: next(it), seed=11), env.unwrapped.trace()))
    (a, ta), (b, tb) = runs
    np.testing.assert_array_equal(ta.s, tb.s)
    assert a["rewards"] == b["rewards"] and len(a["rewards"]) == 100  # 20 s of control at 0.2 s
    assert a["infos"][-1]["length"] == b["infos"][-1]["length"]
    other = gym.make(ID, warmup=10.0, horizon=20.0)
    _, i1 = other.reset(seed=11)
    _, i2 = other.reset(seed=12)
    assert i1["length"] == a["infos"][-1]["length"] and i2["ring_seed"] != i1["ring_seed"]
    lengths = [other.reset(seed=s)[1]["length"] for s in range(20)]
    assert min(lengths) >= 220.0 and max(lengths) <= 270.0 and np.std(lengths) > 5.0  # drawn across the range


def test_follower_stopper_through_the_action_is_simulate_rings_follower_stopper():
    # no warm-up: the ego drives from the start, so the episode is simulate_ring's ring with the
    # controller at the ego's position (the last), on the env's drawn length and seed
    env = gym.make(ID, warmup=0.0, horizon=80.0)
    fs = FollowerStopper()
    run = _run(env, lambda o: fs.predict(o)[0], seed=4)
    last = run["infos"][-1]
    tr = simulate_ring(last["length"], 22, layout=ring_layout(22, (21,)), seeds=last["ring_seed"],
                       controller=FollowerStopper(), duration=80.0, version=1)
    mine = env.unwrapped.trace()
    np.testing.assert_array_equal(mine.s, tr.s)
    np.testing.assert_array_equal(mine.a, tr.a)
    assert last["ring"]["speed_sd"] == speed_sd(tr.v, tr.t, 0.0)[0]
    assert last["ring"]["speed_sd"] > 0.1  # there is a ring to measure (waves start to form)


def test_gaps_wrap_around_the_ring():
    env = gym.make(ID, warmup=120.0, horizon=10.0)
    obs, info = env.reset(seed=2)
    tr = env.unwrapped.trace()
    L = info["length"]
    assert np.sum(tr.s[-1, 0] >= L) >= 5  # several vehicles crossed the seam in the warm-up
    x = tr.x[-1, 0]
    assert np.any(x < tr.s[-1, 0] - L + 1e-9)  # their positions wrapped
    assert np.all((x >= 0) & (x < L))
    # the ego (the last vehicle) follows vehicle 20; vehicle 0 follows the ego, one lap ahead
    assert obs[2] == pytest.approx(np.mod(x[20] - x[21], L) - 4.7, abs=1e-4)
    assert tr.gap[-1, 0, 0] == pytest.approx(np.mod(x[21] - x[0], L) - 4.7, abs=1e-9)
    assert obs[3] == pytest.approx(tr.v[-1, 0, 20] - tr.v[-1, 0, 21], abs=1e-5)
    assert obs[0] == pytest.approx(tr.v[-1, 0, 21], abs=1e-5)


def test_reward_terms_are_the_rings_flow_and_smoothness_and_sum_to_the_reward():
    env = gym.make(ID, warmup=30.0, horizon=20.0)
    run = _run(env, lambda o: np.array([0.0], np.float32), seed=3, options={"ego": "human"})
    tr = env.unwrapped.trace()
    k0 = 150  # 30 s of warm-up
    for i, (r, info) in enumerate(zip(run["rewards"], run["infos"])):
        terms = info["rewards"]
        assert set(terms) == {"flow", "smoothness", "collision"}
        assert r == sum(terms.values())
        k = k0 + i + 1
        assert terms["flow"] == pytest.approx(tr.v[k, 0].mean() / SUGIYAMA_SPEED)
        assert terms["smoothness"] == pytest.approx(-0.2 * np.mean(tr.a[k, 0] ** 2))
        assert terms["collision"] == 0.0
    last = run["infos"][-1]
    assert run["trunc"] and not run["term"] and last["episode_return"] == pytest.approx(sum(run["rewards"]))
    # the ego's report is paper 003's score of its drive over the control time
    e = slice(k0, None)
    ego = EgoTrace(t=tr.t[e], v=tr.v[e, 0, 21], a=tr.a[e, 0, 21], gap=tr.gap[e, 0, 21], v_lead=tr.v[e, 0, 20],
                   a_lead=tr.a[e, 0, 20], set_speed=SUGIYAMA_SPEED, time_gap=1.5)
    assert last["report"] == score_episode(ego).to_dict() and last["score"] == last["report"]["score"]
    assert {"safety", "car_following", "road_edge", "boundary_line"} == set(last["report"]["items"])
    assert {"u", "j_x", "j_y"} <= set(last["report"])  # Q, D, G items, efficiency u and comfort j
    assert last["ring"]["speed_sd"] == pytest.approx(speed_sd(tr.v, tr.t, 30.0)[0])


def test_the_all_human_option_ignores_the_actions():
    env = gym.make(ID, warmup=10.0, horizon=10.0)
    a = _run(env, lambda o: np.array([1.0], np.float32), seed=9, options={"ego": "human"})
    ta = env.unwrapped.trace()
    b = _run(env, lambda o: np.array([-1.0], np.float32), seed=9, options={"ego": "human"})
    np.testing.assert_array_equal(ta.s, env.unwrapped.trace().s)
    assert a["rewards"] == b["rewards"]


def test_a_collision_terminates_with_the_penalty():
    env = gym.make(ID, warmup=0.0, horizon=60.0)
    run = _run(env, lambda o: np.array([1.0], np.float32), seed=1)  # full throttle into the car ahead
    last = run["infos"][-1]
    assert run["term"] and not run["trunc"] and len(run["rewards"]) < 300
    assert 21 in last["collided"] and last["gap"] <= 0.0
    assert last["rewards"]["collision"] == -100.0 and run["rewards"][-1] == pytest.approx(sum(last["rewards"].values()))
    assert last["ring"]["collisions"] >= 1 and not last["qualified"]
    assert all(i["rewards"]["collision"] == 0.0 for i in run["infos"][:-1])
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.array([0.0], np.float32))


@pytest.mark.parametrize("action, message", [(np.array([np.nan], np.float32), "NaN"),
                                             (np.zeros(2, np.float32), r"shape \(1,\), got \(2,\)"),
                                             ("0.5", "numeric"), (np.array([np.inf]), "finite")])
def test_bad_actions_are_named(action, message):
    env = gym.make(ID, warmup=0.0, horizon=10.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


def test_the_observation_is_the_v1_ids_and_connected_adds_the_rings_speeds():
    plain = gym.make(ID, warmup=20.0, horizon=10.0)
    v1 = observation_space(EnvConfig(version=1))
    assert plain.observation_space.shape == (13,) and np.array_equal(plain.observation_space.low, v1.low)
    assert plain.action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    conn = gym.make(ID, warmup=20.0, horizon=10.0, connected=True)
    o1, _ = plain.reset(seed=5)
    o2, _ = conn.reset(seed=5)
    assert o2.shape == (15,) and np.array_equal(o1, o2[:13])
    v = conn.unwrapped.trace().v[-1, 0]
    assert o2[13] == pytest.approx(v.mean(), rel=1e-6) and o2[14] == pytest.approx(v.std(), rel=1e-5)


def test_bad_settings_are_named():
    with pytest.raises(ValueError, match="lengths"):
        gym.make(ID, lengths=(270.0, 220.0))
    with pytest.raises(ValueError, match="horizon"):
        gym.make(ID, horizon=float("nan"))
    env = gym.make(ID, warmup=0.0, horizon=1.0)
    with pytest.raises(ValueError, match="ego"):
        env.reset(seed=0, options={"ego": "robot"})


def test_gymnasiums_checker_passes():
    env = gym.make(ID, warmup=2.0, horizon=4.0)
    check_env(env.unwrapped)
    assert gym.make("acc_gym:acc_gym/Ring-v1", warmup=0.0, horizon=1.0).unwrapped.__class__.__name__ == "RingEnv"


def _rl_curves():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import rl_curves

    return rl_curves


def test_rl_curves_compares_a_controller_with_the_all_human_ring_on_the_same_seed():
    rl_curves = _rl_curves()
    fs = FollowerStopper()
    out = rl_curves.ring_compare(ID, [3], {"fs": lambda o: fs.predict(o)[0]}, warmup=20.0, horizon=20.0)
    (h,), (f,) = out["human"], out["fs"]
    assert h["length"] == f["length"] and h["seed"] == f["seed"] == 3
    assert f["speed_sd_ratio"] == pytest.approx(f["speed_sd"] / h["speed_sd"])
    env = gym.make(ID, warmup=20.0, horizon=20.0)
    run = _run(env, lambda o: np.zeros(1, np.float32), seed=3, options={"ego": "human"})
    assert h["speed_sd"] == run["infos"][-1]["ring"]["speed_sd"]  # the all-human ring is the stand-in's


def test_the_shipped_ppo_settings_are_valid_sb3_arguments():
    sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")
    from stable_baselines3.common.vec_env import DummyVecEnv

    tuned = _rl_curves().ring_defaults("ppo", ID)
    venv = DummyVecEnv([lambda: gym.make(ID, warmup=0.0, horizon=2.0)])
    model = sb3.PPO("MlpPolicy", venv, seed=0, device="cpu", **tuned["algo_kwargs"])
    assert model.gamma == tuned["entry"]["gamma"] and model.n_steps == tuned["entry"]["n_steps"]
    assert tuned["timesteps"] <= 300_000 and tuned["num_envs"] >= 1
