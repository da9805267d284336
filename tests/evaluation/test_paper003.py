"""Paper 003's car-following test under the default scoring rules.

A linear ACC (paper 004 Eq. 1: a = k2 e_v + k1 e_x, spacing s0 + h v) tuned k1 = 0.3 1/s^2,
k2 = 1.2 1/s, s0 = 2.5 m, h = 1.5 s (the scenario's nominal time gap) qualifies at 60, 90 and
120 km/h (120 of 120 runs over seeds 0-39 when this was written; three seeds here); a
follower holding a 0.5 s time gap does not, nor does one that collides. Read literally, the
rules fail even the ACC (why the defaults differ; see acc_gym.evaluation.scoring).
"""

import numpy as np
import pytest

from acc_gym import scenarios
from acc_gym.drivers import ACC, ACCParams
from acc_gym.evaluation import EgoTrace, ScoringConfig, score_episode

SEEDS = (0, 1, 2)
IDS = ("carfollowing/60", "carfollowing/90", "carfollowing/120")


class CruiseOnly:
    """Ignores the vehicle ahead: holds the set speed (collides when the lead stops)."""

    def __init__(self, v_set):
        self.n, self.v_set, self.info = 1, v_set, {}

    def reset(self):
        pass

    def act(self, obs):
        return np.clip(0.5 * (self.v_set - obs.v), -2.0, 2.0)


def controllers(sc):
    v = sc.set_speed
    return {
        "acc": ACC(ACCParams(k1=0.3, k2=1.2, s0=2.5, time_gap=sc.time_gap, v_set=v), n=1, dt=sc.dt),
        "tailgater": ACC(ACCParams(k1=0.5, k2=1.0, s0=2.0, time_gap=0.5, v_set=v), n=1, dt=sc.dt),
        "collider": CruiseOnly(v),
    }


@pytest.fixture(scope="module")
def reports():
    out = {}
    for sid in IDS:
        for seed in SEEDS:
            sc = scenarios.build(sid, seed=seed)
            for name, ego in controllers(sc).items():
                trace = EgoTrace.from_world(scenarios.simulate(sc, ego), 0, sc)
                out[sid, seed, name] = (score_episode(trace), score_episode(trace, ScoringConfig.literal()))
    return out


@pytest.mark.parametrize("sid", IDS)
def test_well_tuned_acc_qualifies(reports, sid):
    for seed in SEEDS:
        r, literal = reports[sid, seed, "acc"]
        assert r.qualified, (seed, r.summary())
        assert 60.0 < r.score <= 100.0
        assert not r.metrics["collision"]
        assert not literal.qualified  # the literal safety rule fails it during the emergency stop
        assert not literal.item("safety").qualified


@pytest.mark.parametrize("sid", IDS)
def test_tailgater_does_not_qualify(reports, sid):
    for seed in SEEDS:
        r, _ = reports[sid, seed, "tailgater"]
        assert not r.qualified and r.score <= 45.0
        assert not r.item("safety").qualified
        assert r.item("safety").detail["violations"] > 0
        assert r.metrics["share_safe_spacing"] < 0.5


@pytest.mark.parametrize("sid", IDS)
def test_colliding_follower_does_not_qualify(reports, sid):
    for seed in SEEDS:
        r, literal = reports[sid, seed, "collider"]
        assert r.metrics["collision"]
        assert not r.item("safety").qualified and not r.qualified
        assert not literal.qualified



@pytest.fixture(scope="module")
def gipps_runs():
    """Gipps through the environment, as `acc-gym evaluate` drives it (its declared time gap
    passed on), and each trace scored again at the scenario's 1.5 s."""
    import gymnasium as gym

    from acc_gym.evaluation.runner import load_controller, run_episode

    env = gym.make("acc_gym/CarFollowing-v0")
    out = {}
    for sid in IDS:
        for seed in SEEDS:
            info, _ = run_episode(env, "gipps", scenario=scenarios.build(sid, seed=seed), record=False)
            trace = env.unwrapped.core.trace(0)
            out[sid, seed] = (info["report"], score_episode(trace, ScoringConfig(tau1=1.5)))
    return out, load_controller("gipps")


@pytest.mark.parametrize("sid", IDS)
def test_gipps_is_judged_at_its_own_reaction_time(gipps_runs, sid):
    """Paper 003 judges Gipps with its Gapsafe at the driver's own reaction time: ours declares
    tau + theta = 0.6 + 0.3 s. There it is safe in every run; at 1.5 s -- a gap it does not
    keep -- it fails safety in most (the verdicts of benchmarks/safety_rules.py, seeds 100-111:
    12/12 safe at 0.9 s at every speed; at 1.5 s 0/12, 1/12 and 2/12 safe)."""
    runs, controller = gipps_runs
    assert controller.time_gap == pytest.approx(0.9)
    at_own = [runs[sid, seed][0] for seed in SEEDS]
    at_nominal = [runs[sid, seed][1] for seed in SEEDS]
    for r in at_own:
        assert r["tau1"] == pytest.approx(0.9)
        assert r["items"]["safety"]["qualified"] and not r["metrics"]["collision"]
    assert sum(r.item("safety").qualified for r in at_nominal) <= 1
    # the band is judged at 0.9 s too: Gipps (b = -3, b_hat = -3.5) follows at 0.9 s + v / 42 s,
    # 1.3-1.7 s here, beyond 1.2 x 0.9 s -- so it is not qualified on car following at its own gap
    assert all(not r["items"]["car_following"]["qualified"] for r in at_own)
