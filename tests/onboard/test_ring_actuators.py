"""The controller's actuators on the ring (simulate_ring(actuators=...), acc-gym ring --actuators)."""

import json

import numpy as np
import pytest

from acc_gym.cli import main
from acc_gym.simulation.ring import ring_layout, simulate_ring


class Constant:
    """Always asks for a tenth of the acceleration range (0.3 m/s^2)."""

    def predict(self, obs, deterministic=True):
        return np.full((np.asarray(obs).shape[0], 1) if np.ndim(obs) == 2 else (1,), 0.1, dtype=np.float32), None


def test_the_controlled_vehicle_realises_its_command_through_the_lag_and_dead_time():
    j = 5
    kw = dict(layout=ring_layout(10, (j,)), seeds=[0], duration=2.4, controller=Constant(), v0=5.0)
    plain = simulate_ring(200.0, 10, **kw)
    late = simulate_ring(200.0, 10, actuators={"lag": 0.4, "dead_time": 0.4}, **kw)
    alpha = 1 - np.exp(-0.2 / 0.4)
    k = np.arange(1, 13)  # a[k] is what was applied over step k - 1
    expected = np.where(k - 1 >= 2, 0.3 * (1 - (1 - alpha) ** (k - 2)), 0.0)
    np.testing.assert_allclose(late.a[1:, 0, j], expected, atol=1e-9)
    np.testing.assert_allclose(plain.a[1:, 0, j], 0.3, atol=1e-9)
    # the humans' vehicles have no actuator model: the same until the controlled vehicle's motion reaches them
    np.testing.assert_array_equal(plain.a[:3, 0, :j], late.a[:3, 0, :j])


def test_the_command_takes_the_actuator_options(capsys):
    args = ["ring", "acc", "--length", "230", "--vehicles", "12", "--duration", "90", "--warmup", "30", "--json"]
    assert main(args) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main(args + ["--actuator-lag", "1.0", "--actuator-delay", "0.6"]) == 0
    late = json.loads(capsys.readouterr().out)
    assert late["speed_sd"] != plain["speed_sd"]
    with pytest.raises(SystemExit):
        main(args + ["--actuator-delay", "-1"])
    assert "--actuator-delay: ActuatorConfig.dead_time" in capsys.readouterr().err
