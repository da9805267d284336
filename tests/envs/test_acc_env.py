"""The single ACC environment (``acc_gym.envs.acc_env.ACCEnv``) through ``gymnasium.make``.

Spaces, action scaling, what the observation shows against the simulated world,
determinism and pickling, reset options, the per-step and final infos, the score,
termination and truncation, reward shaping, error handling and rendering.
"""

from __future__ import annotations

import math
import pickle
import warnings

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.evaluation.scoring import ScoringConfig, score_episode
from acc_gym.scenarios import build, list_scenarios

CF = "acc_gym/CarFollowing-v0"
NCAP = "acc_gym/NCAP-v0"
SL = "acc_gym/SingleLane-v0"
SG = "acc_gym/StopAndGo-v0"
DT = 0.2
STEP_KEYS = {"q", "g", "gap_safe", "a_applied", "violation", "modes", "fallbacks", "rewards", "t"}
FINAL_KEYS = {"score", "qualified", "report", "episode_return"}
REWARD_TERMS = {"band", "efficiency", "speed", "comfort", "jerk", "safety", "collision", "lag"}


# ---------------------------------------------------------------------------- helpers
def to_action(acc: float, accel_max: float = 3.0, decel_max: float = 8.0) -> np.ndarray:
    acc = float(np.clip(acc, -decel_max, accel_max))
    return np.array([acc / accel_max if acc >= 0 else acc / decel_max], dtype=np.float32)


def linear_acc(obs) -> np.ndarray:
    """A plain linear ACC on the observation: relative speed plus spacing error (1.5 s gap)."""
    v, _, gap, v_rel, seen, set_speed = (float(x) for x in obs[:6])
    if seen < 0.5:
        acc = 0.5 * (set_speed - v)
    else:
        acc = 1.2 * v_rel + 0.3 * (gap - 2.5 - 1.5 * v)
        acc = min(acc, 0.5 * (set_speed - v))
    return to_action(acc)


def tailgater(obs) -> np.ndarray:
    """Holds about 3 m behind the vehicle ahead and never brakes harder than 1.5 m/s^2."""
    v, _, gap, v_rel, seen = (float(x) for x in obs[:5])
    acc = 1.0 * v_rel + 0.5 * (gap - 3.0) if seen > 0.5 else 1.0
    return to_action(float(np.clip(acc, -1.5, 3.0)))


def run_episode(env, policy, *, seed=None, options=None, max_steps=10_000):
    """Runs one episode; returns (observations, rewards, infos, terminated, truncated, reset_info)."""
    obs, reset_info = env.reset(seed=seed, options=options)
    observations, rewards, infos = [obs], [], []
    for k in range(max_steps):
        obs, reward, terminated, truncated, info = env.step(policy(obs, k))
        observations.append(obs)
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            return observations, rewards, infos, terminated, truncated, reset_info
    raise AssertionError(f"episode did not end within {max_steps} steps")


def assert_same(a, b, path="info"):
    """Exact recursive equality (NaN equals NaN; arrays compared by dtype, shape and value)."""
    if isinstance(a, dict):
        assert isinstance(b, dict), path
        assert a.keys() == b.keys(), f"{path}: keys {sorted(a)} != {sorted(b)}"
        for k in a:
            assert_same(a[k], b[k], f"{path}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape, path
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), f"{path}: {a} != {b}"
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), f"{path}: {a} != {b}"
    else:
        assert type(a) is type(b) and a == b, f"{path}: {a!r} != {b!r}"


def true_gap(world, ego=0, other=1):
    """Bumper-to-bumper gap from the world's positions: other's rear minus the ego's front."""
    return world.x[0, other] - world.lengths[0, other] - world.x[0, ego]


@pytest.fixture(scope="module")
def cf_env():
    env = gymnasium.make(CF, drivers="idm")
    yield env
    env.close()


@pytest.fixture(scope="module")
def ncap_env():
    env = gymnasium.make(NCAP)
    yield env
    env.close()


@pytest.fixture(scope="module")
def cf_episodes(cf_env):
    """One CarFollowing episode (seed 0) per controller, recorded with the score computed
    independently from the core's trace right after the last step."""
    out = {}
    policies = {"linear": lambda o, k: linear_acc(o), "park": lambda o, k: np.array([-1.0], np.float32),
                "bang": lambda o, k: np.array([1.0 if (k // 10) % 2 == 0 else -1.0], np.float32)}
    for name, policy in policies.items():
        obs, rewards, infos, term, trunc, reset_info = run_episode(cf_env, policy, seed=0)
        core = cf_env.unwrapped.core
        report = score_episode(core.trace(0), cf_env.unwrapped.config.scoring)
        out[name] = dict(obs=obs, rewards=rewards, infos=infos, term=term, trunc=trunc, reset_info=reset_info,
                         report=report, scenario=cf_env.unwrapped.scenario)
    return out


# ---------------------------------------------------------------------------- spaces
def test_action_space():
    env = gymnasium.make(CF, drivers="idm")
    space = env.action_space
    assert isinstance(space, gymnasium.spaces.Box)
    assert space.shape == (1,) and space.dtype == np.float32
    assert np.array_equal(space.low, [-1.0]) and np.array_equal(space.high, [1.0])


@pytest.mark.parametrize("v2v", [False, True])
def test_observation_space_bounds_follow_the_docstring(v2v):
    env = gymnasium.make(CF, drivers="idm", v2v=v2v)
    space = env.observation_space
    assert isinstance(space, gymnasium.spaces.Box) and space.dtype == np.float32
    low = [0, -15, 0, -70, 0, 0, 0]
    high = [70, 15, 200, 70, 1, 70, 10]
    if v2v:
        low += [-15, 0, -70, 0]
        high += [15, 200, 70, 1]
    assert space.shape == (11 if v2v else 7,)
    assert np.array_equal(space.low, np.array(low, np.float32))
    assert np.array_equal(space.high, np.array(high, np.float32))
    obs, _ = env.reset(seed=0)
    assert obs.shape == space.shape and obs.dtype == np.float32 and space.contains(obs)


def test_gap_bounds_follow_sensor_range():
    env = gymnasium.make(CF, drivers="idm", v2v=True, sensor_range=55.0)
    assert env.observation_space.high[2] == 55.0 and env.observation_space.high[8] == 55.0


# ---------------------------------------------------------------------------- actions
@pytest.mark.parametrize("action, expected", [(1.0, 3.0), (-1.0, -8.0), (0.5, 1.5), (-0.5, -4.0), (0.0, 0.0),
                                              (2.5, 3.0), (-7.0, -8.0)])
def test_action_scaling_at_mid_speed(ncap_env, action, expected):
    """At 50 km/h the vehicle model limits neither +3 nor -8 m/s^2: the action is the request.
    Values outside [-1, 1] are clipped."""
    obs, _ = ncap_env.reset(seed=0, options={"scenario": "ncap/ccrm/50"})
    assert obs[0] == pytest.approx(50 / 3.6)
    obs, _, _, _, info = ncap_env.step(np.array([action], np.float32))
    assert info["a_applied"] == pytest.approx(expected, abs=1e-9)
    assert obs[1] == pytest.approx(expected, abs=1e-6)  # the observation shows the applied acceleration
    assert obs[0] == pytest.approx(50 / 3.6 + expected * DT, abs=1e-5)


def test_action_scaling_uses_configured_limits():
    env = gymnasium.make(NCAP, accel_max=2.0, decel_max=5.0)
    for action, expected in ((1.0, 2.0), (-1.0, -5.0), (0.25, 0.5), (-0.5, -2.5)):
        env.reset(seed=0, options={"scenario": "ncap/ccrm/50"})
        _, _, _, _, info = env.step(np.array([action], np.float32))
        assert info["a_applied"] == pytest.approx(expected, abs=1e-9)


def test_vehicle_model_limits_an_excessive_request():
    """A 12 m/s^2 braking request is cut to the tyre limit (about 0.87 g)."""
    env = gymnasium.make(NCAP, decel_max=12.0)
    env.reset(seed=0, options={"scenario": "ncap/ccrm/50"})
    _, _, _, _, info = env.step(np.array([-1.0], np.float32))
    assert -9.5 < info["a_applied"] < -8.0


# ---------------------------------------------------------------------------- observation
def test_ccrs_starts_at_four_seconds_ttc(ncap_env):
    for kmh in (10, 30, 50):
        obs, info = ncap_env.reset(seed=1, options={"scenario": f"ncap/ccrs/{kmh}"})
        v = kmh / 3.6
        assert info["scenario"] == f"ncap/ccrs/{kmh}"
        assert obs[0] == pytest.approx(v, rel=1e-6)
        assert obs[2] == pytest.approx(4.0 * v, rel=1e-6)
        assert obs[3] == pytest.approx(-v, rel=1e-6)  # the target stands
        assert obs[4] == 1.0
        assert obs[5] == pytest.approx(v, rel=1e-6)  # the set speed is the initial speed
        assert obs[6] == pytest.approx(1.5)


def test_observed_gap_is_the_true_bumper_gap(ncap_env):
    obs, _ = ncap_env.reset(seed=0, options={"scenario": "ncap/ccrb/2-40"})
    world = ncap_env.unwrapped.core.world
    for k in range(40):
        assert obs[4] == 1.0
        assert obs[2] == pytest.approx(true_gap(world), rel=1e-6, abs=1e-4)
        assert obs[3] == pytest.approx(world.v[0, 1] - world.v[0, 0], abs=1e-5)
        assert obs[0] == pytest.approx(world.v[0, 0], abs=1e-5)
        obs, _, term, trunc, _ = ncap_env.step(linear_acc(obs))
        assert not (term or trunc)


def test_out_of_range_lead_shows_sensor_range_and_flag_zero():
    """CCRs at 50 km/h starts 55.6 m away: beyond a 30 m radar until the ego closes in."""
    env = gymnasium.make(NCAP, sensor_range=30.0)
    obs, _ = env.reset(seed=0, options={"scenario": "ncap/ccrs/50"})
    world = env.unwrapped.core.world
    seen_at = None
    for k in range(30):
        gap = true_gap(world)
        if gap > 30.0:
            assert obs[2] == 30.0 and obs[4] == 0.0 and obs[3] == 0.0
        else:
            seen_at = k if seen_at is None else seen_at
            assert obs[4] == 1.0
            assert obs[2] == pytest.approx(gap, rel=1e-6, abs=1e-4)
            assert obs[3] == pytest.approx(-world.v[0, 0], abs=1e-5)
        obs, _, term, trunc, _ = env.step(np.array([0.0], np.float32))
        if term or trunc:
            break
    assert seen_at is not None and seen_at > 0  # first unseen, then seen


def test_no_vehicle_ahead_shows_sensor_range_and_infinite_q():
    env = gymnasium.make(SL, drivers="idm", v2v=True)
    obs, _ = env.reset(seed=0, options={"scenario": "singlelane/1/free-flow"})
    for _ in range(5):
        assert obs[2] == 200.0 and obs[3] == 0.0 and obs[4] == 0.0
        assert obs[7] == 0.0 and obs[8] == 200.0 and obs[9] == 0.0 and obs[10] == 0.0
        obs, _, _, _, info = env.step(np.array([0.1], np.float32))
        assert info["q"] == math.inf and info["g"] == math.inf
        assert np.array_equal(info["modes"], [-1, -1])


def test_v2v_observes_the_second_vehicle_ahead():
    env = gymnasium.make(SG, drivers="idm", v2v=True)
    obs, _ = env.reset(seed=0)
    world = env.unwrapped.core.world
    for _ in range(60):
        assert obs.shape == (11,)
        assert obs[4] == 1.0 and obs[10] == 1.0
        assert obs[2] == pytest.approx(true_gap(world, 0, 1), rel=1e-6, abs=1e-4)
        assert obs[8] == pytest.approx(true_gap(world, 0, 2), rel=1e-6, abs=1e-4)
        assert obs[9] == pytest.approx(world.v[0, 2] - world.v[0, 0], abs=1e-5)
        assert obs[7] == pytest.approx(world.a[0, 1], abs=1e-5)
        obs, _, term, trunc, _ = env.step(linear_acc(obs))
        assert not (term or trunc)


# ---------------------------------------------------------------------------- determinism
def _random_run(env, seed, steps=300):
    rng = np.random.default_rng(seed)
    out = []
    obs, info = env.reset(seed=seed)
    out.append(("reset", obs, info))
    ends = 0
    for _ in range(steps):
        obs, reward, term, trunc, info = env.step(rng.uniform(-1, 1, 1).astype(np.float32))
        out.append(("step", obs, reward, term, trunc, info))
        if term or trunc:
            ends += 1
            obs, info = env.reset()
            out.append(("reset", obs, info))
    return out, ends


def test_same_seed_same_run_across_resets():
    a, ends = _random_run(gymnasium.make(NCAP), 11)
    b, _ = _random_run(gymnasium.make(NCAP), 11)
    assert ends >= 3  # several episodes, so the reset chain is compared too
    finals = [r[5] for r in a if r[0] == "step" and (r[3] or r[4])]
    assert finals and all("report" in f for f in finals)
    assert_same(a, b, "run")


def test_different_seeds_differ():
    a, _ = _random_run(gymnasium.make(CF, drivers="idm"), 1, steps=50)
    b, _ = _random_run(gymnasium.make(CF, drivers="idm"), 2, steps=50)
    assert a[0][2]["scenario_seed"] != b[0][2]["scenario_seed"]
    assert any(not np.array_equal(x[1], y[1]) for x, y in zip(a, b))


def _solver_paths(env) -> int:
    """Steps the MPC drivers of the current episode solved by an active-set or QP backend."""
    mpc = env.unwrapped.core.drivers._mpc  # both surrounding slots' MPC drivers, one batch
    if mpc is None:
        return 0
    stats = mpc.stats
    return int(stats["active_set"].sum() + stats["qp"].sum())


@pytest.mark.parametrize("env_id, kwargs, seed", [(NCAP, {}, 3), (CF, {"drivers": "idm"}, 3), (SL, {}, 3),
                                                  (SL, {"drivers": "atypical"}, 1)],
                         ids=["ncap", "carfollowing", "singlelane-mpc", "singlelane-mpc-qp"])
def test_pickled_env_continues_identically(env_id, kwargs, seed):
    """A copy made mid-episode (and after earlier episodes) gives bit-identical results, also
    through MPC steps solved by the QP backends (whose workspaces are not pickled)."""
    env = gymnasium.make(env_id, **kwargs)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1, 1, (400, 1)).astype(np.float32)
    env.reset(seed=seed)
    cut = 37
    for k in range(cut):
        *_, term, trunc, _ = env.step(actions[k])
        if term or trunc:
            env.reset()
    copy = pickle.loads(pickle.dumps(env))
    base, solved = _solver_paths(env), 0
    for k in range(cut, 400):
        ra, rb = env.step(actions[k]), copy.step(actions[k])
        assert np.array_equal(ra[0], rb[0]), f"step {k}: {ra[0]} != {rb[0]}"  # tolerance 0
        assert ra[1:4] == rb[1:4], f"step {k}"
        assert_same(ra[4], rb[4], f"info@{k}")
        if ra[2] or ra[3]:
            solved += _solver_paths(env) - base
            base = 0
            assert_same(env.reset(), copy.reset(), f"reset@{k}")
    solved += _solver_paths(env) - base
    if kwargs.get("drivers") == "atypical":
        assert solved > 0  # the comparison did go through backend solves


# ---------------------------------------------------------------------------- reset options
def test_reset_forces_a_scenario_id(cf_env):
    for sid in ("ncap/ccrs/30", "carfollowing/120"):
        obs, info = cf_env.reset(seed=4, options={"scenario": sid})
        assert info["scenario"] == sid and cf_env.unwrapped.scenario.id == sid
        assert info["t"] == 0.0
    obs, info = cf_env.reset(seed=4, options={"scenario": "ncap/ccrs/30"})
    assert obs[2] == pytest.approx(4 * 30 / 3.6, rel=1e-6)
    again, info2 = cf_env.reset(seed=4, options={"scenario": "ncap/ccrs/30"})  # seeded: the same draw
    assert info2 == info and np.array_equal(again, obs)
    _, _, _, _, step_info = cf_env.step(np.array([0.0], np.float32))
    assert step_info["scenario"] == "ncap/ccrs/30"


def test_reset_accepts_a_scenario_object(cf_env):
    sc = build("ncap/ccrm/50", seed=17)
    obs, info = cf_env.reset(options={"scenario": sc})
    assert cf_env.unwrapped.scenario is sc
    assert info["scenario"] == "ncap/ccrm/50" and info["scenario_seed"] == 17
    assert obs[0] == pytest.approx(50 / 3.6, rel=1e-6)
    assert obs[2] == pytest.approx(4 * (50 - 20) / 3.6, rel=1e-6)
    # the forced scenario lasts for that episode only; the next reset draws from the env's family
    cf_env.reset(seed=4)
    assert cf_env.unwrapped.scenario.id in list_scenarios("carfollowing")


def test_reset_option_errors(cf_env):
    with pytest.raises(ValueError, match="unknown reset option.*'foo'"):
        cf_env.reset(seed=0, options={"foo": 1})
    with pytest.raises(ValueError, match="ncap/ccrs/31"):
        cf_env.reset(seed=0, options={"scenario": "ncap/ccrs/31"})
    with pytest.raises(TypeError, match="scenario"):
        cf_env.reset(seed=0, options={"scenario": 5})


# ---------------------------------------------------------------------------- infos, score
def test_every_step_info(cf_episodes):
    for name, ep in cf_episodes.items():
        assert {"scenario", "scenario_seed", "t"} <= set(ep["reset_info"])
        for k, info in enumerate(ep["infos"]):
            assert STEP_KEYS <= set(info), (name, k, set(info))
            assert info["t"] == pytest.approx((k + 1) * DT)
            assert isinstance(info["violation"], bool) and isinstance(info["fallbacks"], int)
            assert info["modes"].shape == (2,)
            assert info["q"] == info["g"]
            assert math.isfinite(info["q"])  # the lead is always there (maybe out of sensor range)
            if ep["obs"][k + 1][4] == 1.0:  # Q = D1 - Gapsafe, with the observed gap
                gap = float(ep["obs"][k + 1][2])
                assert info["q"] == pytest.approx(gap - info["gap_safe"], abs=1e-3)
            assert set(info["rewards"]) == REWARD_TERMS
            assert sum(info["rewards"].values()) == pytest.approx(ep["rewards"][k], abs=1e-12)
            # documented terms: comfort -0.1 (a/3)^2, collision only at a terminating collision
            assert info["rewards"]["comfort"] == pytest.approx(-0.1 * (info["a_applied"] / 3.0) ** 2, abs=1e-12)
            assert info["rewards"]["safety"] == (-2.0 if info["violation"] else 0.0)
            last = k == len(ep["infos"]) - 1
            assert (FINAL_KEYS <= set(info)) == last


def test_last_info_score_matches_independent_scoring(cf_episodes):
    for name, ep in cf_episodes.items():
        final = ep["infos"][-1]
        assert 0.0 <= final["score"] <= 100.0
        assert isinstance(final["qualified"], bool) and isinstance(final["report"], dict)
        assert final["score"] == ep["report"].score
        assert final["qualified"] == ep["report"].qualified
        assert_same(final["report"], ep["report"].to_dict(), f"{name}.report")
        assert final["episode_return"] == pytest.approx(sum(ep["rewards"]), abs=1e-9)


@pytest.mark.parametrize("env_id, kwargs", [(CF, {"drivers": "idm"}), (SL, {}), (NCAP, {})],
                         ids=["carfollowing", "singlelane-mpc", "ncap"])
def test_reward_terms_count_what_the_score_counts(env_id, kwargs):
    """The band reward is paid on exactly the score's in-band car-following samples, and the
    safety penalty on exactly its proper-response violations (same definitions)."""
    env = gymnasium.make(env_id, **kwargs)
    checked = 0
    for seed in range(3):
        for policy in (lambda o, k: linear_acc(o), lambda o, k: hang_back(o, 1.7), lambda o, k: tailgater(o)):
            _, _, infos, _, _, _ = run_episode(env, policy, seed=seed)
            items = infos[-1]["report"]["items"]
            band = sum(i["rewards"]["band"] for i in infos)
            share = items["car_following"]["share_in_band"]
            assert band == pytest.approx((share or 0.0) * items["car_following"]["samples"], abs=1e-9)
            assert sum(i["violation"] for i in infos) == items["safety"]["violations"]
            checked += band > 0
    if env_id == CF:
        assert checked >= 3  # some episodes did earn band rewards (the others are short: mostly transients)


def test_linear_acc_truncates_at_scenario_end_and_qualifies(cf_episodes):
    ep = cf_episodes["linear"]
    steps = ep["scenario"].steps
    assert len(ep["infos"]) == steps
    assert ep["trunc"] and not ep["term"]
    final = ep["infos"][-1]
    assert final["t"] == pytest.approx(steps * DT)
    assert final["rewards"]["collision"] == 0.0
    assert final["report"]["items"]["safety"]["collision"] is False
    assert final["qualified"] is True and final["score"] >= 60.0


def test_reward_prefers_following_to_parking_and_oscillating(cf_episodes):
    ret = {name: sum(ep["rewards"]) for name, ep in cf_episodes.items()}
    assert ret["linear"] > ret["park"], ret
    assert ret["linear"] > ret["bang"], ret
    assert ret["linear"] > 50.0, ret
    assert cf_episodes["park"]["infos"][-1]["qualified"] is False
    assert cf_episodes["bang"]["infos"][-1]["qualified"] is False


def hang_back(obs, time_gap=3.0) -> np.ndarray:
    """The linear ACC at twice the nominal time gap: safe but far behind the band."""
    v, _, gap, v_rel, seen, set_speed = (float(x) for x in obs[:6])
    if seen < 0.5:
        return to_action(0.5 * (set_speed - v))
    return to_action(min(1.2 * v_rel + 0.3 * (gap - 2.5 - time_gap * v), 0.5 * (set_speed - v)))


@pytest.mark.parametrize("kmh", [60, 90, 120])
def test_reward_ordering_at_every_test_speed(cf_env, kmh):
    """Following well earns more than parking, oscillating, hanging back or crawling, at each speed."""
    def run(policy):
        _, rewards, infos, term, trunc, _ = run_episode(cf_env, policy, seed=1,
                                                          options={"scenario": f"carfollowing/{kmh}"})
        return sum(rewards), infos[-1], term, trunc

    linear, final, term, trunc = run(lambda o, k: linear_acc(o))
    assert trunc and not term and final["qualified"] is True
    others = {
        "park": run(lambda o, k: np.array([-1.0], np.float32))[0],
        "bang": run(lambda o, k: np.array([1.0 if (k // 7) % 2 == 0 else -1.0], np.float32))[0],
        "hang-back": run(lambda o, k: hang_back(o))[0],
        "crawl": run(lambda o, k: to_action(0.5 * (3.0 - float(o[0]))))[0],
    }
    assert all(linear > r for r in others.values()), (linear, others)


def beyond_sensor_range(obs) -> np.ndarray:
    """Hangs back just out of the radar's view, cruising towards the set speed while nothing is seen."""
    v, _, gap, _, seen, set_speed = (float(x) for x in obs[:6])
    acc = (-1.0 if gap < 199.0 else 0.0) if seen > 0.5 else 0.5 * (set_speed - v)
    return to_action(float(np.clip(acc, -2.0, 1.0)))


def test_hanging_back_beyond_sensor_range_earns_nothing(cf_env):
    """reward.py: 'a followable vehicle ahead at any distance makes the step a following step, so
    hanging back out of sensor range earns nothing either'. Steps whose lead is followable
    (moving, not faster than the set speed + 1 m/s) must pay no positive term unless the ego
    really follows it."""
    obs, _ = cf_env.reset(seed=0, options={"scenario": "carfollowing/60"})
    world, set_speed = cf_env.unwrapped.core.world, cf_env.unwrapped.scenario.set_speed
    paid_while_hanging_back = 0.0
    while True:
        obs, _, term, trunc, info = cf_env.step(beyond_sensor_range(obs))
        v_lead = world.v[0, 1]
        followable = 1.0 < v_lead <= set_speed + 1.0
        if followable and true_gap(world) > 200.0:
            r = info["rewards"]
            paid_while_hanging_back += r["speed"] + r["band"] + r["efficiency"]
        if term or trunc:
            break
    assert info["qualified"] is False  # the score does punish it (band item fails, R1 = 0)
    assert paid_while_hanging_back == 0.0


def test_collision_terminates_with_collision_penalty(ncap_env):
    obs, rewards, infos, term, trunc, _ = run_episode(
        ncap_env, lambda o, k: np.array([0.0], np.float32), seed=0, options={"scenario": "ncap/ccrs/50"})
    assert term and not trunc
    assert len(infos) == 20  # 4 s TTC at constant speed: 20 steps of 0.2 s
    final = infos[-1]
    assert final["rewards"]["collision"] == -100.0
    assert rewards[-1] <= -100.0
    assert all(i["rewards"]["collision"] == 0.0 for i in infos[:-1])
    assert final["violation"] is True
    assert final["report"]["items"]["safety"]["collision"] is True
    assert final["qualified"] is False
    assert obs[-1][2] == 0.0  # the gap is clipped at 0 in the observation
    with pytest.raises(RuntimeError, match="reset"):
        ncap_env.step(np.array([0.0], np.float32))


def test_braking_in_time_avoids_the_ccrs_collision(ncap_env):
    obs, rewards, infos, term, trunc, _ = run_episode(
        ncap_env, lambda o, k: linear_acc(o), seed=0, options={"scenario": "ncap/ccrs/50"})
    assert trunc and not term
    assert all(i["rewards"]["collision"] == 0.0 for i in infos)
    assert min(float(o[2]) for o in obs) > 0.0


def test_terminate_on_violation_ends_a_tailgating_episode():
    env = gymnasium.make(CF, drivers="idm", terminate_on_violation=True)
    obs, rewards, infos, term, trunc, _ = run_episode(env, lambda o, k: tailgater(o), seed=0)
    assert term and not trunc
    assert len(infos) < 60
    final = infos[-1]
    assert final["violation"] is True
    assert final["rewards"]["collision"] == 0.0 and final["rewards"]["safety"] == -2.0
    assert obs[-1][2] > 1.0  # no collision: still metres apart
    assert final["report"]["items"]["safety"]["qualified"] is False
    assert final["report"]["items"]["safety"]["collision"] is False
    # the same tailgater without the option drives on past the first violation
    env2 = gymnasium.make(CF, drivers="idm")
    _, _, infos2, _, _, _ = run_episode(env2, lambda o, k: tailgater(o), seed=0)
    assert len(infos2) > len(infos)
    assert infos2[len(infos) - 1]["violation"] is True


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize("action", [np.zeros(1, np.float32), np.float32(0.3), 0.3, [0.3]],
                         ids=["(1,)", "0-d", "float", "list"])
def test_accepted_action_forms(ncap_env, action):
    """The source reshapes any single number to (1,) (check_actions: size 1, ndim <= 1)."""
    ncap_env.reset(seed=0, options={"scenario": "ncap/ccrm/50"})
    _, _, _, _, info = ncap_env.step(action)
    assert info["a_applied"] == pytest.approx(3.0 * float(np.asarray(action).reshape(-1)[0]), abs=1e-6)


@pytest.mark.parametrize("action, match", [
    (np.zeros(2, np.float32), r"shape \(1,\)"),
    (np.zeros((1, 1), np.float32), r"shape \(1,\)"),  # 2-D is rejected, not reshaped
    (np.zeros(0, np.float32), r"shape \(1,\)"),
    (np.array([np.nan], np.float32), "NaN"),
    (np.array([np.inf], np.float32), "finite"),
    ("fast", "numeric"),
], ids=["(2,)", "(1,1)", "(0,)", "nan", "inf", "str"])
def test_bad_actions_raise_value_error(ncap_env, action, match):
    ncap_env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        ncap_env.step(action)
    # the episode is untouched: a valid step still works from t = 0
    _, _, _, _, info = ncap_env.step(np.array([0.0], np.float32))
    assert info["t"] == pytest.approx(DT)


def test_step_before_reset():
    env = gymnasium.make(NCAP)
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.step(np.array([0.0], np.float32))
    with pytest.raises(gymnasium.error.ResetNeeded):  # the OrderEnforcing wrapper of make()
        env.step(np.array([0.0], np.float32))


def test_unknown_env_id():
    with pytest.raises(gymnasium.error.Error):
        gymnasium.make("acc_gym/Nope-v0")
    with pytest.raises(gymnasium.error.Error):
        gymnasium.make("acc_gym/NCAP-v9")


@pytest.mark.parametrize("as_dict", [False, True], ids=["EnvConfig", "dict"])
def test_explicit_config_scenarios_are_honoured_or_rejected(as_dict):
    """``gymnasium.make(id, config=...)``: the config's scenarios must be used -- or the
    conflict with the id's family reported -- never silently replaced by the family."""
    from acc_gym.envs.config import EnvConfig

    config = {"scenarios": ("ncap/ccrs/30",), "drivers": "idm"}
    try:
        env = gymnasium.make(CF, config=config if as_dict else EnvConfig(**config))
    except ValueError:
        return
    assert env.unwrapped.config.scenarios == ("ncap/ccrs/30",)
    _, info = env.reset(seed=0)
    assert info["scenario"] == "ncap/ccrs/30"


def test_config_object_fields_other_than_scenarios_are_used():
    from acc_gym.envs.config import EnvConfig

    env = gymnasium.make(NCAP, config=EnvConfig(decel_max=6.0, sensor_range=80.0, drivers="idm"))
    cfg = env.unwrapped.config
    assert cfg.decel_max == 6.0 and cfg.sensor_range == 80.0 and cfg.drivers == "idm"
    assert env.observation_space.high[2] == 80.0


def test_misspelt_setting_is_named():
    with pytest.raises(ValueError, match="sensor_rang"):
        gymnasium.make(CF, sensor_rang=5)


@pytest.mark.parametrize("kwargs, match", [
    ({"decel_max": -1.0}, r"decel_max.*-1\.0"),
    ({"accel_max": 0.0}, r"accel_max.*0\.0"),
    ({"sensor_range": float("nan")}, r"sensor_range.*nan"),
    ({"scenarios": "nope/1"}, "nope/1"),
    ({"scenarios": ()}, "scenarios"),
    ({"drivers": "robot"}, "robot"),
    ({"v2v": "yes"}, "v2v.*yes"),
    ({"weights": (1.0,)}, "weights"),
    ({"render_mode": "bogus"}, "bogus"),
], ids=lambda x: x if isinstance(x, str) else None)
def test_invalid_config_values_are_named(kwargs, match):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gymnasium.make itself warns about an unknown render_mode
        with pytest.raises(ValueError, match=match):
            gymnasium.make(CF, **kwargs)


# ---------------------------------------------------------------------------- rendering
def test_rgb_array_frames_change_as_vehicles_move():
    env = gymnasium.make(NCAP, render_mode="rgb_array")
    env.reset(seed=0, options={"scenario": "ncap/ccrs/30"})
    first = env.render()
    assert isinstance(first, np.ndarray) and first.dtype == np.uint8
    assert first.ndim == 3 and first.shape[2] == 3 and first.shape[0] > 0 and first.shape[1] > 0
    # the ego is drawn (blue: rendering.EGO)
    assert np.any(np.all(first == np.array([40, 110, 235], np.uint8), axis=2))
    again = env.render()
    assert np.array_equal(first, again)  # rendering does not change the state
    for _ in range(5):
        env.step(np.array([0.0], np.float32))
    later = env.render()
    assert later.shape == first.shape and later.dtype == np.uint8
    assert not np.array_equal(first, later)  # the target came 8 m closer


def test_render_without_render_mode_returns_none():
    env = gymnasium.make(NCAP)
    env.reset(seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert env.render() is None
    assert any("render_mode" in str(w.message) for w in caught)


def test_human_render_mode_shows_frames_and_closes():
    import matplotlib  # a core dependency: never skipped

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = gymnasium.make(NCAP, render_mode="human")
    try:
        env.reset(seed=0)
        viewer = env.unwrapped._viewer
        assert viewer is not None and viewer._fig is not None  # reset already showed a frame
        shown = viewer._image.get_array().copy()
        assert env.render() is None
        for _ in range(5):
            env.step(np.array([0.0], np.float32))
        assert not np.array_equal(shown, viewer._image.get_array())  # the window follows the steps
        fig = viewer._fig
    finally:
        env.close()
    assert env.unwrapped._viewer is None and not plt.fignum_exists(fig.number)


def test_a_declared_time_gap_judges_the_episode_and_bad_ones_are_named():
    """reset(options={"time_gap": h}): the per-step Gapsafe, the violations and the final score
    use tau1 = min(max(h, 0.8), nominal); the default (no option) is the scenario's gap."""
    from acc_gym.evaluation.scoring import judged_tau1

    cf_env = gymnasium.make(CF, drivers="idm")

    sc = build("carfollowing/90", seed=3)
    for declared in (None, 0.9, 0.3):
        options = {"scenario": sc} if declared is None else {"scenario": sc, "time_gap": declared}
        obs, _ = cf_env.reset(seed=0, options=options)
        tau1 = judged_tau1(sc.time_gap, declared, ScoringConfig())
        info = {}
        for _ in range(40):
            obs, _, term, trunc, info = cf_env.step(np.array([0.3], dtype=np.float32))
        v, v_rel = float(obs[0]), float(obs[3])
        v0 = v + v_rel
        assert info["gap_safe"] == pytest.approx(v * tau1 + v ** 2 / 16.0 - v0 ** 2 / 16.0, rel=1e-5, abs=1e-4)
        assert cf_env.unwrapped.core.trace(0).declared_time_gap == declared
    for bad in (float("nan"), -1.0, 0.0, "1.5", True):
        with pytest.raises(ValueError, match=r"options\['time_gap'\].*declared time gap.*> 0"):
            cf_env.reset(seed=0, options={"time_gap": bad})


def test_reward_fn_given_as_weights_sets_the_default_rewards_weights():
    """``reward_fn={...}`` (what a config file such as rl-zoo3's env_kwargs can hold) is the
    version's default reward with these weights, in the single and the vector env; an
    unknown weight or a value that is neither callable nor a mapping is named."""
    from acc_gym.envs.reward import CriteriaReward, MarginReward

    full = np.ones(1, dtype=np.float32)
    env = gymnasium.make("acc_gym/SingleLane-v1", reward_fn={"overspeed": 1.0})
    assert env.unwrapped.core.reward_fn == MarginReward(overspeed=1.0)
    env.reset(seed=0, options={"scenario": "singlelane/1/free-flow"})
    charged = []
    for _ in range(40):  # full throttle in free flow: past the set speed, the overspeed term charges
        obs, _, term, trunc, info = env.step(full)
        over = max(obs[0] - obs[5], 0.0) / (0.1 * obs[5])
        charged.append((info["rewards"]["overspeed"], -min(over, 5.0)))
        if term or trunc:
            break
    assert any(c < -1.0 for c, _ in charged)
    assert [c for c, _ in charged] == pytest.approx([h for _, h in charged], abs=1e-4)  # obs is float32
    plain = gymnasium.make("acc_gym/SingleLane-v1")
    plain.reset(seed=0, options={"scenario": "singlelane/1/free-flow"})
    assert plain.step(full)[4]["rewards"]["overspeed"] == 0.0  # off in the id's own reward
    vec = gymnasium.make_vec("acc_gym/CarFollowing-v1", num_envs=2, vectorization_mode="vector_entry_point",
                             reward_fn={"lag": 0.25})
    assert vec.core.reward_fn == MarginReward(lag=0.25)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert gymnasium.make("acc_gym/CarFollowing-v0", reward_fn={"band": 2.0}).unwrapped.core.reward_fn == \
            CriteriaReward(band=2.0)
        with pytest.raises(ValueError, match="overspeed"):  # the v0 reward has no such weight
            gymnasium.make("acc_gym/CarFollowing-v0", reward_fn={"overspeed": 1.0})
    with pytest.raises(ValueError, match="overspeeed"):
        gymnasium.make("acc_gym/CarFollowing-v1", reward_fn={"overspeeed": 1.0})
    with pytest.raises(ValueError, match="overspeed.*-1"):
        gymnasium.make("acc_gym/CarFollowing-v1", reward_fn={"overspeed": -1.0})
    with pytest.raises(TypeError, match="reward_fn.*str"):
        gymnasium.make("acc_gym/CarFollowing-v1", reward_fn="margin")
