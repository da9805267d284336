"""sb3-contrib's off-policy learners (TQC, CrossQ) through ``acc-gym train``: the shipped TQC
settings train for a few thousand steps, update the networks, save, reload and are scored;
CrossQ runs from its keyword arguments; a run repeats itself from its seed."""

import json

import numpy as np
import pytest

pytest.importorskip("sb3_contrib", reason="sb3-contrib is not installed (pip install '.[rl]' or '.[test]')")

from acc_gym.cli import main  # noqa: E402
from acc_gym.evaluation.runner import evaluate  # noqa: E402
from acc_gym_agents.rl import hyperparams as hp  # noqa: E402
from acc_gym_agents.rl.policy import ALGOS, algorithm_class, load_policy  # noqa: E402
from acc_gym_agents.rl.train import train  # noqa: E402



def test_every_algorithm_has_its_class_and_an_unknown_one_is_named():
    import sb3_contrib
    import stable_baselines3 as sb3

    assert algorithm_class("tqc") is sb3_contrib.TQC and algorithm_class("crossq") is sb3_contrib.CrossQ
    assert algorithm_class("sac") is sb3.SAC and set(ALGOS) == {"ppo", "sac", "td3", "tqc", "crossq"}
    with pytest.raises(ValueError, match="unknown algorithm 'dqn'"):
        algorithm_class("dqn")


def test_the_shipped_tqc_entry_trains_updates_saves_and_reloads(tmp_path):
    entry = hp.defaults("tqc", "acc_gym/CarFollowing-v1")
    starts = entry["algo_kwargs"]["learning_starts"]
    # a few thousand steps: past learning_starts, so that 1,000 / 8 = 125 gradient steps are taken
    run = train("tqc", "acc_gym/CarFollowing-v1", timesteps=starts + 1000, seed=5, out=tmp_path / "tqc",
                eval_episodes=1)
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["algo"] == "tqc" and manifest["hyperparams"]["file"] == "tqc.yml"
    assert manifest["num_envs"] == entry["num_envs"] and manifest["versions"]["sb3-contrib"]
    # trained on PPO's mixture with its reward weights, scored on the id's own scenarios
    assert manifest["train_env_settings"]["reward_fn"] == hp.load("ppo")["acc_gym/CarFollowing-v1"]["env_kwargs"][
        "reward_fn"]
    assert "reward_fn" not in manifest["env_settings"]
    model = algorithm_class("tqc").load(run / "model.zip", device="cpu")
    assert model._n_updates == 1000 // entry["num_envs"]  # one gradient step per vector step after learning_starts
    assert model.critic.quantiles_total == 2 * 25 and model.top_quantiles_to_drop_per_net == 2
    venv = _venv("acc_gym/CarFollowing-v1")
    fresh = algorithm_class("tqc")("MlpPolicy", venv, seed=5, device="cpu", **entry["algo_kwargs"])
    venv.close()
    trained = model.actor.latent_pi[0].weight.detach().numpy()
    assert not np.allclose(trained, fresh.actor.latent_pi[0].weight.detach().numpy())  # the updates moved it
    policy = load_policy(run)  # no numpy export for off-policy runs: stable-baselines3's model
    action, _ = policy.predict(_observation("acc_gym/CarFollowing-v1"))
    assert action.shape == (1,) and -1.0 <= action[0] <= 1.0
    s = evaluate(str(run), "acc_gym/CarFollowing-v1", episodes=1, seed=2)
    assert s["episodes"] == 1 and 0.0 <= s["mean_score"] <= 100.0


def _venv(env_id):
    import gymnasium as gym

    from acc_gym_agents.rl.vec_env import SB3VecEnv

    return SB3VecEnv(2, seed=0, **gym.spec(env_id).kwargs)


def _observation(env_id):
    import gymnasium as gym

    with gym.make(env_id) as env:
        return env.reset(seed=0)[0]


def test_crossq_trains_from_its_keyword_arguments_and_repeats_from_its_seed(tmp_path):
    kwargs = {"learning_starts": 200, "batch_size": 64, "policy_kwargs": "dict(net_arch=dict(pi=[32, 32], qf=[64, 64]))"}
    runs = [train("crossq", "acc_gym/CarFollowing-v0", timesteps=600, seed=7, out=tmp_path / f"cq{i}", num_envs=2,
                  eval_episodes=1, algo_kwargs=kwargs) for i in range(2)]
    manifests = [json.loads((r / "manifest.json").read_text()) for r in runs]
    assert manifests[0]["algo"] == "crossq" and manifests[0]["hyperparams"] is None  # its kwargs, no file
    model = algorithm_class("crossq").load(runs[0] / "model.zip", device="cpu")
    assert model._n_updates == (600 - 200) // 2
    obs = _observation("acc_gym/CarFollowing-v0")
    a, b = (load_policy(r).predict(obs)[0] for r in runs)
    assert np.array_equal(a, b)  # the same seed, the same network (one torch thread)
    same = [{k: v for k, v in m["final_evaluation"].items() if k != "wall_time_s"} for m in manifests]
    assert same[0] == same[1] and manifests[0]["final_evaluation"]["wall_time_s"] > 0.0


def test_the_cli_offers_both_and_names_the_tuned_file(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["train", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "{ppo,sac,td3,tqc,crossq}" in text and "sb3-contrib" in text
    assert hp.available("tqc") == ["acc_gym/CarFollowing-v1", "acc_gym/SingleLane-v1"]
