"""A PPO actor exported to numpy acts as the stable-baselines3 model, and a run loads without torch."""

import json

import gymnasium as gym
import numpy as np
import pytest
import stable_baselines3 as sb3
import torch

import acc_gym  # noqa: F401
from acc_gym.evaluation.runner import evaluate
from acc_gym_agents.rl.mlp import POLICY_FILE, NumpyActor, export, from_sb3
from acc_gym_agents.rl.policy import load_policy
from acc_gym_agents.rl.train import train


def observations(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0, 40, n), rng.uniform(-8, 3, n), rng.uniform(0, 200, n),
                            rng.uniform(-15, 15, n), rng.integers(0, 2, n), rng.uniform(8, 36, n),
                            rng.uniform(1, 2.5, n)]).astype(np.float32)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    # policy_kwargs: a non-default net with ReLU, so the export follows the architecture it finds
    return train("ppo", "acc_gym/CarFollowing-v0", timesteps=256, seed=4, num_envs=4, eval_episodes=2,
                 out=tmp_path_factory.mktemp("mlp") / "ppo", residual="acc", residual_scale=0.5, shield=True,
                 algo_kwargs={"n_steps": 64, "batch_size": 64,
                              "policy_kwargs": {"net_arch": [32, 16], "activation_fn": torch.nn.ReLU}})


def test_the_numpy_actor_equals_the_torch_policy_on_single_and_batched_observations(run):
    model = sb3.PPO.load(str(run / "model.zip"), device="cpu")
    actor = NumpyActor.load(run / POLICY_FILE)
    assert actor.activations == ("relu", "relu") and [w.shape for w in actor.weights] == [(32, 7), (16, 32), (1, 16)]
    obs = np.clip(observations(2000), -5, 5)  # (normalised-looking) inputs; the actor takes any
    torch_a, _ = model.predict(obs, deterministic=True)
    numpy_a, _ = actor.predict(obs)
    assert numpy_a.shape == torch_a.shape == (2000, 1) and numpy_a.dtype == np.float32
    np.testing.assert_allclose(numpy_a, torch_a, atol=1e-6)
    assert actor.predict(obs[3])[0].shape == model.predict(obs[3], deterministic=True)[0].shape == (1,)
    # the whole controller (normalisation, residual, shield) through either backend
    a, b = load_policy(run), load_policy(run, backend="sb3")
    assert isinstance(a.model, NumpyActor) and isinstance(b.model, sb3.PPO)
    np.testing.assert_allclose(a.predict(observations(500, 1))[0], b.predict(observations(500, 1))[0], atol=1e-6)


def test_the_final_evaluation_is_what_the_loaded_run_scores(run):
    manifest = json.loads((run / "manifest.json").read_text())
    again = evaluate(str(run), "acc_gym/CarFollowing-v0", episodes=2, seed=manifest["eval_seed"])
    assert again["mean_score"] == manifest["final_evaluation"]["mean_score"]


def test_save_load_round_trip_and_errors(run, tmp_path):
    actor = NumpyActor.load(run / POLICY_FILE)
    again = NumpyActor.load(actor.save(tmp_path / "a.npz"))
    for x, y in zip(actor.weights + actor.biases, again.weights + again.biases):
        np.testing.assert_array_equal(x, y)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="bad.npz"):
        NumpyActor.load(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="deterministic"):
        actor.predict(observations(1)[0], deterministic=False)
    with pytest.raises(ValueError, match=r"\(5,\)"):
        actor.predict(np.zeros(5, np.float32))
    with pytest.raises(ValueError, match="activation"):
        NumpyActor(actor.weights, actor.biases, ("tanh", "gelu"), actor.low, actor.high)
    with pytest.raises(ValueError, match="backend"):
        load_policy(run, backend="onnx")


def test_only_ppo_exports(tmp_path):
    env = gym.make("acc_gym/CarFollowing-v0")
    with pytest.raises(ValueError, match="PPO"):
        from_sb3(sb3.SAC("MlpPolicy", env, device="cpu"))
    run = tmp_path / "td3"  # an off-policy run: loads with stable-baselines3 only
    run.mkdir()
    (run / "manifest.json").write_text(json.dumps({"algo": "td3"}))
    with pytest.raises(ValueError, match="td3"):
        export(run)
    with pytest.raises(ValueError, match=POLICY_FILE):
        load_policy(run, backend="numpy")


@pytest.mark.parametrize("name", ["ppo", "ppo-acc"])
def test_an_observation_gets_the_same_action_alone_and_in_any_batch(name):
    """Row by row and in batches of any size, to the bit: the leaderboard answers a batch of
    episodes' rows in one call, and its scores must not depend on the batch (with BLAS's
    matrix products they did, by 2e-7 on an action, on an AMD EPYC)."""
    from acc_gym_agents.policies import load_shipped

    actor = load_shipped(name).model
    rng = np.random.default_rng(11)
    rows = rng.normal(0.0, 2.0, size=(257, actor.obs_dim)).astype(np.float32)
    alone = np.array([actor.predict(r)[0] for r in rows])
    for n in (2, 16, 257):
        assert np.array_equal(actor.predict(rows[:n])[0], alone[:n]), n
