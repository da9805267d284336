"""Users' own tools: outer time limits keep the evaluation, and the ids work in spawned
SB3 workers (issue 19)."""

import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import acc_gym
from acc_gym.evaluation import EgoTrace, score_episode
from acc_gym.scenarios import build

ENV = "acc_gym/CarFollowing-v0"


def test_a_time_limited_episode_is_scored_as_what_was_driven():
    """TimeLimit(env, 50): its report equals scoring the first 50 steps of the same drive
    recorded by an environment without the limit (and RecordEpisodeStatistics still works)."""
    sc = build("carfollowing/90", seed=4)
    actions = np.random.default_rng(5).uniform(-0.3, 0.6, 50).astype(np.float32)
    env = gym.wrappers.RecordEpisodeStatistics(gym.wrappers.TimeLimit(gym.make(ENV), 50))
    env.reset(seed=0, options={"scenario": sc})
    for k, a in enumerate(actions):
        _, _, term, trunc, info = env.step(np.array([a]))
    assert trunc and not term and "score" not in info and info["episode"]["l"] == 50
    report = env.unwrapped.episode_report()
    free = gym.make(ENV)
    free.reset(seed=0, options={"scenario": sc})
    for a in actions:
        free.step(np.array([a]))
    for _ in range(20):  # and on: the first 50 steps are what was driven under the limit
        free.step(np.array([0.0], dtype=np.float32))
    full = free.unwrapped.core.trace(0)
    head = EgoTrace(**{k: getattr(full, k)[:51] for k in ("t", "v", "a", "gap", "v_lead", "a_lead", "lead_id", "a_y",
                                                         "d2", "d3")}, set_speed=full.set_speed, time_gap=full.time_gap)
    assert report == score_episode(head).to_dict()
    assert report["metrics"]["duration"] == pytest.approx(10.0)
    fresh = gym.make(ENV)
    fresh.reset(seed=0)
    with pytest.raises(RuntimeError, match="at least one step"):
        fresh.unwrapped.episode_report()


def test_the_vector_env_reports_each_scene_so_far():
    venv = gym.make_vec(ENV, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=2)
    for _ in range(30):
        venv.step(np.full((3, 1), 0.2, dtype=np.float32))
    reports = venv.unwrapped.episode_reports()
    singles = []
    for row in range(3):
        sc = venv.unwrapped.core.scenarios[row]
        env = gym.make(ENV)
        env.reset(seed=0, options={"scenario": sc})
        for _ in range(30):
            env.step(np.array([0.2], dtype=np.float32))
        singles.append(env.unwrapped.episode_report())
    assert reports == singles


@pytest.mark.parametrize("how", ["helper-spawn", "qualified-forkserver"])
def test_sb3_subprocess_workers_find_the_ids_when_acc_gym_is_imported_inside_main(tmp_path, how):
    pytest.importorskip("stable_baselines3")
    script = tmp_path / "train.py"
    script.write_text(textwrap.dedent(f"""
        import numpy as np

        def main():
            import acc_gym
            from stable_baselines3.common.env_util import make_vec_env
            from stable_baselines3.common.vec_env import SubprocVecEnv
            if {how!r} == "helper-spawn":
                venv = acc_gym.make_vec_env("{ENV}", n_envs=2, seed=0, vec_env_cls=SubprocVecEnv,
                                            vec_env_kwargs={{"start_method": "spawn"}})
            else:
                venv = make_vec_env("acc_gym:{ENV}", n_envs=2, seed=0, vec_env_cls=SubprocVecEnv,
                                    vec_env_kwargs={{"start_method": "forkserver"}})
            obs = venv.reset()
            obs, rewards, dones, infos = venv.step(np.zeros((2, 1), dtype=np.float32))
            venv.close()
            print("ok", obs.shape)

        if __name__ == "__main__":
            main()
    """))
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "ok (2, 7)" in done.stdout


def test_qualified_ids():
    assert acc_gym.qualified_id(ENV) == "acc_gym:" + ENV
    assert acc_gym.qualified_id("acc_gym:" + ENV) == "acc_gym:" + ENV
    assert acc_gym.qualified_id("CartPole-v1") == "CartPole-v1"
    assert gym.make("acc_gym:" + ENV).unwrapped.spec.id == ENV
