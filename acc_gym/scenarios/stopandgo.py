"""Stop-and-go traffic (id ``stopandgo``): a queue that keeps stopping and starting.

Three vehicles start at rest in a queue, ``queue_gap`` apart. POV2 drives a scripted
stop-and-go wave drawn from the scenario's generator: stand 2-6 s, pull away at
1.0-1.8 m/s^2 to a peak speed (normal around ``v_peak``, in [2, 15] m/s), cruise 2-8 s,
brake at 1.0-2.5 m/s^2 to a stop, again until ``duration``. The POV between it and the
ego is a surrounding driver (human-like MPC by default), so the ego faces a human's
reactions to the wave, not the wave itself. The ego's set speed is ``set_speed``.
"""

from __future__ import annotations

import numpy as np

from acc_gym.scenarios.distributions import Constant, Normal
from acc_gym.scenarios.registry import ScenarioType, driver_for, register
from acc_gym.scenarios.spec import DriverSpec, Scenario, VehicleSpec
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import Road

LENGTH = 4.7  # [m]


def wave_profile(rng: np.random.Generator, v_peak: float, duration: float) -> SpeedProfile:
    """POV2's stop-and-go speed profile from rest, at least ``duration`` [s] long."""
    segs: list[tuple[float, float]] = []
    t = 0.0
    while t < duration:
        peak = float(np.clip(rng.normal(v_peak, 2.0), 2.0, 15.0))
        up, down = rng.uniform(1.0, 1.8), rng.uniform(1.0, 2.5)
        cycle = [(0.0, rng.uniform(2.0, 6.0)), (up, peak / up), (0.0, rng.uniform(2.0, 8.0)), (-down, peak / down)]
        segs += cycle
        t += sum(d for _, d in cycle)
    profile = SpeedProfile.from_segments(0.0, segs + [(0.0, 1.0)])
    return SpeedProfile(profile.times, np.maximum(profile.speeds, 0.0))


def _build(stype: ScenarioType, p: dict, rng: np.random.Generator, drivers: str, seed: int) -> Scenario:
    wave = wave_profile(rng, p["v_peak"], p["duration"])
    g = p["queue_gap"]
    pov = driver_for(rng, drivers, max(p["v_peak"] + 3.0, 5.0))
    vehicles = (VehicleSpec("SV", 0.0, 0.0, 0, None, None, LENGTH),
                VehicleSpec("POV", g + LENGTH, 0.0, 0, pov, None, LENGTH),
                VehicleSpec("POV2", 2 * (g + LENGTH), 0.0, 0, DriverSpec.from_profile(wave), None, LENGTH))
    return Scenario(id=stype.id, seed=seed, params=p, vehicles=vehicles, duration=p["duration"],
                    set_speed=p["set_speed"], time_gap=p["time_gap"], road=Road(3.75, 2), drivers=drivers,
                    description=stype.description)


register(ScenarioType(
    "stopandgo", "stopandgo",
    "Stop-and-go queue: POV2 drives a scripted stop-and-go wave, a human-like POV follows it, the ego follows the POV.",
    {"v_peak": Normal(8.0, 2.0, low=3.0, high=14.0), "duration": Constant(120.0), "queue_gap": Constant(5.0),
     "set_speed": Constant(20.0), "time_gap": Constant(1.5)},
    _build, in_paper=False, positive=frozenset({"v_peak", "duration", "queue_gap", "set_speed", "time_gap"}),
    units={"v_peak": "[m/s] typical peak speed of the wave", "duration": "[s]", "queue_gap": "[m] initial bumper gaps",
           "set_speed": "[m/s] ego's set speed", "time_gap": "[s] ego's nominal time gap"}))
