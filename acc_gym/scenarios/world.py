"""Turn scenarios into a running :class:`~acc_gym.simulation.single_lane.SingleLaneWorld`.

``make_world(scenarios)`` builds one world for a batch of scenarios (same step ``dt``):
slot 0 the ego, slot 1 the POV, slot 2 the POV2 (absent where a scenario has none). The
surrounding drivers of each slot are a :class:`~acc_gym.drivers.slots.SlotDrivers`, as in
the environments, so all MPC drivers of a slot are one batched
:class:`~acc_gym.drivers.mpc.MPCDriver` whatever mix of scenarios the batch holds. ``simulate(scenario, ego)`` runs one scenario with an ego model to its end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acc_gym.drivers.mpc import MPCSettings
from acc_gym.drivers.slots import SlotDrivers
from acc_gym.scenarios.spec import ROLES, Scenario
from acc_gym.simulation.single_lane import LateralPlan, SingleLaneWorld, WorldTrace, rollout
from acc_gym.vehicle import VehicleParams

ABSENT_X = -1.0e6  # [m] where absent vehicles are parked (never anyone's target)


def _slot_driver(specs, dt: float, mpc_settings: MPCSettings | None):
    """The drivers of a slot over the batch, as the environments hold them
    (:class:`~acc_gym.drivers.slots.SlotDrivers`): ``specs[b]`` is scene ``b``'s DriverSpec or
    None (absent); None when no scene has a vehicle in the slot."""
    if all(spec is None for spec in specs):
        return None
    settings = mpc_settings if mpc_settings is not None else MPCSettings(dt=dt)
    if settings.dt != dt:
        raise ValueError(f"MPC settings dt={settings.dt} differs from the scenarios' dt={dt}")
    slot = SlotDrivers(len(specs), dt, settings)
    for b, spec in enumerate(specs):
        slot.assign(b, spec)
    return slot


@dataclass
class SceneArrays:
    """Initial arrays ``(B, 3)`` of a batch of scenarios, slot 0 the ego (absent slots parked)."""

    x0: np.ndarray
    v0: np.ndarray
    present: np.ndarray
    lateral: LateralPlan
    length: np.ndarray
    width: np.ndarray
    drivers: list  # per slot: per scene DriverSpec or None


def scene_arrays(scenarios, road) -> SceneArrays:
    """Lay ``scenarios`` out as arrays for :class:`SingleLaneWorld` (lateral moves on ``road``)."""
    B, S = len(scenarios), len(ROLES)
    # every float column as rows of Python numbers (x0, v0, y0, y1, t_start, duration, length, width), made
    # into arrays once: an absent slot is parked at ABSENT_X, still, in lane 0, 4.7 m by 1.8 m
    absent = (ABSENT_X, 0.0, 0.0, 0.0, 0.0, 1.0, 4.7, 1.8)
    rows = [[absent] * S for _ in range(B)]
    present = np.zeros((B, S), dtype=bool)
    lane_width = float(road.lane_width)
    specs = [[None] * B for _ in range(S)]
    for b, sc in enumerate(scenarios):
        row = rows[b]
        for v in sc.vehicles:
            s = ROLES.index(v.role)
            present[b, s] = True
            y = v.lane * lane_width  # Road.lane_centre's product, on numbers
            lc = v.lane_change
            if lc is not None:
                row[s] = (v.x0, v.v0, y, lc.to_lane * lane_width, lc.t_start, lc.duration, v.length, v.width)
            else:
                row[s] = (v.x0, v.v0, y, y, 0.0, 1.0, v.length, v.width)
            specs[s][b] = v.driver
    x0, v0, y0, y1, t_start, dur, length, width = np.ascontiguousarray(np.array(rows, dtype=float).transpose(2, 0, 1))
    # the lateral values are validated scenarios' (finite lanes, start times; durations > 0): not checked again
    return SceneArrays(x0, v0, present, LateralPlan.checked(y0, y1, t_start, dur), length, width, specs)


def make_world(scenarios, *, ego=None, mpc_settings: MPCSettings | None = None,
               sensor_range: float | None = None) -> SingleLaneWorld:
    """One world stepping ``scenarios`` together (``ego``: optional model for slot 0, ``n == B``)."""
    scenarios = [scenarios] if isinstance(scenarios, Scenario) else list(scenarios)
    if not scenarios:
        raise ValueError("make_world needs at least one scenario")
    dts = {s.dt for s in scenarios}
    if len(dts) != 1:
        raise ValueError(f"scenarios in one world must share dt, got {sorted(dts)}")
    roads = {s.road for s in scenarios}
    if len(roads) != 1:
        raise ValueError("scenarios in one world must share the road geometry")
    dt = dts.pop()
    road = roads.pop()
    arr = scene_arrays(scenarios, road)
    drivers = [ego] + [_slot_driver(arr.drivers[s], dt, mpc_settings) for s in range(1, len(ROLES))]
    kwargs = {} if sensor_range is None else {"sensor_range": sensor_range}
    return SingleLaneWorld(arr.x0, arr.v0, drivers, present=arr.present, lateral=arr.lateral,
                           vehicle=VehicleParams(length=arr.length), width=arr.width, road=road, dt=dt, **kwargs)


def simulate(scenario: Scenario, ego, **kwargs) -> WorldTrace:
    """Run ``scenario`` to its end with the ego driven by model ``ego`` (``n == 1``)."""
    world = make_world([scenario], **kwargs)
    return rollout(world, scenario.steps, ego=ego)
