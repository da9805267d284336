"""The environment's fast paths equal the slow paths they short-cut, bit for bit.

* :func:`acc_gym.envs._kernel.action_to_accel` (behind :func:`acc_gym.envs.acc_env.action_to_accel`)
  equals a numpy formulation;
* :meth:`CriteriaReward.from_criteria` (the core's path for the default reward) and
  :meth:`CriteriaReward.__call__` on the :class:`StepIndicators` built from the same rows
  equal the numpy oracle (``reward_oracle.py``);
* :func:`acc_gym.envs._kernel.settle` equals the numpy bookkeeping it replaced (termination,
  truncation, returns, ended scenes);
* end to end, an environment with the default reward gives what one with an equal reward
  object that takes the :class:`StepIndicators` path gives.
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
from world_oracle import move_by_parts  # tests/world_oracle.py
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
    n_rows, n_ended = K.settle(active, reward, bo, k, steps, terminate_on_violation, ret, term, trunc, rows, ended)
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


def reference_step(core, a_des, active=None):
    """:meth:`EpisodeBatch.step` as separate calls (the world's own step, then the criteria,
    reward, settle, record and observe kernels one by one): what the fused kernels replace."""
    w = core.world
    a_prev = w.a[:, 0].copy()
    move_by_parts(w, w.decide(a_des))  # the world's separate kernels (advance, then refresh)
    t = w.t
    cfg = core.config.scoring
    grace = core._grace if core._grace is not None else core.tau1
    fl = np.empty((K.N_FLOAT, core.n))
    bo = np.empty((K.N_BOOL, core.n), dtype=bool)
    nb = w.neighbours
    K.criteria(t, w.v, w.a, nb.lead, nb.gap, a_prev, w.dt, core.set_speed, core.tau1, grace, core._cfg,
               core.lead_prev, core.last_change, core.neg_since, fl, bo)
    reward, terms = core.reward_fn.from_criteria(fl, bo, core.set_speed, core.tau1, cfg.a_x_comfort)
    active = ~core.done if active is None else active
    term, trunc = np.empty(core.n, dtype=bool), np.empty(core.n, dtype=bool)
    rows, ended = np.empty(core.n, dtype=np.int64), np.empty(core.n, dtype=np.int64)
    n_rows, n_ended = K.settle(active, reward, bo, w.k, core.steps, core.config.terminate_on_violation,
                               core.episode_return, term, trunc, rows, ended)
    core._record(rows[:n_rows])
    obs = core.observe(*core.obs_bounds, dtype=np.float32)
    final = {int(r): core._final(int(r)) for r in ended[:n_ended]}
    core.done[ended[:n_ended]] = True
    return obs, reward, term, trunc, {"t": t, "q": fl[K.F_Q], "gap_safe": fl[K.F_GS], "a_applied": fl[K.F_A],
                                      "violation": bo[K.B_VIOLATION], "rewards": terms, "final": final}


@pytest.mark.parametrize("env_id, settings, drivers_in_kernel", [
    ("acc_gym/SingleLane-v0", {}, False),  # MPC drivers: they decide in Python, then _kernel.step_finish
    ("acc_gym/NCAP-v0", {}, True),  # the targets' profiles: _kernel.laws_step_finish decides and steps
    ("acc_gym/SingleLane-v0", {"drivers": "idm"}, True),  # baseline models: likewise
], ids=["singlelane-mpc", "ncap-profiles", "singlelane-idm"])
def test_fused_core_step_equals_the_separate_kernels(env_id, settings, drivers_in_kernel):
    """The core's step in one compiled call (``_kernel.step_finish`` after the drivers decided,
    or ``_kernel.laws_step_finish`` with the drivers' laws inside it) equals the world's step
    (its ``decide``, then its separate kernels) followed by the separate criteria, reward,
    settle, record and observe kernels, bit for bit, over episodes and restarts of 6 scenes."""
    cores = [gymnasium.make_vec(env_id, num_envs=6, vectorization_mode="vector_entry_point",
                                **settings).unwrapped.core for _ in range(2)]
    rngs = [[np.random.default_rng(s) for s in range(6)] for _ in range(2)]
    for core, r in zip(cores, rngs):
        core.reset_rows(range(6), r)
    fused, ref = cores
    act = np.random.default_rng(9)
    n_final = 0
    for _ in range(150):
        a = act.uniform(-6.0, 3.0, 6)
        assert (fused.world.joint.compiled_laws() is not None) == drivers_in_kernel  # the path under test
        r1, te1, tr1, i1 = fused.step(a)
        o2, r2, te2, tr2, i2 = reference_step(ref, a)
        assert np.array_equal(fused.last_obs, o2)
        assert np.array_equal(r1, r2) and np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        for key in ("t", "q", "gap_safe", "a_applied", "violation"):
            assert np.array_equal(i1[key], i2[key]), key
        assert all(np.array_equal(i1["rewards"][k], i2["rewards"][k]) for k in K.TERMS)
        assert i1["final"] == i2["final"]
        n_final += len(i1["final"])
        assert np.array_equal(fused._rec_arr, ref._rec_arr)
        for core, r in zip(cores, rngs):
            ended = np.flatnonzero(core.done)
            if ended.size:
                core.reset_rows(ended, [r[i] for i in ended])
    assert n_final >= 6  # episodes ended (and restarted) along the way


@pytest.mark.parametrize("env_id, settings", [
    ("acc_gym/SingleLane-v1", {"drivers": "idm"}), ("acc_gym/SingleLane-v0", {"drivers": "idm"}),
    ("acc_gym/NCAP-v1", {}), ("acc_gym/CarFollowing-v0", {}),
], ids=["singlelane-v1-idm", "singlelane-v0-idm", "ncap-v1", "carfollowing-v0"])
def test_the_single_envs_prepared_step_equals_the_assembled_one(env_id, settings):
    """Once an episode's step has taken the drivers-inside call, the single env reuses its
    argument list with the per-step entries replaced (``EpisodeBatch._step_prepared``): over
    episodes, resets, a pickled copy and a NaN action, everything equals an env whose list is
    assembled afresh every step -- observations, rewards, flags, infos, records -- bit for bit."""
    import pickle

    envs = [gymnasium.make(env_id, **settings) for _ in range(2)]
    fast, ref = (e.unwrapped for e in envs)
    rng = np.random.default_rng(4)
    for e in envs:
        e.reset(seed=11)
    used = 0
    for k in range(400):
        if k == 150:
            envs[0] = pickle.loads(pickle.dumps(envs[0]))
            fast = envs[0].unwrapped
        a = rng.uniform(-1.0, 1.0, 1).astype(np.float32)
        ref.core._prepared = None  # the reference assembles its list every step
        out = [e.step(a) for e in envs]
        used += fast.core._prepared is not None
        (o1, r1, te1, tr1, i1), (o2, r2, te2, tr2, i2) = out
        assert np.array_equal(o1, o2) and r1 == r2 and te1 == te2 and tr1 == tr2, k
        assert i1.keys() == i2.keys() and all(np.array_equal(i1[key], i2[key]) for key in i1 if key != "report")
        assert i1.get("report") == i2.get("report")
        assert np.array_equal(fast.core._rec_arr, ref.core._rec_arr)
        if te1 or tr1:
            for e in envs:
                e.reset()
    assert used > 300  # the prepared list served most steps
    envs[0].reset(seed=3)
    envs[0].step(np.zeros(1, dtype=np.float32))
    k = fast.core.world.k.copy()
    assert fast.core._prepared is not None
    with pytest.raises(ValueError, match="ego_a_des"):  # named, and nothing moved
        fast.core.step(np.array([np.nan]), arrays=False)
    assert np.array_equal(fast.core.world.k, k)
    fast.core.slots[0].assign(0, None)  # a driver changed by hand mid-episode: the list is not reused
    calls = []
    fast.core._step_prepared = lambda *args: calls.append(args)
    fast.core.step(np.zeros(1), arrays=False)
    assert not calls and fast.core._prepared is not None  # assembled again, and kept for the next steps


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
    """The single env's core reuses its per-step arrays (``step(arrays=False)``), so what it
    hands out must be copies or fresh: a vector env's rewards, flags and info arrays and a
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


def test_a_nan_ego_acceleration_stops_the_fused_step_before_anything_moves():
    """With the drivers' laws inside the step's compiled call, a non-finite desired ego
    acceleration raises the world's error naming it, and leaves the scenes as they were
    (positions, speeds, step counters, the drivers' clocks)."""
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

