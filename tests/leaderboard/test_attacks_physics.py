"""Round two: scenario values outside physical ranges are refused, each bound named.

Positions far from the origin lose float64's metres (the same scene shifted to x0 = 1e15 m
scored 76.97 instead of 78.67), and impossible values (a lead from 0 to 70 m/s in 0.01 s, IDM
with a = 1e300, a lead 1e9 m wide) passed; a reset with options='x' failed with a dict-update
message.
"""

import gymnasium as gym
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.scenarios import spec
from acc_gym.scenarios.registry import build
from acc_gym.scenarios.spec import Scenario
from acc_gym.suites import get_suite


def _scene() -> dict:
    return build("carfollowing/60", seed=3).to_dict()


def _with(role: str, **changes) -> dict:
    d = _scene()
    v = next(v for v in d["vehicles"] if v["role"] == role)
    v.update(changes)
    return d


@pytest.mark.parametrize("x0, ok", [(1e15, False), (-2e6, False), (9e5, True)])
def test_positions_beyond_float64s_metres_are_refused(x0, ok):
    d = _scene()
    shift = x0 - d["vehicles"][0]["x0"]
    for v in d["vehicles"]:
        v["x0"] += shift  # the same scene, shifted
    if ok:
        Scenario.from_dict(d)
    else:
        with pytest.raises(ValueError, match=r"SV.x0 must be within -1e\+06 and 1e\+06"):
            Scenario.from_dict(d)


def test_a_lead_wider_or_longer_than_a_road_vehicle_is_refused():
    with pytest.raises(ValueError, match=r"POV.width must be at most 5"):
        Scenario.from_dict(_with("POV", width=1e9))
    with pytest.raises(ValueError, match=r"POV.length must be at most 50"):
        Scenario.from_dict(_with("POV", length=120.0))


def test_a_profile_faster_than_a_road_vehicle_is_refused():
    d = _with("POV", driver={"model": "profile", "params": {}, "times": [0.0, 0.01, 60.0],
                             "speeds": [0.0, 70.0, 70.0]})
    with pytest.raises(ValueError, match=r"from 0 to 70 m/s between t = 0 and 0.01 s: 7000 m/s\^2, more than "
                                         r"a road vehicle's 20 m/s\^2 \(MAX_PROFILE_ACCEL\)"):
        Scenario.from_dict(d)


def test_a_driver_parameter_of_no_physical_size_is_refused():
    d = _with("POV", driver={"model": "idm", "params": {"a": 1e300}})
    with pytest.raises(ValueError, match=r"driver params\['a'\] \(MAX_DRIVER_PARAM\) must be within -1e\+09 and "
                                         r"1e\+09, got 1e\+300"):
        Scenario.from_dict(d)


def test_shipped_episodes_are_within_the_bounds():
    for name in ("ncap-v1", "carfollowing-v1", "malicious-v3"):
        for sc in get_suite(name).episodes("test"):
            assert all(abs(v.x0) <= spec.MAX_POSITION and v.width <= spec.MAX_WIDTH for v in sc.vehicles)


def test_reset_with_options_that_are_not_a_dict_names_them():
    env = gym.make("acc_gym/CarFollowing-v1")
    with pytest.raises(TypeError, match=r"reset\(options=...\) must be a dict \(keys \['scenario', 'time_gap'\]\) "
                                        r"or None, got str 'x'"):
        env.reset(options="x")
    env.reset(seed=0, options=None)
