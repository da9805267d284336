"""The ring's one step (acc_gym.simulation.ring.RingWorld): simulate_ring is a RingWorld stepped with
the controller's answers; every driver decides from one snapshot, then every vehicle moves; stand-ins
leave the ring's humans as they are; bad accelerations are named."""

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDMParams, idm_accel
from acc_gym.simulation.ring import CONTROLLER, RingWorld, ring_gaps, ring_layout, simulate_ring
from acc_gym.vehicle import VehicleParams, accel_lower, accel_upper


class Fixed:
    """A controller answering one action (a desired acceleration of ``0.1 * 3 = 0.3`` m/s^2)."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.array([0.1], dtype=np.float32), None


def _layout():
    lay = list(ring_layout(10, (4, 9)))
    lay[2] = "idm"
    return lay


def test_simulate_ring_is_the_world_stepped_with_the_controllers_answers():
    kw = dict(layout=_layout(), seeds=[3, 8], dt=0.2)
    tr = simulate_ring(120.0, 10, controller=Fixed(), duration=30.0, v0=1.0, **kw)
    world = RingWorld(120.0, 10, **kw)
    world.reset(v0=1.0)
    a_ctl = np.full(len(world.cells), float(np.float32(0.1)) * 3.0)  # the action scaled as the envs scale it
    assert world.cells.tolist() == [[0, 4], [0, 9], [1, 4], [1, 9]]
    s = [world.s.copy()]
    for _ in range(150):
        world.step(a_ctl)
        s.append(world.s.copy())
    np.testing.assert_array_equal(np.array(s), tr.s)
    np.testing.assert_array_equal(world.v, tr.v[-1])
    for name, counts in world.stats.items():
        np.testing.assert_array_equal(counts, tr.stats[name])


def test_every_driver_decides_from_the_snapshot_before_anyone_moves():
    # three IDM vehicles close together: each one's first acceleration is IDM's of the start, by hand
    p, L = IDMParams(v_desired=15.0), 40.0
    world = RingWorld(L, 3, layout=ring_layout(3, default="idm"), models={"idm": p})
    x0, v0 = np.array([30.0, 18.0, 3.0]), np.array([6.0, 8.0, 2.0])
    world.reset(v0=v0, x0=x0)
    v, a, gap, v_lead, a_lead = world.fields()
    np.testing.assert_allclose(gap[0], [3.0 + L - 30.0 - 4.7, 30.0 - 18.0 - 4.7, 18.0 - 3.0 - 4.7])
    np.testing.assert_array_equal(v_lead[0], [2.0, 6.0, 8.0])  # vehicle 0's leader is the last
    world.step()
    veh = VehicleParams()
    for i in range(3):
        want = idm_accel(v0[i], gap[0, i], v_lead[0, i] - v0[i], p.a, p.b, p.time_gap, p.s0, p.v_desired)
        assert world.a[0, i] == pytest.approx(np.clip(want, accel_lower(v0[i], veh), accel_upper(v0[i], veh)))
    assert world.k == 1 and world.t == pytest.approx(0.2)
    # the snapshot is now the new state's
    np.testing.assert_array_equal(world.fields()[2], ring_gaps(world.s, world.lengths, L))


def test_stand_ins_leave_the_rings_humans_as_they_are():
    kw = dict(layout=ring_layout(12, (11,)), seeds=[5], driver_model=6)
    plain, withs = RingWorld(150.0, 12, **kw), RingWorld(150.0, 12, standins=True, **kw)
    plain.reset()
    withs.reset()
    for k in range(100):
        a = np.array([0.5 if k < 40 else -0.2])
        plain.step(a)
        withs.step(a)
    np.testing.assert_array_equal(plain.s, withs.s)
    np.testing.assert_array_equal(plain.a, withs.a)


def test_stand_ins_drive_when_no_acceleration_is_given_and_reset_starts_afresh():
    world = RingWorld(230.0, 22, layout=ring_layout(22, (21,)), seeds=[2], standins=True)
    runs = []
    for _ in range(2):
        world.reset()
        for _ in range(300):
            world.step()
        runs.append(world.s.copy())
    np.testing.assert_array_equal(runs[0], runs[1])  # fresh drivers: the same 60 s again
    assert np.all(world.v >= 0) and np.all(world.gaps() > 0)
    assert world.s[0, 21] > 0.0 and world.layout[21] == CONTROLLER  # the stand-in drove the ego's position


def test_bad_accelerations_are_named():
    world = RingWorld(100.0, 5, layout=ring_layout(5, (4,), default="idm"), seeds=[0])
    world.reset()
    with pytest.raises(ValueError, match="no stand-ins"):
        world.step()
    with pytest.raises(ValueError, match=r"shape \(1,\), got \(2,\)"):
        world.step(np.zeros(2))
    with pytest.raises(ValueError, match=r"vehicle 4 \(controller\) asked for an acceleration of nan"):
        world.step(np.array([np.nan]))
    with pytest.raises(RuntimeError, match="reset"):
        RingWorld(100.0, 5).step()
