"""The compiled world kernels (``acc_gym.simulation._world_kernel``) equal their numpy references.

* ``refresh``: neighbours equal :meth:`SingleLaneWorld._neighbours` exactly (ties to the lower
  slot, absent vehicles, the lane-corridor rule), lateral motion equals :class:`LateralPlan`,
  collision flags are sticky and set only after a step;
* ``advance``: equals :func:`acc_gym.vehicle.applied_acceleration` + :func:`acc_gym.vehicle.integrate`;
* ``observe_all``: every slot's observation from the neighbours (sensor range, right slot),
  fresh arrays each step, read-only.

States are random (``numpy.random.default_rng(seed)``) and drawn on coarse grids so that
equal gaps (ties) and vehicles exactly on the corridor's edge occur often.
"""

import pickle
from dataclasses import fields

import numpy as np
import pytest

from acc_gym.drivers.base import Observation
from acc_gym.simulation import _world_kernel as K
from acc_gym.simulation.single_lane import LateralPlan, Road, SingleLaneWorld
from acc_gym.vehicle import VehicleParams, accel_lower, accel_upper, applied_acceleration, integrate
from world_oracle import move_by_parts  # tests/world_oracle.py

B = 50
SEEDS = range(12)


class Fixed:
    """A driver model asking for given accelerations; records what it saw."""

    def __init__(self, n, a=0.0):
        self.n = n
        self.a = np.broadcast_to(np.asarray(a, float), (n,)).copy()
        self.seen = []
        self.info = {}

    def reset(self):
        self.seen = []

    def act(self, obs):
        self.seen.append(obs)
        return self.a.copy()


def make_world(S, *, B=B, road=None, vehicle=None, sensor_range=200.0, dt=0.2):
    """A valid world (vehicles 100 m apart in lane 0) whose state the tests then overwrite."""
    x0 = np.tile(np.arange(S) * 100.0, (B, 1))
    drivers = [None] + [Fixed(B) for _ in range(S - 1)]
    return SingleLaneWorld(x0, np.full((B, S), 10.0), drivers, vehicle=vehicle, road=road, dt=dt,
                           sensor_range=sensor_range)


def randomise(w, rng, *, moving=True, spread=1.0):
    """Random positions, speeds, accelerations, lengths, widths, presence, lateral plans and clocks.

    Positions, lengths and lateral positions are on coarse binary grids, so that equal gaps
    (ties) and vehicles exactly on the corridor's edge (|dy| == (lane_width + width) / 2) occur."""
    Bw, S = w.B, w.S
    w.x = rng.integers(0, 20, size=(Bw, S)) * spread  # [m] many equal positions and gaps
    w.lengths = rng.choice([4.0, 5.0], size=(Bw, S))
    # in a third of the scenes the last two slots' rear bumpers are level (a tie for whoever is behind)
    tie = rng.random(Bw) < 0.35
    w.x[tie, -1] = w.x[tie, -2] - w.lengths[tie, -2] + w.lengths[tie, -1]
    w.width = rng.choice([1.5, 2.0, 2.5], size=(Bw, S))
    w.v = rng.uniform(0.0, 30.0, size=(Bw, S))
    w.a = rng.uniform(-5.0, 3.0, size=(Bw, S))
    w.present = rng.random((Bw, S)) < 0.8
    w.v = np.where(w.present, w.v, 0.0)
    w.a = np.where(w.present, w.a, 0.0)
    # lateral: half the vehicles hold a grid position (exact y), the others are mid-move
    grid = np.arange(-8, 33) * 0.125  # [m] on it, |dy| hits (lane_width + width) / 2 for 3.75 and 4 m lanes
    y0 = rng.choice(grid, size=(Bw, S))
    y1 = np.where(rng.random((Bw, S)) < 0.5, y0, rng.choice(grid, size=(Bw, S))) if moving else y0
    w.k = rng.integers(0, 40, size=Bw)
    t = w.t[:, None]
    duration = rng.uniform(1.0, 6.0, size=(Bw, S))
    # starts before, during and after the current time, and exactly at it (phase 0)
    t_start = t - rng.uniform(-2.0, 8.0, size=(Bw, S))
    t_start = np.where(rng.random((Bw, S)) < 0.1, np.broadcast_to(t, (Bw, S)), t_start)
    w.lateral = LateralPlan(y0, y1, t_start, duration)
    w.collided = np.zeros((Bw, S), dtype=bool)
    w._refresh(mark=False)


def assert_neighbours_equal(w):
    ref = w._neighbours()
    nb = w.neighbours
    for name in ("lead", "gap", "lead2", "gap2"):
        np.testing.assert_array_equal(getattr(nb, name), getattr(ref, name), err_msg=name)
    assert nb.lead.dtype.kind == "i" and nb.lead2.dtype.kind == "i"
    return ref


# ----------------------------------------------------------------------------- neighbours
@pytest.mark.parametrize("S", [3, 4])
@pytest.mark.parametrize("lane_width", [3.75, 4.0])
def test_neighbours_equal_the_numpy_reference(S, lane_width):
    w = make_world(S, road=Road(lane_width=lane_width, n_lanes=3))
    ties = edge = absent_ahead = other_lane = 0
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        randomise(w, rng)
        ref = assert_neighbours_equal(w)
        nb = w.neighbours
        # absent vehicles: never a target, and see nothing themselves
        for lead in (nb.lead, nb.lead2):
            hit = lead >= 0
            assert np.all(np.take_along_axis(w.present, np.maximum(lead, 0), axis=1)[hit])
        assert np.all(nb.lead[~w.present] == -1) and np.all(np.isinf(nb.gap[~w.present]))
        assert np.all(nb.lead2[~w.present] == -1) and np.all(np.isinf(nb.gap2[~w.present]))
        # a second target only with a first, never the same, never nearer
        assert np.all((nb.lead2 < 0) | (nb.lead >= 0))
        assert np.all((nb.lead2 < 0) | (nb.lead2 != nb.lead))
        assert np.all(nb.gap <= nb.gap2)
        # equal gaps: the lower slot first (as a stable argsort)
        tie = np.isfinite(nb.gap2) & (nb.gap == nb.gap2)
        assert np.all(nb.lead[tie] < nb.lead2[tie])
        ties += int(tie.sum())
        # scenes that exercise the rules (counted below, so that the test cannot pass vacuously)
        dy = np.abs(w.y[:, None, :] - w.y[:, :, None])
        half = 0.5 * (lane_width + w.width[:, None, :])
        ahead = w.x[:, None, :] > w.x[:, :, None]
        both = w.present[:, None, :] & w.present[:, :, None]
        edge += int(np.sum(ahead & both & (dy == half)))
        other_lane += int(np.sum(ahead & both & (dy > half)))
        absent_ahead += int(np.sum(ahead & w.present[:, :, None] & ~w.present[:, None, :]))
        assert ref.gap.shape == (w.B, S)
    assert ties > 20 and edge > 5 and other_lane > 20 and absent_ahead > 20, (ties, edge, other_lane, absent_ahead)


def test_corridor_rule_by_hand():
    """|y_j - y_i| < (lane_width + width_j) / 2, with the *target's* width; on the edge: not a target."""
    LW = 4.0
    w = make_world(3, B=4, road=Road(lane_width=LW, n_lanes=3))
    w.x = np.tile([0.0, 20.0, 40.0], (4, 1))
    w.lengths = np.full((4, 3), 4.0)
    w.width = np.array([[2.0, 2.0, 2.0], [2.0, 2.0, 2.0], [2.0, 2.5, 2.0], [2.0, 2.0, 2.0]])
    # slot 1 at 3.0 m (the edge for width 2: (4 + 2) / 2), 3.25 (inside for width 2.5), 2.999
    y = np.array([[0.0, 3.0, 0.0], [0.0, 2.999, 0.0], [0.0, 3.0, 0.0], [0.0, -3.0, 3.0]])
    w.lateral = LateralPlan.still(y)
    w._refresh(mark=False)
    assert_neighbours_equal(w)
    nb = w.neighbours
    assert nb.lead[:, 0].tolist() == [2, 1, 1, -1]
    assert nb.gap[:, 0].tolist() == [36.0, 16.0, 16.0, np.inf]
    assert nb.lead2[:, 0].tolist() == [-1, 2, 2, -1]
    # scene 3: slots 1 and 2 are 6 m apart, more than (4 + 2) / 2: neither follows the other
    assert nb.lead[3].tolist() == [-1, -1, -1]


def test_tie_goes_to_the_lower_slot_by_hand():
    """Two vehicles with their rear bumpers level ahead of the ego, either side of its lane centre."""
    w = make_world(4, B=2, road=Road(lane_width=4.0, n_lanes=3))
    # slot 3 and slot 1 tie (rear at 25 m: 30 - 5 and 29 - 4); slot 2 further
    w.x = np.array([[0.0, 29.0, 50.0, 30.0], [0.0, 30.0, 50.0, 29.0]])
    w.lengths = np.array([[4.5, 4.0, 4.5, 5.0], [4.5, 5.0, 4.5, 4.0]])
    w.lateral = LateralPlan.still(np.array([[0.0, 1.0, 0.0, -1.5], [0.0, -1.5, 0.0, 1.0]]))
    w._refresh(mark=False)
    assert_neighbours_equal(w)
    nb = w.neighbours
    assert nb.lead[:, 0].tolist() == [1, 1] and nb.lead2[:, 0].tolist() == [3, 3]
    assert nb.gap[:, 0].tolist() == [25.0, 25.0] and nb.gap2[:, 0].tolist() == [25.0, 25.0]
    # a third vehicle at the same gap: still in slot order, the farther one not among the two
    w.x[0, 2], w.lengths[0, 2] = 30.0, 5.0
    w._refresh(mark=False)
    assert_neighbours_equal(w)
    assert (w.neighbours.lead[0, 0], w.neighbours.lead2[0, 0]) == (1, 2)


def test_vehicle_level_with_the_ego_is_not_ahead():
    w = make_world(3, B=1)
    w.x = np.array([[10.0, 10.0, 30.0]])
    w._refresh(mark=False)
    assert_neighbours_equal(w)
    assert w.neighbours.lead[0].tolist() == [2, 2, -1]


# ----------------------------------------------------------------------------- lateral motion
@pytest.mark.parametrize("S", [3, 4])
def test_lateral_motion_equals_the_lateral_plan(S):
    w = make_world(S)
    moving = before = after = at_start = 0
    for seed in SEEDS:
        rng = np.random.default_rng(100 + seed)
        randomise(w, rng)
        t = w.t[:, None]
        lat = w.lateral
        np.testing.assert_allclose(w.y, lat.position(t), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(w.a_y, lat.acceleration(t), rtol=1e-12, atol=1e-12)
        ph = (t - lat.t_start) / lat.duration
        inside = (ph > 0) & (ph < 1)
        # outside a move the lateral acceleration is exactly 0 and the position exactly y0 / y1
        assert np.all(w.a_y[~inside] == 0.0)
        np.testing.assert_array_equal(w.y[ph <= 0], lat.y0[ph <= 0])
        # mid-move it is not 0 (where the move has a length and is not at its midpoint)
        sel = inside & (lat.y1 != lat.y0) & (np.abs(ph - 0.5) > 1e-6)
        assert np.all(w.a_y[sel] != 0.0)
        moving += int(sel.sum())
        before += int(np.sum(ph < 0))
        after += int(np.sum(ph > 1))
        at_start += int(np.sum(ph == 0))
    assert moving > 50 and before > 20 and after > 20 and at_start > 5, (moving, before, after, at_start)


def test_lateral_motion_follows_each_scene_clock_through_steps():
    """Stepping the world: y and a_y at every step equal the plan at the scene's own time."""
    S = 3
    w = make_world(S, B=6)
    rng = np.random.default_rng(7)
    lat = LateralPlan(rng.choice([0.0, 3.75], size=(6, S)), rng.choice([0.0, 3.75, 7.5], size=(6, S)),
                      rng.uniform(0.0, 2.0, size=(6, S)), rng.uniform(1.0, 3.0, size=(6, S)))
    w.lateral = lat
    w.k = np.arange(6)  # each scene on its own clock
    w._refresh(mark=False)
    for _ in range(25):
        w.step(np.zeros(6))
        t = w.t[:, None]
        np.testing.assert_allclose(w.y, lat.position(t), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(w.a_y, lat.acceleration(t), rtol=1e-12, atol=1e-12)
        assert_neighbours_equal(w)


# ----------------------------------------------------------------------------- physics
def random_vehicles(rng, Bw, S):
    return VehicleParams(mass=rng.uniform(900.0, 2500.0, (Bw, S)), power=rng.uniform(40e3, 250e3, (Bw, S)),
                         traction_accel=rng.uniform(2.0, 5.0, (Bw, S)), mu_brake=rng.uniform(0.3, 1.0, (Bw, S)),
                         c_r1=rng.uniform(0.0, 1e-3, (Bw, S)), c_d=rng.uniform(0.2, 0.4, (Bw, S)))


@pytest.mark.parametrize("S", [3, 4])
def test_advance_equals_applied_acceleration_and_integrate(S):
    clipped_hi = clipped_lo = stops = held = 0
    for seed in SEEDS:
        rng = np.random.default_rng(200 + seed)
        p = random_vehicles(rng, B, S)
        w = make_world(S, vehicle=p)
        randomise(w, rng, moving=False)
        # speeds: many stopped, many slow (stopping inside the step), some above top speed
        v = rng.choice([0.0, 0.05, 0.3, 1.0], size=(B, S))
        v = np.where(rng.random((B, S)) < 0.5, rng.uniform(0.0, 70.0, (B, S)), v)
        w.v = np.where(w.present, v, 0.0)
        a_des = rng.uniform(-15.0, 10.0, size=(B, S))
        a_des[rng.random((B, S)) < 0.1] = 0.0
        for s in range(1, S):
            w.drivers[s].a = a_des[:, s].copy()
        w._refresh(mark=False)
        x_prev, v_prev = w.x.copy(), w.v.copy()
        w.step(a_des[:, 0])
        # reference: Eq. (3) and exact integration in numpy, absent vehicles asking for and getting 0
        a_ref = applied_acceleration(a_des, v_prev, p)
        x_ref, v_ref = integrate(x_prev, v_prev, a_ref, w.dt)
        pres = w.present
        np.testing.assert_array_equal(w.a, np.where(pres, a_ref, 0.0))
        np.testing.assert_array_equal(w.x, np.where(pres, x_ref, x_prev))
        np.testing.assert_array_equal(w.v, np.where(pres, v_ref, v_prev))
        np.testing.assert_array_equal(w.a_des, np.where(pres, a_des, 0.0))
        assert np.all(w.v >= 0.0)
        lo, hi = accel_lower(v_prev, p), accel_upper(v_prev, p)
        clipped_hi += int(np.sum(pres & (a_des > hi) & (w.a == hi) & (v_prev > 0)))
        clipped_lo += int(np.sum(pres & (a_des < lo) & (w.a == lo) & (v_prev > 0)))
        stop = pres & (v_prev > 0) & (v_prev + w.a * w.dt < 0)
        assert np.all(w.v[stop] == 0.0)
        np.testing.assert_allclose(w.x[stop] - x_prev[stop], v_prev[stop] ** 2 / (-2.0 * w.a[stop]), rtol=0,
                                   atol=1e-12)
        stops += int(stop.sum())
        hold = pres & (v_prev == 0) & (a_des < 0)
        assert np.all(w.a[hold] == 0.0) and np.all(w.x[hold] == x_prev[hold]) and np.all(w.v[hold] == 0.0)
        held += int(hold.sum())
    assert clipped_hi > 50 and clipped_lo > 50 and stops > 50 and held > 50, (clipped_hi, clipped_lo, stops, held)


def test_absent_vehicles_never_move_and_are_never_targets_over_many_steps():
    S = 4
    rng = np.random.default_rng(5)
    w = make_world(S)
    w.present = rng.random((B, S)) < 0.6
    w.present[:, 0] = True
    w.reset()  # absent vehicles get v = a = 0
    for s in range(1, S):
        w.drivers[s].a = rng.uniform(-2.0, 3.0, B)
    x_absent = w.x[~w.present].copy()
    for _ in range(30):
        w.step(rng.uniform(-3.0, 3.0, B))
        assert_neighbours_equal(w)
        np.testing.assert_array_equal(w.x[~w.present], x_absent)
        assert np.all(w.v[~w.present] == 0.0) and np.all(w.a[~w.present] == 0.0)
        assert np.all(w.a_des[~w.present] == 0.0)
        for lead in (w.neighbours.lead, w.neighbours.lead2):
            assert np.all(np.take_along_axis(w.present, np.maximum(lead, 0), axis=1)[lead >= 0])


# ----------------------------------------------------------------------------- collisions
def test_collision_flags_are_sticky_and_set_only_after_a_step():
    # slot 1 stands with its rear bumper exactly at the ego's front (gap 0: allowed at the start)
    L = VehicleParams().length
    x0 = np.array([[0.0, L, 100.0], [0.0, 50.0, 100.0]])
    v0 = np.array([[0.0, 0.0, 0.0], [10.0, 10.0, 10.0]])
    pov = Fixed(2, [3.0, 0.0])
    w = SingleLaneWorld(x0, v0, [None, pov, Fixed(2)])
    assert w.neighbours.gap[0, 0] == 0.0
    assert not w.collided.any()  # at a reset: not marked
    w.step([0.0, 0.0])  # slot 1 drives away: the gap opens to 0.5 a dt^2 > 0 within the step
    assert not w.collided.any()
    w.reset()
    w.drivers[1].a = np.array([0.0, 0.0])
    w.step([0.0, 0.0])  # nobody moves: the gap stays 0 -> marked after the step
    assert w.collided.tolist() == [[True, False, False], [False, False, False]]
    w.drivers[1].a = np.array([3.0, 0.0])
    for _ in range(10):
        w.step([0.0, 0.0])
    assert w.neighbours.gap[0, 0] > 0.0
    assert w.collided[0, 0]  # sticky
    w.reset()
    assert not w.collided.any()  # a reset clears, and does not mark the gap of 0 at the start
    w.reset_rows([1], [[0.0, L, 50.0]], [[0.0, 0.0, 0.0]])
    assert not w.collided.any()


@pytest.mark.parametrize("S", [3, 4])
def test_collision_flags_equal_the_running_or_of_the_reference_gaps(S):
    rng = np.random.default_rng(11 + S)
    x0 = np.tile(np.arange(S) * 8.0, (B, 1)) + rng.uniform(0.0, 2.0, (B, S)).cumsum(axis=1)
    w = SingleLaneWorld(x0, rng.uniform(5.0, 20.0, (B, S)), [None] + [Fixed(B) for _ in range(S - 1)],
                        present=rng.random((B, S)) < 0.85)
    sticky = np.zeros((B, S), dtype=bool)
    assert not w.collided.any()
    for k in range(25):
        for s in range(1, S):
            w.drivers[s].a = rng.uniform(-8.0, 2.0, B)
        w.step(rng.uniform(-1.0, 3.0, B))
        ref = assert_neighbours_equal(w)
        sticky |= ref.gap <= 0.0
        np.testing.assert_array_equal(w.collided, sticky)
    assert 5 < sticky.sum() and np.any(sticky & (w.neighbours.gap > 0)), sticky.sum()  # some collide, some drift apart


# ----------------------------------------------------------------------------- observations
def test_obs_fields_are_the_observation_field_order():
    assert K.OBS_FIELDS == tuple(f.name for f in fields(Observation))[:len(K.OBS_FIELDS)]


def reference_observation(w, slot):
    nb, r = w.neighbours, w.sensor_range
    rows = np.arange(w.B)
    lead, lead2 = nb.lead[:, slot], nb.lead2[:, slot]
    seen = nb.gap[:, slot] <= r
    return dict(v=w.v[:, slot], a=w.a[:, slot], gap=np.where(seen, nb.gap[:, slot], np.inf),
                v_lead=np.where(lead >= 0, w.v[rows, np.maximum(lead, 0)], 0.0),
                a_lead=np.where(lead >= 0, w.a[rows, np.maximum(lead, 0)], 0.0),
                gap2=np.where(seen & (nb.gap2[:, slot] <= r), nb.gap2[:, slot], np.inf),
                v_lead2=np.where(lead2 >= 0, w.v[rows, np.maximum(lead2, 0)], 0.0),
                a_lead2=np.where(lead2 >= 0, w.a[rows, np.maximum(lead2, 0)], 0.0))


@pytest.mark.parametrize("S", [3, 4])
def test_observations_equal_the_neighbours_with_the_sensor_range(S):
    w = make_world(S, sensor_range=18.0)
    hidden = hidden2 = no_lead = seen2 = 0
    for seed in SEEDS:
        randomise(w, np.random.default_rng(300 + seed), spread=2.0)
        nb = w.neighbours
        for s in range(S):
            obs = w.observe(s)
            ref = reference_observation(w, s)
            for name in K.OBS_FIELDS:
                np.testing.assert_array_equal(getattr(obs, name), ref[name], err_msg=f"slot {s} {name}")
            g, g2 = nb.gap[:, s], nb.gap2[:, s]
            hidden += int(np.sum(np.isfinite(g) & (g > w.sensor_range)))
            hidden2 += int(np.sum((g <= w.sensor_range) & np.isfinite(g2) & (g2 > w.sensor_range)))
            seen2 += int(np.sum(np.isfinite(obs.gap2)))
            no_lead += int(np.sum(nb.lead[:, s] < 0))
            # gap beyond range -> inf; the second is not seen without the first
            assert np.all(np.isinf(obs.gap[g > w.sensor_range]))
            assert np.all(np.isinf(obs.gap2[np.isinf(obs.gap)]))
            assert np.all(obs.v_lead[nb.lead[:, s] < 0] == 0.0) and np.all(obs.a_lead[nb.lead[:, s] < 0] == 0.0)
    assert hidden > 20 and hidden2 > 20 and seen2 > 20 and no_lead > 20, (hidden, hidden2, seen2, no_lead)


def test_second_vehicle_in_range_is_hidden_when_the_first_is_out_of_range():
    # the first vehicle ahead beyond the range hides the second (which is farther still)
    w = make_world(3, B=1, sensor_range=30.0)
    w.x = np.array([[0.0, 40.0, 60.0]])
    w._refresh(mark=False)
    o = w.observe(0)
    assert np.isinf(o.gap[0]) and np.isinf(o.gap2[0])
    assert o.v_lead[0] == w.v[0, 1] and o.v_lead2[0] == w.v[0, 2]  # the slots are reported regardless


def test_observations_of_an_earlier_step_keep_their_values_and_are_read_only():
    S = 3
    w = make_world(S, B=8)
    rng = np.random.default_rng(9)
    w.x = np.tile([0.0, 30.0, 60.0], (8, 1)) + rng.uniform(0.0, 5.0, (8, S))
    w.v = rng.uniform(5.0, 20.0, (8, S))
    w._refresh(mark=False)
    for s in range(1, S):
        w.drivers[s].a = rng.uniform(-2.0, 2.0, 8)
    kept = []
    for k in range(6):
        obs = [w.observe(s) for s in range(S)]
        values = [{n: getattr(o, n).copy() for n in K.OBS_FIELDS} for o in obs]
        for s, o in enumerate(obs):
            ref = reference_observation(w, s)
            for n in K.OBS_FIELDS:
                np.testing.assert_array_equal(getattr(o, n), ref[n])
                arr = getattr(o, n)
                assert not arr.flags.writeable, (s, n)
                with pytest.raises(ValueError):
                    arr[0] = 123.0
        assert w.observe(0).gap is obs[0].gap or np.array_equal(w.observe(0).gap, obs[0].gap)  # no change without a step
        kept.append((obs, values))
        w.step(rng.uniform(-2.0, 2.0, 8))
    for obs, values in kept:  # later steps did not overwrite them
        for o, val in zip(obs, values):
            for n in K.OBS_FIELDS:
                np.testing.assert_array_equal(getattr(o, n), val[n])
    assert not np.array_equal(kept[0][1][0]["v"], w.observe(0).v)  # the state did change
    # the drivers saw, at each step, the snapshot before anyone moved
    assert len(w.drivers[1].seen) == 6
    np.testing.assert_array_equal(w.drivers[1].seen[0].gap, kept[0][1][1]["gap"])
    np.testing.assert_array_equal(w.drivers[2].seen[3].v, kept[3][1][2]["v"])


def test_observe_all_called_directly():
    """observe_all writes ``out[s, f, b]`` in OBS_FIELDS order for every slot. The inputs here are
    arbitrary (a second gap may be shorter than the first, which the world never produces) so
    that the rule "the second vehicle is seen only if the first is" is pinned on its own."""
    rng = np.random.default_rng(4)
    Bw, S = 30, 4
    v, a = rng.uniform(0, 30, (Bw, S)), rng.uniform(-3, 3, (Bw, S))
    lead = rng.integers(-1, S, (Bw, S))
    lead2 = np.where(lead >= 0, rng.integers(-1, S, (Bw, S)), -1)
    gap = np.where(lead >= 0, rng.uniform(0, 60, (Bw, S)), np.inf)
    gap2 = np.where(lead2 >= 0, rng.uniform(0, 80, (Bw, S)), np.inf)
    out = np.full((S, len(K.OBS_FIELDS), Bw), np.nan)
    K.observe_all(v, a, lead, gap, lead2, gap2, 40.0, out)
    rows = np.arange(Bw)
    for s in range(S):
        j, j2 = lead[:, s], lead2[:, s]
        seen = gap[:, s] <= 40.0
        expect = [v[:, s], a[:, s], np.where(seen, gap[:, s], np.inf),
                  np.where(j >= 0, v[rows, j], 0.0), np.where(j >= 0, a[rows, j], 0.0),
                  np.where(seen & (gap2[:, s] <= 40.0), gap2[:, s], np.inf),
                  np.where(j2 >= 0, v[rows, j2], 0.0), np.where(j2 >= 0, a[rows, j2], 0.0)]
        np.testing.assert_array_equal(out[s], np.array(expect))
    hidden_first = np.isfinite(gap) & (gap > 40.0) & (gap2 <= 40.0)
    assert hidden_first.sum() > 2 and np.all(np.isinf(out[:, 5, :].T[hidden_first]))


# ----------------------------------------------------------------------------- fused move, compiled reset
def twin_worlds(seed: int) -> list:
    """Two worlds of three slots in the same random state (:func:`randomise` with ``seed``)."""
    worlds = []
    for _ in range(2):
        w = make_world(3)
        randomise(w, np.random.default_rng(seed))
        worlds.append(w)
    return worlds


@pytest.mark.parametrize("seed", range(4))
def test_fused_move_equals_move(seed):
    """``decide`` + the one-call ``_world_kernel.move`` + ``adopt`` (``move``, and the environment
    core's path) leave exactly the state the separate kernels (``move_by_parts``, tests/world_oracle.py: advance,
    then refresh) leave, step after step; ``step`` is ``decide`` + ``move``."""
    worlds = twin_worlds(seed)
    ref, fused = worlds
    rng = np.random.default_rng(100 + seed)
    for _ in range(25):
        a = rng.uniform(-9.0, 4.0, size=(B, 3))
        for w in worlds:
            for s in (1, 2):
                w.drivers[s].a = a[:, s].copy()
        move_by_parts(ref, ref.decide(a[:, 0]))
        a_all = fused.decide(a[:, 0])
        F, I, obs = fused.move_buffers()
        t = np.empty(B)
        K.move(a_all, fused.x, fused.v, fused.kernel_record(), F, I, obs, t)
        fused.adopt(F, I, obs)
        assert np.array_equal(t, ref.t)
        for name in ("x", "v", "a", "y", "a_y", "k", "collided"):
            assert np.array_equal(getattr(fused, name), getattr(ref, name)), name
        assert np.array_equal(fused.a_des, ref.a_des, equal_nan=True)
        for name in ("lead", "gap", "lead2", "gap2"):
            assert np.array_equal(getattr(fused.neighbours, name), getattr(ref.neighbours, name)), name
        for s in range(3):
            assert np.array_equal(fused.observation_array(s), ref.observation_array(s))
        assert not fused.observation_array(0).flags.writeable
    stepped = make_world(3)
    randomise(stepped, np.random.default_rng(seed))
    for name in ("x", "v"):
        assert not np.array_equal(getattr(stepped, name), getattr(ref, name))
    assert ref.collided.any() and (ref.neighbours.lead >= 0).any()  # the states exercised collisions and leads


@pytest.mark.parametrize("seed", range(2))
def test_reused_buffers_leave_the_state_fresh_buffers_leave(seed):
    """The environments' core moves a world into two sets of buffers in turn
    (``reused_buffers`` + ``adopt_buffers``): the same states as fresh buffers, step after
    step; the set handed out never holds the current state, consecutive steps use different
    sets, and a pickled copy mid-run continues identically (pickle copies a view's data: the
    copy's state views are made again from its own buffers)."""
    ref, reused = twin_worlds(seed)
    rng = np.random.default_rng(200 + seed)
    last = None
    for k in range(20):
        if k == 10:
            reused = pickle.loads(pickle.dumps(reused))
        a = rng.uniform(-9.0, 4.0, size=(B, 3))
        for w in (ref, reused):
            for s in (1, 2):
                w.drivers[s].a = a[:, s].copy()
        move_by_parts(ref, ref.decide(a[:, 0]))
        a_all = reused.decide(a[:, 0])
        buf = reused.reused_buffers()
        assert reused.x.base is not buf.F and buf is not last
        buf.obs.setflags(write=True)
        K.move(a_all, reused.x, reused.v, reused.kernel_record(), buf.F, buf.I, buf.obs, np.empty(B))
        reused.adopt_buffers(buf)
        last = buf
        assert reused.x.base is buf.F and reused.neighbours.gap.base is buf.F
        for name in ("x", "v", "a", "y", "a_y", "k", "collided"):
            assert np.array_equal(getattr(reused, name), getattr(ref, name)), (k, name)
        for name in ("lead", "gap", "lead2", "gap2"):
            assert np.array_equal(getattr(reused.neighbours, name), getattr(ref.neighbours, name)), (k, name)
        for s in range(3):
            assert np.array_equal(reused.observation_array(s), ref.observation_array(s))
        assert not reused.observation_array(0).flags.writeable


def test_compiled_reset_rows_equals_the_numpy_path():
    """Array inputs take the compiled ``place``; the same values as lists take the numpy
    path; both leave the same world (other scenes untouched)."""
    rng = np.random.default_rng(5)
    worlds = [make_world(3, B=6) for _ in range(2)]
    for w in worlds:
        randomise(w, np.random.default_rng(7), moving=False)
    rows = np.array([1, 4])
    x0 = np.array([[0.0, 30.0, 80.0], [5.0, 25.0, 60.0]])
    v0 = rng.uniform(0.0, 30.0, (2, 3))
    a0 = rng.uniform(-1.0, 1.0, (2, 3))
    present = np.array([[True, True, False], [True, True, True]])
    lengths = np.array([[4.5, 4.7, 5.0], [4.2, 4.8, 4.6]])
    width = np.array([[1.8, 1.9, 2.0], [1.7, 1.8, 1.9]])
    plan = LateralPlan(np.zeros((2, 3)), np.array([[0.0, 3.75, 0.0], [0.0, 0.0, 3.75]]),
                       np.array([[0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]), np.full((2, 3), 4.0))
    fast, slow = worlds
    fast.reset_rows(rows, x0, v0, present=present, lateral=plan, lengths=lengths, width=width, a0=a0)
    slow.reset_rows(rows.tolist(), x0.tolist(), v0.tolist(), present=present.tolist(), lateral=plan,
                    lengths=lengths.tolist(), width=width.tolist(), a0=a0.tolist())
    for name in ("x0", "v0", "a0", "present", "lengths", "width", "x", "v", "a", "k", "collided", "y", "a_y"):
        assert np.array_equal(getattr(fast, name), getattr(slow, name)), name
    assert np.array_equal(fast.a_des, slow.a_des, equal_nan=True)
    for f in ("y0", "y1", "t_start", "duration"):
        assert np.array_equal(getattr(fast.lateral, f), getattr(slow.lateral, f)), f
    for name in ("lead", "gap", "lead2", "gap2"):
        assert np.array_equal(getattr(fast.neighbours, name), getattr(slow.neighbours, name)), name
    assert np.array_equal(fast.v[1], np.where(present[0], v0[0], 0.0))  # absent vehicles stand still
    assert np.isnan(fast.a_des[rows]).all() and (fast.k[rows] == 0).all()


@pytest.mark.parametrize("field, value, match", [("x0", np.nan, "x0"), ("v0", -1.0, "v0"), ("lengths", np.inf, "lengths")])
def test_compiled_reset_rows_names_a_bad_value(field, value, match):
    w = make_world(3, B=2)
    args = {"x0": np.array([[0.0, 30.0, 80.0]]), "v0": np.full((1, 3), 10.0), "lengths": np.full((1, 3), 4.7)}
    args[field][0, 1] = value
    with pytest.raises(ValueError, match=match):
        w.reset_rows([1], args["x0"], args["v0"], present=np.ones((1, 3), bool), lateral=LateralPlan.still(np.zeros((1, 3))),
                     lengths=args["lengths"], width=np.full((1, 3), 1.8))


def test_compiled_reset_rows_names_overlapping_vehicles():
    w = make_world(3, B=2)
    with pytest.raises(ValueError, match="slots 1 and 2 overlap"):
        w.reset_rows([0], np.array([[0.0, 30.0, 32.0]]), np.full((1, 3), 10.0), present=np.ones((1, 3), bool),
                     lateral=LateralPlan.still(np.zeros((1, 3))), lengths=np.full((1, 3), 4.7),
                     width=np.full((1, 3), 1.8))
    # in different lanes they may overlap lengthwise
    w.reset_rows([0], np.array([[0.0, 30.0, 32.0]]), np.full((1, 3), 10.0), present=np.ones((1, 3), bool),
                 lateral=LateralPlan.still(np.array([[0.0, 0.0, 3.75]])), lengths=np.full((1, 3), 4.7),
                 width=np.full((1, 3), 1.8))
    assert w.neighbours.lead[0, 0] == 1 and w.neighbours.lead[0, 1] == -1


def test_a_plain_number_for_the_ego_equals_an_array():
    worlds = [make_world(3, B=4) for _ in range(2)]
    for w in worlds:
        randomise(w, np.random.default_rng(3))
    worlds[0].step(-1.5)
    worlds[1].step(np.full(4, -1.5))
    for name in ("x", "v", "a", "a_des"):
        assert np.array_equal(getattr(worlds[0], name), getattr(worlds[1], name)), name
    with pytest.raises(ValueError, match="ego_a_des"):
        worlds[0].step(float("nan"))


@pytest.mark.parametrize("ego_a", [0.0, -1.5])
def test_coast_in_one_compiled_call_equals_stepping(ego_a):
    """:meth:`SingleLaneWorld.coast` with baseline drivers, a profile and an absent vehicle (one
    compiled call) gives bit for bit what stepping the same world gives: every state's x and v,
    then the state, neighbours, observations, step counts, collision flags and the drivers'
    clocks (a later step of both worlds agrees too); scenes with a lane change and a collision
    course included. With an MPC driver it steps in Python, to the same numbers."""
    from acc_gym.drivers.population import sample_driver_values
    from acc_gym.drivers.slots import SlotDrivers, SlotView
    from acc_gym.scenarios.spec import DriverSpec
    from acc_gym.simulation import SpeedProfile

    B, S, steps = 4, 3, 45
    profile = SpeedProfile.from_segments(12.0, [(1.0, 2.0), (-3.0, 2.0), (0.0, 5.0)])
    specs = [DriverSpec("idm", {"v_desired": 20.0}), DriverSpec("acc", {"predecessors": 2}),
             DriverSpec.from_profile(profile), None, DriverSpec("gipps", {"tau": 0.2}), DriverSpec("idm", {}),
             DriverSpec("fuzzy", {}), DriverSpec("idm", {"time_gap": 0.8})]

    def world(specs):
        joint = SlotDrivers(B * (S - 1), 0.2)
        views = [SlotView(joint, j, B) for j in range(S - 1)]
        for r, spec in enumerate(specs):
            views[r // B].assign(r % B, spec)
        x0 = np.array([[0.0, 30.0, 60.0], [0.0, 12.0, 25.0], [0.0, 50.0, 52.0 + 4.7], [0.0, 8.0, 100.0]])
        v0 = np.array([[20.0, 15.0, 14.0], [25.0, 5.0, 0.0], [18.0, 18.0, 20.0], [30.0, 10.0, 22.0]])
        lateral = LateralPlan(np.array([[0.0, 3.75, 0.0]] * B), np.zeros((B, S)), np.full((B, S), 1.0),
                              np.full((B, S), 3.0))
        return SingleLaneWorld(x0, v0, [None, *views], lateral=lateral, road=Road(n_lanes=2), joint=joint)

    for kinds in (specs, specs[:-1] + [DriverSpec("mpc", sample_driver_values(np.random.default_rng(1), 20.0))]):
        fast, slow = world(kinds), world(kinds)
        compiled = fast.joint.compiled_laws() is not None
        assert compiled == (kinds is specs)
        xs, vs = fast.coast(steps, ego_a)
        x_ref, v_ref = [slow.x.copy()], [slow.v.copy()]
        for _ in range(steps):
            slow.step(ego_a)
            x_ref.append(slow.x.copy())
            v_ref.append(slow.v.copy())
        assert np.array_equal(xs, np.array(x_ref)) and np.array_equal(vs, np.array(v_ref))
        for name in ("x", "v", "a", "a_des", "y", "a_y", "k", "collided"):
            assert np.array_equal(getattr(fast, name), getattr(slow, name), equal_nan=True), name
        for f in fields(fast.neighbours):
            assert np.array_equal(getattr(fast.neighbours, f.name), getattr(slow.neighbours, f.name)), f.name
        assert np.array_equal(fast.observation_array(1), slow.observation_array(1))
        assert np.array_equal(fast.joint._clock, slow.joint._clock)
        assert np.array_equal(fast.joint.info["mode"], slow.joint.info["mode"])
        fast.step(0.3)
        slow.step(0.3)
        assert np.array_equal(fast.x, slow.x) and np.array_equal(fast.v, slow.v)
    assert fast.collided[1, 0]  # scene 1: the ego ran into the stopped POV2 (a collision inside the run)
    with pytest.raises(ValueError, match="ego_a_des"):
        fast.coast(3, float("nan"))
