"""The environment step's compiled parts against numpy oracles, and its contracts.

* :func:`acc_gym.envs._kernel.action_to_accel` (behind :func:`acc_gym.envs.acc_env.action_to_accel`)
  equals a numpy formulation;
* :meth:`CriteriaReward.from_criteria` and :meth:`CriteriaReward.__call__` on the
  :class:`StepIndicators` built from the same rows equal the numpy oracle (``reward_oracle.py``);
* :func:`acc_gym.envs._kernel.settle` equals the numpy bookkeeping (termination, truncation,
  returns, ended scenes);
* end to end, an environment with the default reward (its compiled terms inside the step)
  gives what one with a reward object the core calls on the :class:`StepIndicators` gives;
  a subclass that overrides ``__call__`` is called;
* the step's arrays handed out stay as they were; a bad ego command raises before anything
  moves.
"""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs import _kernel as K
from acc_gym.envs.acc_env import action_to_accel
from acc_gym.envs.config import EnvConfig
from acc_gym.envs.reward import CriteriaReward
from kernel_rows import indicators, random_rows, rollout  # tests/envs/kernel_rows.py
from reward_oracle import criteria_oracle  # tests/envs/reward_oracle.py


def numpy_action_to_accel(action, config):
    a = np.minimum(np.maximum(action, -1.0), 1.0)
    return np.where(a >= 0, a * config.accel_max, a * config.decel_max)


@pytest.mark.parametrize("config", [EnvConfig(), EnvConfig(accel_max=2, decel_max=7.5)], ids=["default", "custom"])
def test_compiled_action_map_equals_the_numpy_formulation(config):
    rng = np.random.default_rng(0)
    a = np.concatenate([rng.uniform(-3.0, 3.0, 500), [-1.0, 1.0, 0.0, -0.0, 1e-300, -1e-300, 5e30]])
    out = action_to_accel(a, config)
    ref = numpy_action_to_accel(a, config)
    assert out.dtype == np.float64 and out.shape == a.shape
    assert np.array_equal(out.view(np.int64), ref.view(np.int64))  # signed zeros included
    # other inputs (float32, 2-D): the mapping of their values as float64, in their shape
    for other in (a.astype(np.float32), a.reshape(-1, 1)):
        got = action_to_accel(other, config)
        assert got.dtype == np.float64 and got.shape == other.shape
        assert np.array_equal(got, numpy_action_to_accel(other.astype(float), config))


@pytest.mark.parametrize("reward", [CriteriaReward(), CriteriaReward(band=2.0, lag=1.5, jerk_scale=4.0)],
                         ids=["default", "weights"])
def test_reward_from_criteria_rows_and_indicators_equal_the_numpy_oracle(reward):
    rng = np.random.default_rng(1)
    n = 300
    fl, bo = random_rows(rng, n)
    set_speed, tau1 = rng.uniform(5.0, 40.0, n), rng.uniform(0.5, 3.0, n)
    ind = indicators(fl, bo, set_speed, tau1)
    r_slow, terms_slow = criteria_oracle(reward, ind)
    r_fast, terms_fast = reward.from_criteria(fl, bo, set_speed, tau1, 2.5)
    r_call, terms_call = reward(ind)
    assert np.array_equal(r_fast, r_slow) and np.array_equal(r_call, r_slow)
    assert list(terms_fast) == list(terms_slow) == list(terms_call) == list(K.TERMS)
    for key in K.TERMS:
        assert np.array_equal(terms_fast[key], terms_slow[key]) and np.array_equal(terms_call[key], terms_slow[key])


@pytest.mark.parametrize("terminate_on_violation", [False, True])
def test_settle_equals_the_numpy_bookkeeping(terminate_on_violation):
    rng = np.random.default_rng(2)
    n = 400
    _, bo = random_rows(rng, n)
    bo[K.B_COLLISION] = rng.random(n) < 0.1
    active = rng.random(n) < 0.7
    reward = rng.normal(0.0, 1.0, n)
    k = rng.integers(0, 60, n)
    steps = rng.integers(1, 60, n)
    ret0 = rng.normal(0.0, 5.0, n)
    # the numpy formulation the core used before the kernel
    rows_ref = np.flatnonzero(active)
    ret_ref = ret0.copy()
    ret_ref[rows_ref] += reward[rows_ref]
    term_ref = bo[K.B_COLLISION] | (bo[K.B_VIOLATION] & terminate_on_violation)
    trunc_ref = (k >= steps) & ~term_ref
    ended_ref = rows_ref[(term_ref | trunc_ref)[rows_ref]]
    ret = ret0.copy()
    term, trunc = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
    rows, ended = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    n_rows, n_ended = K.settle(~active, reward, bo, k, steps, terminate_on_violation, ret, term, trunc, rows, ended)
    assert np.array_equal(term, term_ref) and np.array_equal(trunc, trunc_ref)
    assert np.array_equal(rows[:n_rows], rows_ref) and np.array_equal(ended[:n_ended], ended_ref)
    assert np.array_equal(ret, ret_ref)


class IndicatorReward:
    """The default reward behind an object the core cannot recognise (the StepIndicators path)."""

    def __init__(self):
        self.inner = CriteriaReward()

    def __call__(self, indicators):
        return self.inner(indicators)


def test_default_reward_fast_path_equals_the_indicators_path_end_to_end():
    fast, slow = (rollout("acc_gym/SingleLane-v0", fn, 300) for fn in (None, IndicatorReward()))
    assert len(fast) == len(slow)
    for a, b in zip(fast, slow):
        assert np.array_equal(a[0], b[0])
        if len(a) == 5:
            assert a[1] == b[1] and a[2:4] == b[2:4]
            assert a[4]["rewards"] == b[4]["rewards"]
            assert a[4].get("episode_return") == b[4].get("episode_return")


class CallOverride(CriteriaReward):
    """A subclass that changes the reward: the core must call it, not the compiled terms."""

    def __call__(self, indicators):
        reward, terms = super().__call__(indicators)
        return reward + 1.0, terms


def test_a_reward_subclass_that_overrides_call_is_called():
    """``compiled_terms`` is the rewards' contract with the core: the built-in rewards offer
    their compiled terms, a subclass overriding ``__call__`` does not (and is called: its
    rewards are the default's plus one, step for step); a subclass that changes nothing keeps
    the compiled terms."""
    assert CriteriaReward().compiled_terms()[0] == K.REWARD_CRITERIA
    assert CallOverride().compiled_terms() is None
    assert type("Same", (CriteriaReward,), {})().compiled_terms()[0] == K.REWARD_CRITERIA
    base, over = (rollout("acc_gym/SingleLane-v0", fn, 120) for fn in (None, CallOverride()))
    steps = [(a, b) for a, b in zip(base, over) if len(a) == 5]
    assert len(steps) >= 100
    for a, b in steps:
        assert b[1] == a[1] + 1.0 and b[4]["rewards"] == a[4]["rewards"]


def test_scenario_sampler_draws_the_index_rng_choice_draws():
    """The sampler's cached cumulative sums give ``rng.choice(n, p=p)``'s index with the
    same draw (generator state after equal), for the weighted single-lane mix."""
    from acc_gym.envs.acc_env import make_config
    from acc_gym.envs.config import ScenarioSampler

    config = make_config(None, {}, "singlelane")
    sampler = ScenarioSampler(config)
    assert len(set(config.probabilities)) > 1  # weighted, not uniform
    seen = set()
    for seed in range(3000):
        r_fast, r_ref = np.random.default_rng(seed), np.random.default_rng(seed)
        i = int(sampler._cdf.searchsorted(r_fast.random(), side="right"))
        assert i == int(r_ref.choice(len(sampler.ids), p=sampler.p))  # numpy's own draw of the index
        assert r_fast.bit_generator.state == r_ref.bit_generator.state
        seen.add(i)
    assert len(seen) == len(config.scenarios)


def test_single_env_action_fast_path_maps_like_the_kernel():
    """ACCEnv.step maps one finite float action with Python floats; the desired acceleration
    it hands the core equals action_to_accel(check_actions(...)) bit for bit (clipping,
    signed zeros, float32 and float64), and other inputs still take check_actions."""
    env = gymnasium.make("acc_gym/NCAP-v0", accel_max=2.5, decel_max=7.0).unwrapped
    seen = []
    step = env.core.step

    def spy(a_des, active=None, **kwargs):
        seen.append(a_des.copy())
        return step(a_des, active, **kwargs)

    env.core.step = spy
    values = [0.0, -0.0, 0.3, -0.3, 1.0, -1.0, 1.7, -2.5, 1e-30, -1e-30, 0.999999]
    for dtype in (np.float32, np.float64):
        for x in values:
            env.reset(seed=0)
            env.step(np.array([x], dtype=dtype))
            ref = action_to_accel(np.array([x], dtype=dtype).astype(float), env.config)
            assert seen[-1].dtype == np.float64 and seen[-1].shape == (1,)
            assert seen[-1].view(np.int64)[0] == ref.view(np.int64)[0], (dtype, x)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan], dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.array([0.1, 0.2]))
    env.step([0.5])  # a list takes check_actions
    assert seen[-1][0] == 0.5 * 2.5


def test_arrays_handed_out_are_not_overwritten_by_the_next_step():
    """The core reuses its per-step arrays (``EpisodeBatch.step``), so what the envs hand out
    must be copies or fresh: a vector env's rewards, flags and info arrays and a
    single env's observations and infos, kept over further steps, still hold their step's
    values (and a single env's keep equalling a fresh single env's of the same step)."""
    vec = gymnasium.make_vec("acc_gym/SingleLane-v1", num_envs=3, vectorization_mode="vector_entry_point",
                             drivers="idm")
    vec.reset(seed=5)
    kept = []
    for _ in range(12):
        obs, reward, term, trunc, info = vec.step(np.full((3, 1), 0.1, dtype=np.float32))
        kept.append((obs, reward, term, trunc, info["q"], {k: v.copy() for k, v in (
            ("obs", obs), ("reward", reward), ("term", term), ("trunc", trunc), ("q", info["q"]))}))
    for obs, reward, term, trunc, q, copy in kept:
        for value, name in ((obs, "obs"), (reward, "reward"), (term, "term"), (trunc, "trunc"), (q, "q")):
            assert np.array_equal(value, copy[name], equal_nan=value.dtype.kind == "f"), name
    single = [gymnasium.make("acc_gym/SingleLane-v1", drivers="idm") for _ in range(2)]
    for env in single:
        env.reset(seed=8)
    steps = [single[0].step(np.array([0.1], dtype=np.float32)) for _ in range(12)]
    for obs, reward, term, trunc, info in steps:
        o2, r2, te2, tr2, i2 = single[1].step(np.array([0.1], dtype=np.float32))
        assert np.array_equal(obs, o2) and reward == r2 and term == te2 and trunc == tr2
        assert info["rewards"] == i2["rewards"] and info["q"] == i2["q"] and info["t"] == i2["t"]
    assert len({id(obs) for obs, *_ in steps}) == len(steps)  # a fresh observation each step


def test_a_nan_ego_acceleration_stops_the_step_before_anything_moves():
    """With drivers whose laws are one compiled call, a non-finite desired ego acceleration
    raises the world's error naming it, and leaves the scenes as they were (positions, speeds,
    step counters, the drivers' clocks)."""
    core = gymnasium.make_vec("acc_gym/SingleLane-v0", num_envs=3, vectorization_mode="vector_entry_point",
                              drivers="idm").unwrapped.core
    core.reset_rows(range(3), [np.random.default_rng(s) for s in range(3)])
    core.step(np.zeros(3))
    joint = core.world.joint
    assert joint.compiled_laws() is not None
    before = [core.world.x.copy(), core.world.v.copy(), core.world.k.copy(), joint._clock.copy()]
    with pytest.raises(ValueError, match=r"ego_a_des must be finite.*nan"):
        core.step(np.array([0.5, np.nan, 0.0]))
    after = [core.world.x, core.world.v, core.world.k, joint._clock]
    assert all(np.array_equal(b, a) for b, a in zip(before, after))
    core.step(np.zeros(3))  # and the next finite step runs
    assert np.array_equal(core.world.k, before[2] + 1)

