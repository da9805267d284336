"""Paper 003's car-following test at 60, 90 and 120 km/h (ids ``carfollowing/60`` ...).

Paper 003 (Section 4.2): a straight urban-expressway road of 1000 m, one lane per
direction (3.75 m wide); the background vehicle (BV, our POV) starts 20 m ahead of the
tested vehicle (TV, the ego), both at rest; the BV accelerates to the speed limit "with
irregular accelerations and decelerations", and about 50 m before the road's end brakes
to a stop in an emergency manoeuvre.

In the paper a human drives the BV in a simulator. Here its speed is a scripted profile
drawn from the scenario's generator, so each seed is a different, reproducible human-like
run (the leaderboard's suites use several seeds as "several drivers"):

* start-up: segments of 2-4 s at 0.8-1.8 m/s^2 (at most 1.4 above 20 m/s), with a
  30 % chance of a 1-2 s hesitation (-0.3 to 0.3 m/s^2) after each, and one slowdown
  (0.4-1.0 m/s^2 for 1.5-3 s) once past 40-75 % of the limit, until the limit (so every
  run has a deceleration before the stop, even at 120 km/h where no cruise dip fits),
  drawn again if it leaves no room to brake (about 1 in 1000 runs at 120 km/h);
* cruise: at the limit, with dips every 3-8 s -- slowing by 1.5-4.5 m/s (at most a
  quarter of the limit) at 0.4-1.2 m/s^2, then back at 0.5-1.0 m/s^2 -- as long as they fit;
* emergency stop: braking at ``brake_decel`` from the limit so that the BV's front bumper
  stops ``stop_margin`` before the road's end, then standing for ``hold`` seconds.

``carfollowing/varied`` (not in the paper; the ``-v1`` CarFollowing id trains on it) is
the same test drawn wider: a speed limit anywhere in 40-130 km/h, a final stop
braking at 2-8 m/s^2 (gentle to emergency) and a road of 1.5-3 km (so that the faster
runs have room to cruise and dip).

``carfollowing/emergency`` (not in the paper; for training and diagnosis) is
the final stop alone: the ego follows the lead at ``speed_limit`` (40-130 km/h), ``headway``
1-3 s behind (bumper gap over the ego's speed) and ``v_rel`` (lead minus ego, within
+-2 m/s) slower or faster; after ``t_brake`` (1-6 s) the lead brakes at ``brake_decel``
(3-8 m/s^2) to a stop and stands ``hold`` (4 s). The road ends 100 m past the lead's stop
(:data:`EMERGENCY_ROAD_MARGIN`). Decision: the box is kept inside what a careful driver
avoids (1 s is the shortest headway, 8 m/s^2 the hardest braking, the ego's own limit):
``tests/scenarios/test_catalogue.py`` runs ``cc-driver`` through its 16 corners.

Parameters (all with defaults; ``speed_limit`` comes from the id): ``brake_decel`` normal
(6.5, 0.7) m/s^2 in [5, 8] (hard but below the tyre limit of about 8.5 m/s^2),
``road_length`` 1000 m, ``start_gap`` 20 m, ``stop_margin`` 50 m, ``hold`` 8 s, and the
ego's ``time_gap`` 1.5 s. The ego's set speed is the speed limit.
"""

from __future__ import annotations

import numpy as np

from acc_gym.scenarios.distributions import Constant, Normal
from acc_gym.scenarios.registry import ScenarioType, register
from acc_gym.scenarios.spec import DriverSpec, Scenario, VehicleSpec
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import Road

LENGTH = 4.7  # [m]
SPEEDS_KMH = (60, 90, 120)
MAX_STARTUP_DRAWS = 50  # start-ups drawn before the road is declared too short


def bv_profile(rng: np.random.Generator, v_limit: float, x_start: float, x_stop: float, brake_decel: float,
               hold: float) -> SpeedProfile:
    """The BV's irregular speed profile from rest at ``x_start`` to rest at ``x_stop`` [m]."""
    x_brake = x_stop - v_limit ** 2 / (2.0 * brake_decel)
    for _ in range(MAX_STARTUP_DRAWS):  # a start-up that leaves room to brake (redrawn if not, rarely)
        segs: list[tuple[float, float]] = []
        v, x = 0.0, x_start

        def add(acc: float, dur: float) -> None:
            nonlocal v, x
            segs.append((acc, dur))
            x += v * dur + 0.5 * acc * dur * dur
            v += acc * dur

        dip_at = rng.uniform(0.4, 0.75) * v_limit  # one sure slowdown in the start-up
        dipped = False
        while v < v_limit - 1e-9:  # start-up
            acc = rng.uniform(0.8, 1.8 if v < 20.0 else 1.4)
            dur = min(rng.uniform(2.0, 4.0), (v_limit - v) / acc)
            add(acc, dur)
            if not dipped and v >= dip_at and v < v_limit - 1e-9:
                dipped = True
                dec = rng.uniform(0.4, 1.0)
                add(-dec, min(rng.uniform(1.5, 3.0), 0.25 * v / dec))
            if v < v_limit - 1e-9 and rng.random() < 0.3:
                hes = rng.uniform(-0.3, 0.3)
                hd = rng.uniform(1.0, 2.0)
                if v + hes * hd > 0.5:
                    add(hes, hd)
            if v > v_limit:
                v = v_limit
        if x <= x_brake:
            break
    else:
        raise ValueError(f"the road is too short for the BV to reach {v_limit:.1f} m/s and stop in time")
    while True:  # cruise with dips, while one more cruise + dip fits
        cruise = rng.uniform(3.0, 8.0)
        dv = min(rng.uniform(1.5, 4.5), 0.25 * v_limit)
        dec, acc = rng.uniform(0.4, 1.2), rng.uniform(0.5, 1.0)
        need = v_limit * cruise + (v_limit ** 2 - (v_limit - dv) ** 2) * (1 / (2 * dec) + 1 / (2 * acc))
        if x + need + 2.0 * v_limit > x_brake:
            break
        add(0.0, cruise)
        add(-dec, dv / dec)
        add(acc, dv / acc)
    add(0.0, (x_brake - x) / v_limit)
    add(-brake_decel, v_limit / brake_decel)
    profile = SpeedProfile.from_segments(0.0, segs + [(0.0, hold)])
    return SpeedProfile(profile.times, np.maximum(profile.speeds, 0.0))


def _build(stype: ScenarioType, p: dict, rng: np.random.Generator, drivers: str, seed: int) -> Scenario:
    v_limit = p["speed_limit"] / 3.6
    x_bv = p["start_gap"] + LENGTH
    profile = bv_profile(rng, v_limit, x_bv, p["road_length"] - p["stop_margin"], p["brake_decel"], max(p["hold"], 0.2))
    vehicles = (VehicleSpec("SV", 0.0, 0.0, 0, None, None, LENGTH),
                VehicleSpec("POV", x_bv, 0.0, 0, DriverSpec.from_profile(profile), None, LENGTH))
    return Scenario(id=stype.id, seed=seed, params=p, vehicles=vehicles, duration=profile.duration,
                    set_speed=v_limit, time_gap=p["time_gap"], road=Road(3.75, 1, p["road_length"]),
                    drivers=drivers, description=stype.description)


_POSITIVE = frozenset({"speed_limit", "brake_decel", "road_length", "start_gap", "stop_margin", "time_gap"})
_UNITS = {"speed_limit": "[km/h]", "brake_decel": "[m/s^2] the lead's emergency braking", "road_length": "[m]",
          "start_gap": "[m] initial bumper gap", "stop_margin": "[m] lead stops this far before the end",
          "hold": "[s] standing time at the end", "time_gap": "[s] ego's nominal time gap"}

for _kmh in SPEEDS_KMH:
    register(ScenarioType(
        f"carfollowing/{_kmh}", "carfollowing",
        f"Paper 003's car-following test at {_kmh} km/h: the lead starts 20 m ahead, accelerates irregularly to "
        f"the limit and stops in an emergency 50 m before the end of a 1000 m road.",
        {"speed_limit": Constant(float(_kmh)), "brake_decel": Normal(6.5, 0.7, low=5.0, high=8.0),
         "road_length": Constant(1000.0), "start_gap": Constant(20.0), "stop_margin": Constant(50.0),
         "hold": Constant(8.0), "time_gap": Constant(1.5)},
        _build, positive=_POSITIVE, nonnegative=frozenset({"hold"}), units=_UNITS))


# --- varied car-following for training: not in the paper -------------------------------------

register(ScenarioType(
    "carfollowing/varied", "carfollowing",
    "Paper 003's test drawn wider, for training: the lead starts 20 m ahead, accelerates irregularly to a "
    "speed limit anywhere in 40-130 km/h, dips, and stops at the end of the road braking anywhere from "
    "2 m/s^2 (a gentle stop) to 8 m/s^2 (an emergency); the road is 1.5-3 km long.",
    {"speed_limit": Normal(85.0, 60.0, low=40.0, high=130.0), "brake_decel": Normal(4.5, 2.5, low=2.0, high=8.0),
     "road_length": Normal(2250.0, 750.0, low=1500.0, high=3000.0), "start_gap": Constant(20.0),
     "stop_margin": Constant(50.0), "hold": Constant(8.0), "time_gap": Constant(1.5)},
    _build, positive=_POSITIVE, nonnegative=frozenset({"hold"}),
    units={**_UNITS, "brake_decel": "[m/s^2] the lead's braking to its final stop"}, in_paper=False))


# --- emergency stops from steady following, for training (not in the paper) ------------------

EMERGENCY_ROAD_MARGIN = 100.0  # [m] road left beyond the lead's stop (nothing there to reach)


def emergency_profile(v_lead: float, t_brake: float, brake_decel: float, hold: float) -> SpeedProfile:
    """The lead's profile in ``carfollowing/emergency``: ``t_brake`` [s] at ``v_lead`` [m/s],
    braking at ``brake_decel`` [m/s^2] to a stop, standing ``hold`` [s]."""
    return SpeedProfile.from_segments(v_lead, [(0.0, t_brake), (-brake_decel, v_lead / brake_decel), (0.0, hold)])


def _build_emergency(stype: ScenarioType, p: dict, rng: np.random.Generator, drivers: str, seed: int) -> Scenario:
    v_lead = p["speed_limit"] / 3.6  # [m/s]
    v_ego = v_lead - p["v_rel"]  # [m/s] (v_rel: lead minus ego, as in the single-lane family)
    if v_ego <= 0.0:
        raise ValueError(f"v_rel {p['v_rel']!r} m/s of {stype.id!r} leaves the ego no speed "
                         f"(lead at {v_lead:.3f} m/s): it must be below the lead's speed")
    gap = p["headway"] * v_ego  # [m] bumper to bumper
    x_lead = gap + LENGTH  # the lead's front bumper (the ego's front bumper at 0)
    profile = emergency_profile(v_lead, p["t_brake"], p["brake_decel"], max(p["hold"], 0.2))
    x_stop = x_lead + v_lead * p["t_brake"] + v_lead ** 2 / (2.0 * p["brake_decel"])
    vehicles = (VehicleSpec("SV", 0.0, v_ego, 0, None, None, LENGTH),
                VehicleSpec("POV", x_lead, v_lead, 0, DriverSpec.from_profile(profile), None, LENGTH))
    return Scenario(id=stype.id, seed=seed, params=p, vehicles=vehicles, duration=profile.duration,
                    set_speed=v_lead, time_gap=p["time_gap"], road=Road(3.75, 1, x_stop + EMERGENCY_ROAD_MARGIN),
                    drivers=drivers, description=stype.description)


register(ScenarioType(
    "carfollowing/emergency", "carfollowing",
    "Emergency stops from steady following, for training: the ego follows the lead at a speed limit anywhere "
    "in 40-130 km/h, 1-3 s behind, and after 1-6 s the lead brakes at 3-8 m/s^2 to a stop (paper 003's final "
    "stop without the kilometre before it).",
    {"speed_limit": Normal(85.0, 60.0, low=40.0, high=130.0), "headway": Normal(1.6, 0.5, low=1.0, high=3.0),
     "v_rel": Normal(0.0, 1.0, low=-2.0, high=2.0), "t_brake": Normal(3.0, 1.5, low=1.0, high=6.0),
     "brake_decel": Normal(6.0, 1.5, low=3.0, high=8.0), "hold": Constant(4.0), "time_gap": Constant(1.5)},
    _build_emergency, positive=frozenset({"speed_limit", "headway", "t_brake", "brake_decel", "time_gap"}),
    nonnegative=frozenset({"hold"}), in_paper=False,
    units={"speed_limit": "[km/h] the lead's speed and the ego's set speed",
           "headway": "[s] initial bumper gap over the ego's speed",
           "v_rel": "[m/s] lead's speed minus the ego's at the start",
           "t_brake": "[s] the lead's steady driving before it brakes",
           "brake_decel": "[m/s^2] the lead's braking to its stop",
           "hold": "[s] standing time at the end", "time_gap": "[s] ego's nominal time gap"}))
