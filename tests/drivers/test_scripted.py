"""Scripted drivers: ProfileDriver follows a speed profile within physics; DriverGroup routes sub-batches."""

import numpy as np
import pytest

from acc_gym.drivers.base import Observation
from acc_gym.drivers.baselines import IDM, Gipps, GippsParams, IDMParams
from acc_gym.drivers.scripted import DriverGroup, ProfileDriver
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import SingleLaneWorld, rollout
from acc_gym.vehicle import VehicleParams, accel_lower, accel_upper

DT = 0.2


def _drive(profile, n=1, dt=DT, steps=None, v0=None):
    """Run ``n`` lone vehicles driven by a ProfileDriver; returns the trace."""
    drv = ProfileDriver(profile, n=n, dt=dt)
    v0 = np.atleast_1d(profile.speed(profile.times[0]) if v0 is None else v0)
    w = SingleLaneWorld(np.zeros((n, 1)), np.broadcast_to(v0, (n,))[:, None], [drv], dt=dt)
    steps = steps if steps is not None else int(round(profile.duration / dt)) + 5
    return rollout(w, steps), drv


def test_feasible_profile_is_followed_exactly_at_every_step():
    p = SpeedProfile.from_segments(10.0, [(1.5, 4.0), (0.0, 3.0), (-3.0, 3.0), (0.7, 2.3), (0.0, 2.0)])
    tr, _ = _drive(p)
    assert np.max(np.abs(tr.v[:, 0, 0] - p.speed(tr.t))) < 1e-9
    # the realised accelerations are the profile's slopes (inside segments, away from breakpoints)
    assert tr.a[1:21, 0, 0] == pytest.approx(np.full(20, 1.5))
    assert np.all(tr.a[1:, 0, 0] <= 1.5 + 1e-9) and np.all(tr.a[1:, 0, 0] >= -3.0 - 1e-9)
    # the distance is the integral of the profile
    assert tr.x[-1, 0, 0] == pytest.approx(p.distance(tr.t[-1], dt=1e-3), abs=0.05)


def test_profile_with_offset_start_time_uses_its_own_clock():
    p = SpeedProfile.from_segments(5.0, [(1.0, 3.0), (-1.0, 3.0)], t0=100.0)
    tr, _ = _drive(p)
    assert np.max(np.abs(tr.v[:, 0, 0] - p.speed(100.0 + tr.t))) < 1e-9


def test_profile_braking_harder_than_tyres_is_followed_at_the_limit():
    p = SpeedProfile.from_segments(20.0, [(-15.0, 2.0), (0.0, 3.0)])
    tr, _ = _drive(p)
    v, a, a_des = tr.v[:, 0, 0], tr.a[:, 0, 0], tr.a_des[:, 0, 0]
    a_low = accel_lower(v[:-1], VehicleParams())
    limited = a_des[1:] < a_low  # asks for more than the tyres give
    assert limited.sum() >= 10
    assert a_des[1] == pytest.approx(-15.0) and np.all(a_des[2:4] < -15.0)  # then more, to catch up
    # there it brakes at exactly the tyre limit a_L(v) (about -8.6 m/s^2) ...
    assert np.allclose(a[1:][limited], a_low[limited])
    assert np.all(a[1:][limited] > -9.0)
    # ... elsewhere it gets what it asks for (or holds still once stopped)
    assert np.allclose(a[1:][~limited], np.where(v[:-1][~limited] > 1e-9, a_des[1:][~limited], 0.0), atol=1e-12)
    # it cannot follow: always at or above the profile, stops later than the profile does (4/3 s)
    assert np.all(v >= p.speed(tr.t) - 1e-12)
    k_stop = int(np.argmax(v < 1e-9))
    assert 20.0 / 15.0 < tr.t[k_stop] <= 20.0 / 8.5 + DT
    assert np.all(v[k_stop:] < 1e-9)  # then stands (no reversing)
    assert np.all(np.diff(tr.x[k_stop:, 0, 0]) < 1e-9)


def test_profile_accelerating_harder_than_the_engine_is_limited():
    p = SpeedProfile.from_segments(30.0, [(5.0, 2.0)])
    tr, _ = _drive(p, steps=10)
    v, a = tr.v[:, 0, 0], tr.a[:, 0, 0]
    assert np.allclose(a[1:], accel_upper(v[:-1], VehicleParams()))
    assert np.all(a[1:] < 5.0)


def test_batched_profile_each_vehicle_its_own_row():
    p = SpeedProfile(np.array([0.0, 2.0, 4.0]), np.array([[10.0, 12.0, 12.0], [20.0, 15.0, 15.0]]))
    drv = ProfileDriver(p, dt=DT)
    assert drv.n == 2
    tr, _ = _drive(p, n=2, v0=[10.0, 20.0], steps=25)
    assert np.max(np.abs(tr.v[:, :, 0] - p.speed(tr.t).T)) < 1e-9
    with pytest.raises(ValueError, match="2 rows for n=3"):
        ProfileDriver(p, n=3)
    # one profile shared by n vehicles
    shared = ProfileDriver(SpeedProfile.from_segments(10.0, [(1.0, 2.0)]), n=4, dt=DT)
    out = shared.act(Observation.build(v=np.full(4, 10.0)))
    assert out.shape == (4,) and np.allclose(out, 1.0)  # reach 10.2 m/s in 0.2 s


def test_reset_restarts_the_clock():
    p = SpeedProfile.from_segments(10.0, [(2.0, 5.0)])
    drv = ProfileDriver(p, n=1, dt=DT)
    obs = Observation.build(v=[10.0])
    first = [drv.act(obs)[0] for _ in range(3)]
    assert first == pytest.approx([2.0, 4.0, 6.0])  # target 10.4, 10.8, 11.2 from 10 m/s
    drv.reset()
    assert drv.act(obs)[0] == pytest.approx(first[0])
    # and a rollout (which resets) reproduces itself
    tr1, d = _drive(p)
    w = SingleLaneWorld([[0.0]], [[10.0]], [d])
    assert np.array_equal(rollout(w, 20).v, rollout(w, 20).v)


def test_profile_driver_validation():
    p = SpeedProfile.from_segments(10.0, [(1.0, 2.0)])
    with pytest.raises(ValueError, match="dt"):
        ProfileDriver(p, dt=0.0)
    with pytest.raises(ValueError, match="shape"):
        ProfileDriver(p, n=2).act(Observation.build(v=[1.0, 2.0, 3.0]))


# ----------------------------------------------------------------------------- DriverGroup
class Stub:
    """Constant output, with per-vehicle info and stats."""

    name = "stub"

    def __init__(self, n, value, mode):
        self.n, self.value, self.mode = n, value, mode
        self.resets = 0

    def reset(self):
        self.resets += 1

    def act(self, obs):
        obs.validate(self.n)
        self.info = {"mode": np.full(self.n, self.mode), "a_req": np.full(self.n, self.value), "other": 1}
        return np.full(self.n, self.value) + obs.v * 0.0

    @property
    def stats(self):
        return {"steps": np.full(self.n, 7, dtype=np.int64)}


def _obs(rng, n):
    v = rng.uniform(5, 30, n)
    gap = rng.uniform(5, 80, n)
    gap[::4] = np.inf
    return Observation.build(v=v, a=rng.uniform(-1, 1, n), gap=gap, v_lead=v + rng.uniform(-5, 5, n),
                             a_lead=rng.uniform(-1, 1, n))


def test_group_routes_sub_batches_exactly():
    idx1, idx2 = [5, 0, 2], [1, 4, 6, 3]  # unsorted: vehicle k of a model is index[k] of the batch
    p1 = IDMParams(v_desired=20.0, a=1.0, b=1.5, time_gap=np.array([1.0, 1.5, 2.0]))
    p2 = GippsParams(tau=0.6)  # with a reaction delay: per-model state must follow its vehicles
    group = DriverGroup([(IDM(p1, n=3), idx1), (Gipps(p2, n=4), idx2)], n=8)
    ref1, ref2 = IDM(p1, n=3), Gipps(p2, n=4)
    rng = np.random.default_rng(0)
    for _ in range(6):
        obs = _obs(rng, 8)
        out = group.act(obs)
        assert out.shape == (8,)
        assert np.array_equal(out[idx1], ref1.act(obs.take(idx1)))
        assert np.array_equal(out[idx2], ref2.act(obs.take(idx2)))
        assert out[7] == 0.0  # no model controls vehicle 7
    assert group.controlled.tolist() == [True] * 7 + [False]
    # the outputs really differ between the models (the routing is not trivially satisfied)
    same = obs.take(idx1)
    assert not np.allclose(IDM(p1, n=3).act(same), Gipps(p2, n=3).act(same))


def test_group_info_stats_and_reset():
    a, b = Stub(2, 1.5, 3), Stub(1, -2.0, 5)
    group = DriverGroup([(a, [3, 0]), (b, [2])], n=5)
    out = group.act(Observation.build(v=np.full(5, 10.0)))
    assert out.tolist() == [1.5, 0.0, -2.0, 1.5, 0.0]
    assert group.info["mode"].tolist() == [3, -1, 5, 3, -1]
    assert group.info["mode"].dtype.kind == "i"
    assert np.isnan(group.info["a_req"][[1, 4]]).all() and group.info["a_req"][2] == -2.0
    assert "other" not in group.info
    assert group.stats["steps"].tolist() == [7, 0, 7, 7, 0]
    group.reset()
    assert a.resets == 1 and b.resets == 1
    # a ProfileDriver inside a group restarts with the group
    prof = ProfileDriver(SpeedProfile.from_segments(10.0, [(2.0, 5.0)]), n=1, dt=DT)
    g2 = DriverGroup([(prof, [1])], n=2)
    obs = Observation.build(v=[0.0, 10.0])
    first = g2.act(obs).copy()
    g2.act(obs)
    g2.reset()
    assert np.array_equal(g2.act(obs), first)


def test_group_validation():
    with pytest.raises(ValueError, match="more than one model"):
        DriverGroup([(IDM(n=2), [0, 1]), (IDM(n=2), [1, 2])], n=3)
    with pytest.raises(ValueError, match=r"controls n=2 vehicles but was given 3"):
        DriverGroup([(IDM(n=2), [0, 1, 2])], n=3)
    with pytest.raises(ValueError, match=r"indices must lie in \[0, 3\)"):
        DriverGroup([(IDM(n=2), [1, 3])], n=3)
    with pytest.raises(ValueError, match=r"indices must lie in"):
        DriverGroup([(IDM(n=1), [-1])], n=3)


@pytest.mark.parametrize("size", [2, 4])
def test_group_rejects_observation_of_wrong_size(size):
    group = DriverGroup([(IDM(n=2), [0, 1])], n=3)
    with pytest.raises(ValueError, match="shape"):
        group.act(Observation.build(v=np.full(size, 10.0)))


def test_group_drives_a_world_like_the_separate_models():
    """Two scenes stepped as one batch with a grouped lead == each scene on its own."""
    prof = SpeedProfile.from_segments(15.0, [(0.0, 2.0), (-3.0, 3.0), (1.0, 4.0)])
    x0, v0 = np.array([[0.0, 40.0], [0.0, 30.0]]), np.array([[20.0, 15.0], [18.0, 22.0]])

    def lead_models():
        return ProfileDriver(prof, n=1, dt=DT), IDM(IDMParams(v_desired=22.0), n=1, dt=DT)

    m0, m1 = lead_models()
    batch = SingleLaneWorld(x0, v0, [None, DriverGroup([(m0, [0]), (m1, [1])], n=2)])
    tb = rollout(batch, 40, ego=IDM(IDMParams(v_desired=25.0), n=2))
    for b, m in enumerate(lead_models()):
        single = SingleLaneWorld(x0[b:b + 1], v0[b:b + 1], [None, m])
        ts = rollout(single, 40, ego=IDM(IDMParams(v_desired=25.0), n=1))
        assert np.allclose(ts.x[:, 0], tb.x[:, b]) and np.allclose(ts.v[:, 0], tb.v[:, b])
    assert np.max(np.abs(tb.v[:, 0, 1] - prof.speed(tb.t))) < 1e-9
