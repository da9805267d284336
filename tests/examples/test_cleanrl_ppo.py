"""examples/cleanrl_ppo.py: the single-file PPO in plain torch. Its advantage estimates
against hand computations under next-step autoreset, a quick run that repeats exactly,
and (slow) a full run that learns CarFollowing-v1."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="the example needs torch (pip install '.[rl]' or '.[test]')")

PATH = Path(__file__).resolve().parents[2] / "examples" / "cleanrl_ppo.py"


def example():
    spec = importlib.util.spec_from_file_location("cleanrl_ppo", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


G, L = 0.9, 0.5


def gae(rewards, values, next_value, term, done, valid):
    t = lambda x: torch.tensor(np.array(x, dtype=np.float32).reshape(-1, 1))  # noqa: E731
    out = example().advantages(t(rewards), t(values), torch.tensor([float(next_value)]), np.array(term).reshape(-1, 1),
                               np.array(done).reshape(-1, 1), np.array(valid, bool).reshape(-1, 1), G, L)
    return out[:, 0].tolist()


def test_advantages_chain_within_an_episode():
    # r = 1, V = 0.5 everywhere, bootstrap 0.5: delta = 1 + 0.9 * 0.5 - 0.5 = 0.95 at each step
    a = gae([1, 1, 1], [0.5, 0.5, 0.5], 0.5, [0, 0, 0], [0, 0, 0], [1, 1, 1])
    assert a == pytest.approx([0.95 + G * L * (0.95 + G * L * 0.95), 0.95 + G * L * 0.95, 0.95])


def test_a_truncated_episode_bootstraps_from_its_last_observation_and_the_reset_step_is_no_transition():
    # step 1 is truncated; step 2 only resets (its stored value 2.0 is V of the episode's last observation)
    a = gae([1, 1, 0, 1], [0.5, 0.5, 2.0, 0.5], 0.5, [0, 0, 0, 0], [0, 1, 0, 0], [1, 1, 0, 1])
    a1 = 1 + G * 2.0 - 0.5  # bootstrapped from the last observation, chain cut after it
    assert a == pytest.approx([1 + G * 0.5 - 0.5 + G * L * a1, a1, 0.0, 1 + G * 0.5 - 0.5])


def test_a_terminated_episode_does_not_bootstrap():
    a = gae([1, -10, 0], [0.5, 0.5, 2.0], 0.0, [0, 1, 0], [0, 1, 0], [1, 1, 0])
    assert a == pytest.approx([1 + G * 0.5 - 0.5 + G * L * (-10.5), -10.5, 0.0])


def test_a_quick_run_repeats_exactly(capsys):
    runs = []
    for _ in range(2):
        assert example().main(["--quick", "--seed", "3"]) == 0
        out = json.loads(capsys.readouterr().out)
        out.pop("train_wall_time_s")
        runs.append(out)
    assert runs[0] == runs[1] and runs[0]["timesteps"] == 8192 and runs[0]["env_id"] == "acc_gym/CarFollowing-v1"
    assert 0.0 <= runs[0]["mean_score"] <= 100.0


@pytest.mark.slow
def test_a_full_run_learns_carfollowing_v1(tmp_path, capsys):
    """1M steps (about 7 minutes on one core): seed 0 qualified in 98 of 100 held-out episodes with no
    collision here (docs/rl-training.md); at least 80 % and no collision wherever it runs."""
    assert example().main(["--seed", "0", "--out", str(tmp_path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["collisions"] == 0 and out["share_qualified"] >= 0.8, out
    assert (tmp_path / "agent.pt").is_file() and (tmp_path / "obs_rms.npz").is_file()
