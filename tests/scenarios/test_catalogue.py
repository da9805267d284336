"""Catalogue scenarios: paper 003's car-following test, Euro NCAP CCRs/CCRm/CCRb, stop-and-go."""

import math

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDM, IDMParams
from acc_gym.scenarios import build, list_scenarios, simulate

L = 4.7  # [m]
EPS = 1e-9


def idm_ego(sc):
    return IDM(IDMParams(v_desired=sc.set_speed), n=1, dt=sc.dt)


class ConstantSpeed:
    """An ego that never touches the pedals (asks for 0 m/s^2)."""

    n = 1

    def reset(self):
        pass

    def act(self, obs):
        return np.zeros(1)


def contact_time(tr):
    """Time of the first row where the ego's gap is <= 0 (nan if never)."""
    hit = tr.gap[:, 0, 0] <= 0.0
    return tr.t[int(np.argmax(hit))] if hit.any() else math.nan


# ----------------------------------------------------------------------------- paper 003
CF = [(kmh, seed) for kmh in (60, 90, 120) for seed in (0, 1)]


@pytest.fixture(scope="module")
def cf_runs():
    out = {}
    for kmh, seed in CF:
        sc = build(f"carfollowing/{kmh}", seed=seed, drivers="idm")
        out[kmh, seed] = sc, simulate(sc, idm_ego(sc))
    return out


@pytest.mark.parametrize("kmh,seed", CF)
def test_carfollowing_lead_profile(cf_runs, kmh, seed):
    sc, tr = cf_runs[kmh, seed]
    p = sc.params
    v_lim = kmh / 3.6
    assert p["speed_limit"] == kmh and sc.set_speed == pytest.approx(v_lim)
    assert sc.road.length == 1000.0 and sc.road.n_lanes == 1 and sc.road.lane_width == 3.75
    x, v, a = tr.x[:, 0, 1], tr.v[:, 0, 1], tr.a[:, 0, 1]
    # both at rest, the lead 20 m ahead (bumper to bumper)
    assert tr.v[0, 0].tolist()[:2] == [0.0, 0.0]
    assert tr.gap[0, 0, 0] == pytest.approx(20.0)
    # reaches the speed limit, never exceeds it
    assert v.max() == pytest.approx(v_lim, abs=0.05) and v.max() <= v_lim + 1e-6
    # stops with its front bumper 50 m before the end of the road, and stays there
    stop = p["road_length"] - p["stop_margin"]
    assert stop == 950.0
    assert x[-1] == pytest.approx(stop, abs=1.0)
    k_stop = int(np.argmax((v < 1e-9) & (np.arange(v.size) > np.argmax(v))))
    assert np.all(v[k_stop:] < 1e-9) and tr.t[-1] - tr.t[k_stop] >= p["hold"] - 2 * sc.dt
    # final braking at brake_decel (a hard stop, inside the tyre limit)
    assert 5.0 <= p["brake_decel"] <= 8.0
    braking = np.isclose(a, -p["brake_decel"], rtol=0, atol=1e-6)
    kb = int(np.argmax(braking))
    n_exp = v_lim / p["brake_decel"] / sc.dt
    assert braking.sum() >= n_exp - 2
    assert np.all(braking[kb + 1:k_stop - 1])  # one uninterrupted phase down to the stop
    # irregular: the accelerations vary (decelerations: see test_carfollowing_lead_decelerates_before_the_stop)
    pos = a[1:kb][a[1:kb] > 0.05]
    assert np.ptp(pos) > 0.2
    # scenario length: the profile plus the standing time
    assert tr.t[-1] == pytest.approx(sc.duration, abs=sc.dt / 2)


def _decelerations_before_final_stop(sc):
    """Slopes [m/s^2] of the lead's scripted profile before its final braking."""
    d = sc.vehicles[1].driver
    slopes = np.diff(d.speeds) / np.diff(d.times)
    k_final = np.flatnonzero(np.isclose(slopes, -sc.params["brake_decel"]))[-1]
    return slopes[:k_final]


@pytest.mark.parametrize("kmh", [60, 90, 120])
def test_carfollowing_lead_decelerates_before_the_stop(kmh):
    """Paper 003: the lead reaches the limit 'with irregular accelerations and decelerations'."""
    for seed in range(30):
        sc = build(f"carfollowing/{kmh}", seed=seed, drivers="idm")
        slopes = _decelerations_before_final_stop(sc)
        assert slopes.min() < -0.1, f"seed {seed}: no deceleration before the final stop"


def test_carfollowing_seeds_are_different_drivers():
    a, b = build("carfollowing/90", seed=0), build("carfollowing/90", seed=1)
    assert a.vehicles[1].driver.speeds != b.vehicles[1].driver.speeds
    assert a.vehicles[1].driver.model == "profile"  # scripted whatever the drivers choice


def test_carfollowing_idm_ego_follows_to_the_stop(cf_runs):
    sc, tr = cf_runs[90, 0]
    assert not tr.collided.any()
    assert tr.v[-1, 0, 0] < 1.0 and 0.0 < tr.gap[-1, 0, 0] < 10.0  # (IDM creeps up to its standstill gap)
    assert tr.x[:, 0, 0].max() < 950.0 - L


# ----------------------------------------------------------------------------- NCAP
def test_ncap_ids():
    ids = list_scenarios("ncap")
    expected = ([f"ncap/ccrs/{v}" for v in range(10, 55, 5)] + [f"ncap/ccrm/{v}" for v in range(30, 85, 5)]
                + [f"ncap/ccrb/{d}-{g}" for d in (2, 6) for g in (12, 40)])
    assert sorted(ids) == sorted(expected)
    assert (len([i for i in ids if "/ccrs/" in i]), len([i for i in ids if "/ccrm/" in i]),
            len([i for i in ids if "/ccrb/" in i])) == (9, 11, 4)


@pytest.mark.parametrize("v", range(10, 55, 5))
def test_ccrs_layout(v):
    sc = build(f"ncap/ccrs/{v}")
    sv, target = sc.vehicles
    assert sv.v0 == pytest.approx(v / 3.6) and target.v0 == 0.0 and sc.set_speed == pytest.approx(v / 3.6)
    gap = target.x0 - target.length - sv.x0
    assert gap == pytest.approx(4.0 * v / 3.6)  # TTC 4 s
    assert target.driver.model == "profile" and max(target.driver.speeds) == 0.0


@pytest.mark.parametrize("v", range(30, 85, 5))
def test_ccrm_layout(v):
    sc = build(f"ncap/ccrm/{v}")
    sv, target = sc.vehicles
    assert target.v0 == pytest.approx(20 / 3.6) and np.allclose(target.driver.speeds, 20 / 3.6)
    gap = target.x0 - target.length - sv.x0
    assert gap / (sv.v0 - target.v0) == pytest.approx(4.0)  # TTC 4 s
    assert sc.duration == 25.0


@pytest.fixture(scope="module")
def ccrb_runs():
    out = {}
    for sid in [i for i in list_scenarios("ncap") if "/ccrb/" in i]:
        sc = build(sid)
        out[sid] = sc, simulate(sc, ConstantSpeed())
    return out


@pytest.mark.parametrize("d,g", [(2, 12), (2, 40), (6, 12), (6, 40)])
def test_ccrb_target_brakes_as_stated(ccrb_runs, d, g):
    sc, tr = ccrb_runs[f"ncap/ccrb/{d}-{g}"]
    v0 = 50 / 3.6
    assert sc.params["decel"] == d and sc.params["t_brake"] == 2.0
    assert tr.gap[0, 0, 0] == pytest.approx(g) and tr.v[0, 0].tolist()[:2] == pytest.approx([v0, v0])
    t, v, a = tr.t, tr.v[:, 0, 1], tr.a[:, 0, 1]
    assert np.allclose(v[t <= 2.0 + EPS], v0)  # holds 50 km/h for 2 s
    t_stop = 2.0 + v0 / d
    braking = (t > 2.0 + EPS) & (t < t_stop - EPS)
    # rows fully inside the braking phase: exactly -d (a row's acceleration is the step ending there)
    inside = braking & (t - sc.dt > 2.0 - EPS)
    assert inside.sum() >= 3
    assert np.allclose(a[inside], -d)
    assert np.allclose(v[braking], v0 - d * (t[braking] - 2.0), atol=1e-9)
    assert np.all(v[t >= t_stop - EPS] < 1e-9)
    # a constant-speed ego hits it when 1/2 d tau^2 (+ the standing part) closes the gap
    tau_meet = math.sqrt(2 * g / d)
    if tau_meet <= v0 / d:
        t_hit = 2.0 + tau_meet
    else:
        t_hit = t_stop + (g - v0 ** 2 / (2 * d)) / v0
    assert tr.collided[0, 0]
    assert t_hit <= contact_time(tr) + EPS <= t_hit + sc.dt + 2 * EPS


@pytest.mark.parametrize("sid", ["ncap/ccrs/10", "ncap/ccrs/30", "ncap/ccrs/50", "ncap/ccrm/30", "ncap/ccrm/80"])
def test_constant_speed_ego_collides_at_the_ttc(sid):
    sc = build(sid)
    tr = simulate(sc, ConstantSpeed())
    assert tr.collided[0, 0]
    assert np.allclose(tr.v[:, 0, 0], sc.vehicles[0].v0)
    assert 4.0 - 1e-6 <= contact_time(tr) <= 4.0 + sc.dt + 1e-6  # the initial TTC


def test_idm_ego_stops_behind_stationary_target():
    sc = build("ncap/ccrs/30")
    tr = simulate(sc, idm_ego(sc))
    assert not tr.collided.any()
    assert tr.v[-1, 0, 0] < 0.01 and 0.0 < tr.gap[-1, 0, 0] < 5.0
    assert np.all(tr.x[:, 0, 1] == tr.x[0, 0, 1])  # the target never moved


# ----------------------------------------------------------------------------- stop-and-go
@pytest.fixture(scope="module")
def sng():
    sc = build("stopandgo", seed=0, drivers="idm")
    return sc, simulate(sc, idm_ego(sc))


def _stops(v, thr, moved=2.0):
    """Number of times ``v`` falls to ``thr`` or below after having exceeded ``moved``."""
    has_moved = np.maximum.accumulate(v) > moved
    s = (v <= thr) & has_moved
    return int(np.sum(s[1:] & ~s[:-1]))


def test_stop_and_go_wave(sng):
    sc, tr = sng
    assert sc.n_vehicles == 3 and sc.duration == 120.0 and sc.set_speed == 20.0
    assert [v.v0 for v in sc.vehicles] == [0.0, 0.0, 0.0]
    assert tr.gap[0, 0, 0] == pytest.approx(5.0) and tr.gap[0, 0, 1] == pytest.approx(5.0)
    assert sc.vehicles[2].driver.model == "profile" and sc.vehicles[1].driver.model == "idm"
    v2 = tr.v[:, 0, 2]
    assert _stops(v2, 1e-6) >= 3  # POV2 stops several times ...
    dt = sc.dt
    still = v2 < 1e-6
    runs, run = [], 0
    for s in still:
        if s:
            run += 1
        else:
            if run:
                runs.append(run)
            run = 0
    assert sum(r * dt >= 2.0 - EPS for r in runs) >= 3  # ... and stands still for seconds each time
    assert v2.max() <= 15.0 + 1e-6


def test_ego_stops_and_goes_without_collision(sng):
    sc, tr = sng
    v0 = tr.v[:, 0, 0]
    assert not tr.collided.any()
    assert np.all(tr.gap[:, 0, 0] > 1.0) and np.all(tr.lead[:, 0, 0] == 1) and np.all(tr.lead[:, 0, 1] == 2)
    assert v0.max() > 4.0  # it goes ...
    assert _stops(v0, 0.5) >= 2  # ... and is brought (nearly) to a standstill repeatedly
    assert _stops(tr.v[:, 0, 1], 0.1) >= 2  # so is the POV between them


@pytest.mark.parametrize("seed", [179, 300, 2860])
def test_carfollowing_120_start_up_that_leaves_no_room_is_drawn_again(seed):
    """These seeds once drew a start-up that left no room to brake (an error that crashed a training run)."""
    from acc_gym.scenarios import build, simulate
    from acc_gym.drivers.baselines import IDM, IDMParams

    sc = build("carfollowing/120", seed=seed, drivers="idm")
    tr = simulate(sc, IDM(IDMParams(v_desired=sc.set_speed), n=1, dt=sc.dt))
    assert tr.v[:, 0, 1].max() == pytest.approx(sc.set_speed, abs=0.05)
    assert tr.x[-1, 0, 1] == pytest.approx(950.0, abs=1.0) and tr.v[-1, 0, 1] == 0.0
    with pytest.raises(ValueError, match="road is too short"):
        build("carfollowing/120", {"road_length": 300.0}, seed=seed)


# ----------------------------------------------------------------------------- emergency stops (training)
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_emergency_layout_and_lead_profile(seed):
    """``carfollowing/emergency``: steady following, then the lead brakes at ``brake_decel``
    to a stop and stands for ``hold``; every number below is recomputed from the params."""
    sc = build("carfollowing/emergency", seed=seed)
    p = sc.params
    ego, lead = sc.vehicles
    v_lead = p["speed_limit"] / 3.6
    assert 40.0 <= p["speed_limit"] <= 130.0 and 1.0 <= p["headway"] <= 3.0 and -2.0 <= p["v_rel"] <= 2.0
    assert 1.0 <= p["t_brake"] <= 6.0 and 3.0 <= p["brake_decel"] <= 8.0 and p["hold"] == 4.0
    assert ego.v0 == pytest.approx(v_lead - p["v_rel"]) and lead.v0 == pytest.approx(v_lead)
    assert sc.set_speed == pytest.approx(v_lead) and sc.time_gap == 1.5
    assert lead.x0 - lead.length - ego.x0 == pytest.approx(p["headway"] * ego.v0)  # bumper to bumper
    t_stop = p["t_brake"] + v_lead / p["brake_decel"]
    assert lead.driver.model == "profile"
    assert np.allclose(lead.driver.times, [0.0, p["t_brake"], t_stop, t_stop + 4.0])
    assert np.allclose(lead.driver.speeds, [v_lead, v_lead, 0.0, 0.0])
    assert sc.duration == pytest.approx(t_stop + 4.0)
    x_stop = lead.x0 + v_lead * p["t_brake"] + v_lead ** 2 / (2 * p["brake_decel"])
    assert sc.road.length == pytest.approx(x_stop + 100.0)
    # the simulated lead brakes as stated and stops where computed
    tr = simulate(sc, ConstantSpeed())
    assert tr.x[-1, 0, 1] == pytest.approx(x_stop, abs=0.5 * v_lead * sc.dt)
    assert np.isclose(tr.a[:, 0, 1], -p["brake_decel"], rtol=0, atol=1e-6).sum() >= v_lead / p["brake_decel"] / sc.dt - 2


def test_emergency_parameters_are_checked():
    with pytest.raises(ValueError, match=r"v_rel 12\.0 m/s of 'carfollowing/emergency' leaves the ego no speed"):
        build("carfollowing/emergency", {"speed_limit": 40.0, "v_rel": 12.0})
    with pytest.raises(ValueError, match="'headway' of 'carfollowing/emergency' must be > 0"):
        build("carfollowing/emergency", {"headway": -1.0})


def test_every_corner_of_the_emergency_family_is_preventable():
    """The careful and competent driver of UN R157 (``cc-driver``) stops behind the lead in
    each of the family's 16 corners (40/130 km/h, 1/3 s behind, 2 m/s^2 closing or opening,
    3/8 m/s^2), braking 1 s after the start: the family trains avoidable stops only."""
    import itertools

    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller, run_episode

    env = gym.make("acc_gym/CarFollowing-v1")
    driver = load_controller("cc-driver")
    gaps = []
    for kmh, hw, vr, dec in itertools.product((40.0, 130.0), (1.0, 3.0), (-2.0, 2.0), (3.0, 8.0)):
        sc = build("carfollowing/emergency", {"speed_limit": kmh, "headway": hw, "v_rel": vr, "t_brake": 1.0,
                                              "brake_decel": dec}, seed=0)
        info, tr = run_episode(env, driver, scenario=sc, record=True)
        assert not info["report"]["metrics"]["collision"], (kmh, hw, vr, dec)
        gaps.append(float(tr.gap[:, 0, 0].min()))  # [m] closest approach (it ends creeping to its standstill gap)
    env.close()
    assert min(gaps) > 1.0, gaps
