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
    (("vehicles", 1, "driver", "params", "v_desired"), 1e5,
     rf"driver params\['v_desired'\] \(a speed of model 'mpc'\) must be at most {MAX_SPEED:g}, got 100000.0"),
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


# ----------------------------------------------------------------------------- build(id, params, seed, drivers)
@pytest.mark.parametrize("kwargs, words", [
    ({"seed": "abc"}, r"seed must be a non-negative integer, got 'abc' \(str\)"),
    ({"seed": None}, r"seed must be a non-negative integer, got None \(NoneType\)"),
    ({"seed": True}, r"seed must be a non-negative integer, got True \(bool\)"),
    ({"seed": 3.0}, r"seed must be a non-negative integer, got 3.0 \(float\)"),
    ({"seed": -1}, r"seed must be a non-negative integer, got -1"),
    ({"params": [1, 2]}, r"params of scenario 'singlelane/2/car-following' must be a dict .*got \[1, 2\] \(list\)"),
    ({"params": "gap=3"}, r"params of scenario .* must be a dict .*got 'gap=3' \(str\)"),
    ({"params": {3: 1.0}}, r"parameter names must be strings, got 3 \(int\)"),
    ({"params": {"duration": "30"}}, r"parameter 'duration' of '.*' must be a number, got '30'"),
    ({"drivers": ["idm"]}, r"unknown drivers \['idm'\]"),
])
def test_build_names_a_bad_seed_or_params(kwargs, words):
    with pytest.raises(ValueError, match=words):
        build("singlelane/2/car-following", **kwargs)


def test_build_accepts_numpy_integer_seeds_and_no_params():
    import numpy as np

    sc = build("singlelane/2/car-following", None, np.int64(3))
    assert sc == build("singlelane/2/car-following", {}, 3) and type(sc.seed) is int


def test_a_scenario_id_that_is_not_text_is_named():
    with pytest.raises(ValueError, match=r"a scenario id must be a string, got None \(NoneType\)"):
        build(None)


# ----------------------------------------------------------------------------- surrounding drivers' speeds
@pytest.mark.parametrize("model, name", [("idm", "v_desired"), ("gipps", "v_desired"), ("acc", "v_set"),
                                         ("mpc", "v_desired"), ("mpc", "v_max")])
def test_driver_speed_parameters_are_bounded_like_vehicle_speeds(model, name):
    from acc_gym.scenarios.spec import DriverSpec

    with pytest.raises(ValueError, match=rf"driver params\['{name}'\] \(a speed of model '{model}'\) must be at "
                                         rf"most {MAX_SPEED:g}, got 100000.0"):
        DriverSpec(model, {name: 1e5})
    with pytest.raises(ValueError, match=rf"driver params\['{name}'\] .* must be >= 0, got -1.0"):
        DriverSpec(model, {name: -1.0})
    assert DriverSpec(model, {name: MAX_SPEED}).params[name] == MAX_SPEED  # the limit itself is allowed


def test_every_speed_parameter_of_every_driver_model_is_bounded():
    """A model's speed parameters are its fields named ``v_*``: each must be in the bounded list."""
    from dataclasses import fields

    from acc_gym.drivers.baselines import MODELS
    from acc_gym.drivers.mpc import MPCDriverParams
    from acc_gym.scenarios.spec import DRIVER_SPEED_PARAMS

    names = {f.name for cls in [MPCDriverParams, *(m.params_type for m in MODELS.values())] for f in fields(cls)}
    speeds = {n for n in names if n.startswith("v_")}
    assert speeds and speeds <= set(DRIVER_SPEED_PARAMS)


# ----------------------------------------------------------------------------- the environment's scenario option
@pytest.fixture(scope="module")
def env():
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the environments)

    e = gym.make("acc_gym/CarFollowing-v0")
    yield e
    e.close()


@pytest.mark.parametrize("scenario, error, words", [
    (123, TypeError, r"options\['scenario'\] must be a scenario id or a Scenario, got int"),
    (["carfollowing/90"], TypeError, r"options\['scenario'\] must be a scenario id or a Scenario, got list"),
    ({"id": "carfollowing/90"}, TypeError, r"options\['scenario'\] must be a scenario id or a Scenario, got dict"),
    ("no/such", ValueError, r"unknown scenario id 'no/such'"),
])
def test_env_reset_names_a_bad_scenario_option(env, scenario, error, words):
    with pytest.raises(error, match=words):
        env.reset(seed=0, options={"scenario": scenario})
    _, info = env.reset(seed=0, options={"scenario": "carfollowing/90"})  # still usable, draws a valid seed
    assert info["scenario"] == "carfollowing/90" and type(info["scenario_seed"]) is int


@pytest.mark.parametrize("field,value,words", [
    ("x0", float("nan"), "POV.x0 must be finite"), ("x0", float("inf"), "POV.x0 must be finite"),
    ("v0", -0.5, r"POV.v0 \(initial speed\) must be >= 0"), ("v0", MAX_SPEED + 1.0, "must be at most"),
    ("length", 0.0, "POV.length must be > 0"), ("width", float("inf"), "POV.width must be finite"),
    ("lane", -1, r"POV.lane \(a lane index\) must be a non-negative integer"),
])
def test_a_vehicle_of_plain_floats_is_still_checked(field, value, words):
    """A builder's vehicle (plain floats, an int lane) skips the conversions but not the
    checks: each bad value is refused, naming the field; ints are still stored as floats."""
    from acc_gym.scenarios.spec import DriverSpec, VehicleSpec

    kwargs = {"role": "POV", "x0": 30.0, "v0": 20.0, "lane": 0, "driver": DriverSpec("idm", {"v_desired": 20.0}),
              "length": 4.7, "width": 1.8, field: value}
    with pytest.raises(ValueError, match=words):
        VehicleSpec(**kwargs)
    ok = VehicleSpec("POV", 30, 20, 0, kwargs["driver"], None, 5, 2)
    assert all(type(getattr(ok, f)) is float for f in ("x0", "v0", "length", "width"))


def test_a_drivers_parameters_object_is_made_once_and_checked_when_the_spec_is():
    import pickle

    from acc_gym.drivers.baselines import MODELS
    from acc_gym.scenarios.spec import DriverSpec

    spec = DriverSpec("idm", {"v_desired": 20.0})
    made = spec.params_object()
    assert made is spec.params_object() and made == MODELS["idm"].params_type(v_desired=20.0)
    assert spec == DriverSpec("idm", {"v_desired": 20.0}) and spec.to_dict() == {"model": "idm",
                                                                                 "params": {"v_desired": 20.0}}
    assert pickle.loads(pickle.dumps(spec)).params_object() == made
    with pytest.raises(ValueError, match="unknown parameter"):
        DriverSpec("idm", {"v_wanted": 20.0})
