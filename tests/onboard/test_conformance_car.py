"""acc-gym conformance in a car: the controller drives with the car, R157's reference without it."""

import json

from acc_gym.cli import main
from acc_gym.standards.conformance import conformance
from acc_gym.standards.r157 import r157_cases


def test_the_controller_drives_in_the_car_and_the_reference_without_it():
    car = {"actuators": {"lag": 0.8, "dead_time": 0.6}}
    plain = r157_cases("acc", families="lead deceleration")
    slow = r157_cases("acc", families="lead deceleration", car=car)
    assert [c["cc_driver_collides"] for c in slow["cases"]] == [c["cc_driver_collides"] for c in plain["cases"]]
    assert sum(c["controller_collides"] for c in slow["cases"]) > sum(c["controller_collides"] for c in plain["cases"])
    again = r157_cases("acc", families="lead deceleration", car={**car, "sensors": "degraded"})
    assert again == r157_cases("acc", families="lead deceleration", car={**car, "sensors": "degraded"})  # seeded


def test_the_report_names_the_car(capsys):
    result = conformance("acc", ["iso15622"], seeds=(0,), car={"actuators": "degraded"})
    assert result["car"]["actuators"] == {"lag": 0.7, "dead_time": 0.25}
    ideal = conformance("acc", ["iso15622"], seeds=(0,))
    assert "car" not in ideal
    assert result["standards"]["iso15622"]["requirements"] != ideal["standards"]["iso15622"]["requirements"]
    assert main(["conformance", "acc", "--standard", "iso15622", "--seeds", "0", "--actuators", "degraded",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["car"] == result["car"] and out["standards"]["iso15622"]["passed"] == \
        result["standards"]["iso15622"]["passed"]
