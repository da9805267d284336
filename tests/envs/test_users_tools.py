"""Users' own tools: outer time limits keep the evaluation, and the ids work in spawned
SB3 workers (issue 19)."""

import json
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


# forkserver (Python 3.14's default on Linux) runs by default; spawn (about 25 s) with the slow tests
@pytest.mark.parametrize("start_method", [pytest.param("spawn", marks=pytest.mark.slow), "forkserver"])
def test_sb3_subprocess_workers_find_the_ids_when_acc_gym_is_imported_inside_main(tmp_path, start_method):
    """Both ways -- acc_gym.make_vec_env and the qualified id given to SB3's own
    make_vec_env -- under both start methods that do not inherit the parent's registry; one
    worker each to keep it cheap. The qualified id's workers also run under a time limit:
    the truncating step's info, pickled back from the worker, has the score."""
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")
    script = tmp_path / "train.py"
    script.write_text(textwrap.dedent(f"""
        import numpy as np

        def main():
            import acc_gym
            from stable_baselines3.common.env_util import make_vec_env
            from stable_baselines3.common.vec_env import SubprocVecEnv
            kwargs = {{"vec_env_cls": SubprocVecEnv, "vec_env_kwargs": {{"start_method": {start_method!r}}}}}
            venvs = {{"helper": acc_gym.make_vec_env("{ENV}", n_envs=1, seed=0, **kwargs),
                      "qualified": make_vec_env("acc_gym:{ENV}", n_envs=1, seed=0,
                                                env_kwargs={{"max_episode_steps": 5}}, **kwargs)}}
            for how, venv in venvs.items():
                obs = venv.reset()
                for _ in range(5):
                    obs, rewards, dones, infos = venv.step(np.zeros((1, 1), dtype=np.float32))
                venv.close()
                print("ok", how, obs.shape)
                if how == "qualified":
                    print("truncated", bool(dones[0]), "terminal_observation" in infos[0],
                          0 <= infos[0].get("score", -1) <= 100)

        if __name__ == "__main__":
            main()
    """))
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "ok helper (1, 7)" in done.stdout and "ok qualified (1, 7)" in done.stdout
    assert "truncated True True True" in done.stdout


def test_qualified_ids():
    assert acc_gym.qualified_id(ENV) == "acc_gym:" + ENV
    assert acc_gym.qualified_id("acc_gym:" + ENV) == "acc_gym:" + ENV
    assert acc_gym.qualified_id("CartPole-v1") == "CartPole-v1"
    assert gym.make("acc_gym:" + ENV).unwrapped.spec.id == ENV


def test_qualified_ids_are_taken_wherever_an_id_is():
    from acc_gym.envs.registration import resolve_env_id
    from acc_gym.evaluation.runner import evaluate

    assert resolve_env_id("acc_gym:" + ENV) == ENV and resolve_env_id(ENV) == ENV
    assert resolve_env_id("CartPole-v1") == "CartPole-v1"  # other registered ids are ids too
    assert evaluate("acc", "acc_gym:" + ENV, episodes=1, seed=3) == evaluate("acc", ENV, episodes=1, seed=3)
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")
    venv = acc_gym.make_vec_env("acc_gym:" + ENV, n_envs=1, seed=0)
    assert venv.reset().shape == (1, 7)
    venv.close()


@pytest.mark.parametrize("bad", ["acc_gym/Nope-v0", "acc_gym:acc_gym/Nope-v0", "acc_gym/CarFollowing-v7", "Nope-v0"])
def test_an_unknown_id_is_named_with_the_registered_ones(bad):
    from acc_gym.envs.registration import resolve_env_id
    from acc_gym.evaluation.runner import evaluate

    for call in (lambda: resolve_env_id(bad), lambda: evaluate("acc", bad, episodes=1)):
        with pytest.raises(ValueError) as err:
            call()
        message = str(err.value)
        assert repr(bad) in message and all(env_id in message for env_id in acc_gym.envs.ENV_IDS)
        assert "'acc_gym:acc_gym/CarFollowing-v0'" in message  # the form subprocess workers need
    with pytest.raises(ValueError, match=r"'nomodule_xyz:X-v0': cannot import its module 'nomodule_xyz'"):
        resolve_env_id("nomodule_xyz:X-v0")
    with pytest.raises(TypeError, match="must be a string, got int"):
        resolve_env_id(3)


def test_the_cli_names_an_unknown_env_instead_of_a_traceback(capsys, tmp_path):
    from acc_gym.cli import main
    from acc_gym.controllers import cli_plugins

    commands = [["evaluate", "acc", "--env", "acc_gym/Nope-v0", "--episodes", "1"]]
    if "train" in cli_plugins():
        commands.append(["train", "ppo", "--env", "acc_gym/Nope-v0", "--timesteps", "8", "--out", str(tmp_path / "r")])
    for argv in commands:
        with pytest.raises(SystemExit) as ended:
            main(argv)
        assert ended.value.code == 2
        err = capsys.readouterr().err
        assert "--env: unknown environment id 'acc_gym/Nope-v0'" in err and "Traceback" not in err
        assert "acc_gym/StopAndGo-v0" in err and "acc_gym:acc_gym/CarFollowing-v0" in err
    assert not (tmp_path / "r").exists()  # refused before anything was written
    assert main(["evaluate", "acc", "--env", "acc_gym:" + ENV, "--episodes", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["episodes"] == 1


def test_train_takes_the_qualified_id(tmp_path, capsys):
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")
    from acc_gym.cli import main

    out = tmp_path / "run"
    assert main(["train", "ppo", "--env", "acc_gym:" + ENV, "--timesteps", "32", "--num-envs", "1",
                 "--eval-episodes", "1", "--no-progress", "--out", str(out),
                 "--algo-kwargs", '{"n_steps": 32, "batch_size": 32, "n_epochs": 1}']) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["env_id"] == ENV and manifest["env_settings"]["default_scenarios"] == ["carfollowing"]
    assert "held-out evaluation" in capsys.readouterr().out


def driven(sc, actions, extra: int = 20) -> tuple[dict, float]:
    """The report of the first ``len(actions)`` steps of a drive with no time limit (scored
    from the head of a longer recording, so it cannot see where a limit would be) and
    their return."""
    free = gym.make(ENV)
    free.reset(seed=0, options={"scenario": sc})
    ret = sum(free.step(np.array([a], dtype=np.float32))[1] for a in actions)
    for _ in range(extra):
        free.step(np.array([0.0], dtype=np.float32))
    full = free.unwrapped.core.trace(0)
    n = len(actions) + 1
    head = EgoTrace(**{k: getattr(full, k)[:n] for k in ("t", "v", "a", "gap", "v_lead", "a_lead", "lead_id", "a_y",
                                                        "d2", "d3")}, set_speed=full.set_speed, time_gap=full.time_gap)
    return score_episode(head).to_dict(), ret


def test_max_episode_steps_under_sb3s_dummy_vec_env_scores_the_truncating_step():
    """gym.make(id, max_episode_steps=50) in SB3's DummyVecEnv (which resets in the same
    step): the truncating step's info -- the one with terminal_observation -- has the score
    of the 50 steps driven; no step before it has one, nor the next episode's first."""
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    sc = build("carfollowing/90", seed=4)
    actions = np.random.default_rng(6).uniform(-0.3, 0.6, 50).astype(np.float32)
    venv = DummyVecEnv([lambda: Monitor(gym.make(ENV, max_episode_steps=50))])
    venv.set_options({"scenario": sc})
    venv.seed(0)
    venv.reset()
    for k, a in enumerate(actions):
        _, _, dones, infos = venv.step(np.array([[a]]))
        if k < 49:
            assert not dones[0] and "score" not in infos[0]
    info = infos[0]
    assert dones[0] and info["TimeLimit.truncated"] and "terminal_observation" in info
    expected, ret = driven(sc, actions)
    assert info["report"] == expected and info["score"] == expected["score"]
    assert info["qualified"] == expected["qualified"] and info["episode_return"] == pytest.approx(ret)
    assert info["report"]["metrics"]["duration"] == pytest.approx(10.0)
    assert info["episode"]["l"] == 50
    _, _, dones, infos = venv.step(np.array([[0.0]]))
    assert not dones[0] and "score" not in infos[0]


def test_a_users_time_limit_scores_its_last_step_with_the_wrapper():
    from gymnasium.utils.env_checker import check_step_determinism

    from acc_gym.wrappers import ScoreOnTruncation

    sc = build("carfollowing/120", seed=7)
    actions = np.random.default_rng(8).uniform(-0.5, 0.5, 40).astype(np.float32)
    expected, ret = driven(sc, actions)
    env = ScoreOnTruncation(gym.wrappers.TimeLimit(gym.make(ENV), 40))
    env.reset(seed=0, options={"scenario": sc})
    for a in actions:
        _, _, term, trunc, info = env.step(np.array([a]))
    assert trunc and not term
    assert info["report"] == expected and info["score"] == expected["score"]
    assert info["episode_return"] == pytest.approx(ret) and info["scenario_seed"] == sc.seed
    # without the wrapper, outside SB3: an info handed over is never changed afterwards
    env = gym.wrappers.TimeLimit(gym.make(ENV), 40)
    env.reset(seed=0, options={"scenario": sc})
    for a in actions:
        _, _, term, trunc, info = env.step(np.array([a]))
    kept = dict(info)
    env.reset()
    assert trunc and "score" not in info and info == kept
    check_step_determinism(gym.make(ENV, max_episode_steps=50))  # check_env compares infos across resets
    # ... but marked truncated by an outer time limit (as SB3's vec envs mark it before their reset), it is completed
    env.reset(seed=0, options={"scenario": sc})
    for a in actions:
        _, _, term, trunc, info = env.step(np.array([a]))
    info["TimeLimit.truncated"] = True
    env.reset()
    assert info["report"] == expected and info["episode_return"] == pytest.approx(ret)
    with pytest.raises(TypeError, match="needs an acc_gym environment.*CartPoleEnv"):
        ScoreOnTruncation(gym.make("CartPole-v1"))
