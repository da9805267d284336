"""What stands between a controller and the world in a car: the radar that measures the
vehicle ahead (:mod:`acc_gym.onboard.sensors`), the powertrain and brakes that realise
the commanded acceleration (:mod:`acc_gym.onboard.actuators`) and the V2V link of the
cooperative controllers (:mod:`acc_gym.onboard.v2v`), with named presets
(:mod:`acc_gym.onboard.presets`). ``gym.make(id, sensors="typical", actuators="typical")``."""

from acc_gym.onboard.actuators import ActuatorConfig, Actuators
from acc_gym.onboard.randomisation import Randomisation, randomisation
from acc_gym.onboard.presets import (ACTUATOR_PRESETS, PRESETS, SENSOR_PRESETS, V2V_PRESETS, actuator_config,
                                     describe, sensor_config, v2v_config)
from acc_gym.onboard.sensors import Radar, SensorConfig
from acc_gym.onboard.v2v import Link, V2VConfig

__all__ = ["ACTUATOR_PRESETS", "ActuatorConfig", "Actuators", "PRESETS", "Radar", "Randomisation", "SENSOR_PRESETS",
           "SensorConfig", "Link", "V2VConfig", "V2V_PRESETS", "actuator_config", "describe", "randomisation", "sensor_config",
           "v2v_config"]
