"""Scenarios: what the ego faces.

* :mod:`~acc_gym.scenarios.singlelane` -- paper 004's 22 single-lane configurations
  (plus ``separate``), with parameter laws;
* :mod:`~acc_gym.scenarios.carfollowing` -- paper 003's car-following test at 60, 90 and
  120 km/h;
* :mod:`~acc_gym.scenarios.ncap` -- Euro NCAP-style CCRs / CCRm / CCRb;
* :mod:`~acc_gym.scenarios.stopandgo` -- a stop-and-go queue;
* :mod:`~acc_gym.scenarios.distributions` and :mod:`~acc_gym.scenarios.calibration` --
  the parameter laws (normal, log-normal, Laplace, bivariate normal) and their fitting
  (maximum likelihood; expectation maximisation with missing values);
* :mod:`~acc_gym.scenarios.montecarlo` -- hours of traffic by occurrence rates.

A scenario is a plain value (:class:`Scenario`, JSON round-trip) built from
``(id, params, seed)``::

    from acc_gym import scenarios
    scenarios.list_scenarios("ncap")
    print(scenarios.describe("singlelane/2/cut-in"))
    sc = scenarios.build("singlelane/2/cut-in", seed=3)
    trace = scenarios.simulate(sc, ego_model)
"""

from acc_gym.scenarios.montecarlo import traffic, traffic_hour
from acc_gym.scenarios.registry import (DRIVER_CHOICES, ScenarioType, build, calibrate, describe, families,
                                        list_scenarios, scenario_type)
from acc_gym.scenarios.spec import SCHEMA_VERSION, DriverSpec, LaneChange, Scenario, VehicleSpec
from acc_gym.scenarios.world import make_world, simulate

__all__ = [
    "DRIVER_CHOICES", "DriverSpec", "LaneChange", "SCHEMA_VERSION", "Scenario", "ScenarioType", "VehicleSpec",
    "build", "calibrate", "describe", "families", "list_scenarios", "make_world", "scenario_type", "simulate",
    "traffic", "traffic_hour",
]
