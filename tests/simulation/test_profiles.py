"""Scripted and recorded lead speed profiles."""

import numpy as np
import pytest

from acc_gym.simulation.profiles import SpeedProfile


def test_segments_build_the_expected_speeds_and_stop_at_zero():
    p = SpeedProfile.from_segments(10.0, [(2.0, 5.0), (0.0, 3.0), (-5.0, 10.0)])
    assert p.speed(0.0) == 10.0
    assert p.speed(5.0) == pytest.approx(20.0)
    assert p.speed(8.0) == pytest.approx(20.0)
    assert p.speed(12.0) == pytest.approx(0.0)  # 20 m/s at -5 m/s^2 stops after 4 s, then holds
    assert p.speed(17.0) == 0.0
    assert p.duration == pytest.approx(18.0)
    assert p.distance(8.0) == pytest.approx(10 * 5 + 0.5 * 2 * 25 + 20 * 3, rel=1e-3)


def test_recorded_and_batched_profiles():
    p = SpeedProfile.recorded([0.0, 1.0, 2.0], [0.0, 1.0, 4.0])
    assert p.speed(1.5) == pytest.approx(2.5)
    b = SpeedProfile(np.array([0.0, 1.0]), np.array([[0.0, 1.0], [2.0, 2.0]]))
    assert np.allclose(b.speed(0.5), [0.5, 2.0])


@pytest.mark.parametrize("times,speeds,match", [([0.0, 0.0], [1.0, 1.0], "increasing"),
                                                ([0.0, 1.0], [1.0, -1.0], ">= 0"),
                                                ([0.0, 1.0], [1.0, np.nan], "finite"),
                                                ([0.0, 1.0], [1.0, 2.0, 3.0], "shape")])
def test_bad_profiles(times, speeds, match):
    with pytest.raises(ValueError, match=match):
        SpeedProfile(np.array(times), np.array(speeds))
    with pytest.raises(ValueError, match="duration"):
        SpeedProfile.from_segments(1.0, [(1.0, 0.0)])
