"""Environments drawing with the counter-based generator (issue 35, ``scenario_generator="counter"``):
each scenario a pure function of (id, seed), whatever the batch size, the number of
environments or workers and the order of resets; the same (id, seed) sequence as numpy's
sampler, other parameters; rebuilt by the registry from what it records; every id's
default sampler untouched."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.config import CounterScenarioSampler, EnvConfig, ScenarioSampler
from acc_gym.scenarios import batched
from acc_gym.scenarios.registry import build


def _scenarios_of_single_envs(env_id, seeds, episodes):
    out = []
    for seed in seeds:
        env = gym.make(env_id, scenario_generator="counter")
        env.reset(seed=seed)
        row = [env.unwrapped.scenario]
        for _ in range(episodes - 1):
            env.reset()
            row.append(env.unwrapped.scenario)
        out.append(row)
    return out


@pytest.mark.parametrize("workers", [1, 2])
def test_a_vector_env_draws_what_single_envs_draw_whatever_its_size(workers):
    """Env i of a vector env of any size draws the scenarios of a single env seeded seed + i,
    episode after episode (the vector env resets its ended scenes in one batched call)."""
    env_id = "acc_gym/SingleLane-v1"
    single = _scenarios_of_single_envs(env_id, [10, 11, 12, 13], 3)
    for n in (4, 3):
        if workers > n:
            continue
        vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", workers=workers,
                           scenario_generator="counter")
        try:
            _, info = vec.reset(seed=10)
            seen = [[(info["scenario"][i], int(info["scenario_seed"][i]))] for i in range(n)]
            for _ in range(400):
                _, _, _, _, info = vec.step(np.full((n, 1), -0.2, dtype=np.float32))
                if "_scenario" in info:
                    for i in np.flatnonzero(info["_scenario"]):
                        seen[i].append((info["scenario"][i], int(info["scenario_seed"][i])))
                if min(len(s) for s in seen) >= 3:
                    break
        finally:
            vec.close()
        for i in range(n):
            assert seen[i][:3] == [(s.id, s.seed) for s in single[i]]


def test_the_env_installs_the_scenario_of_its_id_and_seed():
    env = gym.make("acc_gym/SingleLane-v1", scenario_generator="counter")
    env.reset(seed=5)
    for _ in range(20):
        sc = env.unwrapped.scenario
        assert sc == batched.build(sc.id, sc.seed, sc.drivers)
        assert build(sc.id, sc.params, sc.seed, sc.drivers) == sc  # the registry rebuilds it from its record
        env.reset()


def test_batches_in_any_order_give_the_same_scenarios():
    config = EnvConfig(scenarios=("singlelane",), version=1)
    sampler = CounterScenarioSampler(config)
    seeds = list(range(24))
    one = [sampler(np.random.default_rng(s)) for s in seeds]
    many = sampler.draw_many([np.random.default_rng(s) for s in seeds])
    backwards = sampler.draw_many([np.random.default_rng(s) for s in seeds[::-1]])[::-1]
    assert one == many == backwards


def test_v1_draws_v0s_ids_and_seeds_with_other_parameters():
    config = EnvConfig(scenarios=("singlelane",))
    v0, v1 = ScenarioSampler(config), CounterScenarioSampler(config)
    differ = 0
    for s in range(30):
        a, b = v0(np.random.default_rng(s)), v1(np.random.default_rng(s))
        assert (a.id, a.seed) == (b.id, b.seed) and set(a.params) == set(b.params)
        differ += a.params != b.params
    assert differ >= 25  # constant-only configurations aside, the numbers differ


def test_every_id_keeps_numpys_sampler_unless_asked():
    for v in (0, 1):
        for name in ("SingleLane", "CarFollowing", "NCAP", "StopAndGo"):
            env_id = f"acc_gym/{name}-v{v}"
            assert type(gym.make(env_id).unwrapped.core.generator) is ScenarioSampler
            assert type(gym.make(env_id, scenario_generator="numpy").unwrapped.core.generator) is ScenarioSampler
            counter = gym.make(env_id, scenario_generator="counter")
            assert type(counter.unwrapped.core.generator) is CounterScenarioSampler
    with pytest.raises(ValueError, match="counter"):
        gym.make("acc_gym/SingleLane-v1", scenario_generator="philox")


def test_a_named_reset_builds_with_the_envs_own_generator():
    env = gym.make("acc_gym/StopAndGo-v1", scenario_generator="counter")
    env.reset(seed=2, options={"scenario": "singlelane/2/cut-in"})
    sc = env.unwrapped.scenario
    assert sc.id == "singlelane/2/cut-in" and sc == batched.build(sc.id, sc.seed, sc.drivers)
