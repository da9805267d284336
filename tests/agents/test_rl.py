"""RL with stable-baselines3: the vector-env adapter, and tiny training runs that save, reload and score."""

import json

import numpy as np
import pytest

from acc_gym.evaluation.runner import evaluate, load_controller
from acc_gym_agents.rl.policy import SB3Policy, load_policy
from acc_gym_agents.rl.train import EVAL_SEED_OFFSET, train
from acc_gym_agents.rl.vec_env import SB3VecEnv


def test_adapter_resets_in_the_same_step_and_keeps_the_terminal_observation():
    venv = SB3VecEnv(3, seed=4, scenarios=("ncap/ccrs/20",))  # full throttle: each episode ends in a collision
    obs = venv.reset()
    assert obs.shape == (3, 7)
    v0 = obs[:, 0].copy()
    for _ in range(200):
        venv.step_async(np.ones((3, 1), dtype=np.float32))
        obs, reward, done, infos = venv.step_wait()
        if done.any():
            break
    assert done.all()  # identical set-ups end together
    for i in range(3):
        term = infos[i]["terminal_observation"]
        assert term[2] == 0.0 and not infos[i]["TimeLimit.truncated"]  # ended at the stopped target
        assert infos[i]["score"] <= 45.0 and not infos[i]["qualified"]
        assert infos[i]["episode"]["r"] < -90.0  # the collision term
        assert obs[i, 0] == v0[i] and obs[i, 2] == pytest.approx(4 * v0[i], rel=1e-5)  # a fresh episode


def test_tiny_ppo_run_saves_reloads_and_is_scored_through_the_same_path(tmp_path, capsys, monkeypatch):
    import os
    import stat

    import torch

    before = torch.get_num_threads()
    monkeypatch.setenv("TTY_COMPATIBLE", "1")  # stderr taken for a terminal: the progress bar is drawn
    run = train("ppo", "acc_gym/NCAP-v0", timesteps=256, seed=3, out=tmp_path / "ppo", num_envs=4,
                eval_episodes=2, algo_kwargs={"n_steps": 64, "batch_size": 64}, progress=True)
    shown = capsys.readouterr()
    assert shown.out == "" and "train ppo" in shown.err and "256/256" in shown.err  # on stderr, to the end
    # every output with the same mode as the manifest (what atomic_write gives), model.zip too (it was 0600)
    mode = stat.S_IMODE(os.stat(run / "manifest.json").st_mode)
    assert mode == 0o644
    for path in [run / "model.zip", *(run / "checkpoints").glob("*/model.zip")]:
        assert stat.S_IMODE(os.stat(path).st_mode) == mode, path
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["algo"] == "ppo" and manifest["timesteps"] >= 256 and manifest["seed"] == 3
    assert manifest["eval_seed"] == 3 + EVAL_SEED_OFFSET and manifest["versions"]["stable-baselines3"]
    assert manifest["torch_threads"] == 1 and torch.get_num_threads() == before  # one thread, then restored
    evals = json.loads((run / "evaluations.json").read_text())
    assert len(evals) >= 2 and evals[-1] == manifest["final_evaluation"]
    assert len(list((run / "checkpoints").iterdir())) == len(evals)
    policy = load_policy(run)
    assert isinstance(policy, SB3Policy) and isinstance(load_controller(str(run)), SB3Policy)
    a1, _ = policy.predict(np.zeros(7, np.float32))  # the run directory: its numpy actor (policy.npz)
    a2, _ = load_policy(run / "model.zip").predict(np.zeros(7, np.float32))  # the stable-baselines3 model
    a3, _ = load_policy(run, backend="sb3").predict(np.zeros(7, np.float32))
    assert a1.shape == (1,) and np.array_equal(a2, a3) and np.allclose(a1, a2, atol=1e-6)
    by_path = evaluate(str(run), "acc_gym/NCAP-v0", episodes=2, seed=9)
    by_object = evaluate(policy, "acc_gym/NCAP-v0", episodes=2, seed=9)
    assert by_path["scores"] == by_object["scores"]


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_tiny_off_policy_runs(tmp_path, algo):
    # learning_starts below the budget, so that gradient steps are taken (the tuned SAC entry
    # starts learning after 2,000 steps; explicit algo_kwargs replace the tuned defaults)
    run = train(algo, "acc_gym/CarFollowing-v0", timesteps=300, seed=1, out=tmp_path / algo, num_envs=2,
                eval_episodes=1, algo_kwargs={"learning_starts": 100})
    assert json.loads((run / "manifest.json").read_text())["hyperparams"] is None
    s = evaluate(str(run), "acc_gym/CarFollowing-v0", episodes=1, seed=2)
    assert s["episodes"] == 1 and 0.0 <= s["mean_score"] <= 100.0


def test_train_help_explains_every_option(capsys):
    from acc_gym.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["train", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--seed SEED seed of the training environments and the model (default 0)" in text
    assert f"held-out seeds from seed + {EVAL_SEED_OFFSET}" in text
    assert "--eval-episodes EVAL_EPISODES episodes of each evaluation" in text
    options = [w for w in text.split() if w.startswith("--") and w != "--help"]
    for opt in dict.fromkeys(options):  # each option is followed by its help, not straight by the next option
        after = text.split(f" {opt} ", 1)[-1].split()
        nxt = after[1] if after and after[0].isupper() else (after[0] if after else "")
        assert not nxt.startswith("--"), f"{opt} has no help"


def test_bad_references_and_runs(tmp_path):
    with pytest.raises(ValueError, match="no manifest.json"):
        load_policy(tmp_path)
    (tmp_path / "manifest.json").write_text("{broken")
    with pytest.raises(ValueError, match="broken manifest"):
        load_policy(tmp_path)
    with pytest.raises(ValueError, match="no such file"):
        load_controller(str(tmp_path / "missing.zip"))
    with pytest.raises(ValueError, match="unknown algorithm"):
        train("dqn", out=tmp_path / "x")
    with pytest.raises(ValueError, match="torch_threads must be a positive integer or None, got 0"):
        train("ppo", out=tmp_path / "x", torch_threads=0)


def test_a_v1_policy_given_the_v0_fields_drives_exactly_as_on_the_v1_observation(tmp_path):
    # the margin features are a pure function of the emitted -v0 fields (float32) and the sensor
    # range, so the policy computes them itself on a -v0 id, a suite or the leaderboard
    run = train("ppo", "acc_gym/SingleLane-v1", timesteps=256, seed=5, out=tmp_path / "v1", num_envs=4,
                eval_episodes=1, algo_kwargs={"n_steps": 64, "batch_size": 64})
    policy = load_policy(run)
    assert policy.sensor_range == 200.0 and policy.mean.shape == (13,)
    for sid in ("singlelane/2/cut-in", "carfollowing/60", "stopandgo"):
        v0 = evaluate(policy, "acc_gym/SingleLane-v0", episodes=2, seed=4, scenarios=(sid,))
        v1 = evaluate(policy, "acc_gym/SingleLane-v1", episodes=2, seed=4, scenarios=(sid,))
        assert v0["scores"] == v1["scores"], sid
    with pytest.raises(ValueError, match="observation has 9 fields .* this policy takes 13"):
        policy.predict(np.zeros(9, np.float32))
    assert load_policy(tmp_path / "v1", backend="sb3").sensor_range == 200.0
    v0_run = SB3Policy(policy.model, policy.mean[:7], policy.var[:7])  # a -v0 policy never appends
    with pytest.raises(ValueError, match="observation has 13 fields"):
        v0_run.predict(np.zeros(13, np.float32))
