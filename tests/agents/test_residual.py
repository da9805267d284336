"""Residual RL on top of the linear ACC: the executed action, the shield, the score bonus, saved runs."""

import json

import numpy as np
import pytest
from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper

from acc_gym.evaluation.runner import evaluate, load_controller
from acc_gym_agents.controllers import LinearACC
from acc_gym_agents.rl.policy import SB3Policy, load_policy
from acc_gym_agents.rl.residual import (
    ResidualVecEnv,
    ScoreBonusVecEnv,
    controller_action,
    make_base,
    proper_response_shield,
    residual_action,
    speed_cap,
)
from acc_gym_agents.rl.train import mix_settings, train
from acc_gym_agents.rl.vec_env import SB3VecEnv


class Recorder(VecEnvWrapper):
    """Records the actions that reach the raw vector env."""

    def __init__(self, venv):
        super().__init__(venv)
        self.actions = []

    def reset(self):
        return self.venv.reset()

    def step_async(self, actions):
        self.actions.append(np.array(actions, copy=True))
        self.venv.step_async(actions)

    def step_wait(self):
        return self.venv.step_wait()


def test_residual_action_is_base_plus_scaled_policy_clipped():
    base = np.array([[0.2], [-0.9], [0.95], [0.0]], dtype=np.float32)
    rl = np.array([[0.5], [-1.0], [1.0], [7.0]], dtype=np.float32)  # the last one is clipped to 1 first
    out = residual_action(base, rl, 0.3)
    assert out.dtype == np.float32 and out.shape == (4, 1)
    np.testing.assert_allclose(out[:, 0], [0.35, -1.0, 1.0, 0.3], atol=1e-6)
    with pytest.raises(ValueError, match="residual_scale"):
        ResidualVecEnv(SB3VecEnv(1, seed=0), "acc", 0.0)
    with pytest.raises(ValueError, match="unknown residual base"):
        make_base("idm")


def test_the_wrapper_executes_the_linear_acc_plus_the_scaled_residual_on_raw_observations():
    rec = Recorder(SB3VecEnv(4, seed=5, scenarios=("singlelane",)))
    venv = ResidualVecEnv(rec, "acc", 0.3)
    obs = venv.reset()
    acc = LinearACC()
    rng = np.random.default_rng(0)
    for _ in range(60):  # through episode ends (same-step autoreset: obs is then the next episode's first)
        rl = rng.uniform(-1.5, 1.5, (4, 1)).astype(np.float32)
        venv.step_async(rl)
        expected = np.clip(acc.predict(obs)[0] + 0.3 * np.clip(rl, -1, 1), -1, 1)
        np.testing.assert_allclose(rec.actions[-1], expected, atol=1e-6)
        obs, _, _, _ = venv.step_wait()
    # a zero residual is the linear ACC itself
    venv.step_async(np.zeros((4, 1), np.float32))
    np.testing.assert_array_equal(rec.actions[-1], acc.predict(obs)[0])
    venv.close()


def test_shield_brakes_firmly_while_q_is_negative_and_otherwise_leaves_the_action():
    # v, a, gap, v_rel, in range, set speed, time gap; Gapsafe = v h + (v^2 - v_lead^2) / 16
    obs = np.array([[20.0, 0.0, 20.0, 0.0, 1.0, 25.0, 1.5],    # gap 20 < 30: Q < 0
                    [20.0, 0.0, 40.0, 0.0, 1.0, 25.0, 1.5],    # Q > 0
                    [20.0, 0.0, 200.0, 0.0, 0.0, 25.0, 1.5],   # nothing in range
                    [0.2, 0.0, 0.1, 0.0, 1.0, 25.0, 1.5]], np.float32)  # standing
    act = np.full((4, 1), 0.5, np.float32)
    out = proper_response_shield(obs, act)
    np.testing.assert_allclose(out[:, 0], [-2.5 / 8.0, 0.5, 0.5, 0.5])
    assert proper_response_shield(obs[0], np.array([-0.9], np.float32))[0] == pytest.approx(-0.9)  # harder stays
    single = controller_action(obs[0], np.zeros(1, np.float32), LinearACC(), 0.3, shield=True)
    assert single.shape == (1,) and single[0] <= -2.5 / 8.0


def test_base_shield_never_brakes_softer_than_the_base_inside_gapsafe_at_any_speed():
    class Base:  # brakes hard everywhere
        def predict(self, obs, deterministic=True):
            return np.full((np.atleast_2d(obs).shape[0], 1), -0.9, np.float32), None

    # Q < 0 moving; Q > 0; Q < 0 creeping at 0.3 m/s towards a stopped car 0.2 m ahead
    obs = np.array([[20.0, 0.0, 20.0, 0.0, 1.0, 25.0, 1.5],
                    [20.0, 0.0, 40.0, 0.0, 1.0, 25.0, 1.5],
                    [0.3, 0.0, 0.2, -0.3, 1.0, 25.0, 1.5]], np.float32)
    wants = np.ones((3, 1), np.float32)  # the learnt part asks for full throttle
    base = controller_action(obs, wants, Base(), 0.5, shield="base")
    plain = controller_action(obs, wants, Base(), 0.5, shield="proper-response")
    # base + 0.5 * 1 = -0.4; inside Gapsafe the base's -0.9 wins, at any speed
    np.testing.assert_allclose(base[:, 0], [-0.9, -0.4, -0.9], atol=1e-6)
    # the plain shield only caps at -2.5 / 8 (moving): -0.4 already brakes harder; it leaves the creeping ego alone
    np.testing.assert_allclose(plain[:, 0], [-0.4, -0.4, -0.4], atol=1e-6)
    with pytest.raises(ValueError, match="shield"):
        controller_action(obs, wants, Base(), 0.5, shield="strong")


def test_speed_cap_keeps_the_ego_near_its_set_speed():
    obs = np.array([[20.0, 0.0, 200.0, 0.0, 0.0, 20.0, 1.5],   # at the set speed: no acceleration
                    [18.0, 0.0, 200.0, 0.0, 0.0, 20.0, 1.5],   # 2 m/s below: up to 2 m/s^2
                    [22.0, 0.0, 200.0, 0.0, 0.0, 20.0, 1.5]], np.float32)  # 2 m/s above: brake 2 m/s^2
    out = speed_cap(obs, np.ones((3, 1), np.float32), 0.0)
    np.testing.assert_allclose(out[:, 0], [0.0, 2.0 / 3.0, -2.0 / 8.0], atol=1e-6)
    np.testing.assert_allclose(speed_cap(obs, np.full((3, 1), -0.5, np.float32), 1.0)[:, 0], -0.5)  # braking stays
    assert controller_action(obs[2], np.ones(1, np.float32), LinearACC(), 0.5, max_overspeed=0.0)[0] < 0


def test_score_bonus_is_added_at_episode_ends_only():
    def rollout(bonus):
        venv = SB3VecEnv(2, seed=4, scenarios=("ncap/ccrs/20",))  # full throttle: a collision, score 0-45
        if bonus:
            venv = ScoreBonusVecEnv(venv, bonus)
        venv.reset()
        out = []
        for _ in range(200):
            venv.step_async(np.ones((2, 1), np.float32))
            _, r, done, infos = venv.step_wait()
            out.append(r.copy())
            if done.any():
                return np.array(out), infos
    plain, infos = rollout(0.0)
    bonus, _ = rollout(50.0)
    np.testing.assert_array_equal(plain[:-1], bonus[:-1])
    np.testing.assert_allclose(bonus[-1], plain[-1] + [50.0 * i["score"] / 100 for i in infos], rtol=1e-6)
    with pytest.raises(ValueError, match="score_bonus"):
        ScoreBonusVecEnv(SB3VecEnv(1, seed=0), -1.0)


def test_mix_weights_families_by_share():
    m = mix_settings({"singlelane": 3, "carfollowing": 1})
    ids, w = m["scenarios"], np.array(m["weights"])
    assert len(ids) == len(w) == 25 and w.sum() == pytest.approx(1.0)
    cf = np.array([i.startswith("carfollowing/") for i in ids])
    assert w[cf].sum() == pytest.approx(0.25) and np.allclose(w[cf], 0.25 / 3)
    with pytest.raises(ValueError, match="either mix or scenarios"):
        train("ppo", out="/nonexistent/x", mix={"ncap": 1}, scenarios=("ncap",))


def test_a_saved_residual_run_reloads_and_scores_as_the_in_memory_policy(tmp_path):
    run = train("ppo", "acc_gym/NCAP-v0", timesteps=256, seed=3, out=tmp_path / "res", num_envs=4, eval_episodes=3,
                residual="acc", residual_scale=0.3, shield=True, score_bonus=10.0, residual_kwargs={"k1": 0.5},
                max_overspeed=1.0,
                algo_kwargs={"n_steps": 64, "batch_size": 64, "policy_kwargs": {"log_std_init": -2.0}})
    manifest = json.loads((run / "manifest.json").read_text())
    assert (manifest["residual"], manifest["residual_scale"], manifest["shield"], manifest["score_bonus"]) == (
        "acc", 0.3, "proper-response", 10.0)
    assert manifest["residual_kwargs"] == {"k1": 0.5} and manifest["max_overspeed"] == 1.0
    policy = load_policy(run)
    assert isinstance(load_controller(str(run)), SB3Policy)
    assert policy.residual == "acc" and policy.residual_scale == 0.3 and policy.shield
    assert policy.base.k1 == 0.5 and policy.max_overspeed == 1.0
    # the saved run scores exactly what the in-memory model scored at the end of training
    final = manifest["final_evaluation"]
    again = evaluate(str(run), "acc_gym/NCAP-v0", episodes=3, seed=manifest["eval_seed"])
    assert (again["mean_score"], again["share_qualified"], again["collisions"]) == (
        final["mean_score"], final["share_qualified"], final["collisions"])
    # and a checkpoint directory is a controller too
    ck = max((run / "checkpoints").iterdir())
    assert load_policy(ck).residual == "acc"
    # the executed action is the linear ACC plus the scaled model action (then the shield)
    obs = np.array([25.0, 0.0, 60.0, -1.0, 1.0, 30.0, 1.5], np.float32)
    raw, _ = policy.model.predict(policy.normalise(obs), deterministic=True)
    expected = np.clip(LinearACC(k1=0.5).predict(obs)[0] + 0.3 * np.clip(raw, -1, 1), -1, 1)
    expected = np.minimum(expected, (30.0 + 1.0 - 25.0) / 3.0)  # the speed cap (not binding here)
    np.testing.assert_allclose(policy.predict(obs)[0], expected, atol=1e-6)


def test_a_residual_policy_with_a_zero_model_is_the_linear_acc():
    class Zero:
        def predict(self, obs, deterministic=True):
            return np.zeros(np.shape(obs)[:-1] + (1,), np.float32), None

    policy = SB3Policy(Zero(), np.zeros(7), np.ones(7), residual="acc", residual_scale=0.3)
    a = evaluate(policy, "acc_gym/CarFollowing-v0", episodes=2, seed=11)
    b = evaluate("acc", "acc_gym/CarFollowing-v0", episodes=2, seed=11)
    assert a["scores"] == b["scores"]
    with pytest.raises(ValueError, match="shield"):
        SB3Policy(Zero(), np.zeros(7), np.ones(7), shield=True)


@pytest.mark.slow
def test_tiny_residual_training_through_the_cli(tmp_path, capsys):
    from acc_gym.cli import main

    out = tmp_path / "cli"
    assert main(["train", "ppo", "--env", "acc_gym/SingleLane-v0", "--mix", "singlelane=0.75", "carfollowing=0.25",
                 "--residual", "acc", "--residual-scale", "0.5", "--shield", "--score-bonus", "30",
                 "--timesteps", "512", "--num-envs", "4", "--eval-episodes", "2", "--seed", "7", "--no-progress",
                 "--out", str(out), "--algo-kwargs", '{"n_steps": 64, "batch_size": 128}']) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["mix"] == {"singlelane": 0.75, "carfollowing": 0.25} and manifest["shield"]
    assert manifest["algo_kwargs"] == {"n_steps": 64, "batch_size": 128}
    s = evaluate(str(out), "acc_gym/CarFollowing-v0", episodes=1, seed=2)
    assert s["episodes"] == 1 and 0.0 <= s["mean_score"] <= 100.0


def test_train_scoring_changes_the_training_environments_only(tmp_path, monkeypatch):
    import acc_gym_agents.rl.vec_env as vec_env

    seen = []

    class Spy(vec_env.SB3VecEnv):
        def __init__(self, num_envs, seed=None, **settings):
            seen.append(settings.get("scoring"))
            super().__init__(num_envs, seed=seed, **settings)

    monkeypatch.setattr(vec_env, "SB3VecEnv", Spy)
    with pytest.raises(ValueError, match="lead_margn"):
        train("ppo", "acc_gym/CarFollowing-v0", timesteps=64, out=tmp_path / "bad", train_scoring={"lead_margn": 1.0})
    run = train("ppo", "acc_gym/CarFollowing-v0", timesteps=128, seed=2, out=tmp_path / "ts", num_envs=2,
                eval_episodes=1, train_scoring={"lead_margin": 1.0}, algo_kwargs={"n_steps": 64, "batch_size": 64})
    assert [s.lead_margin for s in seen] == [1.0]  # the training envs
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["train_scoring"] == {"lead_margin": 1.0} and "scoring" not in manifest["env_settings"]
    again = evaluate(str(run), "acc_gym/CarFollowing-v0", episodes=1, seed=manifest["eval_seed"])  # default scoring
    assert again["mean_score"] == manifest["final_evaluation"]["mean_score"]
