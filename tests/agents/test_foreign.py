"""Models trained with the user's own tooling score like any controller (issue 19).

A plain stable-baselines3 model file and an rl-zoo3-style run folder (model, VecNormalize
statistics, config) are made here; ``acc-gym evaluate`` must give what driving the model
by hand (stable-baselines3's own ``predict`` and ``VecNormalize.normalize_obs``) gives.
"""

import json
import pickle
import shutil
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")

from acc_gym.cli import main  # noqa: E402
from acc_gym.evaluation.runner import load_controller  # noqa: E402
from acc_gym_agents.rl.foreign import detect_algo, load_foreign  # noqa: E402

ENV = "acc_gym/CarFollowing-v0"
EPISODES, SEED = 2, 11


def by_hand(model, normalize=None) -> dict:
    """Drive the model as a user would, episode after episode from one seeded reset; the
    summary ``acc-gym evaluate --json`` prints for it."""
    from acc_gym.evaluation.runner import by_scenario, preventability, summarise

    env = gym.make(ENV)
    reports, ids, collided = [], [], []
    obs, _ = env.reset(seed=SEED)
    for ep in range(EPISODES):
        if ep:
            obs, _ = env.reset()
        while True:
            o = obs if normalize is None else normalize(obs[None, :])[0]
            action, _ = model.predict(o, deterministic=True)
            obs, _, term, trunc, info = env.step(np.asarray(action, dtype=np.float32).reshape(1))
            if term or trunc:
                break
        reports.append(info["report"])
        ids.append(info["scenario"])
        if info["report"]["metrics"]["collision"]:
            collided.append(env.unwrapped.scenario)
    out = summarise(reports, ids)
    out.update(preventability(collided, ENV))
    out["by_scenario"] = by_scenario(reports, ids)
    return json.loads(json.dumps(out))


def cli_summary(capsys, ref, *extra) -> dict:
    assert main(["evaluate", str(ref), "--env", ENV, "--episodes", str(EPISODES), "--seed", str(SEED), "--json",
                 *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def ppo_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("sb3")
    model = sb3.PPO("MlpPolicy", gym.make(ENV), n_steps=64, batch_size=32, n_epochs=1, seed=3, device="cpu")
    model.learn(128)
    model.save(d / "model.zip")
    return d / "model.zip", model


def test_a_plain_sb3_model_file_scores_as_driving_it_by_hand(ppo_file, capsys):
    path, model = ppo_file
    assert detect_algo(path) == "ppo"
    assert cli_summary(capsys, path) == by_hand(model)
    assert cli_summary(capsys, path, "--algo", "ppo") == by_hand(model)


def test_an_rl_zoo3_run_folder_applies_its_vecnormalize(ppo_file, tmp_path, capsys):
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    path, model = ppo_file
    run = tmp_path / "ppo" / "acc_gym-CarFollowing-v0_1"
    (run / "acc_gym-CarFollowing-v0").mkdir(parents=True)
    shutil.copy(path, run / "acc_gym-CarFollowing-v0.zip")
    shutil.copy(path, run / "best_model.zip")
    (run / "acc_gym-CarFollowing-v0" / "config.yml").write_text("!!python/object/apply:collections.OrderedDict\n")
    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]), norm_reward=True, clip_obs=5.0)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)
    for _ in range(300):  # statistics that are far from the identity
        venv.step(rng.uniform(-1, 1, (1, 1)).astype(np.float32))
    venv.save(str(run / "acc_gym-CarFollowing-v0" / "vecnormalize.pkl"))
    with open(run / "acc_gym-CarFollowing-v0" / "vecnormalize.pkl", "rb") as f:
        stats = pickle.load(f)
    assert np.abs(stats.obs_rms.mean).max() > 1.0  # the statistics matter
    expected = by_hand(model, normalize=stats.normalize_obs)
    assert cli_summary(capsys, run) == expected
    assert by_hand(model) != expected  # and applying them changes the drive
    controller = load_controller(str(run))
    obs = gym.make(ENV).reset(seed=1)[0]
    assert np.array_equal(controller.normalise(obs), stats.normalize_obs(obs[None, :])[0].astype(np.float32))


def test_other_algorithms_are_read_from_the_file_and_unknown_files_are_named(tmp_path, capsys):
    env = gym.make(ENV)
    sac = sb3.SAC("MlpPolicy", env, learning_starts=0, buffer_size=100, seed=0, device="cpu")
    sac.save(tmp_path / "sac.zip")
    a2c = sb3.A2C("MlpPolicy", env, n_steps=8, seed=0, device="cpu")
    a2c.save(tmp_path / "a2c.zip")
    assert detect_algo(tmp_path / "sac.zip") == "sac" and detect_algo(tmp_path / "a2c.zip") == "a2c"
    assert type(load_foreign(tmp_path / "sac.zip").model).__name__ == "SAC"
    with pytest.raises(ValueError, match=r"a2c\.zip: could not load it as SAC"):
        load_foreign(tmp_path / "a2c.zip", algo="sac")
    with pytest.raises(ValueError, match="unknown algorithm 'dqn'"):
        load_foreign(tmp_path / "a2c.zip", algo="dqn")
    (tmp_path / "junk.zip").write_bytes(b"not a zip")
    with pytest.raises(SystemExit):
        main(["evaluate", str(tmp_path / "junk.zip"), "--episodes", "1"])
    assert "junk.zip" in capsys.readouterr().err and "stable-baselines3 model file" in \
        str(pytest.raises(ValueError, load_controller, str(tmp_path / "junk.zip")).value)


def test_module_controllers_resolve_from_the_working_directory(tmp_path):
    (tmp_path / "mymod_issue19.py").write_text(
        "import numpy as np\n\nclass Ctrl:\n    def predict(self, obs, deterministic=True):\n"
        "        return np.array([0.1], dtype=np.float32), None\n")
    exe = shutil.which("acc-gym", path=str(__import__("pathlib").Path(sys.executable).parent))
    assert exe is not None
    done = subprocess.run([exe, "evaluate", "mymod_issue19:Ctrl", "--episodes", "1", "--json"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["episodes"] == 1
    done = subprocess.run([sys.executable, "-m", "acc_gym", "--help"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and "acc-gym" in done.stdout and "evaluate" in done.stdout


def _stats_file(path, shift: float) -> None:
    """A VecNormalize file whose observation mean is ``shift`` everywhere (distinct statistics)."""
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make(ENV)]), norm_reward=False)
    venv.obs_rms.mean[:] = shift
    venv.obs_rms.var[:] = 4.0
    path.parent.mkdir(parents=True, exist_ok=True)
    venv.save(str(path))


def test_a_model_files_vecnormalize_is_its_own_or_an_error_naming_the_candidates(ppo_file, tmp_path, capsys):
    """Several ``*/vecnormalize.pkl`` beside a bare model file: none is taken by guess (the
    alphabetically first was applied silently before); the model's own wins: next to it,
    or rl-zoo3's ``<model name>/`` folder."""
    path, _ = ppo_file
    model = tmp_path / "model.zip"
    shutil.copy(path, model)
    _stats_file(tmp_path / "a_run" / "vecnormalize.pkl", 1.0)
    _stats_file(tmp_path / "b_run" / "vecnormalize.pkl", 2.0)
    with pytest.raises(ValueError) as err:
        load_foreign(model)
    assert "ambiguous" in str(err.value) and "a_run/vecnormalize.pkl" in str(err.value) \
        and "b_run/vecnormalize.pkl" in str(err.value)
    with pytest.raises(SystemExit):
        main(["evaluate", str(model), "--episodes", "1"])
    assert "a_run/vecnormalize.pkl" in capsys.readouterr().err
    obs = gym.make(ENV).reset(seed=1)[0]
    _stats_file(tmp_path / "model" / "vecnormalize.pkl", 3.0)  # rl-zoo3's layout: <model name>/vecnormalize.pkl
    assert np.array_equal(load_foreign(model).normalise(obs), np.clip((obs - 3.0) / np.sqrt(4.0 + 1e-8), -10, 10)
                          .astype(np.float32))
    _stats_file(tmp_path / "vecnormalize.pkl", 5.0)  # next to the model: first
    assert load_foreign(model).mean.tolist() == [5.0] * 7
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(path, alone / "model.zip")
    _stats_file(alone / "only" / "vecnormalize.pkl", 6.0)  # a single candidate is still found
    assert load_foreign(alone / "model.zip").mean.tolist() == [6.0] * 7
