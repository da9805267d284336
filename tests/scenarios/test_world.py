"""``acc_gym.scenarios.world.scene_arrays``: a batch of scenarios laid out as the world's
initial arrays, checked against the layout written out vehicle by vehicle (the definition:
each role's slot, its lane's centre by :meth:`Road.lane_centre`, its lane change, absent
slots parked still in lane 0)."""

from __future__ import annotations

import numpy as np

from acc_gym.scenarios import build, list_scenarios
from acc_gym.scenarios.spec import ROLES
from acc_gym.scenarios.world import ABSENT_X, scene_arrays


def reference_layout(scenarios, road) -> dict:
    B, S = len(scenarios), len(ROLES)
    out = {"x0": np.full((B, S), ABSENT_X), "v0": np.zeros((B, S)), "present": np.zeros((B, S), dtype=bool),
           "y0": np.zeros((B, S)), "y1": np.zeros((B, S)), "t_start": np.zeros((B, S)), "duration": np.ones((B, S)),
           "length": np.full((B, S), 4.7), "width": np.full((B, S), 1.8)}
    for b, sc in enumerate(scenarios):
        for v in sc.vehicles:
            s = ROLES.index(v.role)
            out["present"][b, s] = True
            out["x0"][b, s], out["v0"][b, s] = v.x0, v.v0
            out["y0"][b, s] = out["y1"][b, s] = road.lane_centre(v.lane)
            if v.lane_change is not None:
                out["y1"][b, s] = road.lane_centre(v.lane_change.to_lane)
                out["t_start"][b, s], out["duration"][b, s] = v.lane_change.t_start, v.lane_change.duration
            out["length"][b, s], out["width"][b, s] = v.length, v.width
    return out


def test_scene_arrays_equal_the_layout_vehicle_by_vehicle():
    ids = list_scenarios("singlelane") + ["ncap/ccrs/30", "carfollowing/90"]
    scenarios = [build(sid, seed=seed, drivers=drivers) for seed, drivers in ((3, "idm"), (8, "typical"))
                 for sid in ids]
    road = scenarios[0].road
    arr = scene_arrays(scenarios, road)
    ref = reference_layout(scenarios, road)
    got = {"x0": arr.x0, "v0": arr.v0, "present": arr.present, "y0": arr.lateral.y0, "y1": arr.lateral.y1,
           "t_start": arr.lateral.t_start, "duration": arr.lateral.duration, "length": arr.length, "width": arr.width}
    for name, value in got.items():
        assert value.shape == (len(scenarios), len(ROLES)) and value.flags.c_contiguous, name
        assert value.dtype == ref[name].dtype and np.array_equal(value, ref[name]), name
    assert (arr.lateral.y1 != arr.lateral.y0).any() and (~arr.present).any()  # lane changes and absent slots met
    for s, role in enumerate(ROLES):
        for b, sc in enumerate(scenarios):
            spec = next((v.driver for v in sc.vehicles if v.role == role), None)
            assert arr.drivers[s][b] is spec
