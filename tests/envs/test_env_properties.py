"""Property tests: whatever the controller does, an episode stays well-formed.

Over seeds and kinds of action sequences (constant, uniform random, bang-bang with a
random period, full brake, full throttle): every observation -- including the last -- is
inside the observation space, and so is the *unclipped* observation the core computes (the
environment clips to the space, which would hide a physically impossible state); nothing
is NaN; rewards and reward terms are finite; every episode ends, by truncation exactly at
the scenario's step budget or earlier by termination; the final info carries a score.
"""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import acc_gym  # noqa: F401  (registers the ids)

KINDS = ("constant", "random", "bang-bang", "brake", "throttle")


def policy(kind: str, c: float, period: int, seed: int):
    rng = np.random.default_rng(seed)

    def act(k: int) -> np.ndarray:
        if kind == "constant":
            a = c
        elif kind == "random":
            a = rng.uniform(-1.0, 1.0)
        elif kind == "bang-bang":
            a = 1.0 if (k // period) % 2 == 0 else -1.0
        elif kind == "brake":
            a = -1.0
        else:
            a = 1.0
        return np.array([a], dtype=np.float32)

    return act


def check_observation(env, obs, k) -> None:
    space = env.observation_space
    assert obs.shape == space.shape and obs.dtype == np.float32
    assert not np.any(np.isnan(obs)), (k, obs)
    assert space.contains(obs), (k, obs)
    raw = env.unwrapped.core.observe()[0]  # before the environment's clipping
    assert np.all(np.isfinite(raw)), (k, raw)
    assert np.all(raw >= space.low) and np.all(raw <= space.high), (k, raw)


def check_episode(env, seed: int, act, options=None) -> tuple[dict, int]:
    """One episode with every per-step property asserted; returns the final info and the
    highest MPC mode the surrounding drivers reported (-1: none)."""
    obs, info = env.reset(seed=seed, options=options)
    assert info["t"] == 0.0
    check_observation(env, obs, 0)
    budget = env.unwrapped.scenario.steps
    assert budget > 0
    max_mode = -1
    for k in range(1, budget + 2):
        obs, reward, terminated, truncated, info = env.step(act(k - 1))
        check_observation(env, obs, k)
        assert isinstance(reward, float) and math.isfinite(reward)
        assert all(math.isfinite(v) for v in info["rewards"].values()), info["rewards"]
        assert info["t"] == pytest.approx(k * 0.2)
        assert info["modes"].shape == (2,) and np.all((info["modes"] >= -1) & (info["modes"] <= 3))
        max_mode = max(max_mode, int(info["modes"].max()))
        if terminated or truncated:
            assert not (terminated and truncated)
            if truncated:
                assert k == budget  # truncation exactly at the scenario's end
            else:
                assert k <= budget
            assert 0.0 <= info["score"] <= 100.0
            assert math.isfinite(info["episode_return"])
            return info, max_mode
    raise AssertionError(f"the episode did not end within its budget of {budget} steps + 1")


ENVS: dict = {}


def get_env(env_id: str, v2v: bool):
    key = (env_id, v2v)
    if key not in ENVS:
        ENVS[key] = gymnasium.make(env_id, drivers="idm", v2v=v2v)
    return ENVS[key]


@settings(max_examples=50, deadline=None)
@given(env_id=st.sampled_from(["acc_gym/CarFollowing-v0", "acc_gym/NCAP-v0"]),
       v2v=st.booleans(),
       seed=st.integers(0, 2 ** 31 - 1),
       kind=st.sampled_from(KINDS),
       c=st.floats(-1.0, 1.0, allow_nan=False),
       period=st.integers(1, 40))
def test_any_controller_gives_a_well_formed_episode(env_id, v2v, seed, kind, c, period):
    env = get_env(env_id, v2v)
    final, max_mode = check_episode(env, seed, policy(kind, c, period, seed))
    assert max_mode == -1  # scripted leads: no MPC modes
    if kind == "throttle" and env_id == "acc_gym/NCAP-v0":
        # full throttle into a target ahead in one lane always ends in a collision
        assert final["report"]["items"]["safety"]["collision"] is True


@pytest.mark.parametrize("kind", ["random", "bang-bang", "brake"])
def test_singlelane_with_mpc_drivers_gives_well_formed_episodes(kind):
    env = gymnasium.make("acc_gym/SingleLane-v0", v2v=True)  # default drivers: human-like MPC
    for seed in (0, 1):
        final, max_mode = check_episode(env, seed, policy(kind, 0.0, 8, seed))
        assert isinstance(final["fallbacks"], int) and final["fallbacks"] >= 0
        assert max_mode >= 0  # the surrounding vehicles really are MPC drivers


def test_stopandgo_with_mpc_driver_gives_a_well_formed_episode():
    env = gymnasium.make("acc_gym/StopAndGo-v0", v2v=True)
    final, max_mode = check_episode(env, 4, policy("random", 0.0, 1, 4))
    assert max_mode >= 0
