"""SingleLaneWorld: lateral plans, road geometry, target selection, two-phase stepping, recording, errors."""

import math

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDM, IDMParams
from acc_gym.drivers.scripted import ProfileDriver
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import LateralPlan, Road, SingleLaneWorld, rollout
from acc_gym.vehicle import VehicleParams

LW = 3.75  # [m] lane width
L = VehicleParams().length  # 4.7 m


class Const:
    """A driver model asking for a constant acceleration; records what it saw."""

    def __init__(self, n=1, a=0.0):
        self.n, self.a, self.seen = n, a, []

    def reset(self):
        self.seen = []

    def act(self, obs):
        self.seen.append(obs)
        return np.full(self.n, self.a)


# ----------------------------------------------------------------------------- LateralPlan
def test_lateral_plan_half_cosine_positions():
    p = LateralPlan(np.array(0.0), np.array(LW), np.array(2.0), np.array(4.0))
    assert p.position(0.0) == 0.0  # before the move
    assert p.position(2.0) == 0.0  # start
    assert p.position(4.0) == pytest.approx(LW / 2)  # midpoint of a half-cosine is half-way
    assert p.position(6.0) == pytest.approx(LW)  # end
    assert p.position(50.0) == pytest.approx(LW)  # held after
    # a quarter of the time covers (1 - cos(pi/4)) / 2 of the way: slow start
    assert p.position(3.0) == pytest.approx(LW * 0.5 * (1 - math.cos(math.pi / 4)))
    t = np.linspace(2.0, 6.0, 101)
    assert np.all(np.diff(p.position(t)) > 0)  # monotone


@pytest.mark.parametrize("y0,y1,T", [(0.0, LW, 4.0), (LW, 0.0, 2.5), (0.0, 2 * LW, 6.0)])
def test_lateral_plan_peak_acceleration_and_zero_outside(y0, y1, T):
    t0 = 1.0
    p = LateralPlan(np.array(y0), np.array(y1), np.array(t0), np.array(T))
    peak = abs(y1 - y0) * math.pi ** 2 / (2 * T ** 2)
    assert p.peak_acceleration() == pytest.approx(peak)
    t = np.linspace(t0 + 1e-9, t0 + T - 1e-9, 20001)
    a = p.acceleration(t)
    assert np.max(np.abs(a)) == pytest.approx(peak, rel=1e-6)
    # it pushes towards y1 at the start and brakes the lateral motion at the end
    assert np.sign(a[0]) == np.sign(y1 - y0) and np.sign(a[-1]) == -np.sign(y1 - y0)
    assert abs(p.acceleration(t0 + T / 2)) < 1e-9 * peak + 1e-12  # inflection at the midpoint
    for outside in (0.0, t0 - 0.1, t0, t0 + T, t0 + T + 0.1, 100.0):
        assert p.acceleration(outside) == 0.0


def test_lateral_acceleration_is_the_second_derivative_of_position():
    p = LateralPlan(np.array(0.5), np.array(-LW), np.array(0.7), np.array(3.3))
    h = 1e-3
    t = np.linspace(0.8, 3.9, 50)  # strictly inside the move
    numeric = (p.position(t + h) - 2 * p.position(t) + p.position(t - h)) / h ** 2
    assert np.allclose(numeric, p.acceleration(t), atol=1e-4)


def test_lateral_plan_broadcasts_over_a_batch():
    p = LateralPlan(np.zeros((2, 3)), np.array([[0.0, LW, 0.0], [0.0, 0.0, -LW]]), np.array([[0, 1, 0], [0, 0, 2]]),
                    np.full((2, 3), 2.0))
    y = p.position(np.array(10.0))
    assert y.shape == (2, 3)
    assert np.allclose(y, [[0, LW, 0], [0, 0, -LW]])
    assert np.allclose(LateralPlan.still(np.array([1.0, 2.0])).position(5.0), [1.0, 2.0])
    with pytest.raises(ValueError, match="duration"):
        LateralPlan(np.array(0.0), np.array(1.0), np.array(0.0), np.array(0.0))


# ----------------------------------------------------------------------------- Road
def test_road_d2_d3_of_lane_centred_car():
    road = Road(lane_width=3.75, n_lanes=2)
    # 3.75 m lane, 1.8 m car centred: (3.75 - 1.8) / 2 = 0.975 m either side
    assert road.d2(road.lane_centre(0), 1.8) == pytest.approx(0.975)
    assert road.d3(road.lane_centre(1), 1.8) == pytest.approx(0.975)
    assert road.d3(road.lane_centre(0), 1.8) == pytest.approx(0.975 + 3.75)
    assert road.d2(road.lane_centre(1), 1.8) == pytest.approx(0.975 + 3.75)
    assert Road(3.75, 1).d3(0.0, 1.8) == pytest.approx(0.975)
    assert road.d2(0.0, 2.5) == pytest.approx(0.625)  # a wider vehicle is closer to the edge


def test_road_margins_stay_positive_during_a_lane_change():
    road = Road(lane_width=3.75, n_lanes=2)
    p = LateralPlan(np.array(0.0), np.array(3.75), np.array(0.0), np.array(4.0))
    y = p.position(np.linspace(0, 4, 401))
    d2, d3 = road.d2(y), road.d3(y)
    assert np.all(d2 > 0) and np.all(d3 > 0)
    assert np.min(np.minimum(d2, d3)) == pytest.approx(0.975)
    assert np.allclose(d2 + d3, 2 * 3.75 - 1.8)  # the carriageway minus the car


def test_road_validation():
    with pytest.raises(ValueError, match="n_lanes"):
        Road(3.75, 0)
    with pytest.raises(ValueError, match="lane_width"):
        Road(-1.0, 2)
    with pytest.raises(ValueError, match="length"):
        Road(3.75, 2, 0.0)


# ----------------------------------------------------------------------------- who is ahead
def _two_car_world(y0_pov, y1_pov, t_lc=1.0, T=4.0, dt=0.05, width_pov=1.8, width_ego=1.8, gap=30.0):
    lat = LateralPlan(np.array([[0.0, y0_pov]]), np.array([[0.0, y1_pov]]), np.array([[0.0, t_lc]]),
                      np.array([[1.0, T]]))
    return SingleLaneWorld([[0.0, gap + L]], [[20.0, 20.0]], [None, Const()], lateral=lat,
                           width=[[width_ego, width_pov]], dt=dt)


def _first(mask):
    assert mask.any()
    return int(np.argmax(mask))


def test_adjacent_lane_vehicle_is_not_a_target_until_its_contour_crosses_the_line():
    t_lc, T, dt = 1.0, 4.0, 0.05
    wp, we = 2.2, 1.6  # the rule uses the *target's* width (the ego's would switch later)
    w = _two_car_world(LW, 0.0, t_lc, T, dt, width_pov=wp, width_ego=we)
    tr = rollout(w, int(7.0 / dt), ego=Const())
    lead = tr.lead[:, 0, 0]
    k = _first(lead == 1)
    assert np.all(lead[:k] == -1) and np.all(np.isinf(tr.gap[:k, 0, 0]))
    assert np.all(lead[k:] == 1) and np.all(np.isfinite(tr.gap[k:, 0, 0]))
    # analytic crossing: LW (1 + cos(pi s)) / 2 = (LW + wp) / 2
    s = math.acos((LW + wp) / LW - 1.0) / math.pi
    t_cross = t_lc + s * T
    assert tr.t[k] - dt - 1e-9 <= t_cross <= tr.t[k] + 1e-9
    assert np.abs(tr.y[k, 0, 1] - tr.y[k, 0, 0]) < 0.5 * (LW + wp) <= np.abs(tr.y[k - 1, 0, 1] - tr.y[k - 1, 0, 0])
    # the gap is the true bumper gap (both at constant speed: 30 m)
    assert tr.gap[k, 0, 0] == pytest.approx(30.0)
    # the POV sees nothing (the ego is behind)
    assert np.all(tr.lead[:, 0, 1] == -1)


def test_cut_out_target_kept_until_the_contour_has_left_the_lane():
    t_lc, T, dt = 1.0, 4.0, 0.05
    w = _two_car_world(0.0, LW, t_lc, T, dt)
    tr = rollout(w, int(7.0 / dt), ego=Const())
    lead = tr.lead[:, 0, 0]
    k = _first(lead == -1)
    assert np.all(lead[:k] == 1) and np.all(lead[k:] == -1)
    s = 1.0 - math.acos((LW + 1.8) / LW - 1.0) / math.pi  # LW (1 - cos(pi s)) / 2 = (LW + 1.8) / 2
    assert s > 0.5  # conservative: the target is kept past the middle of the move
    t_cross = t_lc + s * T
    assert tr.t[k] - dt - 1e-9 <= t_cross <= tr.t[k] + 1e-9


def test_neighbours_second_vehicle_ahead_and_observation():
    # three in lane 0, one in lane 1 in between (not anyone's target)
    x0 = [[0.0, 30.0, 70.0, 50.0]]
    lat = LateralPlan.still(np.array([[0.0, 0.0, 0.0, LW]]))
    w = SingleLaneWorld(x0, [[20.0, 18.0, 16.0, 25.0]], [None, Const(), Const(), Const()], lateral=lat)
    nb = w.neighbours
    assert nb.lead[0].tolist() == [1, 2, -1, -1]
    assert nb.gap[0, 0] == pytest.approx(30.0 - L) and nb.gap[0, 1] == pytest.approx(40.0 - L)
    assert nb.lead2[0].tolist() == [2, -1, -1, -1]
    assert nb.gap2[0, 0] == pytest.approx(70.0 - L)
    assert np.isinf(nb.gap2[0, 1]) and np.isinf(nb.gap[0, 2])
    obs = w.observe(0)
    assert obs.gap[0] == pytest.approx(30.0 - L) and obs.v_lead[0] == 18.0
    assert obs.gap2[0] == pytest.approx(70.0 - L) and obs.v_lead2[0] == 16.0
    obs1 = w.observe(1)
    assert obs1.v[0] == 18.0 and obs1.v_lead[0] == 16.0 and np.isinf(obs1.gap2[0])


# ----------------------------------------------------------------------------- two-phase step
def _three_car(order):
    """Ego, a middle IDM vehicle and a braking scripted front vehicle; ``order`` puts
    (middle, front) in slots (1, 2) or (2, 1)."""
    front = SpeedProfile.from_segments(18.0, [(0.0, 2.0), (-4.0, 3.0), (1.0, 5.0)])
    mid = IDM(IDMParams(v_desired=22.0, a=1.2, b=2.5), n=1, dt=0.2)
    fr = ProfileDriver(front, n=1, dt=0.2)
    xs = {"ego": 0.0, "mid": 25.0, "front": 55.0}
    vs = {"ego": 20.0, "mid": 19.0, "front": 18.0}
    models = {"mid": mid, "front": fr}
    roles = ["ego", *order]
    return SingleLaneWorld([[xs[r] for r in roles]], [[vs[r] for r in roles]],
                           [None] + [models[r] for r in order]), roles


def test_two_phase_step_slot_order_does_not_matter():
    w_a, roles_a = _three_car(("mid", "front"))
    w_b, roles_b = _three_car(("front", "mid"))
    ego_a, ego_b = IDM(IDMParams(v_desired=25.0), n=1), IDM(IDMParams(v_desired=25.0), n=1)
    ta, tb = rollout(w_a, 50, ego=ego_a), rollout(w_b, 50, ego=ego_b)
    perm = [roles_b.index(r) for r in roles_a]  # slot in B of each role of A
    assert perm == [0, 2, 1]
    for key in ("x", "v", "a", "a_des", "gap"):
        assert np.array_equal(getattr(ta, key)[1:], getattr(tb, key)[1:, :, perm]), key
    # the target slots are the same vehicles
    map_b_to_role = {s: roles_b[s] for s in range(3)} | {-1: None}
    map_a_to_role = {s: roles_a[s] for s in range(3)} | {-1: None}
    for k in range(ta.t.size):
        for i in range(3):
            assert map_a_to_role[ta.lead[k, 0, i]] == map_b_to_role[tb.lead[k, 0, perm[i]]]
    assert ta.v[:, 0, 1].min() < 15.0  # the scene is dynamic: the middle car brakes


def test_every_model_sees_the_snapshot_before_anyone_moves():
    rec = Const(a=-3.0)
    w = SingleLaneWorld([[0.0, 40.0]], [[20.0, 25.0]], [None, Const(a=2.0)])
    tr = rollout(w, 10, ego=rec)
    for k, obs in enumerate(rec.seen):
        assert obs.gap[0] == pytest.approx(tr.x[k, 0, 1] - L - tr.x[k, 0, 0])
        assert obs.v_lead[0] == pytest.approx(tr.v[k, 0, 1])
        assert obs.v[0] == pytest.approx(tr.v[k, 0, 0])
    # exact integration of the applied constant accelerations
    t = tr.t
    assert np.allclose(tr.x[:, 0, 1], 40.0 + 25.0 * t + 0.5 * 2.0 * t ** 2)
    assert np.allclose(tr.x[:, 0, 0], 20.0 * t - 0.5 * 3.0 * t ** 2)
    assert np.all(tr.a_des[1:, 0, 0] == -3.0) and np.isnan(tr.a_des[0]).all()


def test_ego_model_in_slot_zero_equals_ego_passed_to_rollout():
    def world(ego):
        return SingleLaneWorld([[0.0, 30.0]], [[25.0, 15.0]], [ego, IDM(IDMParams(v_desired=15.0), n=1)])
    ta = rollout(world(IDM(IDMParams(v_desired=30.0), n=1)), 40)
    tb = rollout(world(None), 40, ego=IDM(IDMParams(v_desired=30.0), n=1))
    assert np.array_equal(ta.x, tb.x) and np.array_equal(ta.v, tb.v)
    # and a rollout is reproducible (rollout resets the world and the models)
    w = world(IDM(IDMParams(v_desired=30.0), n=1))
    assert np.array_equal(rollout(w, 40).x, rollout(w, 40).x)


# ----------------------------------------------------------------------------- absent vehicles
def test_absent_vehicles_are_never_a_target_and_never_move():
    # slot 2 absent, parked between the ego and the POV (and in scene 1 overlapping the ego)
    x0 = [[0.0, 60.0, 20.0], [0.0, 60.0, 2.0]]
    present = [[True, True, False], [True, True, False]]
    pushy = Const(n=2, a=3.0)  # would accelerate if it were moved
    w = SingleLaneWorld(x0, [[20.0, 20.0, 20.0]] * 2, [None, Const(n=2), pushy], present=present)
    tr = rollout(w, 30, ego=Const(n=2, a=1.0))
    assert np.all(tr.lead != 2)
    assert np.all(tr.x[:, :, 2] == np.array([20.0, 2.0]))
    assert np.all(tr.v[:, :, 2] == 0.0) and np.all(tr.a[:, :, 2] == 0.0)
    assert np.all(tr.lead[:, :, 0] == 1)  # the ego sees the POV through the absent vehicle
    assert np.all(np.isinf(tr.gap[:, :, 2]))
    assert not tr.collided.any()


# ----------------------------------------------------------------------------- sensor range
def test_sensor_range_hides_far_vehicle_but_trace_keeps_true_gap():
    rng = 100.0
    w = SingleLaneWorld([[0.0, 250.0 + L]], [[30.0, 10.0]], [None, Const()], sensor_range=rng)
    assert np.isinf(w.observe(0).gap[0])
    assert w.neighbours.gap[0, 0] == pytest.approx(250.0)
    tr = rollout(w, 60, ego=IDM(IDMParams(v_desired=30.0), n=1))
    assert np.all(np.isfinite(tr.gap[:, 0, 0])) and np.all(tr.lead[:, 0, 0] == 1)
    assert tr.gap[0, 0, 0] == pytest.approx(250.0)
    # the ego's decision at step k uses row k-1: unseen -> cruising (IDM at its desired speed asks 0)
    unseen = tr.gap[:-1, 0, 0] > rng
    assert unseen[:5].all() and not unseen.all()
    assert np.all(tr.a_des[1:, 0, 0][unseen] == 0.0)
    assert np.all(tr.a_des[1:, 0, 0][~unseen] < 0.0)  # seen: it brakes for the slower vehicle


# ----------------------------------------------------------------------------- collisions
def test_constant_speed_ego_runs_into_stopped_vehicle():
    w = SingleLaneWorld([[0.0, 50.0 + L]], [[20.0, 0.0]], [None, Const()])
    tr = rollout(w, 30, ego=Const(a=0.0))
    assert np.allclose(tr.v[:, 0, 0], 20.0) and np.all(tr.x[:, 0, 1] == 50.0 + L)
    k = _first(tr.gap[:, 0, 0] <= 0.0)
    assert tr.t[k] - 0.2 - 1e-9 <= 50.0 / 20.0 <= tr.t[k] + 1e-9  # contact at t = 2.5 s
    assert tr.collided[0, 0]
    # (no contact model: the ego drives through the POV; only once its front is past the POV's
    # does the POV see it "ahead" with a negative gap)
    k1 = _first(tr.gap[:, 0, 1] <= 0.0)
    assert k1 > k and tr.x[k1, 0, 0] > tr.x[k1, 0, 1] >= tr.x[k1 - 1, 0, 0]
    # the world's flag is sticky once set
    w.reset()
    flags = []
    for _ in range(30):
        w.step(0.0)
        flags.append(bool(w.collided[0, 0]))
    assert flags.index(True) == k - 1 and all(flags[k - 1:])


def test_no_collision_flag_when_stopping_short():
    w = SingleLaneWorld([[0.0, 50.0 + L]], [[20.0, 0.0]], [None, Const()])
    tr = rollout(w, 40, ego=Const(a=-5.0))  # stops after 40 m
    assert tr.v[-1, 0, 0] == 0.0
    assert tr.gap[-1, 0, 0] == pytest.approx(10.0)
    assert not tr.collided.any()


# ----------------------------------------------------------------------------- errors
def test_constructor_errors_name_the_problem():
    with pytest.raises(ValueError, match="x0 must have shape"):
        SingleLaneWorld([0.0, 30.0], [20.0, 20.0], [None, Const()])
    with pytest.raises(ValueError, match="drivers must have one entry per slot"):
        SingleLaneWorld([[0.0, 30.0]], [[20.0, 20.0]], [None])
    with pytest.raises(ValueError, match=r"driver of slot 1 controls n=2"):
        SingleLaneWorld([[0.0, 30.0]], [[20.0, 20.0]], [None, Const(n=2)])
    with pytest.raises(ValueError, match="start apart"):
        SingleLaneWorld([[0.0, 3.0]], [[20.0, 20.0]], [None, Const()])
    with pytest.raises(ValueError, match="v0 must be >= 0"):
        SingleLaneWorld([[0.0, 30.0]], [[-1.0, 20.0]], [None, Const()])
    with pytest.raises(ValueError, match="v0 must be finite"):
        SingleLaneWorld([[0.0, 30.0]], [[np.nan, 20.0]], [None, Const()])
    with pytest.raises(ValueError, match="present must broadcast"):
        SingleLaneWorld([[0.0, 30.0]], [[20.0, 20.0]], [None, Const()], present=[True, True, True])
    with pytest.raises(ValueError, match="dt"):
        SingleLaneWorld([[0.0, 30.0]], [[20.0, 20.0]], [None, Const()], dt=0.0)
    with pytest.raises(ValueError, match="sensor_range"):
        SingleLaneWorld([[0.0, 30.0]], [[20.0, 20.0]], [None, Const()], sensor_range=0.0)


def test_step_and_rollout_errors():
    w = SingleLaneWorld([[0.0, 30.0]], [[20.0, 20.0]], [None, Const()])
    with pytest.raises(ValueError, match="ego has no model"):
        w.step()
    with pytest.raises(ValueError, match="ego has no model"):
        rollout(w, 5)
    with pytest.raises(ValueError, match="ego_a_des must be finite"):
        w.step(np.nan)
    with pytest.raises(ValueError, match="steps"):
        rollout(w, -1, ego=Const())
    with pytest.raises(ValueError, match=r"ego model controls n=3"):
        rollout(w, 5, ego=Const(n=3))
    # adjacent lanes: overlapping longitudinally is allowed (side by side)
    SingleLaneWorld([[0.0, 2.0]], [[20.0, 20.0]], [None, Const()], lateral=LateralPlan.still(np.array([[0.0, LW]])))


def test_vehicles_overlapping_in_one_lane_are_rejected():
    # same position: neither is strictly ahead of the other, still an overlap
    with pytest.raises(ValueError, match="start apart.*slots 0 and 1"):
        SingleLaneWorld([[0.0, 0.0]], [[20.0, 20.0]], [None, Const()])
    # a car cutting in is in the corridor once its contour crosses the line: overlapping there is rejected
    lat = LateralPlan.still(np.array([[0.0, 2.0]]))
    with pytest.raises(ValueError, match="start apart"):
        SingleLaneWorld([[0.0, 2.0]], [[20.0, 20.0]], [None, Const()], lateral=lat)
    # 10 cm apart is apart
    w = SingleLaneWorld([[0.0, 0.1 + L]], [[20.0, 20.0]], [None, Const()])
    assert w.neighbours.gap[0, 0] == pytest.approx(0.1) and not w.collided.any()
