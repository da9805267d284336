"""The compiled environment kernels (``acc_gym.envs._kernel``) equal numpy oracles.

* ``criteria_reward_rows`` (behind :meth:`CriteriaReward.__call__`) equals the oracle
  ``reward_oracle.criteria_oracle`` exactly, reward and every term; other reward objects still plug
  in through ``reward_fn=``;
* ``criteria`` equals a numpy reference written here from the definitions of
  :mod:`acc_gym.evaluation.scoring` / :mod:`acc_gym.evaluation.indicators`, step by step and
  over whole random sequences (including its state arrays ``lead_prev``, ``last_change``,
  ``neg_since``), and the sequence-level scoring functions (proper-response violations,
  transients) agree with its per-step bookkeeping;
* ``record`` writes the world's state; and end to end, a SingleLane episode's per-step
  ``info`` (Q, violations, reward terms) is what the final report and the trace say.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs import _kernel as K
from acc_gym.envs.reward import CriteriaReward, StepIndicators
from acc_gym.evaluation.indicators import efficiency_u, gap_safe, in_band, safety_q
from acc_gym.evaluation.scoring import ScoringConfig
from kernel_rows import scenes  # tests/envs/kernel_rows.py
from reward_oracle import criteria_oracle  # tests/envs/reward_oracle.py
from score_oracle import _after_transients, _proper_response_violations  # tests/score_oracle.py

DT = 0.2
DT_SEQ = 0.25  # the random sequences' step (the kernel takes dt as an argument)
SL = "acc_gym/SingleLane-v0"


# ----------------------------------------------------------------------------- reward
def random_indicators(rng, n=200, scalar_a_comfort=3.0):
    v = rng.choice([0.0, 5.0, 20.0], n) + rng.uniform(0.0, 15.0, n) * (rng.random(n) < 0.7)
    has = rng.random(n) < 0.8
    gap = np.where(has, rng.uniform(-2.0, 120.0, n), np.inf)
    gap[has & (rng.random(n) < 0.05)] = 0.0
    gs = rng.uniform(-5.0, 50.0, n)
    q = np.where(has, gap - gs, np.inf)
    u = np.where(has & (gs > 0), np.clip(q / (0.2 * np.where(gs > 0, gs, 1.0)), 0.0, 1.0), np.nan)
    following = rng.random(n) < 0.5
    return StepIndicators(
        v=v, a=rng.uniform(-9.0, 4.0, n), jerk=rng.normal(0.0, 20.0, n), set_speed=rng.uniform(5.0, 40.0, n),
        has_lead=has, gap=gap, gap_safe=gs, q=q, in_band=rng.random(n) < 0.5, following=following,
        free=~following & (rng.random(n) < 0.6), u=u, violation=rng.random(n) < 0.3, collision=rng.random(n) < 0.1,
        a_comfort=scalar_a_comfort, followable=rng.random(n) < 0.6, v_lead=rng.uniform(0.0, 35.0, n),
        tau1=rng.uniform(0.5, 3.0, n))


WEIGHTS = [CriteriaReward(),
           CriteriaReward(band=2.5, efficiency=0.0, speed=0.3, comfort=1.7, jerk=0.5, safety=11.0, collision=3.0,
                          lag=1.25, jerk_scale=2.5),
           CriteriaReward(band=0.0, efficiency=3.0, speed=0.0, comfort=0.0, jerk=0.0, safety=0.0, collision=0.0,
                          lag=0.0, jerk_scale=100.0)]


@pytest.mark.parametrize("reward", WEIGHTS, ids=["default", "weights", "sparse"])
def test_compiled_reward_equals_the_reference_exactly(reward):
    seen = dict(nan_u=0, followable=0, not_followable=0, violation=0, collision=0, lag=0, following_nan=0)
    for seed in range(15):
        ind = random_indicators(np.random.default_rng(seed), scalar_a_comfort=[3.0, 2.2, 4.5][seed % 3])
        r, terms = reward(ind)
        r_ref, terms_ref = criteria_oracle(reward, ind)
        assert list(terms) == list(K.TERMS) == list(terms_ref)
        for name in K.TERMS:
            np.testing.assert_array_equal(terms[name], terms_ref[name], err_msg=name)
            assert terms[name].dtype == np.float64 and terms[name].shape == ind.v.shape
        np.testing.assert_array_equal(r, r_ref)
        seen["nan_u"] += int(np.isnan(ind.u).sum())
        seen["following_nan"] += int((np.isnan(ind.u) & ind.following).sum())
        seen["followable"] += int(ind.followable.sum())
        seen["not_followable"] += int((~ind.followable).sum())
        seen["violation"] += int(ind.violation.sum())
        seen["collision"] += int(ind.collision.sum())
        seen["lag"] += int((terms["lag"] != 0).sum())
    lag = seen.pop("lag")
    assert all(c > 20 for c in seen.values()), seen
    if reward.lag > 0:
        assert lag > 100


def test_compiled_reward_broadcasts_and_reads_missing_lag_inputs_as_no_followable_vehicle():
    reward = CriteriaReward(lag=0.7, speed=0.4)
    ind = random_indicators(np.random.default_rng(3), n=12)
    # scalar set speed and tau1 (broadcast by __call__) give the same as full arrays
    same = replace(ind, set_speed=np.asarray(25.0), tau1=np.asarray(1.4))
    full = replace(ind, set_speed=np.full(12, 25.0), tau1=np.full(12, 1.4))
    r1, t1 = reward(same)
    r2, t2 = criteria_oracle(reward, full)
    np.testing.assert_array_equal(r1, r2)
    for name in K.TERMS:
        np.testing.assert_array_equal(t1[name], t2[name])
    # without followable / v_lead / tau1: no vehicle ahead is followable, the lag term is 0
    bare = replace(ind, followable=None, v_lead=None, tau1=None)
    r3, t3 = reward(bare)
    r4, t4 = criteria_oracle(reward, bare)  # the oracle leaves the term out
    assert list(t3) == list(K.TERMS) and not t3["lag"].any() and list(t4) == [k for k in K.TERMS if k != "lag"]
    np.testing.assert_array_equal(r3, r4)


class ReferenceReward(CriteriaReward):
    """A subclass: the numpy oracle instead of the compiled terms."""

    def __call__(self, s):
        return criteria_oracle(self, s)


class Recorder:
    """Any object with __call__(StepIndicators) -> (reward, terms): keeps what it was given."""

    def __init__(self):
        self.seen = []

    def __call__(self, s):
        self.seen.append(s)
        return s.v * 0.0 + 1.0, {"one": np.ones_like(s.v)}


def policy(obs, factor):
    """A linear ACC keeping ``factor`` times the nominal time gap (factor < 1: a tailgater)."""
    v, _, gap, v_rel, seen, vs, tg = (float(x) for x in obs[:7])
    acc = 0.5 * (vs - v) if seen < 0.5 else min(1.2 * v_rel + 0.3 * (gap - 2.5 - factor * tg * v), 0.5 * (vs - v))
    acc = float(np.clip(acc, -8.0, 3.0))
    return np.array([acc / 3.0 if acc >= 0 else acc / 8.0], dtype=np.float32)


def run(env, seed, factor):
    obs, _ = env.reset(seed=seed)
    out = []
    while True:
        obs, reward, term, trunc, info = env.step(policy(obs, factor))
        out.append((reward, info))
        if term or trunc:
            return out


def test_other_reward_objects_plug_in_through_reward_fn():
    default = gymnasium.make(SL)
    subclass = gymnasium.make(SL, reward_fn=ReferenceReward())
    for seed, factor in ((0, 0.4), (4, 1.05)):
        a, b = run(default, seed, factor), run(subclass, seed, factor)
        assert len(a) == len(b)
        for (ra, ia), (rb, ib) in zip(a, b):
            assert ra == rb and ia["rewards"] == ib["rewards"]
        assert a[-1][1]["episode_return"] == b[-1][1]["episode_return"]
    rec = Recorder()
    env = gymnasium.make(SL, reward_fn=rec)
    steps = run(env, 5, 0.4)
    assert all(r == 1.0 and info["rewards"] == {"one": 1.0} for r, info in steps)
    assert steps[-1][1]["episode_return"] == pytest.approx(len(steps))
    # what it was given is the step's criteria, and later steps did not overwrite it
    trace = env.unwrapped.core.trace(0)
    assert len(rec.seen) == len(steps) == trace.n - 1
    np.testing.assert_array_equal([s.v[0] for s in rec.seen], trace.v[1:])
    np.testing.assert_array_equal([s.a[0] for s in rec.seen], trace.a[1:])
    np.testing.assert_array_equal([s.gap[0] for s in rec.seen], trace.gap[1:])
    np.testing.assert_array_equal([s.q[0] for s in rec.seen], [info["q"] for _, info in steps])
    assert sum(bool(s.violation[0]) for s in rec.seen) == sum(info["violation"] for _, info in steps) > 0


# ----------------------------------------------------------------------------- criteria
def cfg_array(cfg: ScoringConfig) -> np.ndarray:
    return np.array([cfg.b0, cfg.b1, cfg.band_width, cfg.steady_dv, cfg.moving_speed, cfg.transient,
                     cfg.sensor_range, cfg.response_decel, cfg.stop_speed, cfg.lead_margin], dtype=float)


def reference_criteria(t, v, a, lead_all, gap_all, a_prev, dt, set_speed, tau1, grace, cfg: ScoringConfig, state):
    """One step of the env's criteria with numpy, from the scoring module's definitions.

    ``state``: dict of lead_prev, last_change, neg_since (updated in place, as the kernel does)."""
    n = v.shape[0]
    rows = np.arange(n)
    v1, a1 = v[:, 0], a[:, 0]
    lead, gap = lead_all[:, 0], gap_all[:, 0]
    has = lead >= 0
    safe = np.maximum(lead, 0)
    v0 = np.where(has, v[rows, safe], 0.0)
    a0 = np.where(has, a[rows, safe], 0.0)
    changed = lead != state["lead_prev"]
    state["last_change"][:] = np.where(changed, t, state["last_change"])
    state["lead_prev"][:] = lead
    gs = gap_safe(v1, v0, tau1, cfg.b0, cfg.b1)  # Gapsafe = v1 tau1 + v1^2/(2 b1) - v0^2/(2 b0)
    q = np.where(has, safety_q(gap, gs), np.inf)  # Q = D1 - Gapsafe, inf without a lead
    band = has & in_band(q, gs, cfg.band_width)  # 0 < Q < band_width Gapsafe (Gapsafe > 0)
    too_fast = v0 > set_speed + cfg.lead_margin
    followable = has & (v0 > cfg.moving_speed) & ~too_fast
    settled = t - state["last_change"] >= cfg.transient
    following = (followable & settled & (v1 > cfg.moving_speed) & (v0 > cfg.moving_speed)
                 & (np.abs(v0 - v1) <= cfg.steady_dv) & (gs > 0))
    # scoring's free samples (nothing in view, or one faster than the set speed); the env also
    # excludes a followable vehicle beyond the sensor range (no speed reward for hanging back)
    free = (~(has & (gap <= cfg.sensor_range)) | (has & too_fast)) & ~followable
    with np.errstate(invalid="ignore"):
        u = np.where(has & (gs > 0), efficiency_u(q, gs, cfg.band_width, clip=True), np.nan)
    neg = has & (q < 0)
    state["neg_since"][:] = np.where(neg, np.where(np.isnan(state["neg_since"]), t, state["neg_since"]), np.nan)
    responding = (a1 <= -cfg.response_decel) | (v1 <= cfg.stop_speed)
    collision = has & (gap <= 0.0)
    with np.errstate(invalid="ignore"):
        violation = (neg & (t - state["neg_since"] > grace) & ~responding) | collision
    fl = {K.F_V: v1, K.F_A: a1, K.F_JERK: (a1 - a_prev) / dt, K.F_GAP: gap, K.F_GS: gs, K.F_Q: q, K.F_U: u,
          K.F_VLEAD: v0, K.F_ALEAD: a0}
    bo = {K.B_HAS: has, K.B_IN_BAND: band, K.B_FOLLOWING: following, K.B_FREE: free, K.B_VIOLATION: violation,
          K.B_COLLISION: collision, K.B_FOLLOWABLE: followable}
    return fl, bo


def random_sequence(rng, n, T, S=3):
    """Random but persistent episodes of ``n`` scenes: the lead changes now and then, the spacing
    drifts through the band, below Gapsafe (long enough to outlast the grace) and into collisions."""
    v = np.empty((T + 1, n, S))
    v[0] = rng.uniform(0.0, 30.0, (n, S))
    for k in range(1, T + 1):
        v[k] = np.clip(v[k - 1] + rng.normal(0.0, 0.6, (n, S)), 0.0, 35.0)
    v[:, : n // 5, 0] = np.where(rng.random((T + 1, n // 5)) < 0.3, 0.0, v[:, : n // 5, 0])  # standing egos
    # speeds on a 0.5 m/s grid in half the scenes: |v0 - v1| == steady_dv and v == moving_speed occur exactly
    v[:, n // 2:] = np.round(v[:, n // 2:] * 2.0) / 2.0
    # accelerations in persistent regimes: hard braking (a proper response), mild, accelerating
    regime = rng.choice([-3.0, -2.0, -0.7, 0.0, 1.2], (T // 8 + 1, n, S))
    a = np.repeat(regime, 8, axis=0)[: T + 1] + rng.normal(0.0, 0.05, (T + 1, n, S)) * (rng.random((T + 1, n, S)) < .5)
    lead = np.empty((T + 1, n, S), dtype=np.int64)
    lead[0] = rng.integers(-1, S, (n, S))
    for k in range(1, T + 1):
        switch = rng.random((n, S)) < 0.04
        lead[k] = np.where(switch, rng.integers(-1, S, (n, S)), lead[k - 1])
    lead[:, :, 0] = np.where(lead[:, :, 0] == 0, 1, lead[:, :, 0])  # the ego does not follow itself
    factor = np.empty((T + 1, n))
    factor[0] = rng.uniform(-0.1, 1.6, n)
    for k in range(1, T + 1):
        factor[k] = np.clip(factor[k - 1] + rng.normal(0.0, 0.08, n), -0.2, 2.5)
    scale = v[:, :, 0] * 1.5 + 2.0
    gap0 = np.where(rng.random((T + 1, n)) < 0.03, 0.0, factor * scale)
    gap0 = np.where(rng.random((T + 1, n)) < 0.02, rng.uniform(150.0, 260.0, (T + 1, n)), gap0)  # out of range
    gap = np.where(lead >= 0, rng.uniform(5.0, 80.0, (T + 1, n, S)), np.inf)
    gap[:, :, 0] = np.where(lead[:, :, 0] >= 0, gap0, np.inf)
    return v, a, lead, gap


CONFIGS = [ScoringConfig(), ScoringConfig(response_time=0.6, transient=2.0, band_width=0.3, steady_dv=1.5,
                                          moving_speed=0.5, sensor_range=120.0, response_decel=2.5, stop_speed=0.3,
                                          b0=7.0, b1=9.0, lead_margin=1.0)]


@pytest.mark.parametrize("cfg", CONFIGS, ids=["default", "custom"])
def test_criteria_equal_the_numpy_reference_over_random_sequences(cfg):
    n, T = 60, 150
    counts = dict.fromkeys(["in_band", "following", "free", "followable", "violation", "collision", "late_neg",
                            "responding_neg", "u_nan", "changes", "q_zero", "dv_edge", "v_edge"], 0)
    for seed in range(4):
        rng = np.random.default_rng(seed)
        v, a, lead, gap = random_sequence(rng, n, T)
        set_speed = rng.uniform(10.0, 30.0, n)
        tau1 = rng.uniform(0.8, 2.0, n)
        # some gaps exactly at Gapsafe (Q == 0: neither in the band nor negative)
        v0_all = np.where(lead[:, :, 0] >= 0,
                          np.take_along_axis(v, np.maximum(lead[:, :, :1], 0), axis=2)[:, :, 0], 0.0)
        exact = (lead[:, :, 0] >= 0) & (rng.random((T + 1, n)) < 0.05)
        gap[:, :, 0] = np.where(exact, gap_safe(v[:, :, 0], v0_all, tau1, cfg.b0, cfg.b1), gap[:, :, 0])
        counts["q_zero"] += int(exact.sum())
        counts["dv_edge"] += int(np.sum((lead[:, :, 0] >= 0) & (np.abs(v0_all - v[:, :, 0]) == cfg.steady_dv)))
        counts["v_edge"] += int(np.sum(v[:, :, 0] == cfg.moving_speed))
        grace = np.full(n, cfg.response_time) if cfg.response_time is not None else tau1
        # the state as EpisodeBatch.reset_rows leaves it at sample 0
        gs0 = gap_safe(v[0, :, 0], np.where(lead[0, :, 0] >= 0, v[0, np.arange(n), np.maximum(lead[0, :, 0], 0)],
                                            0.0), tau1, cfg.b0, cfg.b1)
        q0 = np.where(lead[0, :, 0] >= 0, gap[0, :, 0] - gs0, np.inf)
        state_k = dict(lead_prev=lead[0, :, 0].copy(), last_change=np.zeros(n), neg_since=np.where(q0 < 0, 0.0, np.nan))
        state_r = {key: value.copy() for key, value in state_k.items()}
        seq = {key: np.empty((T, n)) for key in ("q", "violation", "following", "in_band", "u")}
        for k in range(1, T + 1):
            t = np.full(n, k * DT_SEQ)
            fl = np.empty((K.N_FLOAT, n))
            bo = np.empty((K.N_BOOL, n), dtype=bool)
            K.criteria(t, v[k], a[k], lead[k], gap[k], a[k - 1, :, 0].copy(), DT_SEQ,
                       scenes(n, set_speed=set_speed, tau1=tau1, grace=grace, **state_k), cfg_array(cfg), fl, bo)
            rfl, rbo = reference_criteria(t, v[k], a[k], lead[k], gap[k], a[k - 1, :, 0], DT_SEQ, set_speed, tau1, grace,
                                          cfg, state_r)
            for row, value in rfl.items():
                np.testing.assert_array_equal(fl[row], value, err_msg=f"float row {row} at step {k}")
            for row, value in rbo.items():
                np.testing.assert_array_equal(bo[row], value, err_msg=f"bool row {row} at step {k}")
            for key in state_k:
                np.testing.assert_array_equal(state_k[key], state_r[key], err_msg=f"{key} at step {k}")
            seq["q"][k - 1], seq["violation"][k - 1] = fl[K.F_Q], bo[K.B_VIOLATION]
            seq["following"][k - 1], seq["in_band"][k - 1], seq["u"][k - 1] = (bo[K.B_FOLLOWING], bo[K.B_IN_BAND],
                                                                               fl[K.F_U])
            neg = rbo[K.B_HAS] & (rfl[K.F_Q] < 0)
            responding = (a[k, :, 0] <= -cfg.response_decel) | (v[k, :, 0] <= cfg.stop_speed)
            late = neg & (t - state_r["neg_since"] > grace)
            counts["late_neg"] += int(late.sum())
            counts["responding_neg"] += int((late & responding).sum())
            counts["in_band"] += int(rbo[K.B_IN_BAND].sum())
            counts["following"] += int(rbo[K.B_FOLLOWING].sum())
            counts["free"] += int(rbo[K.B_FREE].sum())
            counts["followable"] += int(rbo[K.B_FOLLOWABLE].sum())
            counts["violation"] += int(rbo[K.B_VIOLATION].sum())
            counts["collision"] += int(rbo[K.B_COLLISION].sum())
            counts["u_nan"] += int((np.isnan(rfl[K.F_U]) & rbo[K.B_HAS]).sum())
            counts["changes"] += int((lead[k, :, 0] != lead[k - 1, :, 0]).sum())
        # the same samples by the scoring module's sequence functions (one scene at a time)
        tt = np.arange(T + 1) * DT_SEQ
        for i in range(n):
            has = lead[:, i, 0] >= 0
            q = np.concatenate([[q0[i]], seq["q"][:, i]])
            bad = _proper_response_violations(tt, q, has, a[:, i, 0], v[:, i, 0], cfg, float(grace[i]))
            bad |= has & (gap[:, i, 0] <= 0.0)
            np.testing.assert_array_equal(seq["violation"][:, i], bad[1:], err_msg=f"scene {i}")
            settled = _after_transients(SimpleNamespace(t=tt, has_lead=has, lead_id=lead[:, i, 0].astype(float)),
                                        cfg.transient)
            v0 = np.where(has, v[:, i, :][np.arange(T + 1), np.maximum(lead[:, i, 0], 0)], 0.0)
            v1 = v[:, i, 0]
            gs = gap_safe(v1, v0, tau1[i], cfg.b0, cfg.b1)
            followable = has & (v0 > cfg.moving_speed) & ~(v0 > set_speed[i] + cfg.lead_margin)
            following = (followable & settled & (v1 > cfg.moving_speed) & (np.abs(v0 - v1) <= cfg.steady_dv)
                         & (gs > 0))
            np.testing.assert_array_equal(seq["following"][:, i], following[1:], err_msg=f"scene {i}")
            np.testing.assert_array_equal(seq["in_band"][:, i], (has & in_band(q, gs, cfg.band_width))[1:])
    assert all(c > 30 for c in counts.values()), counts


def test_criteria_by_hand():
    """A few samples worked out by hand (default scoring constants)."""
    cfg = ScoringConfig()
    n = 4
    v = np.array([[20.0, 20.0, 0.0], [20.0, 25.0, 0.0], [0.3, 10.0, 0.0], [20.0, 0.0, 0.0]])
    a = np.array([[0.5, 0.0, 0.0], [-1.0, 0.0, 0.0], [-0.5, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    lead = np.array([[1, -1, -1], [1, -1, -1], [1, -1, -1], [-1, -1, -1]])
    gap = np.array([[32.0, np.inf, np.inf], [10.0, np.inf, np.inf], [-0.5, np.inf, np.inf],
                    [np.inf, np.inf, np.inf]])
    tau1 = np.full(n, 1.5)
    state = dict(lead_prev=np.array([1, 1, 1, -1]), last_change=np.zeros(n), neg_since=np.array([np.nan, 0.0, 0.0, 0.0]))
    fl, bo = np.empty((K.N_FLOAT, n)), np.empty((K.N_BOOL, n), dtype=bool)
    K.criteria(np.full(n, 6.0), v, a, lead, gap, np.array([0.0, -1.0, 1.5, 0.0]), DT,
               scenes(n, set_speed=np.full(n, 25.0), tau1=tau1, grace=tau1, **state), cfg_array(cfg), fl, bo)
    # scene 0: Gapsafe = 20 * 1.5 = 30, Q = 2 in (0, 6): a following sample in the band, u = 2 / 6
    assert fl[K.F_GS, 0] == 30.0 and fl[K.F_Q, 0] == 2.0 and fl[K.F_U, 0] == pytest.approx(1 / 3)
    assert bo[[K.B_HAS, K.B_IN_BAND, K.B_FOLLOWING, K.B_FOLLOWABLE], 0].all() and not bo[K.B_FREE, 0]
    assert fl[K.F_JERK, 0] == pytest.approx(2.5)
    # scene 1: lead at 25 m/s, Gapsafe = 30 + 25 - 39.0625, Q < 0 since t = 0 (6 s > 1.5 s), braking -1: violation
    assert fl[K.F_GS, 1] == pytest.approx(30 + 400 / 16 - 625 / 16) and fl[K.F_Q, 1] < 0
    assert bo[K.B_VIOLATION, 1] and not bo[K.B_COLLISION, 1] and not bo[K.B_FOLLOWING, 1]
    assert state["neg_since"][1] == 0.0
    # scene 2: standing ego (0.3 m/s <= stop_speed) is responding -- but the gap is < 0: a collision
    assert bo[K.B_COLLISION, 2] and bo[K.B_VIOLATION, 2]
    # scene 3: nothing ahead: Q inf, u NaN, free, neg_since cleared
    assert fl[K.F_Q, 3] == np.inf and np.isnan(fl[K.F_U, 3]) and bo[K.B_FREE, 3] and not bo[K.B_HAS, 3]
    assert np.isnan(state["neg_since"][3]) and fl[K.F_VLEAD, 3] == 0.0 and fl[K.F_ALEAD, 3] == 0.0


# ----------------------------------------------------------------------------- end to end
def test_record_writes_the_world_state():
    env = gymnasium.make(SL)
    core = env.unwrapped.core
    obs, _ = env.reset(seed=4)
    snaps = []

    def snap():
        w = core.world
        lead = int(w.neighbours.lead[0, 0])
        road = env.unwrapped.scenario.road
        snaps.append([w.t[0], w.v[0, 0], w.a[0, 0], w.neighbours.gap[0, 0], w.v[0, lead] if lead >= 0 else 0.0,
                      w.a[0, lead] if lead >= 0 else 0.0, float(lead), w.a_y[0, 0],
                      float(road.d2(w.y[0, 0], w.width[0, 0])), float(road.d3(w.y[0, 0], w.width[0, 0]))])

    snap()
    while True:
        obs, _, term, trunc, _ = env.step(policy(obs, 1.05))
        snap()
        if term or trunc:
            break
    tr = core.trace(0)
    got = np.array([getattr(tr, c) for c in K.RECORD]).T
    np.testing.assert_array_equal(got, np.array(snaps))
    assert np.any(tr.lead_id >= 0) and np.any(tr.lead_id < 0) and np.any(tr.a_y != 0)  # cut-ins and lane changes


def test_record_called_directly():
    """Scenes ``rows`` at their own step ``k``; other scenes and other steps untouched."""
    rng = np.random.default_rng(2)
    n, S, steps = 9, 3, 6
    t, k = rng.uniform(0, 10, n), rng.integers(0, steps, n)
    v, a = rng.uniform(0, 30, (n, S)), rng.uniform(-3, 3, (n, S))
    lead = rng.integers(-1, S, (n, S))
    gap = np.where(lead >= 0, rng.uniform(0, 80, (n, S)), np.inf)
    a_y, y = rng.normal(0, 1, (n, S)), rng.uniform(-1, 5, (n, S))
    width0, lane_width, n_lanes = rng.uniform(1.5, 2.5, n), rng.uniform(3.0, 4.0, n), rng.integers(1, 4, n) * 1.0
    rows = np.array([0, 2, 3, 7])
    rec = np.full((len(K.RECORD), n, steps), -7.0)
    K.record(rows, k, t, (v, a, lead, gap, a_y, y), scenes(n, ego_width=width0, lane_width=lane_width, n_lanes=n_lanes,
                                                           rec=rec))
    expect = np.full_like(rec, -7.0)
    for i in rows:
        j = lead[i, 0]
        expect[:, i, k[i]] = [t[i], v[i, 0], a[i, 0], gap[i, 0], v[i, j] if j >= 0 else 0.0,
                              a[i, j] if j >= 0 else 0.0, j, a_y[i, 0], y[i, 0] + 0.5 * lane_width[i] - 0.5 * width0[i],
                              (n_lanes[i] - 0.5) * lane_width[i] - y[i, 0] - 0.5 * width0[i]]
    np.testing.assert_array_equal(rec, expect)
    assert np.any(lead[rows, 0] < 0) and np.any(lead[rows, 0] >= 0)


def numpy_observation(o, set_speed, time_gap, rng, v2v, low, high):
    """EpisodeBatch.observe as it was written with numpy (before the compiled ``observe``), then clipped."""
    v, a, gap, v_lead, a_lead, gap2, v_lead2 = o[0], o[1], o[2], o[3], o[4], o[5], o[6]
    seen = np.isfinite(gap)
    cols = [v, a, np.where(seen, np.clip(gap, 0.0, rng), rng), np.where(seen, v_lead - v, 0.0), seen.astype(float),
            set_speed, time_gap]
    if v2v:
        seen2 = np.isfinite(gap2)
        cols += [np.where(seen, a_lead, 0.0), np.where(seen2, np.clip(gap2, 0.0, rng), rng),
                 np.where(seen2, v_lead2 - v, 0.0), seen2.astype(float)]
    return np.clip(np.stack(cols, axis=1), low, high)


@pytest.mark.parametrize("v2v", [False, True])
def test_env_observe_kernel_equals_the_numpy_formulation(v2v):
    from acc_gym.envs.acc_env import observation_space
    from acc_gym.envs.config import EnvConfig

    rng = np.random.default_rng(int(v2v))
    n = 400
    gap = np.where(rng.random(n) < 0.7, rng.uniform(-3.0, 260.0, n), np.inf)
    gap2 = np.where(np.isfinite(gap) & (rng.random(n) < 0.7), gap + rng.uniform(0.0, 100.0, n), np.inf)
    o = np.array([rng.uniform(0.0, 80.0, n), rng.uniform(-20.0, 20.0, n), gap, rng.uniform(0.0, 80.0, n),
                  rng.uniform(-20.0, 20.0, n), gap2, rng.uniform(0.0, 80.0, n), rng.uniform(-20.0, 20.0, n)])
    set_speed, time_gap = rng.uniform(5.0, 75.0, n), rng.uniform(0.5, 12.0, n)
    space = observation_space(EnvConfig(v2v=v2v, sensor_range=150.0))
    low, high = space.low.astype(float), space.high.astype(float)
    m = 11 if v2v else 7
    ref = numpy_observation(o, set_speed, time_gap, 150.0, v2v, low, high)
    for dtype in (np.float64, np.float32):
        out = np.empty((n, m), dtype=dtype)
        K.observe(o, set_speed, time_gap, 150.0, v2v, low, high, out)
        np.testing.assert_array_equal(out, ref.astype(dtype))
    unclipped = np.empty((n, m))
    K.observe(o, set_speed, time_gap, 150.0, v2v, np.full(m, -np.inf), np.full(m, np.inf), unclipped)
    np.testing.assert_array_equal(unclipped, numpy_observation(o, set_speed, time_gap, 150.0, v2v, -np.inf, np.inf))
    assert np.any(unclipped != ref)  # the bounds did clip something (speeds, accelerations, time gaps)


def test_singlelane_step_infos_are_what_the_report_and_trace_say():
    env = gymnasium.make(SL)
    core = env.unwrapped.core
    cfg = env.unwrapped.config.scoring
    weights = CriteriaReward()
    totals = dict(band=0, violations=0, free=0, lag=0, following=0)
    for seed in range(8):
        for factor in (1.05, 0.4):
            steps = run(env, seed, factor)
            infos = [info for _, info in steps]
            final = infos[-1]
            report = final["report"]
            tr = core.trace(0)
            assert tr.n == len(infos) + 1
            tau1 = report["tau1"]
            has = tr.has_lead
            v0 = np.where(has, tr.v_lead, 0.0)
            gs = gap_safe(tr.v, v0, tau1, cfg.b0, cfg.b1)
            q = np.where(has, safety_q(tr.gap, gs), np.inf)
            # Q and Gapsafe of every step, exactly those of the trace's samples 1..T
            np.testing.assert_array_equal([i["q"] for i in infos], q[1:])
            np.testing.assert_array_equal([i["gap_safe"] for i in infos], gs[1:])
            if has.any():
                assert report["items"]["safety"]["min_q"] == float(np.min(q[has]))
            # violations: the report's proper-response samples, one by one
            grace = cfg.response_time if cfg.response_time is not None else tau1
            bad = _proper_response_violations(tr.t, q, has, tr.a, tr.v, cfg, grace) | (has & (tr.gap <= 0.0))
            np.testing.assert_array_equal([i["violation"] for i in infos], bad[1:])
            assert report["items"]["safety"]["violations"] == int(bad.sum())
            first = report["items"]["safety"]["first_violation_t"]
            assert (first is None) == (not bad.any())
            if bad.any():
                assert first == infos[int(np.argmax(bad[1:]))]["t"]
            # band and efficiency rewards on exactly the report's car-following samples
            settled = _after_transients(tr, cfg.transient)
            followable = has & (v0 > cfg.moving_speed) & ~(v0 > tr.set_speed + cfg.lead_margin)
            following = (followable & settled & (tr.v > cfg.moving_speed) & (np.abs(v0 - tr.v) <= cfg.steady_dv)
                         & (gs > 0))
            band = following & in_band(q, gs, cfg.band_width)
            np.testing.assert_array_equal([i["rewards"]["band"] for i in infos], weights.band * band[1:])
            u_t = efficiency_u(q, gs, cfg.band_width)
            eff = np.where(following, weights.efficiency * (1.0 - np.nan_to_num(u_t, nan=1.0)), 0.0)
            np.testing.assert_allclose([i["rewards"]["efficiency"] for i in infos], eff[1:], rtol=1e-12, atol=1e-15)
            assert report["items"]["car_following"]["samples"] == int(following.sum())
            if following.any():
                assert report["u"] == pytest.approx(float(np.mean(u_t[following])), rel=1e-12)
                eff_sum = sum(i["rewards"]["efficiency"] for i in infos)
                assert report["u"] == pytest.approx(1.0 - eff_sum / (weights.efficiency * following.sum()), abs=1e-9)
            # speed, comfort, jerk, collision and lag terms from the trace
            free = (~(has & (tr.gap <= cfg.sensor_range)) | (has & (v0 > tr.set_speed + cfg.lead_margin))) & ~followable
            speed = np.where(free, 1.0 - np.minimum(np.abs(tr.v - tr.set_speed) / (0.2 * tr.set_speed), 1.0), 0.0)
            np.testing.assert_allclose([i["rewards"]["speed"] for i in infos], weights.speed * speed[1:], rtol=1e-12)
            np.testing.assert_allclose([i["rewards"]["comfort"] for i in infos],
                                       -weights.comfort * (tr.a[1:] / cfg.a_x_comfort) ** 2, rtol=1e-12)
            jerk = np.diff(tr.a) / DT
            np.testing.assert_allclose([i["rewards"]["jerk"] for i in infos],
                                       -weights.jerk * (jerk / weights.jerk_scale) ** 2, rtol=1e-12, atol=1e-15)
            collision = has & (tr.gap <= 0.0)
            np.testing.assert_array_equal([i["rewards"]["collision"] for i in infos], -weights.collision * collision[1:])
            assert report["items"]["safety"]["collision"] == bool(collision.any())
            far = 1.2 * tau1 * v0 + 5.0
            lag = np.where(followable, np.clip((tr.gap - far) / far, 0.0, 1.0), 0.0)
            np.testing.assert_allclose([i["rewards"]["lag"] for i in infos], -weights.lag * lag[1:], rtol=1e-12)
            np.testing.assert_allclose([r for r, _ in steps], [sum(i["rewards"].values()) for i in infos], rtol=1e-12)
            totals["band"] += int(band.sum())
            totals["violations"] += int(bad.sum())
            totals["free"] += int(free[1:].sum())
            totals["lag"] += int((lag[1:] > 0).sum())
            totals["following"] += int((following & ~band).sum())
    assert all(c > 10 for c in totals.values()), totals
