"""Paper 004's single-lane configurations: each builds, runs to its end and shows its defining event.

Every id is run with baseline (IDM) surrounding drivers and an IDM ego at the scenario's
set speed; the events are read from the recorded WorldTrace: ``trace.lead[:, 0, s]`` is the
slot vehicle ``s`` follows (-1: none), ``trace.gap`` the true bumper gap to it.
"""

import math

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDM, IDMParams
from acc_gym.scenarios import build, list_scenarios, simulate
from acc_gym.scenarios.singlelane import EGO_LANE, MERGE_LANE, SIDE_LANE, entry_gap

SINGLE = list_scenarios("singlelane")
SEEDS = (0, 1, 2)
LW = 3.75  # [m] lane width (three lanes: 0 the SV's merge lane, 1 the lane under study, 2 for cut-ins/outs)
W = 1.8  # [m] vehicle width
L = 4.7  # [m] vehicle length
# phase of a half-cosine move at which a vehicle's contour crosses the lane line, seen from
# a vehicle centred in the destination lane: LW (1 + cos(pi s)) / 2 = (LW + W) / 2
S_IN = math.acos((LW + W) / LW - 1.0) / math.pi  # ~0.34: entering the corridor
S_OUT = 1.0 - S_IN  # ~0.66: leaving it
EPS = 1e-9


def ego_for(sc):
    return IDM(IDMParams(v_desired=sc.set_speed), n=1, dt=sc.dt)


@pytest.fixture(scope="module")
def runs():
    out = {}
    for sid in SINGLE:
        for seed in SEEDS:
            sc = build(sid, seed=seed, drivers="idm")
            out[sid, seed] = sc, simulate(sc, ego_for(sc))
    return out


def parts(sid):
    n, rel = sid.split("/")[1:]
    p = rel.split("+")
    return int(n), p[0], (p[1] if len(p) > 1 else None)


def first(mask):
    assert mask.any(), "the event never happens"
    return int(np.argmax(mask))


def assert_switch_near(tr, k, t_event, dt):
    """Row ``k`` is the first sampled at or after the analytic event time."""
    assert tr.t[k] - dt - EPS <= t_event <= tr.t[k] + EPS, (tr.t[k], t_event)


# ----------------------------------------------------------------------------- every id
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("sid", SINGLE)
def test_runs_to_its_end(runs, sid, seed):
    sc, tr = runs[sid, seed]
    n, _, _ = parts(sid)
    assert sc.n_vehicles == n
    assert tr.t.size == sc.steps + 1 and abs(tr.t[-1] - sc.duration) <= sc.dt / 2 + EPS
    for key in ("x", "v", "a", "y", "a_y"):
        assert np.isfinite(getattr(tr, key)).all(), key
    assert np.isfinite(tr.a_des[1:]).all()
    assert tr.present[0].tolist() == [True] * n + [False] * (3 - n)
    assert np.all(tr.v[:, 0, :n] >= 0.0)
    # initial state as specified; the ego's set speed is its initial speed
    for s, v in enumerate(sc.vehicles):
        assert tr.x[0, 0, s] == v.x0 and tr.v[0, 0, s] == v.v0 and tr.y[0, 0, s] == v.lane * LW
    assert sc.set_speed == sc.vehicles[0].v0 == sc.params["v_sv"]
    assert sc.time_gap == 1.5
    for v in sc.vehicles[1:]:  # surrounding drivers want their initial speed
        assert v.driver.model == "idm" and v.driver.params["v_desired"] == pytest.approx(max(v.v0, 0.5))
    # duration: the drawn one, extended to 4 s after the last lateral move
    ends = [v.lane_change.t_start + v.lane_change.duration for v in sc.vehicles if v.lane_change]
    assert sc.duration == pytest.approx(max([sc.params["duration"]] + [e + 4.0 for e in ends]))
    for v, s in zip(sc.vehicles, range(n)):  # every lateral move completes within the run
        if v.lane_change:
            assert tr.y[-1, 0, s] == pytest.approx(v.lane_change.to_lane * LW)


@pytest.mark.parametrize("sid", SINGLE)
def test_layout_follows_the_parameters(sid):
    """Gaps are bumper to bumper; for a lane entry the gap (raised to the survivable floor)
    holds when the entering vehicle becomes the follower's target, at phase S_IN of its move."""
    n, a, b = parts(sid)
    sc = build(sid, seed=4, drivers="idm")
    p = sc.params
    if n == 1:
        return
    sv, pov = sc.vehicles[:2]
    dx = pov.x0 - L - sv.x0
    dv = pov.v0 - sv.v0
    if a in ("cut-in", "lane-change"):
        if not (a == "lane-change" and n == 3):  # (that SV is placed by simulating the others: see below)
            t_entry = p["t_lc"] + S_IN * p["lc_duration"]
            assert dx + dv * t_entry == pytest.approx(entry_gap(p["gap"], sv.v0, pov.v0))
            assert entry_gap(p["gap"], sv.v0, pov.v0) >= p["gap"]
    else:
        assert dx == pytest.approx(p["gap"])
    expected_dv = {"car-following": p.get("v_rel"), "cut-in": p.get("v_rel"), "cut-out": p.get("v_rel"),
                   "lane-change": p.get("v_rel"), "approach": -p.get("closing", 0), "separate": p.get("opening")}[a]
    assert dv == pytest.approx(expected_dv)
    if b is not None:
        pov2 = sc.vehicles[2]
        dx2, dv2 = pov2.x0 - L - pov.x0, pov2.v0 - pov.v0
        if b == "cut-in":
            assert dx2 + dv2 * (p["t_lc2"] + S_IN * p["lc_duration2"]) == pytest.approx(entry_gap(p["gap2"], pov.v0,
                                                                                                   pov2.v0))
        else:
            assert dx2 == pytest.approx(p["gap2"])
        assert dv2 == pytest.approx(-p["closing2"] if b == "approach" else p["v_rel2"])


# ----------------------------------------------------------------------------- SV-POV events
def check_sv_lane_change(sc, tr, pov_pov2):
    sv = sc.vehicles[0]
    lc = sv.lane_change
    assert sv.lane == MERGE_LANE and lc.to_lane == EGO_LANE
    y, a_y, t = tr.y[:, 0, 0], tr.a_y[:, 0, 0], tr.t
    assert y[0] == pytest.approx(0.0) and y[-1] == pytest.approx(LW)
    inside = (t > lc.t_start + EPS) & (t < lc.t_start + lc.duration - EPS)
    assert np.all(a_y[inside] != 0.0) and np.all(a_y[~inside] == 0.0)
    peak = LW * math.pi ** 2 / (2 * lc.duration ** 2)
    assert 0.8 * peak < np.max(np.abs(a_y)) <= peak + EPS
    assert np.all(np.diff(y) >= -EPS)
    lead = tr.lead[:, 0, 0]
    if sc.n_vehicles == 1:
        assert np.all(lead == -1)
        return
    if pov_pov2 == "lane-change":  # both change lanes: the SV ends behind POV2
        assert lead[-1] == 2
        return
    k = first(lead == 1)
    assert_switch_near(tr, k, lc.t_start + S_IN * lc.duration, sc.dt)
    assert np.all(lead[k:] == 1)
    assert np.all(lead[:k] == -1)  # nothing ahead in the merge lane
    # the gap at entry is the stated one (raised to the survivable floor), whatever the POV did before
    t_entry = lc.t_start + S_IN * lc.duration
    g_entry = np.interp(t_entry, tr.t[k - 1:k + 1], [tr.gap[k, 0, 0] + (tr.v[k, 0, 0] - tr.v[k, 0, 1]) * (
        tr.t[k] - tr.t[k - 1]), tr.gap[k, 0, 0]])
    v_pov_entry = np.interp(t_entry, tr.t, tr.v[:, 0, 1])
    assert g_entry == pytest.approx(entry_gap(sc.params["gap"], sc.params["v_sv"], v_pov_entry), abs=0.3)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("sid", SINGLE)
def test_sv_pov_event(runs, sid, seed):
    sc, tr = runs[sid, seed]
    n, kind, pov_pov2 = parts(sid)
    p, t, dt = sc.params, tr.t, sc.dt
    lead, gap, v = tr.lead[:, 0, 0], tr.gap[:, 0, 0], tr.v[:, 0]
    # when the POV leaves (POV-POV2 lane change), the SV-POV relation lasts until then
    until = len(t) if pov_pov2 != "lane-change" else first(lead == 2)
    if kind == "free-flow":
        assert np.all(lead == -1) and np.all(np.isinf(gap))
        assert np.allclose(v[:, 0], sc.set_speed)  # nothing ahead: IDM cruises at the set speed
    elif kind == "lane-change":
        check_sv_lane_change(sc, tr, pov_pov2)
    elif kind == "car-following":
        assert np.all(lead[:until] == 1)
        assert abs(v[0, 1] - v[0, 0]) <= 4.0 and v[0, 1] - v[0, 0] == pytest.approx(p["v_rel"])
        assert gap[0] == pytest.approx(p["gap"])
    elif kind == "approach":
        assert v[0, 0] - v[0, 1] >= 1.0 - EPS  # closing speed at the start
        k1 = int(round(1.0 / dt))
        assert np.all(lead[:k1 + 1] == 1)
        # the gap shrinks at first (the ego may soon brake the closing speed away)
        assert gap[1] < gap[0] and np.min(gap[1:k1 + 1]) < gap[0] - 0.1
        assert gap[0] == pytest.approx(p["gap"])
    elif kind == "separate":
        assert v[0, 1] - v[0, 0] == pytest.approx(p["opening"]) and p["opening"] > 0
        assert np.all(lead == 1) and np.all(np.diff(gap) > 0)  # the gap grows
    elif kind == "cut-in":
        pov = sc.vehicles[1]
        assert pov.lane == SIDE_LANE and pov.lane_change.to_lane == EGO_LANE
        assert np.all(lead[t <= p["t_lc"]] == -1)  # nothing ahead before the POV moves
        k = first(lead == 1)
        assert_switch_near(tr, k, p["t_lc"] + S_IN * p["lc_duration"], dt)
        assert p["t_lc"] < t[k] < p["t_lc"] + p["lc_duration"]
        assert np.isinf(gap[k - 1]) and np.isfinite(gap[k])  # the gap jumps from inf to finite
        assert np.all(lead[k:] == 1)
        assert tr.a_y[k, 0, 1] != 0.0  # the POV is mid-move when it becomes the target
    elif kind == "cut-out":
        pov = sc.vehicles[1]
        assert pov.lane == EGO_LANE and pov.lane_change.to_lane == SIDE_LANE
        assert np.all(lead[t <= p["t_lc"]] == 1)
        k = first(lead != 1)
        assert_switch_near(tr, k, p["t_lc"] + S_OUT * p["lc_duration"], dt)
        assert np.all(lead[k:] == -1) and np.isinf(gap[k])
    else:  # pragma: no cover
        raise AssertionError(kind)


# ----------------------------------------------------------------------------- POV-POV2 events
THREE = [i for i in SINGLE if i.startswith("singlelane/3/")]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("sid", THREE)
def test_pov_pov2_event(runs, sid, seed):
    sc, tr = runs[sid, seed]
    _, sv_pov, kind = parts(sid)
    p, t, dt = sc.params, tr.t, sc.dt
    lead_pov, gap_pov, v = tr.lead[:, 0, 1], tr.gap[:, 0, 1], tr.v[:, 0]
    if kind == "car-following":
        assert np.all(lead_pov == 2)
        assert abs(v[0, 2] - v[0, 1]) <= 4.0 and v[0, 2] - v[0, 1] == pytest.approx(p["v_rel2"])
        assert gap_pov[0] == pytest.approx(p["gap2"])
    elif kind == "approach":
        assert v[0, 1] - v[0, 2] >= 1.0 - EPS  # the POV closes on POV2
        k1 = int(round(1.0 / dt))
        assert gap_pov[1] < gap_pov[0] and np.min(gap_pov[1:k1 + 1]) < gap_pov[0] - 0.1
        assert np.all(lead_pov == 2)
    elif kind == "cut-in":
        assert sc.vehicles[2].lane == SIDE_LANE and sc.vehicles[2].lane_change.to_lane == EGO_LANE
        assert np.all(lead_pov[t <= p["t_lc2"]] == -1)
        k = first(lead_pov == 2)
        assert_switch_near(tr, k, p["t_lc2"] + S_IN * p["lc_duration2"], dt)
        assert np.all(lead_pov[k:] == 2)
    elif kind == "cut-out":
        assert sc.vehicles[2].lane == EGO_LANE and sc.vehicles[2].lane_change.to_lane == SIDE_LANE
        assert np.all(lead_pov[t <= p["t_lc2"]] == 2)
        k = first(lead_pov != 2)
        assert_switch_near(tr, k, p["t_lc2"] + S_OUT * p["lc_duration2"], dt)
        assert np.all(lead_pov[k:] == -1)
    elif kind == "lane-change":  # the POV leaves; the SV is left behind POV2 (paper 004, Example 1)
        pov = sc.vehicles[1]
        assert pov.lane == EGO_LANE and pov.lane_change.to_lane == SIDE_LANE and sc.vehicles[2].lane == EGO_LANE
        lead_sv = tr.lead[:, 0, 0]
        assert lead_sv[-1] == 2 and tr.y[-1, 0, 1] == pytest.approx(SIDE_LANE * LW)
        if sv_pov != "lane-change":
            assert lead_sv[0] == 1
            k = first(lead_sv == 2)
            assert np.all(lead_sv[:k] == 1) and np.all(lead_sv[k:] == 2)
            assert_switch_near(tr, k, p["t_lc2"] + S_OUT * p["lc_duration2"], dt)
            assert tr.gap[k, 0, 0] > tr.gap[k - 1, 0, 0]  # the new target is further away
    else:  # pragma: no cover
        raise AssertionError(kind)


# ----------------------------------------------------------------------------- feasibility
ENTRY_CASES = ["singlelane/2/cut-in", "singlelane/3/lane-change+approach", "singlelane/3/lane-change+lane-change"]


@pytest.mark.parametrize("sid", ENTRY_CASES)
def test_entering_vehicle_is_ahead_of_the_ego_when_it_becomes_its_target(sid):
    for seed in range(40):
        sc = build(sid, seed=seed, drivers="idm")
        tr = simulate(sc, ego_for(sc))
        lead = tr.lead[:, 0, 0]
        k = first(lead >= 1)
        # (in lane-change+lane-change the POV may have left before the SV merges: then POV2 is first)
        assert lead[k] in ((1, 2) if sid.endswith("+lane-change") else (1,)), f"seed {seed}: first target {lead[k]}"
        assert tr.gap[k, 0, 0] > 1.0, f"seed {seed}: gap {tr.gap[k, 0, 0]:.2f} m when the POV enters"
        assert not tr.collided[0, 0], f"seed {seed}: the IDM ego collided"


# ----------------------------------------------------------------------------- MPC drivers
def test_default_mpc_drivers_run_and_report_modes():
    sc = build("singlelane/3/car-following+cut-in", seed=1)  # drivers="typical": human-like MPC drivers
    assert [v.driver.model for v in sc.vehicles[1:]] == ["mpc", "mpc"]
    tr = simulate(sc, ego_for(sc))
    assert np.isfinite(tr.x).all() and np.isfinite(tr.v).all()
    assert np.all(tr.mode[1:, 0, 1:] >= 0) and np.all(tr.mode[0] == -1)
    assert np.all(tr.mode[:, 0, 0] == -1)  # the IDM ego has no modes
    for s in (1, 2):
        assert tr.solver_stats[s]["steps"].tolist() == [sc.steps]
    # the event still happens with MPC drivers: POV2 cuts in in front of the POV
    p = sc.params
    k = first(tr.lead[:, 0, 1] == 2)
    assert_switch_near(tr, k, p["t_lc2"] + S_IN * p["lc_duration2"], sc.dt)
    assert np.all(tr.lead[:, 0, 0] == 1)
    # the MPC POV responds: its speed is not constant
    assert np.ptp(tr.v[:, 0, 1]) > 0.05
