"""The vector env over worker processes (``ACCVectorEnv(workers=k)``, :mod:`acc_gym.envs.shards`)
equals the in-process vector env: observations, rewards, flags and every info entry, step
for step through episode ends and autoresets, and with reset options, ``reset_ended`` and
rendering; bad settings and a failing worker give clear errors."""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.shards import ShardError, merge_infos, split
from acc_gym.envs.vector import ACCVectorEnv


def assert_same(a, b, path="") -> None:
    """Equal values, recursively (dicts, arrays of any dtype incl. objects, NaN equal to NaN)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"{path}: keys {sorted(a)} != {sorted(b)}"
        for k in a:
            assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.shape == b.shape and a.dtype == b.dtype, path
        if a.dtype == object:
            for i, (x, y) in enumerate(zip(a, b)):
                assert_same(x, y, f"{path}[{i}]")
        else:
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), path
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), path
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


def make(env_id, n, workers, **kw):
    return gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", workers=workers, **kw)


@pytest.mark.parametrize("env_id, steps", [("acc_gym/NCAP-v0", 200), ("acc_gym/SingleLane-v0", 120)])
def test_workers_equal_the_in_process_vector_env(env_id, steps):
    n = 5
    ref, sharded = make(env_id, n, 1), make(env_id, n, 2)
    try:
        assert_same(ref.reset(seed=11), sharded.reset(seed=11))
        rng = np.random.default_rng(4)
        ended = 0
        for k in range(steps):
            a = rng.uniform(-1.0, 1.0, (n, 1)).astype(np.float32)
            out_ref, out_sh = ref.step(a), sharded.step(a)
            assert_same(out_ref, out_sh, f"step {k}")
            ended += int(np.sum(out_ref[2] | out_ref[3]))
        assert ended >= 3  # episodes ended and restarted in both shards' ranges
    finally:
        sharded.close()


def test_workers_reset_options_reset_ended_and_render():
    n = 4
    ref = make("acc_gym/NCAP-v0", n, 1, render_mode="rgb_array")
    sharded = make("acc_gym/NCAP-v0", n, 3, render_mode="rgb_array")
    try:
        options = {"scenarios": ["ncap/ccrs/50", None, "ncap/ccrm/50", "ncap/ccrs/30"]}
        assert_same(ref.reset(seed=[3, 1, 4, 1], options=options), sharded.reset(seed=[3, 1, 4, 1], options=options))
        assert_same(ref.render(), sharded.render())
        zero = np.zeros((n, 1), np.float32)
        for _ in range(20):  # the stationary target (ccrs/50) is hit at step 20
            assert_same(ref.step(zero), sharded.step(zero))
        rows_ref, obs_ref = ref.reset_ended()
        rows_sh, obs_sh = sharded.reset_ended()
        assert rows_ref.size >= 1  # the stationary target was hit
        assert np.array_equal(rows_ref, rows_sh) and np.array_equal(obs_ref, obs_sh)
        assert_same(ref.step(zero), sharded.step(zero))
        with pytest.raises(ValueError, match="4 seeds"):
            sharded.reset(seed=[1, 2])
        with pytest.raises(ValueError, match="NaN"):
            sharded.step(np.full((n, 1), np.nan))
    finally:
        sharded.close()
    with pytest.raises(RuntimeError, match="closed"):
        sharded.step(zero)


def test_split_covers_every_environment_once():
    for n in (1, 2, 5, 256, 257):
        for k in range(1, min(n, 7) + 1):
            ranges = split(n, k)
            assert len(ranges) == k and ranges[0][0] == 0 and ranges[-1][1] == n
            sizes = [b - a for a, b in ranges]
            assert all(a_next == b for (_, b), (a_next, _) in zip(ranges, ranges[1:]))
            assert max(sizes) - min(sizes) <= 1 and min(sizes) >= 1


def test_merge_fills_keys_a_shard_lacks_as_the_in_process_env_would():
    a = {"score": np.array([1.5]), "_score": np.array([True]), "report": np.array([{"x": 1}], dtype=object),
         "rewards": {"band": np.array([0.5])}}
    b = {"rewards": {"band": np.array([1.0, 0.0])}}
    out = merge_infos([a, b], [1, 2])
    assert np.array_equal(out["score"], [1.5, 0.0, 0.0]) and np.array_equal(out["_score"], [True, False, False])
    assert out["report"].dtype == object and out["report"][0] == {"x": 1} and out["report"][1] is None
    assert np.array_equal(out["rewards"]["band"], [0.5, 1.0, 0.0])


@pytest.mark.parametrize("workers", [0, 5, 1.5, True, "2"])
def test_bad_workers(workers):
    with pytest.raises(ValueError, match="workers"):
        ACCVectorEnv(num_envs=4, workers=workers)


class BrokenGenerator:
    """A scenario generator that fails (picklable, so it reaches the workers)."""

    def __call__(self, rng):
        raise RuntimeError("no scenarios today")


def test_a_failing_worker_raises_in_the_parent_with_its_message():
    sharded = make("acc_gym/NCAP-v0", 2, 2, scenario_generator=BrokenGenerator())
    with pytest.raises(ShardError, match="no scenarios today"):
        sharded.reset(seed=0)
    with pytest.raises(RuntimeError, match="closed"):  # the workers were stopped
        sharded.reset(seed=0)


# ----------------------------------------------------------------------------- drawing ahead
def test_drawing_the_next_scenarios_ahead_changes_nothing():
    """``prepare_resets`` (what each worker does after answering a step) draws the ended
    environments' next scenarios early; stepping, autoresets, ``reset_ended`` and a
    ``reset`` after drawing ahead give the same results as never drawing ahead."""
    n = 6
    ref, ahead = make("acc_gym/SingleLane-v0", n, 1), make("acc_gym/SingleLane-v0", n, 1)
    assert_same(ref.reset(seed=5), ahead.reset(seed=5))
    rng = np.random.default_rng(2)
    drawn, reseeded = 0, False
    for k in range(160):
        a = rng.uniform(-1.0, 1.0, (n, 1)).astype(np.float32)
        out_ref, out_ahead = ref.step(a), ahead.step(a)
        assert_same(out_ref, out_ahead, f"step {k}")
        ended = int(np.sum(out_ref[2] | out_ref[3]))
        count = ahead.prepare_resets()
        assert count == ended and ahead.prepare_resets() == 0  # each ended environment, once
        drawn += count
        if k == 70 and count:
            rows_ref, obs_ref = ref.reset_ended()
            rows_ahead, obs_ahead = ahead.reset_ended()
            assert np.array_equal(rows_ref, rows_ahead) and np.array_equal(obs_ref, obs_ahead)
        if k >= 100 and count and not reseeded:  # drawn ahead, then dropped: reset() seeds new generators
            assert_same(ref.reset(seed=8), ahead.reset(seed=8))
            reseeded = True
    assert drawn >= 5 and reseeded


def test_a_draw_ahead_that_fails_is_raised_by_the_reset_that_needs_it(monkeypatch):
    env = make("acc_gym/NCAP-v0", 2, 1)
    env.reset(seed=0, options={"scenarios": ["ncap/ccrs/50", "ncap/ccrm/50"]})
    zero = np.zeros((2, 1), np.float32)
    for _ in range(20):  # the stationary target (ccrs/50) is hit at step 20
        env.step(zero)

    def broken(rng):
        raise RuntimeError("generator broke")

    monkeypatch.setattr(env.core, "draw", broken)
    assert env.prepare_resets() == 1  # not raised here ...
    with pytest.raises(RuntimeError, match="generator broke"):
        env.step(zero)  # ... but by the step that resets environment 0


def test_an_injected_generator_is_not_called_ahead():
    """A user's scenario generator may keep state, so its calls stay where they were."""
    from acc_gym.envs.config import ScenarioSampler

    calls = []

    class Counting:
        sampler = None

        def __call__(self, rng):
            calls.append(1)
            return self.sampler(rng)

    gen = Counting()
    env = make("acc_gym/NCAP-v0", 2, 1, scenario_generator=gen)
    gen.sampler = ScenarioSampler(env.config)
    env.reset(seed=0, options={"scenarios": ["ncap/ccrs/50", "ncap/ccrm/50"]})
    zero = np.zeros((2, 1), np.float32)
    for _ in range(20):
        env.step(zero)
    assert env.prepare_resets() == 0 and not calls
    env.step(zero)
    assert len(calls) == 1  # drawn by the autoreset, as without prepare_resets


def test_workers_draw_ahead_and_still_equal_the_in_process_env():
    n = 4
    ref, sharded = make("acc_gym/NCAP-v0", n, 1), make("acc_gym/NCAP-v0", n, 2)
    try:
        options = {"scenarios": ["ncap/ccrs/50", "ncap/ccrs/50", "ncap/ccrm/50", "ncap/ccrs/50"]}
        assert_same(ref.reset(seed=2, options=options), sharded.reset(seed=2, options=options))
        zero = np.zeros((n, 1), np.float32)
        for _ in range(20):
            assert_same(ref.step(zero), sharded.step(zero))
        # each worker drew its ended environments' next scenarios after answering that step
        assert sharded.prepare_resets() == 0
        for _ in range(30):
            assert_same(ref.step(zero), sharded.step(zero))
    finally:
        sharded.close()
