"""The same work as ``acc_gym/SingleLane-v0`` with IDM drivers, in SUMO through libsumo.

A straight single-lane road; a lead and two IDM followers (SUMO's ``IDM`` car-following
model: a 1.5 m/s^2, b 2.0 m/s^2, T 1.5 s, s0 2 m, desired speed 25 m/s, vehicles 4.7 m
long), one of them ahead
of the ego and one behind (the lead, POV ahead of the ego, POV2 behind, as in paper 004's
three-vehicle configurations), and an ego whose speed is set every step (its own safety
checks off, ``setSpeedMode(0)``: the controller under test decides) and read back with
its leader's gap and speed, as an environment's observation needs. Steps of 0.2 s, one
``load`` (reload) per 200-step episode, counted in the time like an environment's reset.
The ego's commanded acceleration alternates between +0.3 and -0.3 m/s^2 (random actions
in [-0.3, 0.3] in :mod:`bench_env`).

Needs ``libsumo`` (``pip install ".[bench]"``); :func:`available` says whether it is
importable. libsumo runs one simulation per process, so this module keeps one.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time

EPISODE_STEPS = 200
DT = 0.2  # [s]

_NET = """<?xml version="1.0" encoding="UTF-8"?>
<net version="1.20" junctionCornerDetail="5" limitTurnSpeed="5.50">
    <location netOffset="0.00,0.00" convBoundary="0.00,0.00,20000.00,0.00"
              origBoundary="0.00,0.00,20000.00,0.00" projParameter="!"/>
    <edge id="road" from="A" to="B" priority="-1">
        <lane id="road_0" index="0" speed="50.00" length="20000.00" shape="0.00,-1.60 20000.00,-1.60"/>
    </edge>
    <junction id="A" type="dead_end" x="0.00" y="0.00" incLanes="" intLanes="" shape="0.00,0.00 0.00,-3.20"/>
    <junction id="B" type="dead_end" x="20000.00" y="0.00" incLanes="road_0" intLanes=""
              shape="20000.00,-3.20 20000.00,0.00"/>
</net>
"""
_ROUTES = """<routes>
  <vType id="idm" carFollowModel="IDM" accel="1.5" decel="2.0" tau="1.5" minGap="2.0" length="4.7"
         maxSpeed="25" speedFactor="1" speedDev="0" emergencyDecel="9"/>
  <vType id="ego" accel="3" decel="9" length="4.7" minGap="2.0" maxSpeed="40" speedFactor="1" speedDev="0"
         emergencyDecel="9"/>
  <route id="r" edges="road"/>
  <vehicle id="lead" type="idm" route="r" depart="0" departPos="300" departSpeed="25"/>
  <vehicle id="pov" type="idm" route="r" depart="0" departPos="250" departSpeed="25"/>
  <vehicle id="ego" type="ego" route="r" depart="0" departPos="200" departSpeed="25"/>
  <vehicle id="pov2" type="idm" route="r" depart="0" departPos="150" departSpeed="25"/>
</routes>
"""
_state: dict = {}


def _libsumo():
    """libsumo, imported with its import-time notices (e.g. "Warning! pyarrow is installed with
    version ..." when pyarrow's version differs from the one SUMO was built against) sent to
    stderr: ``bench_env.py --json`` prints one JSON document on stdout and nothing else."""
    with contextlib.redirect_stdout(sys.stderr):
        import libsumo
    return libsumo


def available() -> bool:
    try:
        _libsumo()
    except ImportError:
        return False
    return True


def _sim():
    if "traci" not in _state:
        libsumo = _libsumo()
        folder = tempfile.mkdtemp(prefix="acc_gym_sumo_")
        for name, text in (("road.net.xml", _NET), ("road.rou.xml", _ROUTES)):
            with open(os.path.join(folder, name), "w") as fh:
                fh.write(text)
        args = ["-n", os.path.join(folder, "road.net.xml"), "-r", os.path.join(folder, "road.rou.xml"),
                "--step-length", str(DT), "--no-step-log", "true", "--no-warnings", "true",
                "--collision.action", "none"]
        libsumo.start(["sumo", *args])
        _state.update(traci=libsumo, args=args)
    return _state["traci"], _state["args"]


def episode(steps: int = EPISODE_STEPS) -> tuple[float, float, float]:
    """Reload and run one episode; returns the ego's last (speed, gap, leader speed)."""
    traci, args = _sim()
    traci.load(args)
    traci.simulationStep()  # the vehicles depart
    traci.vehicle.setSpeedMode("ego", 0)
    v, gap, v_lead = traci.vehicle.getSpeed("ego"), float("inf"), 0.0
    for k in range(steps - 1):
        a = 0.3 if k % 7 < 3 else -0.3  # [m/s^2]
        traci.vehicle.setSpeed("ego", max(v + a * DT, 0.0))
        traci.simulationStep()
        v = traci.vehicle.getSpeed("ego")
        leader = traci.vehicle.getLeader("ego", 500.0)
        if leader and leader[0]:
            gap, v_lead = leader[1], traci.vehicle.getSpeed(leader[0])
    return v, gap, v_lead


def rate(steps: int) -> float:
    """Steps per second over ``steps`` steps (whole episodes, reloads included)."""
    n = max(1, round(steps / EPISODE_STEPS))
    t0 = time.perf_counter()
    for _ in range(n):
        episode()
    return n * EPISODE_STEPS / (time.perf_counter() - t0)
