"""UN R157 preventability against the careful and competent driver (cc-driver)."""

import dataclasses

import numpy as np
import pytest

from acc_gym.scenarios.registry import scenario_type
from acc_gym.scenarios.spec import DriverSpec, LaneChange
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.standards.r157 import grid, preventability, r157_cases


def staged_cut_in(gap_at_intrusion: float = 2.0, closing: float = 10.0):
    """The ego at 30 m/s; a vehicle at 30 - closing m/s moves over in 1 s from t = 1 s and is in
    the ego's lane (0.4 s into its move) ``gap_at_intrusion`` ahead."""
    st = scenario_type("singlelane/2/cut-in")
    sc = st.build(st.sample_params(np.random.default_rng(0), {"v_sv": 30.0, "gap": 20.0, "v_rel": -closing,
                                                              "t_lc": 1.0, "lc_duration": 2.5, "duration": 10.0}),
                  0, "typical")
    sv, pov = sc.vehicles[:2]
    v = 30.0 - closing
    x_intrusion = sv.x0 + 30.0 * 1.4 + gap_at_intrusion + pov.length  # its front when it enters the lane
    pov = dataclasses.replace(pov, x0=x_intrusion - v * 1.4, v0=v,
                              driver=DriverSpec.from_profile(SpeedProfile.from_segments(v, [(0.0, 20.0)])),
                              lane_change=LaneChange(to_lane=pov.lane_change.to_lane, t_start=1.0, duration=1.0))
    return dataclasses.replace(sc, vehicles=(sv, pov) + tuple(sc.vehicles[2:]))


def test_a_staged_unavoidable_cut_in_is_non_preventable_for_every_controller():
    sc = staged_cut_in()
    for name in ("acc", "idm", "mpc", "constant", "ppo", "cc-driver"):
        r = preventability(name, sc)
        assert r["cc_driver_collides"] and r["controller_collides"] and r["preventable"] is False, name


def test_a_controller_that_never_brakes_has_preventable_collisions_and_the_cc_driver_none():
    never = r157_cases("constant")
    assert never["preventable_collisions"] >= 10
    # every lead deceleration it hits, the careful driver avoids: a collision it could have prevented
    assert all(c["preventable"] for c in never["cases"] if c["family"] == "lead deceleration")
    cc = r157_cases("cc-driver")
    assert cc["preventable_collisions"] == 0
    assert all(c["preventable"] in (None, False) for c in cc["cases"])
    assert len(cc["cases"]) == len(grid()) and not cc["errors"]


def test_case_parameters_are_the_documented_ones():
    fams = {}
    for family, params, _, _ in grid():
        fams.setdefault(family, []).append(params)
    assert set(fams["lead deceleration"][0]) == {"ego_speed", "lead_decel", "time_headway"}
    assert set(fams["cut-in"][0]) == {"ego_speed", "other_speed", "gap", "lateral_speed"}
    assert len(fams["lead deceleration"]) == 18 and len(fams["cut-in"]) == 16


def test_conformance_json_carries_the_r157_cases(capsys):
    import json

    from acc_gym.cli import main

    assert main(["conformance", "constant", "--standard", "r157", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    r = d["standards"]["r157"]
    assert set(d["standards"]) == {"r157"} and r["preventable_collisions"] > 0
    for c in r["cases"]:
        assert {"family", "params", "controller_collides", "cc_driver_collides", "preventable"} <= set(c)
    with pytest.raises(SystemExit):
        main(["conformance", "constant", "--standard", "r158"])
