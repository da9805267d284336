"""The tuned rl-zoo3 hyperparameter files: they load, are valid stable-baselines3 arguments,
``acc-gym train`` takes them as defaults, and (slow) they reproduce their documented curves."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")

from acc_gym.cli import main  # noqa: E402
from acc_gym.envs.registration import ENV_IDS  # noqa: E402
from acc_gym_agents.rl import hyperparams as hp  # noqa: E402
from acc_gym_agents.rl.train import train  # noqa: E402
from acc_gym_agents.rl.vec_env import SB3VecEnv  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CURVES = ROOT / "agents" / "rl" / "curves.json"
# issue 33: PPO 1M steps, "2M if the shipped settings say so"; SAC 200k; issue 69: the off-policy learner 500k
BUDGET = {"ppo": 2_000_000, "sac": 200_000, "tqc": 500_000}
REQUIRED = {"ppo": {"acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v0"}, "sac": {"acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v0"},
            "tqc": {"acc_gym/CarFollowing-v1", "acc_gym/SingleLane-v1"}}  # TQC: one policy for both -v1 ids (issue 69's bar)
ZOO_KEYS = {"n_envs", "n_timesteps", "policy", "normalize", "env_kwargs"}


@pytest.mark.parametrize("algo", ["ppo", "sac", "tqc"])
def test_files_load_name_registered_envs_and_fit_the_budget(algo):
    data = hp.load(algo)
    assert set(data) <= set(ENV_IDS) and REQUIRED[algo] <= set(data)
    for env_id, entry in data.items():
        # spelt out, so that rl-zoo3 (which reads `true` as VecNormalize's defaults) trains as acc-gym train does
        assert entry["policy"] == "MlpPolicy" and isinstance(entry["normalize"], str)
        assert hp.normalize_settings(entry["normalize"])["norm_reward"] == ("norm_reward=True" in entry["normalize"])
        assert 1 <= entry["n_envs"] <= 64 and 0 < entry["n_timesteps"] <= BUDGET[algo]
        d = hp.defaults(algo, env_id)
        assert d["timesteps"] == entry["n_timesteps"] and d["num_envs"] == entry["n_envs"]
        assert not ZOO_KEYS & set(d["algo_kwargs"])  # rl-zoo3's own keys are not algorithm arguments
    assert hp.defaults(algo, "acc_gym/NoSuch-v0") is None


@pytest.mark.parametrize("algo", ["ppo", "sac", "tqc"])
def test_entries_are_valid_sb3_arguments(algo):
    if algo == "tqc":
        pytest.importorskip("sb3_contrib", reason="sb3-contrib is not installed (pip install '.[rl]' or '.[test]')")
    from acc_gym_agents.rl.policy import algorithm_class

    cls = algorithm_class(algo)
    venv = SB3VecEnv(2, seed=0, scenarios=("carfollowing/60",))
    try:
        for env_id in hp.available(algo):
            kwargs = hp.defaults(algo, env_id)["algo_kwargs"]
            model = cls("MlpPolicy", venv, seed=0, device="cpu", **kwargs)  # an unknown key is a TypeError
            for key, value in kwargs.items():
                if key in ("policy_kwargs", "learning_rate", "clip_range", "train_freq"):
                    continue
                assert getattr(model, key) == value, key
            if isinstance(kwargs.get("learning_rate"), hp.LinearSchedule):
                lr = kwargs["learning_rate"]
                assert model.lr_schedule(1.0) == pytest.approx(lr.initial) and model.lr_schedule(0.0) == 0.0
            pk = kwargs.get("policy_kwargs", {})
            if "log_std_init" in pk:
                assert model.policy.log_std.item() == pytest.approx(pk["log_std_init"])
            if "net_arch" in pk:
                linear = [m for m in model.actor.modules() if m.__class__.__name__ == "Linear"] if algo != "ppo" else \
                    [m for m in model.policy.mlp_extractor.policy_net.modules() if m.__class__.__name__ == "Linear"]
                arch = pk["net_arch"]["pi"] if isinstance(pk["net_arch"], dict) else pk["net_arch"]
                assert [m.out_features for m in linear][:len(arch)] == list(arch)
    finally:
        venv.close()


def test_normalize_maps_to_vecnormalize_settings():
    off = {"norm_reward": False, "clip_obs": 10.0}  # acc-gym train's own default (VecNormalize's clip)
    assert hp.normalize_settings(None) == off
    assert hp.normalize_settings("dict(norm_obs=True, norm_reward=False)") == off
    assert hp.normalize_settings(True) == {"norm_reward": True, "gamma": 0.99, "clip_obs": 10.0}  # as rl-zoo3 reads it
    assert hp.normalize_settings("dict(norm_obs=True, norm_reward=True)", 0.98) == {"norm_reward": True, "gamma": 0.98,
                                                                                    "clip_obs": 10.0}
    assert hp.normalize_settings("dict(norm_obs=True, norm_reward=False, clip_obs=50)") == {"norm_reward": False,
                                                                                           "clip_obs": 50.0}
    with pytest.raises(ValueError, match="always normalises observations"):
        hp.normalize_settings("dict(norm_obs=False)")
    with pytest.raises(ValueError, match="always normalises observations"):
        hp.normalize_settings("dict(norm_obs=True, clip_ob=50)")  # a misspelt key is an error
    for bad in ("0", "-5", "float('nan')", "True", "'50'"):
        with pytest.raises(ValueError, match="clip_obs must be a positive finite number"):
            hp.normalize_settings({"norm_obs": True, "clip_obs": eval(bad)})


def test_clip_obs_reaches_the_run_and_the_saved_policy(tmp_path):
    """A run trained with ``clip_obs`` C keeps C with its statistics and its policy clips there:
    a normalised feature beyond 10 standard deviations is no longer cut at 10."""
    from acc_gym_agents.rl.policy import SB3Policy, load_policy

    kw = {"n_steps": 32, "batch_size": 32, "n_epochs": 1, "normalize": "dict(norm_obs=True, norm_reward=False, clip_obs=50)"}
    run = train("ppo", "acc_gym/CarFollowing-v1", timesteps=64, seed=0, out=tmp_path / "run", num_envs=2,
                eval_freq=10**9, eval_episodes=1, algo_kwargs=kw)
    rms = np.load(run / "obs_rms.npz")
    assert float(rms["clip"]) == 50.0
    policy = load_policy(run)
    assert policy.clip == 50.0
    o = rms["mean"].astype(np.float32).copy()
    o[12] = rms["mean"][12] - 30.0 * np.sqrt(rms["var"][12] + 1e-8)  # a_req 30 standard deviations below its mean
    assert policy.normalise(o)[12] == pytest.approx(-30.0, rel=1e-3)
    assert SB3Policy(policy.model, rms["mean"], rms["var"]).normalise(o)[12] == -10.0  # the default clip cuts it


def test_zoo_strings_are_converted_as_rl_zoo3_converts_them():
    kw = hp.to_sb3({"n_envs": 4, "n_timesteps": 1000, "policy": "MlpPolicy", "normalize": True,
                    "learning_rate": "lin_3e-4", "clip_range": 0.2, "train_freq": [1, "step"],
                    "policy_kwargs": "dict(log_std_init=-1, net_arch=[64, 64], activation_fn=nn.ReLU)"})
    assert set(kw) == {"learning_rate", "clip_range", "train_freq", "policy_kwargs"}
    assert kw["learning_rate"](1.0) == pytest.approx(3e-4) and kw["learning_rate"](0.25) == pytest.approx(7.5e-5)
    assert kw["clip_range"] == 0.2 and kw["train_freq"] == (1, "step")
    import torch.nn as nn

    assert kw["policy_kwargs"] == {"log_std_init": -1, "net_arch": [64, 64], "activation_fn": nn.ReLU}
    with pytest.raises(ValueError, match="linear schedules"):
        hp.to_sb3({"learning_rate": "exp_3e-4"})
    with pytest.raises(Exception):
        hp.to_sb3({"policy_kwargs": "__import__('os').getcwd()"})  # no builtins in scope


@pytest.mark.parametrize("env_id", ["acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v1"])
def test_train_takes_the_tuned_defaults_and_records_them(tmp_path, env_id):
    entry = hp.load("ppo")[env_id]
    run = train("ppo", env_id, timesteps=2_000, seed=1, out=tmp_path / "tuned", num_envs=2, eval_episodes=1,
                eval_freq=10_000)
    m = json.loads((run / "manifest.json").read_text())
    assert m["hyperparams"] == {"file": "ppo.yml", "env_id": env_id, "entry": entry}
    for key, value in hp.env_kwargs(entry).items():  # the training envs' settings (the v1 entries' mixture)
        assert m["train_env_settings"][key] == value and m["env_settings"].get(key) != value
    assert m["algo_kwargs"] == entry and m["num_envs"] == 2  # the given num_envs wins over n_envs
    model = sb3.PPO.load(run / "model.zip", device="cpu")
    assert model.n_steps == entry.get("n_steps", 2048) and model.gamma == entry.get("gamma", 0.99)
    assert model.batch_size == entry.get("batch_size", 64)
    # explicit algorithm arguments: no tuned defaults, stable-baselines3's own plus these
    run = train("ppo", env_id, timesteps=256, seed=1, out=tmp_path / "plain", num_envs=2, eval_episodes=1, eval_freq=10_000,
                algo_kwargs={"n_steps": 128, "batch_size": 64})
    m = json.loads((run / "manifest.json").read_text())
    assert m["hyperparams"] is None and m["algo_kwargs"] == {"n_steps": 128, "batch_size": 64}
    assert sb3.PPO.load(run / "model.zip", device="cpu").gamma == 0.99


def test_env_kwargs_shape_the_training_envs_only(tmp_path, monkeypatch):
    """rl-zoo3's env_kwargs (here the scenario mixture trained on) reach the training envs;
    the checkpoint evaluations score on the id's own scenarios."""
    import acc_gym.evaluation.runner as runner
    import acc_gym_agents.rl.vec_env as vec_env

    made, scored = [], []
    real_init, real_evaluate = vec_env.SB3VecEnv.__init__, runner.evaluate

    def init(self, num_envs, seed=0, **settings):
        made.append(settings)
        real_init(self, num_envs, seed=seed, **settings)

    def evaluate(policy, env_id, **kw):
        scored.append(kw)
        return real_evaluate(policy, env_id, **kw)

    monkeypatch.setattr(vec_env.SB3VecEnv, "__init__", init)
    monkeypatch.setattr(runner, "evaluate", evaluate)
    mixture = {"singlelane/1/free-flow": 0.5, "carfollowing/varied": 0.5}
    run = train("ppo", "acc_gym/SingleLane-v1", timesteps=128, seed=1, out=tmp_path / "zoo", num_envs=2,
                eval_episodes=1, algo_kwargs={"n_steps": 64, "batch_size": 64,
                                              "env_kwargs": {"default_scenarios": mixture}})
    assert made[0]["default_scenarios"] == mixture and made[0]["version"] == 1
    assert scored and all("default_scenarios" not in kw for kw in scored)
    m = json.loads((run / "manifest.json").read_text())
    assert m["train_env_settings"]["default_scenarios"] == mixture
    assert m["env_settings"]["default_scenarios"] == ["singlelane"]
    with pytest.raises(ValueError, match="env_kwargs must be a mapping"):
        hp.env_kwargs({"env_kwargs": [1, 2]})


def test_cli_train_defaults_to_the_tuned_entry(tmp_path, capsys):
    env_id = "acc_gym/CarFollowing-v0"
    out = tmp_path / "cli"
    assert main(["train", "ppo", "--env", env_id, "--timesteps", "1000", "--num-envs", "2", "--seed", "2",
                 "--eval-episodes", "1", "--eval-freq", "10000", "--out", str(out), "--no-progress"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert m["hyperparams"]["entry"] == hp.load("ppo")[env_id] and m["timesteps"] >= 1000
    assert "held-out evaluation" in capsys.readouterr().out
    out2 = tmp_path / "cli-sb3"
    assert main(["train", "ppo", "--env", "acc_gym/NCAP-v0", "--timesteps", "256", "--num-envs", "2",
                 "--eval-episodes", "1", "--out", str(out2), "--no-progress", "--algo-kwargs",
                 '{"n_steps": 128, "batch_size": 64, "learning_rate": "lin_1e-3"}']) == 0
    m2 = json.loads((out2 / "manifest.json").read_text())
    assert m2["hyperparams"] is None and m2["algo_kwargs"]["learning_rate"] == "lin_1e-3"


def _documented():
    if not CURVES.is_file():
        return []
    return json.loads(CURVES.read_text())["curves"]


@pytest.mark.slow
@pytest.mark.parametrize("algo,env_id", sorted({(c["algo"], c["env_id"]) for c in _documented()}))
def test_tuned_hyperparameters_reproduce_their_documented_curve(tmp_path, algo, env_id):
    """A fresh run of the first documented seed, with the documented evaluation settings, ends
    within the documented seed spread of the documented seeds' final mean score (and its
    share qualified within their spread likewise)."""
    import torch

    torch.set_num_threads(1)
    curves = [c for c in _documented() if c["algo"] == algo and c["env_id"] == env_id]
    ref = curves[0]
    finals = [c["mean_score"][-1] for c in curves]
    quals = [c["share_qualified"][-1] for c in curves]
    spread = max(max(finals) - min(finals), 2.0)
    qspread = max(max(quals) - min(quals), 0.05)
    steps = ref["steps"]
    run = train(algo, env_id, seed=ref["seed"], out=tmp_path / "run", eval_freq=steps[1] - steps[0] if len(steps) > 1
                else None, eval_episodes=ref["eval_episodes"])
    evals = json.loads((run / "evaluations.json").read_text())
    assert [e["timesteps"] for e in evals] == steps
    mean = sum(finals) / len(finals)
    assert math.isclose(evals[-1]["mean_score"], mean, abs_tol=spread), (evals[-1], finals)
    assert abs(evals[-1]["share_qualified"] - sum(quals) / len(quals)) <= qspread


def test_documented_curves_are_consistent_and_redraw(tmp_path):
    """agents/rl/curves.json (benchmarks/rl_curves.py) covers every tuned entry, its summaries
    follow from its points, and --plot-only redraws the PNG from it."""
    import subprocess
    import sys

    curves = _documented()
    assert {(c["algo"], c["env_id"]) for c in curves} == {(a, e) for a in ("ppo", "sac") for e in hp.available(a)}
    for c in curves:
        n = len(c["steps"])
        assert n >= 2 and c["steps"] == sorted(c["steps"]) and c["steps"][-1] >= hp.defaults(c["algo"], c["env_id"])["timesteps"]
        assert len(c["mean_score"]) == len(c["share_qualified"]) == len(c["collisions"]) == n
        assert c["last_mean_score"] == c["mean_score"][-1] and c["best_mean_score"] == max(c["mean_score"])
        assert c["last_within_5_of_best"] == (max(c["mean_score"]) - c["mean_score"][-1] <= 5.0)
        assert c["eval_seed"] == c["seed"] + 1_000_003 and 0.0 <= c["heldout"]["share_qualified"] <= 1.0
        assert c["heldout"]["seed"] not in (c["seed"], c["eval_seed"])  # held out: neither trained nor selected on
    png = tmp_path / "curves.png"
    subprocess.run([sys.executable, str(ROOT / "benchmarks" / "rl_curves.py"), "--plot-only", "--json", str(CURVES),
                    "--png", str(png)], check=True, capture_output=True)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_v1_entries_train_with_the_reward_the_reward_tests_check():
    """PPO's -v1 training reward is the one tests/envs/test_margin_reward.py ranks behaviours
    with (SHIPPED: reach 0.5; SAC's entries, 0.10.0's, train with the ids' own reward), and
    both -v1 ids' entries are the same for each algorithm (one run serves both)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.envs.reward import MarginReward

    for algo in ("ppo", "sac", "tqc"):
        entries = hp.load(algo)
        assert entries["acc_gym/CarFollowing-v1"] == entries["acc_gym/SingleLane-v1"]
    weights = hp.env_kwargs(hp.load("ppo")["acc_gym/CarFollowing-v1"])["reward_fn"]
    env = gym.make("acc_gym/CarFollowing-v1", reward_fn=weights)
    assert env.unwrapped.core.reward_fn == MarginReward(reach=0.5, demand=1.0, let_go=0.08, overspeed=3.0, behind=1.0,
                                                       stop_demand=3.0, behind_outside_margin=True)
    assert "reward_fn" not in hp.env_kwargs(hp.load("sac")["acc_gym/CarFollowing-v1"])
