"""Euro NCAP 2026's car-to-car test points with a scripted target (ids ``ncap2026/...``).

From 2026 Euro NCAP rates ACC performance itself (Safe Driving, "ACC performance") and
keeps the AEB car-to-car tests (Crash Avoidance, "Frontal Collisions"). The test points
are those of the official rating calculator's templates (``euroncap-rating-2026``:
``sd_template.xlsx`` sheet "VA - ACC pred." and ``ca_template.xlsx`` sheet
"FC - Car & PTW pred."); :data:`acc_gym.standards.ncap.ACC_POINTS` and
:data:`~acc_gym.standards.ncap.FC_POINTS` list them and a test checks them against the
installed calculator. Ids:

* ``ncap2026/acc/ccrs/<v>`` (60-130 km/h), ``ncap2026/acc/ccrm/<v>-<vt>`` (60-130 against
  20 km/h, 70-130 against 60 km/h): ACC approaches -- the ego cruises at its set speed ``v``
  and comes upon a stationary (CCRs) or slower (CCRm) target that starts ``gap`` = 210 m
  ahead, beyond the 200 m radar (decided here: an ACC test starts in steady cruise, before
  the target is in reach; the calculator gives no start distance);
* ``ncap2026/acc/ccrb/55-50``: the ego (set speed 55 km/h) follows a target at 50 km/h at
  1 s headway; 2 s in, the target brakes at 4 m/s^2 to a standstill (the headway and
  deceleration of the 2026 CCRb [S], see ``../shared/STANDARDS.md``);
* ``ncap2026/acc/cut-in/<v>-<vt>``: the ego cruises at ``v``; a target at ``vt`` in the next
  lane changes into the ego's lane (a half-cosine move over ``lc_duration`` = 2 s from
  ``t_lc`` = 2 s) and is in the lane -- its contour crosses the lane line, :mod:`~acc_gym.
  simulation.single_lane`'s target rule -- at the time-to-collision ``ttc`` [s] (decided
  here: TTC at lane intrusion, R157's reference point; the ego holds ``v`` until then);
* ``ncap2026/acc/cut-out/<v>-<vt>``: the ego (set speed ``v``) follows a lead at ``vt`` at
  its nominal time gap; 4 s in, the lead changes out over 2 s and reveals a stationary
  vehicle at ``ttc`` = 3 s from the ego (decided here: TTC when the lead's contour has left
  the ego's lane; the ego is at ``vt`` until then);
* ``ncap2026/fc/ccrs/<v>`` (10-80 km/h), ``ncap2026/fc/ccrm/<v>-<vt>`` (30-80 against 20,
  then 90/30 ... 130/70 km/h), ``ncap2026/fc/ccrb/<v>`` (30-130 km/h, both at ``v``, 1 s
  headway, the target brakes at 4 m/s^2 to a standstill 2 s in): the frontal-collision
  points, started as the AEB protocol starts them (CCRs / CCRm at a 4 s time-to-collision),
  driven here by the controller under test with nothing else to help it.

Every value is a parameter (a constant law), so a variant is one ``params`` away; the ego's
set speed is ``v_ego`` and its nominal time gap 1.5 s. Lateral offset (the calculator's
"Impact location") is not modelled: the model is longitudinal, so every test is at 100 %
overlap. Road: two 3.75 m lanes (the ego in lane 0).
"""

from __future__ import annotations

import math

import numpy as np

from acc_gym.scenarios.distributions import Constant
from acc_gym.scenarios.registry import ScenarioType, register
from acc_gym.scenarios.spec import DriverSpec, LaneChange, Scenario, VehicleSpec
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import VEHICLE_WIDTH, Road

LENGTH = 4.7  # [m]
ROAD = Road(3.75, 2)
ACC_START_GAP = 210.0  # [m] ACC approaches start beyond the 200 m radar
FC_TTC0 = 4.0  # [s] frontal-collision CCRs / CCRm start at this time-to-collision
CCRB_HEADWAY = 1.0  # [s]
CCRB_DECEL = 4.0  # [m/s^2]
T_BRAKE = 2.0  # [s] the CCRb target starts braking
T_LC, LC_DURATION = 2.0, 2.0  # [s] cut-in: the lateral move starts at / lasts
T_CO = 4.0  # [s] cut-out: the lead's lateral move starts
TIME_GAP = 1.5  # [s] the ego's nominal time gap
ACC_CCRS = tuple(range(60, 140, 10))  # [km/h]
ACC_CCRM = tuple((v, 20) for v in range(60, 140, 10)) + tuple((v, 60) for v in range(70, 140, 10))
ACC_CCRB = ((55, 50),)
ACC_CUT_IN = ((50, 10, 0.0), (120, 70, 1.5))  # (VUT, target [km/h], TTC [s])
ACC_CUT_OUT = ((70, 50, 3.0), (90, 70, 3.0))
FC_CCRS = tuple(range(10, 90, 10))
FC_CCRM = tuple((v, 20) for v in range(30, 90, 10)) + ((90, 30), (100, 40), (110, 50), (120, 60), (130, 70))
FC_CCRB = tuple(range(30, 140, 10))
UNITS = {"v_ego": "[km/h] the ego's test speed and set speed", "v_target": "[km/h] the target's (lead's) speed",
         "gap": "[m] initial bumper gap", "decel": "[m/s^2] target braking", "t_brake": "[s] target starts braking",
         "ttc": "[s] time-to-collision at the cut-in's lane intrusion / the cut-out's reveal",
         "t_lc": "[s] the lateral move starts", "lc_duration": "[s] the lateral move lasts",
         "duration": "[s]", "time_gap": "[s] ego's nominal time gap"}
POSITIVE = frozenset({"v_ego", "gap", "duration", "decel", "t_brake", "time_gap", "lc_duration"})
NONNEGATIVE = frozenset({"v_target", "ttc", "t_lc"})


def intrusion_fraction(lane_width: float = ROAD.lane_width, width: float = VEHICLE_WIDTH) -> float:
    """How far through a half-cosine lane change (0-1) a vehicle's contour crosses into the
    lane it moves to: ``y(s) = W (1 + cos(pi s)) / 2`` meets ``(W + w) / 2`` (the target rule
    of :mod:`acc_gym.simulation.single_lane`) at ``cos(pi s) = w / W``."""
    return math.acos(width / lane_width) / math.pi


def reveal_fraction(lane_width: float = ROAD.lane_width, width: float = VEHICLE_WIDTH) -> float:
    """How far through a half-cosine lane change its contour has left the lane it started in."""
    return math.acos(-width / lane_width) / math.pi


def _constant(v: float, duration: float) -> DriverSpec:
    return DriverSpec.from_profile(SpeedProfile(np.array([0.0, max(duration, 0.2)]), np.array([v, v])))


def _scenario(stype, p, seed, drivers, vehicles, v0_set) -> Scenario:
    return Scenario(id=stype.id, seed=seed, params=p, vehicles=vehicles, duration=p["duration"], set_speed=v0_set,
                    time_gap=p["time_gap"], road=ROAD, drivers=drivers, description=stype.description)


def _build(stype: ScenarioType, p: dict, rng: np.random.Generator, drivers: str, seed: int) -> Scenario:
    kind = stype.id.split("/")[2]
    v_ego, v_t, dur = p["v_ego"] / 3.6, p["v_target"] / 3.6, p["duration"]
    if kind == "ccrb":
        profile = SpeedProfile.from_segments(v_t, [(0.0, p["t_brake"]), (-p["decel"], v_t / p["decel"]),
                                                   (0.0, max(dur - p["t_brake"] - v_t / p["decel"], 0.2))])
        vehicles = (VehicleSpec("SV", 0.0, v_t, 0, None, None, LENGTH),
                    VehicleSpec("POV", p["gap"] + LENGTH, v_t, 0, DriverSpec.from_profile(profile), None, LENGTH))
    elif kind == "cut-in":
        t_in = p["t_lc"] + intrusion_fraction() * p["lc_duration"]  # [s] lane intrusion
        gap_in = p["ttc"] * (v_ego - v_t)  # [m] at the intrusion
        x_pov = (v_ego - v_t) * t_in + gap_in + LENGTH  # its front at t = 0
        vehicles = (VehicleSpec("SV", 0.0, v_ego, 0, None, None, LENGTH),
                    VehicleSpec("POV", x_pov, v_t, 1, _constant(v_t, dur), LaneChange(0, p["t_lc"], p["lc_duration"]),
                                LENGTH))
    elif kind == "cut-out":
        t_rev = p["t_lc"] + reveal_fraction() * p["lc_duration"]  # [s] the lead has left the lane
        x_stopped = v_t * t_rev + p["ttc"] * v_t + LENGTH  # its front: ttc * v_t ahead of the ego then
        vehicles = (VehicleSpec("SV", 0.0, v_t, 0, None, None, LENGTH),
                    VehicleSpec("POV", p["time_gap"] * v_t + LENGTH, v_t, 0, _constant(v_t, dur),
                                LaneChange(1, p["t_lc"], p["lc_duration"]), LENGTH),
                    VehicleSpec("POV2", x_stopped, 0.0, 0, _constant(0.0, dur), None, LENGTH))
    else:  # ccrs / ccrm: an approach to a target at constant speed
        vehicles = (VehicleSpec("SV", 0.0, v_ego, 0, None, None, LENGTH),
                    VehicleSpec("POV", p["gap"] + LENGTH, v_t, 0, _constant(v_t, dur), None, LENGTH))
    return _scenario(stype, p, seed, drivers, vehicles, v_ego)


def _add(sid: str, description: str, params: dict) -> None:
    laws = {k: Constant(float(round(v, 6))) for k, v in params.items()}
    register(ScenarioType(sid, "ncap2026", description, laws, _build, in_paper=False, units=UNITS,
                          positive=POSITIVE, nonnegative=NONNEGATIVE))


def _approach(v: float, vt: float, gap: float) -> dict:
    closing = (v - vt) / 3.6
    stop = v / 3.6 / 2.0 if vt == 0 else 10.0  # [s] time to stop at 2 m/s^2, or to settle behind
    return {"v_ego": v, "v_target": vt, "gap": gap, "duration": round(gap / closing + stop + 8.0, 1),
            "time_gap": TIME_GAP}


def _ccrb(v_set: float, v: float) -> dict:
    return {"v_ego": v_set, "v_target": v, "gap": CCRB_HEADWAY * v / 3.6, "decel": CCRB_DECEL, "t_brake": T_BRAKE,
            "duration": round(T_BRAKE + v / 3.6 / CCRB_DECEL + 8.0, 1), "time_gap": TIME_GAP}


def _register_all() -> None:
    for v in ACC_CCRS:
        _add(f"ncap2026/acc/ccrs/{v}", f"ACC CCRs: cruising at {v} km/h onto a stationary target from 210 m.",
             _approach(v, 0, ACC_START_GAP))
    for v, vt in ACC_CCRM:
        _add(f"ncap2026/acc/ccrm/{v}-{vt}", f"ACC CCRm: cruising at {v} km/h onto a target at {vt} km/h from 210 m.",
             _approach(v, vt, ACC_START_GAP))
    for v, vt in ACC_CCRB:
        _add(f"ncap2026/acc/ccrb/{v}-{vt}", f"ACC CCRb: set speed {v} km/h, following a target at {vt} km/h at "
             f"1 s headway; it brakes at 4 m/s^2 to a stop 2 s in.", _ccrb(v, vt))
    for v, vt, ttc in ACC_CUT_IN:
        _add(f"ncap2026/acc/cut-in/{v}-{vt}", f"ACC cut-in: cruising at {v} km/h; a target at {vt} km/h changes "
             f"into the lane, in it at a TTC of {ttc:g} s.",
             {"v_ego": v, "v_target": vt, "ttc": ttc, "t_lc": T_LC, "lc_duration": LC_DURATION,
              "duration": round(T_LC + LC_DURATION + 15.0, 1), "time_gap": TIME_GAP})
    for v, vt, ttc in ACC_CUT_OUT:
        _add(f"ncap2026/acc/cut-out/{v}-{vt}", f"ACC cut-out: set speed {v} km/h, following a lead at {vt} km/h "
             f"that changes out and reveals a stationary vehicle at a TTC of {ttc:g} s.",
             {"v_ego": v, "v_target": vt, "ttc": ttc, "t_lc": T_CO, "lc_duration": LC_DURATION,
              "duration": round(T_CO + LC_DURATION + ttc + vt / 3.6 / 2.0 + 8.0, 1), "time_gap": TIME_GAP})
    for v in FC_CCRS:
        _add(f"ncap2026/fc/ccrs/{v}", f"FC CCRs: the ego at {v} km/h onto a stationary target from a 4 s TTC.",
             _approach(v, 0, FC_TTC0 * v / 3.6))
    for v, vt in FC_CCRM:
        _add(f"ncap2026/fc/ccrm/{v}-{vt}", f"FC CCRm: the ego at {v} km/h onto a target at {vt} km/h from a 4 s TTC.",
             _approach(v, vt, FC_TTC0 * (v - vt) / 3.6))
    for v in FC_CCRB:
        _add(f"ncap2026/fc/ccrb/{v}", f"FC CCRb: both at {v} km/h, 1 s apart; the target brakes at 4 m/s^2 to a "
             f"stop 2 s in.", _ccrb(v, v))


_register_all()
