"""Euro NCAP-style car-to-car rear tests with a scripted target (ids ``ncap/...``).

* ``ncap/ccrs/<v>``: Car-to-Car Rear stationary -- the target stands still, the ego
  approaches at ``v`` = 10, 15, ..., 50 km/h, starting at a time-to-collision of 4 s.
* ``ncap/ccrm/<v>``: Car-to-Car Rear moving -- the target drives at 20 km/h, the ego at
  ``v`` = 30, 35, ..., 80 km/h, starting at a time-to-collision of 4 s.
* ``ncap/ccrb/<d>-<g>``: Car-to-Car Rear braking -- both at 50 km/h, ``g`` = 12 or 40 m
  apart; after ``t_brake`` (2 s) the target brakes at ``d`` = 2 or 6 m/s^2 to a stop.

The target follows its speed profile (through the vehicle model); the ego's set speed is
its initial speed and its nominal time gap 1.5 s. Durations leave the ego time to stop
(or to settle behind the moving target): CCRs ``4 s + v/2 m/s^2 + 6 s``, CCRm 25 s,
CCRb ``t_brake + 50 km/h / d + 8 s``. Every value is a parameter (a constant law), so a
variant is one ``params`` away. Road: one 3.75 m lane.
"""

from __future__ import annotations

import numpy as np

from acc_gym.scenarios.distributions import Constant
from acc_gym.scenarios.registry import ScenarioType, register
from acc_gym.scenarios.spec import DriverSpec, Scenario, VehicleSpec
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import Road

LENGTH = 4.7  # [m]
TTC0 = 4.0  # [s] initial time-to-collision of CCRs and CCRm
CCRS_SPEEDS = tuple(range(10, 55, 5))  # [km/h]
CCRM_SPEEDS = tuple(range(30, 85, 5))  # [km/h]
CCRM_TARGET = 20.0  # [km/h]
CCRB_DECELS = (2, 6)  # [m/s^2]
CCRB_GAPS = (12, 40)  # [m]
CCRB_SPEED = 50.0  # [km/h]
ROAD = Road(3.75, 1)
UNITS = {"v_ego": "[km/h]", "v_target": "[km/h]", "gap": "[m] initial bumper gap",
         "decel": "[m/s^2] target braking", "t_brake": "[s] target starts braking", "duration": "[s]",
         "time_gap": "[s] ego's nominal time gap"}


POSITIVE = frozenset({"v_ego", "gap", "duration", "decel", "t_brake", "time_gap"})
NONNEGATIVE = frozenset({"v_target"})


def _build(stype: ScenarioType, p: dict, rng: np.random.Generator, drivers: str, seed: int) -> Scenario:
    kind = stype.id.split("/")[1]
    v_ego, v_t = p["v_ego"] / 3.6, p["v_target"] / 3.6
    if kind == "ccrb":
        profile = SpeedProfile.from_segments(v_t, [(0.0, p["t_brake"]), (-p["decel"], v_t / p["decel"]),
                                                   (0.0, max(p["duration"] - p["t_brake"] - v_t / p["decel"], 0.2))])
    else:
        profile = SpeedProfile(np.array([0.0, p["duration"]]), np.array([v_t, v_t]))
    vehicles = (VehicleSpec("SV", 0.0, v_ego, 0, None, None, LENGTH),
                VehicleSpec("POV", p["gap"] + LENGTH, v_t, 0, DriverSpec.from_profile(profile), None, LENGTH))
    return Scenario(id=stype.id, seed=seed, params=p, vehicles=vehicles, duration=p["duration"], set_speed=v_ego,
                    time_gap=p["time_gap"], road=ROAD, drivers=drivers, description=stype.description)


def _register_all() -> None:
    for v in CCRS_SPEEDS:
        ms = v / 3.6
        register(ScenarioType(
            f"ncap/ccrs/{v}", "ncap", f"CCRs: the ego at {v} km/h approaches a stationary target from a 4 s TTC.",
            {"v_ego": Constant(float(v)), "v_target": Constant(0.0), "gap": Constant(TTC0 * ms),
             "duration": Constant(round(TTC0 + ms / 2.0 + 6.0, 1)), "time_gap": Constant(1.5)},
            _build, units=UNITS, positive=POSITIVE, nonnegative=NONNEGATIVE))
    for v in CCRM_SPEEDS:
        closing = (v - CCRM_TARGET) / 3.6
        register(ScenarioType(
            f"ncap/ccrm/{v}", "ncap",
            f"CCRm: the ego at {v} km/h approaches a target at {CCRM_TARGET:.0f} km/h from a 4 s TTC.",
            {"v_ego": Constant(float(v)), "v_target": Constant(CCRM_TARGET), "gap": Constant(TTC0 * closing),
             "duration": Constant(25.0), "time_gap": Constant(1.5)},
            _build, units=UNITS, positive=POSITIVE, nonnegative=NONNEGATIVE))
    for d in CCRB_DECELS:
        for g in CCRB_GAPS:
            register(ScenarioType(
                f"ncap/ccrb/{d}-{g}", "ncap",
                f"CCRb: both at 50 km/h, {g} m apart; the target brakes at {d} m/s^2 to a stop after 2 s.",
                {"v_ego": Constant(CCRB_SPEED), "v_target": Constant(CCRB_SPEED), "gap": Constant(float(g)),
                 "decel": Constant(float(d)), "t_brake": Constant(2.0),
                 "duration": Constant(round(2.0 + CCRB_SPEED / 3.6 / d + 8.0, 1)), "time_gap": Constant(1.5)},
                _build, units=UNITS, positive=POSITIVE, nonnegative=NONNEGATIVE))


_register_all()
