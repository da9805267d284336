"""Column rollouts: two-phase update, batching, recording, validation."""

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDM, Gipps
from acc_gym.drivers.mpc import MPCDriver, preset
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import simulate_column
from acc_gym.vehicle import VehicleParams, applied_acceleration, integrate

LENGTH = VehicleParams().length


class Recorder:
    """A follower that holds a constant request and records what it saw."""

    def __init__(self, n=1, a=0.0):
        self.n, self.a, self.seen = n, a, []

    def reset(self):
        self.seen = []

    def act(self, obs):
        self.seen.append(obs)
        return np.full(self.n, self.a)


def test_two_phase_update_every_driver_sees_the_same_snapshot():
    lead = SpeedProfile.from_segments(20.0, [(-2.0, 2.0)])
    r1, r2 = Recorder(a=1.0), Recorder(a=-1.0)
    tr = simulate_column(lead, [r1, r2], [60.0, 30.0, 0.0], [20.0, 20.0, 20.0], duration=2.0)
    for k in range(len(r1.seen)):
        # follower 2 sees follower 1 where it was at the start of the step, not after it moved
        assert r2.seen[k].gap[0] == pytest.approx(tr.x[k, 1] - LENGTH - tr.x[k, 2])
        assert r2.seen[k].v_lead[0] == pytest.approx(tr.v[k, 1])
        assert r1.seen[k].gap[0] == pytest.approx(tr.x[k, 0] - LENGTH - tr.x[k, 1])
    # and positions follow the exact integration of the applied accelerations
    veh = VehicleParams()
    x, v = tr.x[0], tr.v[0]
    for k in range(tr.t.size - 1):
        a = applied_acceleration(tr.a_des[k + 1], v, veh)
        x, v = integrate(x, v, a, 0.2)
        assert np.allclose(x, tr.x[k + 1]) and np.allclose(v, tr.v[k + 1])


def test_order_of_models_does_not_matter():
    lead = SpeedProfile.from_segments(15.0, [(1.0, 5.0), (-2.0, 5.0), (0.0, 5.0)])
    a = simulate_column(lead, [IDM(), Gipps()], [80.0, 40.0, 0.0], [15.0, 15.0, 15.0])
    # the same vehicles, the models built fresh in the other order of construction
    g, i = Gipps(), IDM()
    b = simulate_column(lead, [i, g], [80.0, 40.0, 0.0], [15.0, 15.0, 15.0])
    assert np.array_equal(a.x, b.x)


def test_batch_equals_single_columns():
    lead = SpeedProfile.from_segments(15.0, [(1.0, 5.0), (-2.0, 5.0), (0.0, 5.0)])
    B = 3
    x0 = np.array([[40.0, 0.0], [50.0, 0.0], [60.0, 0.0]])
    batch = simulate_column(SpeedProfile(lead.times, np.tile(lead.speeds, (B, 1))), [IDM(n=B)], x0,
                            np.full((B, 2), 15.0), batch=B)
    for b in range(B):
        single = simulate_column(lead, [IDM()], x0[b], [15.0, 15.0])
        assert np.allclose(batch.x[:, b], single.x)


def test_sensor_range_and_stop_line():
    lead = SpeedProfile(np.array([0.0, 60.0]), np.array([30.0, 30.0]))
    d = MPCDriver(preset("#57", v_desired=20.0))
    tr = simulate_column(lead, [d], [1000.0, 0.0], [30.0, 20.0], sensor_range=150.0, stop_position=300.0)
    # nothing in range: the driver stops at the stop line, front bumper at or before it
    assert tr.x[-1, 1] <= 300.0 + 1e-6
    assert tr.x[-1, 1] >= 299.0
    assert tr.v[-1, 1] == 0.0


@pytest.mark.parametrize("kw,match", [(dict(x0=[10.0, 8.0]), "behind"), (dict(v0=[1.0, -1.0]), "v0"),
                                      (dict(dt=0.0), "dt"), (dict(x0=[10.0, np.nan]), "x0")])
def test_bad_setups(kw, match):
    args = dict(x0=[40.0, 0.0], v0=[10.0, 10.0], dt=0.2)
    args.update(kw)
    lead = SpeedProfile(np.array([0.0, 5.0]), np.array([10.0, 10.0]))
    with pytest.raises(ValueError, match=match):
        simulate_column(lead, [IDM()], args["x0"], args["v0"], dt=args["dt"])
    with pytest.raises(ValueError, match="one per column"):
        simulate_column(lead, [IDM(n=2)], [40.0, 0.0], [10.0, 10.0])
