"""The default reward: each term by hand, and following well beats parking or hanging back."""

import numpy as np
import pytest

from acc_gym.envs.reward import CriteriaReward, StepIndicators


def ind(**kw):
    base = dict(v=np.array([20.0]), a=np.array([0.0]), jerk=np.array([0.0]), set_speed=np.array([25.0]),
                has_lead=np.array([True]), gap=np.array([32.0]), gap_safe=np.array([30.0]), q=np.array([2.0]),
                in_band=np.array([True]), following=np.array([True]), free=np.array([False]),
                u=np.array([2.0 / 6.0]), violation=np.array([False]), collision=np.array([False]))
    base.update({k: np.atleast_1d(np.asarray(v)) for k, v in kw.items()})
    return StepIndicators(**base)


def test_terms_by_hand():
    r, t = CriteriaReward()(ind(a=1.5, jerk=5.0))
    assert t["band"][0] == 1.0
    assert t["efficiency"][0] == pytest.approx(0.5 * (1 - 1 / 3))
    assert t["speed"][0] == 0.0
    assert t["comfort"][0] == pytest.approx(-0.1 * 0.25)
    assert t["jerk"][0] == pytest.approx(-0.02 * 0.25)
    assert r[0] == pytest.approx(sum(v[0] for v in t.values()))
    r, t = CriteriaReward()(ind(following=False, in_band=False, free=True, v=22.5))
    assert t["speed"][0] == pytest.approx(1 - 2.5 / 5.0) and t["band"][0] == 0.0
    r, t = CriteriaReward()(ind(violation=True, collision=True))
    assert t["safety"][0] == -2.0 and t["collision"][0] == -100.0


def test_following_well_beats_parking_hanging_back_and_free_driving():
    reward = CriteriaReward()
    follow, _ = reward(ind())
    # parked behind a moving lead: a followable lead that it does not follow, nothing free either
    parked, _ = reward(ind(v=0.0, following=False, in_band=False, q=400.0, u=np.nan))
    # hanging back out of sensor range at the lead's speed: still a following sample, out of the band
    hanging, _ = reward(ind(gap=260.0, q=230.0, in_band=False, u=1.0))
    free, _ = reward(ind(following=False, in_band=False, free=True, v=25.0, has_lead=False))
    assert follow[0] > free[0] >= hanging[0] and hanging[0] <= 0.0 and parked[0] <= 0.0


def test_weights_are_validated():
    with pytest.raises(ValueError, match="band"):
        CriteriaReward(band=-1.0)
    with pytest.raises(ValueError, match="jerk_scale"):
        CriteriaReward(jerk_scale=0.0)


def test_lag_term_makes_standing_behind_a_moving_vehicle_cost():
    kw = dict(followable=np.array([True]), v_lead=np.array([20.0]), tau1=np.array([1.5]))
    far = 1.2 * 1.5 * 20.0 + 5.0  # 41 m
    _, t = CriteriaReward()(ind(gap=32.0, **kw))
    assert t["lag"][0] == 0.0  # inside the band's reach: no lag
    _, t = CriteriaReward()(ind(gap=far * 1.5, following=False, in_band=False, **kw))
    assert t["lag"][0] == pytest.approx(-0.5 * 0.5)
    parked, t = CriteriaReward()(ind(v=0.0, gap=500.0, following=False, in_band=False, u=np.nan, **kw))
    assert t["lag"][0] == -0.5 and parked[0] < 0.0  # parking now costs, instead of earning 0
    _, t = CriteriaReward()(ind(gap=500.0, followable=np.array([False]), v_lead=np.array([20.0]),
                                tau1=np.array([1.5])))
    assert t["lag"][0] == 0.0  # nothing followable: no lag
