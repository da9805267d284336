"""The -v1 ids' fast paths (issue 35) equal the paths they short-cut, bit for bit.

* :meth:`MarginReward.from_criteria` (the compiled :func:`acc_gym.envs._kernel.margin_reward_rows`,
  the core's path for the -v1 default reward) and :meth:`MarginReward.__call__` on the
  :class:`StepIndicators` built from the same rows equal the numpy oracle (``reward_oracle.py``);
* :func:`acc_gym.envs._kernel.features32` equals the float64 chain it replaced (fields
  rounded to float32, features appended, all rounded to float32);
* end to end, every -v1 id with its default reward gives the observations, rewards,
  terminations and infos that the same id gives with an equal reward object taking the
  :class:`StepIndicators` path (single env, and a vector env with autoresets).
"""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
import kernel_rows  # tests/envs/kernel_rows.py
from acc_gym.envs import _kernel as K
from acc_gym.envs.observation import B0, B1, append_features, feature_bounds
from acc_gym.envs.reward import MarginReward
from reward_oracle import margin_oracle  # tests/envs/reward_oracle.py

V1 = ["acc_gym/CarFollowing-v1", "acc_gym/SingleLane-v1", "acc_gym/NCAP-v1", "acc_gym/StopAndGo-v1"]


def random_rows(rng, n):
    return kernel_rows.random_rows(rng, n, v_max=45.0, a_range=(-12.0, 5.0), jerk_sd=30.0, gap_max=400.0)


def same_bits(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


@pytest.mark.parametrize("reward", [MarginReward(), MarginReward(band=2.0, lag=1.5, peak=0.2, slope=0.5, jerk_scale=4.0,
                                                                 response_decel=3.0, collision=50.0, overspeed=1.5,
                                                                 overspeed_scale=0.05, reach=0.7, behind=0.9,
                                                                 standstill=0.8, standstill_gap=4.0, demand=0.6,
                                                                 release=0.3, let_go=0.4, stop_demand=0.7),
                                    MarginReward(behind=0.9, lag=1.5, behind_outside_margin=True)],
                         ids=["default", "weights", "outside"])
def test_margin_reward_equals_the_numpy_oracle(reward):
    rng = np.random.default_rng(1)
    n = 2000
    fl, bo = random_rows(rng, n)
    fl[K.F_VLEAD, :300] = 0.0  # stopped vehicles ahead (the standstill term)
    set_speed, tau1 = rng.uniform(5.0, 40.0, n), rng.uniform(0.5, 3.0, n)
    steps, k = rng.integers(1, 400, n), rng.integers(0, 420, n)  # some past their budget (steps left < 0)
    ind = kernel_rows.indicators(fl, bo, set_speed, tau1, steps_left=steps - k)
    r_slow, terms_slow = margin_oracle(reward, ind)
    r_fast, terms_fast = reward.from_criteria(fl, bo, set_speed, tau1, steps, k, 2.5)
    r_call, terms_call = reward(ind)
    assert list(terms_fast) == list(terms_slow) == list(terms_call) == list(MarginReward.TERMS) == list(K.MARGIN_TERMS)
    for key in MarginReward.TERMS:
        assert same_bits(terms_fast[key], terms_slow[key]), key
        assert same_bits(terms_call[key], terms_slow[key]), key
    assert same_bits(r_fast, r_slow) and same_bits(r_call, r_slow)
    # the rows cover every branch: behind with an infinite gap, the response term, collisions
    assert np.isinf(fl[K.F_GAP][bo[K.B_FOLLOWABLE]]).any() and (terms_slow["response"] < 0).any()
    assert (terms_slow["collision"] < -reward.collision).any()
    if reward.standstill:  # behind stopped vehicles: charged in full, in part, and not at all
        st = terms_slow["standstill"]
        assert (st == -reward.standstill).any() and ((st < 0) & (st > -reward.standstill)).any() and (st == 0).any()
    if reward.demand:  # closing faster than the proper response covers: charged in full, in part, and not at all
        d = terms_slow["demand"]
        assert (d == -reward.demand).any() and ((d < 0) & (d > -reward.demand)).any() and (d == 0).any()
    if reward.release:  # a rising acceleration inside Gapsafe: counted in full (30 m/s^3), in part, and not at all
        rl = terms_slow["release"]
        full = -reward.release * (MarginReward.JERK_COUNTED / reward.jerk_scale) ** 2
        assert (rl == full).any() and ((rl < 0) & (rl > full)).any() and (rl == 0).any()
    if reward.let_go:  # the same, where the acceleration then is above -response_decel: also 0 where release charges
        lg = terms_slow["let_go"]
        full = -reward.let_go * (MarginReward.JERK_COUNTED / reward.jerk_scale) ** 2
        assert (lg == full).any() and ((lg < 0) & (lg > full)).any() and ((lg == 0) & (terms_slow["release"] < 0)).any()
    if reward.behind:  # far behind: charged outside Gapsafe, and inside it unless behind_outside_margin
        inside_far = (terms_slow["lag"] < 0) & (fl[K.F_Q] < 0)
        assert (terms_slow["behind"] < 0).any() and inside_far.any() != reward.behind_outside_margin
    if reward.stop_demand:  # behind a braking vehicle, stopping needing more than the proper response: full, part, none
        sd = terms_slow["stop_demand"]
        assert (sd == -reward.stop_demand).any() and ((sd < 0) & (sd > -reward.stop_demand)).any() and (sd == 0).any()


def test_features32_equals_the_float64_chain():
    rng = np.random.default_rng(2)
    for v2v in (False, True):
        m = 11 if v2v else 7
        obs = rng.uniform(-5.0, 80.0, (500, m))
        obs[:, 2] = np.where(rng.random(500) < 0.2, 200.0, rng.uniform(0.0, 200.0, 500))
        obs[:, 0] = np.where(rng.random(500) < 0.05, 0.0, obs[:, 0])
        low, high = feature_bounds(v2v)
        ref = np.empty((500, m + low.size))
        append_features(np.ascontiguousarray(obs.astype(np.float32), dtype=float), 200.0, B0, B1, low, high, ref)
        ref = ref.astype(np.float32)
        out = np.empty_like(ref)
        K.features32(obs, 200.0, B0, B1, low, high, out)
        assert np.array_equal(out.view(np.int32), ref.view(np.int32))


class IndicatorMarginReward:
    """MarginReward behind an object the core does not recognise (the StepIndicators path,
    the reference of the compiled one)."""

    def __init__(self):
        self.inner = MarginReward()

    def __call__(self, indicators):
        return self.inner(indicators)


def _plain(info: dict) -> dict:
    return {k: (v.tolist() if isinstance(v, np.ndarray) else _plain(v) if isinstance(v, dict) else v)
            for k, v in info.items()}


@pytest.mark.parametrize("env_id", V1)
def test_a_v1_episode_with_the_compiled_reward_is_the_reference_episode(env_id):
    # 700 steps: StopAndGo's 600-step episode ends too
    fast, slow = (kernel_rows.rollout(env_id, fn, 700) for fn in (None, IndicatorMarginReward()))
    assert len(fast) == len(slow)
    ends = 0
    for a, b in zip(fast, slow):
        assert a[0].dtype == b[0].dtype == np.float32 and np.array_equal(a[0], b[0])
        if len(a) == 5:
            assert a[1] == b[1] and a[2:4] == b[2:4]
            assert _plain(a[4]) == _plain(b[4])
            ends += bool(a[2] or a[3])
        else:
            assert _plain(a[1]) == _plain(b[1])
    assert ends >= 1  # an episode ended (score, report and return compared too)


@pytest.mark.parametrize("env_id", ["acc_gym/SingleLane-v1", "acc_gym/CarFollowing-v1"])
def test_a_v1_vector_env_with_the_compiled_reward_is_the_reference(env_id):
    def run(reward_fn):
        envs = gymnasium.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point", reward_fn=reward_fn)
        rng = np.random.default_rng(5)
        out = [envs.reset(seed=6)]
        for _ in range(150):
            out.append(envs.step(rng.uniform(-1.0, 1.0, (4, 1)).astype(np.float32)))
        envs.close()
        return out

    fast, slow = run(None), run(IndicatorMarginReward())
    for a, b in zip(fast, slow):
        assert np.array_equal(a[0], b[0])
        if len(a) == 5:
            assert np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2]) and np.array_equal(a[3], b[3])
            ia, ib = a[4], b[4]
            assert set(ia) == set(ib)
            for key in ia:
                if key == "rewards":
                    assert all(np.array_equal(ia[key][t], ib[key][t]) for t in ia[key])
                elif key != "report":
                    assert np.array_equal(ia[key], ib[key]), key
