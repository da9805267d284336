"""--sensors, --actuators, --actuator-lag and --actuator-delay on the commands."""

import json

import pytest

from acc_gym.cli import main
from acc_gym.evaluation.runner import evaluate
from acc_gym.onboard import ActuatorConfig


def test_evaluate_with_a_car_is_the_api_s_evaluate_with_it(capsys):
    assert main(["evaluate", "acc", "--env", "acc_gym/SingleLane-v1", "--episodes", "4", "--sensors", "degraded",
                 "--actuators", "typical", "--actuator-lag", "0.9", "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    api = evaluate("acc", "acc_gym/SingleLane-v1", 4, 0, sensors="degraded",
                   actuators=ActuatorConfig(lag=0.9, dead_time=0.1))  # typical's dead time, the lag replaced
    assert cli["scores"] == api["scores"]
    plain = evaluate("acc", "acc_gym/SingleLane-v1", 4, 0)
    assert plain["scores"] != api["scores"]


def test_string_stability_takes_the_actuator_options(capsys):
    assert main(["string-stability", "acc", "--vehicles", "3", "--time-gap", "1.0", "--actuator-delay", "1.0",
                 "--frequencies", "0.02", "0.1", "--no-disturbance", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["string_stable"] is False
    assert main(["string-stability", "acc", "--vehicles", "3", "--time-gap", "1.0",
                 "--frequencies", "0.02", "0.1", "--no-disturbance", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["string_stable"] is True


@pytest.mark.parametrize("argv,message", [
    (["evaluate", "acc", "--actuator-lag", "-2"], "--actuator-lag: ActuatorConfig.lag must be"),
    (["evaluate", "acc", "--actuator-delay", "nan"], "--actuator-delay: ActuatorConfig.dead_time must be"),
    (["evaluate", "acc", "--sensors", "foggy"], "invalid choice: 'foggy'"),
])
def test_bad_options_are_named(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err
