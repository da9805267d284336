"""Scenario values are checked by type and within physical bounds, naming the field and the
limit (issue 20): nothing is accepted silently, nothing ends in a bare TypeError or
MemoryError."""

import copy
import json

import pytest

from acc_gym.scenarios import build
from acc_gym.scenarios.spec import MAX_DURATION, MAX_SPEED, Scenario


@pytest.fixture(scope="module")
def doc():
    return build("singlelane/2/car-following", seed=3).to_dict()


def changed(doc, path, value):
    d = copy.deepcopy(doc)
    target = d
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return d


@pytest.mark.parametrize("path,value,words", [
    (("duration",), 1e7, f"Scenario.duration must be at most {MAX_DURATION:g}"),
    (("duration",), 1e300, "Scenario.duration must be at most"),
    (("duration",), 1e-9, r"Scenario.duration must be at least two steps \(0.4 s\)"),
    (("duration",), "60", "Scenario.duration must be a number, got '60' \\(str\\)"),
    (("duration",), True, "Scenario.duration must be a number, got True \\(bool\\)"),
    (("schema_version",), True, "schema_version True is not supported"),
    (("schema_version",), 1.0, "schema_version 1.0 is not supported"),
    (("params", "v_ego"), True, r"Scenario.params\['v_ego'\] must be a number, got True"),
    (("params",), [1, 2], "Scenario.params must be a JSON object, got list"),
    (("drivers",), 123, "Scenario.drivers must be a string, got 123"),
    (("seed",), "abc", "Scenario.seed must be a non-negative integer, got 'abc'"),
    (("seed",), None, "Scenario.seed must be a non-negative integer, got None"),
    (("set_speed",), 1e9, f"Scenario.set_speed must be at most {MAX_SPEED:g}"),
    (("road", "length"), "x", "road.length must be a number, got 'x'"),
    (("vehicles", 1, "v0"), 1e5, f"POV.v0 \\(initial speed\\) must be at most {MAX_SPEED:g}"),
    (("vehicles", 1, "x0"), -10.0, "POV starts behind or overlapping the ego in its lane"),
    (("vehicles", 1, "lane"), 0.5, r"POV.lane \(a lane index\) must be a non-negative integer, got 0.5"),
])
def test_bad_values_are_refused_naming_the_field(doc, path, value, words):
    with pytest.raises(ValueError, match=words):
        Scenario.from_dict(changed(doc, path, value))


def test_profile_drivers_take_no_parameters_and_bounded_speeds(doc):
    from acc_gym.scenarios.spec import DriverSpec

    with pytest.raises(ValueError, match=r"a 'profile' driver takes no parameters, got \['k'\]"):
        DriverSpec("profile", {"k": 1.0}, (0.0, 1.0), (10.0, 10.0))
    with pytest.raises(ValueError, match=f"profile speed must be at most {MAX_SPEED:g}"):
        DriverSpec("profile", {}, (0.0, 1.0), (10.0, 1e5))


def test_deeply_nested_json_is_named():
    with pytest.raises(ValueError, match="nested too deeply"):
        Scenario.from_json("[" * 100000 + "]" * 100000)


def test_the_valid_document_still_round_trips(doc):
    sc = Scenario.from_dict(doc)
    assert Scenario.from_json(json.dumps(doc)) == sc and sc.to_dict() == doc
