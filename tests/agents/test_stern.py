"""Stern et al.'s FollowerStopper and PI-with-saturation (agents/controllers/stern.py), by hand."""

import numpy as np
import pytest

from acc_gym_agents.controllers import FollowerStopper, PISaturation


def _obs(v, gap, dv, set_speed=8.0):
    return np.array([v, 0.0, gap, dv, 1.0, set_speed, 1.5], dtype=np.float32)


@pytest.mark.parametrize("gap, want_cmd", [(4.0, 0.0), (5.0, 3.0 * 0.5 / 0.75), (5.625, 3.0 + (6.0 - 3.0) * 0.5),
                                           (8.0, 6.0)])
def test_follower_stopper_regions(gap, want_cmd):
    fs = FollowerStopper(v_des=6.0)  # U = 6; the lead drives at 3 m/s, the ego at 3 (dv = 0: dx = 4.5, 5.25, 6)
    act, _ = fs.predict(_obs(3.0, gap, 0.0))
    a = np.clip((want_cmd - 3.0) / 0.2, -3.0, 1.5)
    assert act[0] == pytest.approx(a / 3.0 if a >= 0 else a / 8.0, abs=1e-6)


def test_follower_stopper_thresholds_grow_with_closing_speed():
    fs = FollowerStopper(v_des=6.0)
    # closing at 2 m/s: dx_1 = 4.5 + 4 / 3 = 5.83 m, so at 5.5 m it commands a stop
    act, _ = fs.predict(_obs(5.0, 5.5, -2.0))
    assert act[0] == pytest.approx(-3.0 / 8.0)


def test_pi_saturation_tracks_its_own_average_and_resets():
    pi = PISaturation()
    o = np.stack([_obs(4.0, 40.0, 0.0), _obs(2.0, 3.0, 0.0)])
    pi.predict(o)
    # row 0: far behind (alpha = 1, beta = 1/2): v_cmd = (U + v_catch) / 2 with U = 4; row 1: close (alpha = 0, beta = 1): v_lead
    assert pi._v_cmd == pytest.approx([2.5, 2.0])
    pi.predict(o)
    assert pi._v_cmd == pytest.approx([0.5 * 5.0 + 0.5 * 2.5, 2.0])
    pi.reset()
    pi.predict(o)
    assert pi._v_cmd == pytest.approx([2.5, 2.0])
