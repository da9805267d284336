"""examples/sb3_train_evaluate.py: PPO with plain stable-baselines3, saved with its VecNormalize
statistics and scored by path like any controller, in quick mode."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("stable_baselines3",
                    reason="the example needs stable-baselines3 (pip install '.[rl]' or '.[test]')")
pytest.importorskip("torch", reason="the example needs torch (pip install '.[rl]' or '.[test]')")


def test_a_quick_run_trains_saves_and_scores_the_model(run_example, tmp_path):
    out = tmp_path / "run"
    stdout = run_example("sb3_train_evaluate.py", "--quick", "--out", str(out)).stdout
    result = json.loads(stdout.strip().splitlines()[-1])
    assert result["env_id"] == "acc_gym/CarFollowing-v1" and result["timesteps"] >= 1024
    assert result["episodes"] == 2 and 0.0 <= result["mean_score"] <= 100.0
    assert 0.0 <= result["share_qualified"] <= 1.0 and result["collisions"] >= 0
    # what the package's loader reads: the model and the normalisation statistics beside it
    assert (out / "model.zip").is_file() and (out / "vecnormalize.pkl").is_file()
    from acc_gym.evaluation.runner import load_controller

    policy = load_controller(str(out / "model.zip"))
    assert policy.mean.shape == (13,)  # the -v1 observation's statistics were applied
