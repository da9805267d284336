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


def _outcome(times, speeds):
    try:
        p = SpeedProfile(times, speeds)
    except ValueError as exc:
        return "error", str(exc)
    return "ok", p.times.tolist(), p.speeds.tolist(), p.times.dtype, p.speeds.dtype


def test_short_profiles_checked_as_floats_as_by_numpy(monkeypatch):
    """A short 1-D float64 profile is checked on Python floats (every reset builds a few):
    the same profile kept, or the same error, as the numpy checks give."""
    rng = np.random.default_rng(3)
    cases = [(np.array([0.0]), np.array([5.0])), (np.array([0.0, -0.0]), np.array([1.0, 1.0])),
             (np.array([-1.0, 0.0]), np.array([0.0, -0.0])), (np.array([0.0, np.inf]), np.array([1.0, 1.0])),
             (np.array([0.0, 1.0]), np.array([-np.inf, 1.0])), (np.array([np.nan, 1.0]), np.array([1.0, 1.0])),
             (np.arange(64.0), np.ones(64)), (np.arange(65.0), np.ones(65)), (np.arange(3), np.ones(3)),
             (np.array([0.0, 1.0]), np.array([1.0, 2.0], np.float32)), ([0.0, 1.0], [2.0, 3.0])]
    for _ in range(300):
        k = int(rng.integers(1, 8))
        t = np.cumsum(rng.choice([-1.0, 0.0, 0.5, 2.0], k, p=[0.05, 0.05, 0.6, 0.3]))
        v = rng.choice([-0.5, 0.0, 3.0, 20.0, np.nan, np.inf], k, p=[0.03, 0.2, 0.4, 0.33, 0.02, 0.02])
        cases.append((t, v))
    fast = [_outcome(t, v) for t, v in cases]
    monkeypatch.setattr("acc_gym.simulation.profiles._SHORT", 0)  # every profile through the numpy checks
    assert fast == [_outcome(t, v) for t, v in cases]
    assert {f[0] for f in fast} == {"ok", "error"}
    t, v = np.array([0.0, 2.0]), np.array([3.0, 3.0])
    monkeypatch.undo()
    p = SpeedProfile(t, v)
    assert p.times is t and p.speeds is v  # float64 arrays kept as given (np.asarray would keep them too)
