"""simulate_column plays a lead's speed profile on the profile's own clock, as ProfileDriver does."""

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDM
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import simulate_column


@pytest.mark.parametrize("t0", [0.0, 10.0, 0.4])
def test_a_profile_that_starts_later_brakes_at_its_own_time(t0):
    """20 m/s for 5 s, then -2 m/s^2 for 5 s, whatever the profile's start time: the lead
    brakes after 5 s of simulation and ends at 10 m/s after the profile's whole 10 s."""
    lead = SpeedProfile.from_segments(20.0, [(0.0, 5.0), (-2.0, 5.0)], t0=t0)
    tr = simulate_column(lead, [IDM()], [100.0, 0.0], [20.0, 20.0])
    v = tr.v[:, 0]
    assert v.shape[0] == 51  # the profile's duration, 10 s in 0.2 s steps
    assert np.all(v[:26] == pytest.approx(20.0))  # cruising for the first 5 s
    assert v[26] < 20.0 - 0.3  # then braking
    assert v[-1] == pytest.approx(10.0, abs=1e-6)
