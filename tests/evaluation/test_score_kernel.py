"""The compiled score (``score_episode``) equals its numpy definition, the oracle ``tests/score_oracle.py``.

Compared: the whole report -- ``to_dict()`` with NaN equal to NaN, and every field of the
report objects with its kind (bool, int, float, None) -- on episodes of the environments
(random, zero and full-throttle actions; some end in a collision), on the ego of simulated
scenarios with ACC controllers (strided columns of a world trace), on random traces and on
hand-made edge cases, under the default config and variants of it (literal rules, no
clipping, a response time, other transients ...). Every value is expected to be equal, not
close: the kernel reproduces numpy's order of operations and its pairwise summation.
"""

import dataclasses
import json
import math

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the environments)
from acc_gym import scenarios
from acc_gym.drivers import ACC, ACCParams
from acc_gym.evaluation import EgoTrace, ScoringConfig, scoring
from acc_gym._io import json_safe_reference
from acc_gym.evaluation import _score_kernel as K
from acc_gym.evaluation.scoring import score_episode
from acc_gym.evaluation.trace import _ARRAY_COLUMNS, _LANE_CENTRED
from score_oracle import score_oracle

CONFIGS = {
    "default": ScoringConfig(),
    "literal": ScoringConfig.literal(),
    "literal-safety": ScoringConfig(safety="literal"),
    "literal-band": ScoringConfig(band="literal"),
    "no-clip": ScoringConfig(clip=False),
    "response-time": ScoringConfig(response_time=0.5),
    "no-transient": ScoringConfig(transient=0.0),
    "long-transient": ScoringConfig(transient=12.0, band_share=1),  # an int share: reported as given
    "tau1": ScoringConfig(tau1=1.2, lead_margin=1.0, steady_dv=2.0),
    "strict": ScoringConfig(response_decel=4.0, stop_speed=0.0, sensor_range=60.0, band_width=0.35,
                            approach_decel=1.5, a_x_comfort=1.0, a_y_comfort=0.2),
}


# ---------------------------------------------------------------- comparison helpers
def _kind(x):
    """The kind of a report value: numpy's float64 (what the reference's metrics may hold)
    counts as a float, as it is one."""
    if x is None or isinstance(x, (bool, np.bool_)):
        return "none" if x is None else "bool"
    if isinstance(x, (int, np.integer)):
        return "int"
    if isinstance(x, (float, np.floating)):
        return "float"
    return type(x).__name__


def same_value(a, b, where):
    assert _kind(a) == _kind(b), f"{where}: {a!r} ({type(a).__name__}) vs {b!r} ({type(b).__name__})"
    if isinstance(a, dict):
        assert a.keys() == b.keys(), f"{where}: keys {sorted(a)} vs {sorted(b)}"
        for k in a:
            same_value(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            same_value(x, y, f"{where}[{k}]")
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b), f"{where}: NaN vs {b!r}"
    else:
        assert a == b, f"{where}: {a!r} vs {b!r}"


def _plain(x):
    """The compiled report holds Python values only (no numpy scalars)."""
    if isinstance(x, dict):
        return all(_plain(v) for v in x.values())
    return x is None or type(x) in (bool, int, float, str)


def assert_same_report(fast, ref):
    """The compiled report equals the reference's: its dict form and every field."""
    same_value(fast.to_dict(), ref.to_dict(), "to_dict()")
    for name in ("score", "qualified", "r1", "r2", "u", "j_x", "j_y", "tau1"):
        same_value(getattr(fast, name), getattr(ref, name), name)
        assert _plain(getattr(fast, name)), name
    assert len(fast.items) == len(ref.items) == 4
    for a, b in zip(fast.items, ref.items):
        assert type(a) is type(b)
        same_value((a.name, a.requirement, a.qualified, a.applicable),
                   (b.name, b.requirement, b.qualified, b.applicable), f"item {b.name}")
        same_value(a.detail, b.detail, f"item {b.name}.detail")
        assert _plain(a.detail), a.detail
    same_value(fast.metrics, ref.metrics, "metrics")
    assert _plain(fast.metrics), fast.metrics
    assert fast.config == ref.config and type(fast) is type(ref)


def check(trace, config=None):
    fast = score_episode(trace, config)
    assert_same_report(fast, score_oracle(trace, config))
    return fast


# ---------------------------------------------------------------- episodes of the environments
def _episodes(env_id, mode, seeds):
    env = gymnasium.make(env_id)
    out = []
    for seed in seeds:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        while True:
            if mode == "random":
                action = env.action_space.sample()
            else:
                action = np.full(env.action_space.shape, 1.0 if mode == "full" else 0.0, env.action_space.dtype)
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        out.append((f"{env_id}/{mode}/{seed}", env.unwrapped.core.trace(0), info["report"],
                    env.unwrapped.config.scoring))
    env.close()
    return out


@pytest.fixture(scope="module")
def env_episodes():
    eps = []
    for mode in ("random", "zero", "full"):
        eps += _episodes("acc_gym/SingleLane-v0", mode, range(8))
        eps += _episodes("acc_gym/CarFollowing-v0", mode, range(4))
    return eps


def test_environment_episodes_cover_the_cases(env_episodes):
    reports = [rep for _, _, rep, _ in env_episodes]
    assert len(reports) == 36
    assert any(r["metrics"]["collision"] for r in reports)  # full throttle ends in collisions
    assert any(r["qualified"] for r in reports) and any(not r["qualified"] for r in reports)
    assert any(r["items"]["car_following"]["approaching"] for r in reports)
    assert any(r["metrics"]["transients"] > 0 for r in reports)
    assert any(r["items"]["car_following"]["samples"] > 0 for r in reports)


def test_environment_reports_equal_the_reference(env_episodes):
    """The report an environment puts in the last step's info (the compiled path) is the reference's."""
    for name, trace, report, cfg in env_episodes:
        same_value(report, score_oracle(trace, cfg).to_dict(), name)


@pytest.mark.parametrize("config", list(CONFIGS))
def test_environment_episodes_under_configs(env_episodes, config):
    for _, trace, _, _ in env_episodes:
        check(trace, CONFIGS[config])


@pytest.mark.parametrize("variant", ["no-lead-id", "no-optional-columns", "no-set-speed", "declared-gap",
                                     "no-time-gap"])
def test_environment_episodes_varied(env_episodes, variant):
    changes = {"no-lead-id": dict(lead_id=None), "no-optional-columns": dict(lead_id=None, a_lead=None, a_y=None,
                                                                           d2=None, d3=None),
               "no-set-speed": dict(set_speed=None), "declared-gap": dict(declared_time_gap=0.9),
               "no-time-gap": dict(time_gap=None, declared_time_gap=2.5)}[variant]
    for _, trace, _, _ in env_episodes:
        tr = dataclasses.replace(trace, **changes)
        for config in ("default", "literal", "no-clip", "no-transient"):
            check(tr, CONFIGS[config])


# ---------------------------------------------------------------- simulated scenarios (world traces)
SCENARIO_IDS = ("carfollowing/60", "carfollowing/120", "singlelane/2/cut-in", "singlelane/2/cut-out",
                "singlelane/2/approach", "singlelane/3/lane-change+cut-in", "stopandgo", "ncap/ccrb/2-12")


@pytest.fixture(scope="module")
def world_traces():
    out = []
    for sid in SCENARIO_IDS:
        sc = scenarios.build(sid, seed=0)
        for k1, time_gap in ((0.3, sc.time_gap), (0.5, 0.5)):  # a tuned ACC and a tailgater
            ego = ACC(ACCParams(k1=k1, k2=1.2, s0=2.5, time_gap=time_gap, v_set=sc.set_speed), n=1, dt=sc.dt)
            out.append(EgoTrace.from_world(scenarios.simulate(sc, ego), 0, sc))
    return out


def test_world_traces(world_traces):
    # long car-following stretches: more than 128 samples (numpy's pairwise summation splits them)
    assert max(score_episode(tr).item("car_following").detail["samples"] for tr in world_traces) > 128
    assert any(score_episode(tr).qualified for tr in world_traces)
    assert any(not tr.v.flags.c_contiguous for tr in world_traces)  # views into the world's arrays
    for tr in world_traces:
        for cfg in CONFIGS.values():
            check(tr, cfg)
        check(dataclasses.replace(tr, lead_id=None))
        check(dataclasses.replace(tr, declared_time_gap=0.9))


# ---------------------------------------------------------------- random traces
def random_trace(rng, n=None):
    """A drive behind a lead with speed steps, dropouts, changes of the vehicle ahead, dips
    below Gapsafe, hard braking, stops and a lane excursion, each switched on at random."""
    n = int(rng.integers(2, 400)) if n is None else n
    dt = rng.choice([0.1, 0.2, 0.5])
    t = np.arange(n) * dt if rng.random() < 0.7 else np.cumsum(rng.uniform(0.05, 0.5, n))
    steps = rng.uniform(0.0, 30.0, 4)
    v_lead = steps[np.minimum((np.arange(n) * 4) // max(n, 1), 3)]
    if n >= 15 and rng.random() < 0.5:  # ramps
        v_lead = np.convolve(v_lead, np.ones(15) / 15, mode="same")
    v_lead = np.maximum(v_lead + rng.normal(0.0, rng.choice([0.0, 0.02, 0.5]), n), 0.0)
    v = np.maximum(v_lead + rng.normal(0.0, rng.choice([0.1, 0.8, 3.0]), n), 0.0)
    if rng.random() < 0.2:
        v[rng.integers(0, n):] = 0.0  # stops
    h = rng.uniform(0.3, 2.5)
    gap = h * v + rng.uniform(0.0, 8.0) + rng.normal(0.0, rng.choice([0.1, 2.0]), n)
    if rng.random() < 0.3:  # a dip below Gapsafe
        i = int(rng.integers(0, n))
        gap[i:i + int(rng.integers(1, 30))] *= 0.3
    if rng.random() < 0.2:
        gap[int(rng.integers(0, n))] = rng.choice([0.0, -0.5])  # contact
    a = np.clip(np.gradient(v, t) if n > 1 else np.zeros(n), -9.0, 4.0)
    if rng.random() < 0.3:
        a[rng.random(n) < 0.3] = rng.uniform(-6.0, -2.0)
    lead_id = np.ones(n)
    if rng.random() < 0.4:  # another vehicle ahead from some sample on
        k = int(rng.integers(0, n))
        lead_id[k:] = 2.0
        gap[k:] += rng.choice([-10.0, 0.5, 10.0])
    has = np.ones(n, bool)
    if rng.random() < 0.5:  # no vehicle ahead at some samples
        has &= rng.random(n) > rng.choice([0.05, 0.5, 1.0])
    if rng.random() < 0.2:
        has[int(rng.integers(0, n)):] = False
    gap = np.where(has, gap, np.inf)
    lead_id = np.where(has, lead_id, -1.0)
    v_lead = np.where(has, v_lead, 0.0)
    d2 = np.full(n, 0.975)
    if rng.random() < 0.2:
        d2[int(rng.integers(0, n))] = -0.1
    cols = dict(t=t, v=v, a=a, gap=gap, v_lead=v_lead)
    if rng.random() < 0.6:
        cols.update(lead_id=lead_id, a_y=rng.normal(0.0, rng.choice([0.0, 1.0, 8.0]), n), d2=d2,
                    d3=np.full(n, 0.9) - (rng.random() < 0.1))
    return EgoTrace(**cols, set_speed=rng.choice([None, float(rng.uniform(5.0, 35.0)), float(steps[-1])]),
                    time_gap=rng.choice([None, 1.0, 1.5, 2.0]),
                    declared_time_gap=rng.choice([None, 0.3, 1.2, 3.0]))


def test_random_traces():
    rng = np.random.default_rng(3)
    names = list(CONFIGS)
    seen = {"qualified": 0, "approaching": 0, "samples": 0, "violations": 0, "transients": 0, "collision": 0}
    for k in range(600):
        tr = random_trace(rng, n=2 if k % 50 == 0 else None)
        r = check(tr, CONFIGS[names[k % len(names)]])
        seen["qualified"] += r.qualified
        seen["approaching"] += r.item("car_following").detail["approaching"]
        seen["samples"] += r.item("car_following").detail["samples"] > 0
        seen["violations"] += r.item("safety").detail["violations"] > 0
        seen["transients"] += r.metrics["transients"] > 0
        seen["collision"] += r.metrics["collision"]
    assert all(count > 0 for count in seen.values()), seen


# ---------------------------------------------------------------- hand-made edge cases
N = 41
T = np.arange(N) * 0.5


def make(gap=30.0, v=20.0, v_lead=20.0, a=0.0, t=T, **kw):
    n = t.size

    def arr(x):
        return np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy()

    gap = arr(gap)
    v_lead = np.where(np.isfinite(gap), arr(v_lead), 0.0)
    return EgoTrace(t=t, v=arr(v), a=arr(a), gap=gap, v_lead=v_lead, **kw)


def dip(length, start=10, depth=0.5, braking=None, **kw):
    """Q < 0 for ``length`` samples (dt 0.5 s) from ``start``; ``braking`` m/s^2 from a sample on."""
    gap = np.full(N, 32.0)
    gap[start:start + length] = 30.0 * depth
    a = np.zeros(N)
    if braking is not None:
        a[start + braking[0]:start + length] = braking[1]
    return make(gap=gap, a=a, **kw)


def lead_changes():
    gap = np.full(N, 30.0)
    gap[15:] = 12.0  # a cut-in
    gap[30:] = 45.0  # and out
    ids = np.ones(N)
    ids[15:30] = 2.0
    return gap, ids


EDGE_CASES = {
    "no-lead": make(gap=np.inf, set_speed=25.0),
    "no-lead-no-set-speed": make(gap=np.inf),
    "no-lead-too-slow": make(gap=np.inf, v=10.0, set_speed=25.0),
    "lead-part-of-the-time": make(gap=np.r_[np.full(10, np.inf), np.full(20, 30.0), np.full(11, np.inf)],
                                  set_speed=22.0),
    "lead-part-of-the-time-ids": make(gap=np.r_[np.full(10, np.inf), np.full(20, 30.0), np.full(11, np.inf)],
                                      lead_id=np.r_[np.full(10, -1.0), np.full(20, 4.0), np.full(11, -1.0)],
                                      set_speed=22.0),
    "lead-changes-ids": make(gap=lead_changes()[0], lead_id=lead_changes()[1], time_gap=1.5),
    "lead-changes-no-ids": make(gap=lead_changes()[0], time_gap=1.5),
    "same-id-gap-jump": make(gap=lead_changes()[0], lead_id=np.ones(N), time_gap=1.5),
    "two-samples": make(gap=[30.0, 29.0], t=np.array([0.0, 0.2]), set_speed=20.0),
    "two-samples-no-lead": make(gap=np.inf, t=np.array([0.0, 0.2])),
    "approaching": make(gap=200.0 - 5.0 * T, v=25.0, v_lead=20.0, set_speed=25.0, time_gap=1.5),
    "approaching-braking": make(gap=1.2 * (20.0 * 1.5) + 2.0 * (5.0 - 0.05 * T) ** 2, v=25.0 - 0.05 * T,
                                v_lead=20.0, set_speed=30.0, time_gap=1.5),
    "dawdling": make(gap=150.0 - 1.5 * T, v=21.5, v_lead=20.0, set_speed=25.0),
    "lead-above-set-speed": make(gap=60.0 + 0.5 * T, v=25.0, v_lead=25.5, set_speed=25.0),
    "lead-at-set-speed": make(gap=30.0, v=25.0, v_lead=25.0 + 1e-7, set_speed=25.0),
    "gapsafe-negative": make(gap=50.0, v=10.0, v_lead=30.0, set_speed=12.0),
    "collision": make(gap=np.r_[np.full(20, 5.0), 0.0, np.full(20, 5.0)], v=10.0, v_lead=30.0),
    "standing": make(gap=0.2, v=0.3, v_lead=0.0),
    "lane-excursion": make(d2=np.r_[np.full(20, 0.5), -0.1, np.full(20, 0.5)], d3=np.full(N, -0.2)),
    "declared-gap": make(gap=20.0, declared_time_gap=0.9, time_gap=1.5, set_speed=25.0),
    "declared-gap-below-floor": make(gap=20.0, declared_time_gap=0.3, time_gap=1.5),
    "lateral": make(a_y=np.linspace(-7.0, 2.0, N), a=np.linspace(-5.0, 4.0, N)),
    "irregular-times": make(t=np.cumsum(np.r_[0.0, np.full(N - 1, 0.3)]) + 0.1 * np.sin(np.arange(N)),
                            v=20.0 + np.sin(np.arange(N))),
}
for _length in range(1, 9):  # grace = tau1 = 1.5 s: runs of 0.0 .. 3.5 s, around it
    EDGE_CASES[f"dip-{_length}"] = dip(_length, time_gap=1.5)
    EDGE_CASES[f"dip-{_length}-braking"] = dip(_length, braking=(1, -3.0), time_gap=1.5)
    EDGE_CASES[f"dip-{_length}-late-braking"] = dip(_length, braking=(4, -3.0), time_gap=1.5)
    EDGE_CASES[f"dip-{_length}-mild-braking"] = dip(_length, braking=(0, -1.0), time_gap=1.5)
for _jump in (2.9, 3.2):  # without identities a gap jump of more than 3 m is a new vehicle ahead
    EDGE_CASES[f"gap-jump-{_jump}"] = make(gap=np.r_[np.full(20, 30.0), np.full(21, 30.0 + _jump)], time_gap=1.5)
EDGE_CASES["two-dips"] = make(gap=np.r_[np.full(5, 32.0), np.full(3, 15.0), 32.0, np.full(6, 15.0), np.full(26, 32.0)])
EDGE_CASES["dip-at-the-start"] = make(gap=np.r_[np.full(6, 15.0), np.full(35, 32.0)])
EDGE_CASES["dip-to-the-end"] = make(gap=np.r_[np.full(35, 32.0), np.full(6, 15.0)])


def _overshoot_trace():
    """The lead settles at 20 m/s; the ego overshoots it (one transient with an overshoot in (0, 1))."""
    t = np.arange(0.0, 40.0, 0.1)
    v = 15.0 + 5.0 * (1.0 - np.exp(-0.24 * t) * (np.cos(0.76 * t) + 0.31 * np.sin(0.76 * t)))
    return make(t=t, gap=np.full(t.size, 35.0), v=v, v_lead=np.full(t.size, 20.0))


EDGE_CASES["overshoot"] = _overshoot_trace()


@pytest.mark.parametrize("case", list(EDGE_CASES))
def test_edge_cases(case):
    tr = EDGE_CASES[case]
    for cfg in (None, *CONFIGS.values(), ScoringConfig(tau1=1.0, transient=0.0),
                ScoringConfig(tau1=1.5, response_time=1.5), ScoringConfig(tau1=1.5, response_time=1.0, clip=False),
                ScoringConfig.literal(tau1=1.0)):
        check(tr, cfg)


def test_edge_cases_cover_the_rules():
    r = {name: score_episode(tr, ScoringConfig(tau1=1.0, transient=0.0)) for name, tr in EDGE_CASES.items()}
    assert r["approaching"].item("car_following").detail["approaching"]
    assert r["collision"].metrics["collision"] and not r["collision"].item("safety").qualified
    assert r["no-lead"].item("safety").detail["min_q"] is None
    assert math.isnan(r["no-lead"].metrics["share_safe_spacing"])
    assert math.isnan(r["no-lead-no-set-speed"].u)
    assert 0.0 < r["overshoot"].metrics["speed_overshoot"] < 1.0 and r["overshoot"].metrics["transients"] == 1
    # around the grace time: violations start after 1 s of Q < 0 without braking
    violations = [r[f"dip-{k}"].item("safety").detail["violations"] for k in range(1, 9)]
    assert violations == [0, 0, 0, 1, 2, 3, 4, 5]  # samples 1.5 s and more after the start of the dip
    assert all(r[f"dip-{k}-braking"].item("safety").qualified for k in range(1, 9))
    assert not r["dip-8-late-braking"].item("safety").qualified
    transient = ScoringConfig(tau1=1.0, transient=5.0)
    samples = [score_episode(EDGE_CASES[f"gap-jump-{j}"], transient).item("car_following").detail["samples"]
               for j in (2.9, 3.2)]
    assert samples == [31, 21]  # from 5 s after the start; after the jump, from 5 s after it


def test_other_types_are_converted_and_a_config_must_be_a_scoring_config():
    """A float32 set speed is read as a float; a subclass of ScoringConfig is one; anything else is refused."""
    tr = make(gap=31.0, set_speed=np.float32(24.0))
    same_value(score_episode(tr).to_dict(), score_oracle(tr).to_dict(), "float32 set speed")
    assert score_episode(tr).to_dict() == score_episode(dataclasses.replace(tr, set_speed=24.0)).to_dict()

    @dataclasses.dataclass(frozen=True)
    class MyConfig(ScoringConfig):
        pass

    tr = EDGE_CASES["dip-5"]
    same_value(score_episode(tr, MyConfig()).to_dict(), score_oracle(tr, MyConfig()).to_dict(), "subclass")
    with pytest.raises(TypeError, match="EgoTrace"):
        score_episode({"t": [0.0, 1.0]})
    with pytest.raises(TypeError, match="ScoringConfig, got dict"):
        score_episode(tr, {"tau1": 1.0})


def test_pairwise_mean_equals_numpy_mean():
    rng = np.random.default_rng(0)
    for n in [*range(1, 300), 511, 512, 513, 1000, 8191, 8192, 8193, 20000]:
        x = rng.normal(size=n) * rng.uniform(1e-3, 1e3) + rng.uniform(-1e3, 1e3)
        assert K.mean(x, 0, n) == float(np.mean(x)), n
        lo = int(rng.integers(0, 4))
        y = rng.normal(size=2 * (n + lo))[::2]  # strided, from an offset
        assert K.mean(y, lo, n) == float(np.mean(y[lo:lo + n])), n


# ---------------------------------------------------------------- a record scored where it is (score_record)
def _as_record(trace, scenes=3, row=1, spare=4):
    """``trace``'s columns as the rows of an environment's record: scene ``row`` of a
    ``(columns, scenes, steps)`` array with steps beyond the episode (filled with NaN, which
    the score must not read)."""
    n = trace.n
    rec = np.full((len(_ARRAY_COLUMNS), scenes, n + spare), np.nan)
    for i, name in enumerate(_ARRAY_COLUMNS):
        col = getattr(trace, name)
        rec[i, row, :n] = col if col is not None else {"a_lead": 0.0, "lead_id": -1.0}.get(name, _LANE_CENTRED)
    return rec[:, row]


def test_the_record_rows_are_the_environments_record():
    from acc_gym.envs import _kernel as env_kernel

    assert env_kernel.RECORD == _ARRAY_COLUMNS


def test_a_record_scores_as_its_trace(env_episodes, monkeypatch):
    """score_record of an environment's record (a strided view, steps beyond the episode
    unread) gives score_episode's report of the trace, in the compiled call."""
    def refuse(*args, **kw):
        raise AssertionError("the trace path was taken")

    records = [(name, trace, _as_record(trace)) for name, trace, _, _ in env_episodes]
    assert not records[0][2].flags.c_contiguous
    with monkeypatch.context() as m:
        m.setattr(scoring, "score_episode", refuse)
        fast = {(name, cfg, k): scoring.score_record(rec, trace.n, *scalars, CONFIGS[cfg])
                for name, trace, rec in records for cfg in ("default", "literal", "no-clip", "response-time")
                for k, scalars in enumerate([(trace.set_speed, trace.time_gap, trace.declared_time_gap),
                                             (None, trace.time_gap, 0.9), (trace.set_speed, None, 2.5)])}
    for name, trace, rec in records:
        for cfg in ("default", "literal", "no-clip", "response-time"):
            for k, changes in enumerate([{}, dict(set_speed=None, declared_time_gap=0.9),
                                         dict(time_gap=None, declared_time_gap=2.5)]):
                assert_same_report(fast[name, cfg, k], score_episode(dataclasses.replace(trace, **changes),
                                                                     CONFIGS[cfg]))
        assert scoring.score_record(rec, trace.n - 1).to_dict() == score_episode(
            EgoTrace(**{c: getattr(trace, c)[:-1] for c in _ARRAY_COLUMNS})).to_dict()  # fewer samples


def test_a_record_the_checks_change_or_reject_takes_the_trace():
    """What the trace's checks would convert (a lead speed without a lead) is scored as the
    trace converts it; what they reject raises their error, naming the value."""
    tr = EDGE_CASES["dip-5"]
    rec = _as_record(tr)
    n = tr.n
    no_lead = rec.copy()
    no_lead[3, 5:9] = np.inf  # no vehicle ahead for four samples, its speed still written
    ref = score_episode(EgoTrace(**dict(zip(_ARRAY_COLUMNS, no_lead[:, :n].copy())), set_speed=tr.set_speed))
    assert ref.to_dict() == scoring.score_record(no_lead, n, tr.set_speed).to_dict()
    bad = rec.copy()
    bad[1, 7] = np.nan
    with pytest.raises(ValueError, match="'v' is NaN at sample 7"):
        scoring.score_record(bad, n)
    with pytest.raises(ValueError, match="at least 2 samples, got 1"):
        scoring.score_record(rec, 1)
    with pytest.raises(ValueError, match="time_gap must be > 0, got -1.0"):
        scoring.score_record(rec, n, time_gap=-1.0)
    # a set speed off the compiled path's types, a list of lists: the trace's path, the same report
    same_value(scoring.score_record(rec, n, np.float32(24.0)).to_dict(),
               score_episode(EgoTrace(**dict(zip(_ARRAY_COLUMNS, rec[:, :n].copy())),
                                      set_speed=np.float32(24.0))).to_dict(), "float32 set speed")
    assert scoring.score_record(rec[:, :n].tolist(), n).to_dict() == scoring.score_record(rec, n).to_dict()
    m = rec.shape[1]
    with pytest.raises(ValueError, match=f"n must be a number of the record's samples, 0 to {m}, got {m + 1}"):
        scoring.score_record(rec, m + 1)  # not cut short to the samples there are
    with pytest.raises(ValueError, match="got 3.0"):
        scoring.score_record(rec, 3.0)
    with pytest.raises(ValueError, match=r"one row per trace column .* got \(11, "):
        scoring.score_record(np.vstack([rec, rec[:1]]), n)  # a row too many is not dropped


def _to_dict_definition(rep):
    """``EpisodeReport.to_dict``'s definition: json_safe of the report's fields, then its config's."""
    out = json_safe_reference({
        "score": rep.score, "qualified": rep.qualified, "r1": rep.r1, "r2": rep.r2, "u": rep.u,
        "j_x": rep.j_x, "j_y": rep.j_y, "tau1": rep.tau1,
        "items": {it.name: {"qualified": it.qualified, "applicable": it.applicable, "points": it.points,
                            "requirement": it.requirement, **it.detail} for it in rep.items},
        "metrics": rep.metrics})
    out["config"] = rep.config.to_json_dict()
    return out


def _json_plain(x):
    if isinstance(x, dict):
        return all(type(k) is str and _json_plain(v) for k, v in x.items())
    if isinstance(x, list):
        return all(_json_plain(v) for v in x)
    return x is None or type(x) in (bool, int, float, str) and (type(x) is not float or math.isfinite(x))


def test_to_dict_is_its_definition(env_episodes):
    """A report's dict, built leaf by leaf, is json_safe of its fields: the same keys in the same
    order, the same values of the same types (ints stay ints, -0.0 stays -0.0), nothing numpy's,
    no NaN or infinity -- for compiled reports and the reference's (numpy scalars in them)."""
    reports = []
    for _, trace, _, _ in env_episodes[::3]:
        for cfg in ("default", "literal", "long-transient", "no-clip"):
            reports += [score_episode(trace, CONFIGS[cfg]), score_oracle(trace, CONFIGS[cfg])]
    reports += [score_episode(tr) for tr in EDGE_CASES.values()]
    reports += [score_oracle(tr) for tr in EDGE_CASES.values()]
    dumped = set()
    for rep in reports:
        d = rep.to_dict()
        assert json.dumps(d) == json.dumps(_to_dict_definition(rep))
        assert _json_plain(d), d
        dumped.add(json.dumps(d))
    text = "".join(dumped)
    assert "null" in text and '"inf"' in text and "NaN" not in text  # NaN and infinities converted, as defined
    assert any(not it.qualified for rep in reports for it in rep.items)
