"""Gymnasium's and Stable-Baselines3's environment checkers on every registered id.

The checkers exercise the API contract (spaces, dtypes, reset/step signatures, seeding
determinism of ``reset(seed=...)``, observations inside the observation space, render
modes). They run with every warning recorded and the test fails on any warning at all:
a checker that merely *warns* (e.g. about an observation outside its space, a float64
observation, a non-deterministic reset) would otherwise pass silently.
"""

from __future__ import annotations

import warnings

import gymnasium
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.acc_env import ACCEnv
from acc_gym.envs.registration import ENV_IDS

IDS = sorted(ENV_IDS)


def _record(fn, *args, **kwargs) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args, **kwargs)
    return [f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in caught]


def test_every_family_is_registered():
    assert set(IDS) == {f"acc_gym/{name}-v{k}" for name in ("CarFollowing", "SingleLane", "NCAP", "StopAndGo")
                        for k in (0, 1)}
    for env_id in IDS:
        spec = gymnasium.spec(env_id)
        v0 = env_id.endswith("-v0")  # the -v0 ids' factories warn what -v1 changes, then make the same classes
        assert spec.entry_point == ("acc_gym.envs.registration:make_v0" if v0 else "acc_gym.envs.acc_env:ACCEnv")
        assert spec.vector_entry_point == ("acc_gym.envs.registration:make_v0_vector" if v0
                                           else "acc_gym.envs.vector:ACCVectorEnv")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = gymnasium.make(env_id)
        try:
            assert type(env.unwrapped) is ACCEnv
        finally:
            env.close()


@pytest.mark.parametrize("v2v", [False, True], ids=["radar", "v2v"])
@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_check_env(env_id, v2v):
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(env_id, v2v=v2v)
    try:
        caught = _record(check_env, env.unwrapped)
    finally:
        env.close()
    assert caught == []


@pytest.mark.parametrize("v2v", [False, True], ids=["radar", "v2v"])
@pytest.mark.parametrize("env_id", IDS)
def test_sb3_check_env(env_id, v2v):
    from stable_baselines3.common.env_checker import check_env

    env = gymnasium.make(env_id, v2v=v2v)
    try:
        caught = _record(check_env, env, warn=True)
    finally:
        env.close()
    assert caught == []


@pytest.mark.parametrize("env_id", ["acc_gym/NCAP-v0", "acc_gym/SingleLane-v0"])
def test_gymnasium_check_env_with_rgb_rendering(env_id):
    """With a render mode the checker also renders and checks the frames."""
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(env_id, render_mode="rgb_array", drivers="idm")
    try:
        caught = _record(check_env, env.unwrapped)
    finally:
        env.close()
    assert caught == []


def test_wrapped_env_passive_checker_is_silent():
    """``gymnasium.make`` adds the passive checker; a reset and a few steps must not warn."""
    env = gymnasium.make("acc_gym/NCAP-v0")

    def run():
        env.reset(seed=0)
        for _ in range(5):
            env.step(env.action_space.sample())

    env.action_space.seed(0)
    assert _record(run) == []
