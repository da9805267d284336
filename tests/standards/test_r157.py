"""UN R157 preventability against the careful and competent driver (cc-driver)."""

import pytest

from acc_gym.standards.r157 import grid, preventability, r157_cases, staged_cut_in


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
    assert set(fams["cut-out"][0]) == {"ego_speed", "other_speed", "gap", "time_headway"}
    assert len(fams["lead deceleration"]) == 18 and len(fams["cut-in"]) == 16 and len(fams["cut-out"]) == 18
    assert list(fams) == ["lead deceleration", "cut-in", "cut-out"]  # in this order


def test_conformance_json_carries_the_r157_cases(capsys):
    import json

    from acc_gym.cli import main

    assert main(["conformance", "constant", "--standard", "r157", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    r = d["standards"]["r157"]
    assert set(d["standards"]) == {"r157"} and r["preventable_collisions"] > 0
    for c in r["cases"]:
        assert {"family", "params", "controller_collides", "cc_driver_collides", "preventable"} <= set(c)
    cut_outs = [c for c in r["cases"] if c["family"] == "cut-out"]
    assert len(cut_outs) == 18
    assert all(set(c["params"]) == {"ego_speed", "other_speed", "gap", "time_headway"} for c in cut_outs)
    with pytest.raises(SystemExit):
        main(["conformance", "constant", "--standard", "r158"])


def test_evaluate_splits_its_collisions_by_preventability():
    from acc_gym.evaluation.runner import evaluate

    s = evaluate("constant", "acc_gym/NCAP-v0", episodes=3, seed=0, scenarios=("ncap/ccrs/30",))
    assert s["collisions"] == 3 and s["preventable_collisions"] == 3 and s["non_preventable_collisions"] == 0
    ok = evaluate("acc", "acc_gym/NCAP-v0", episodes=2, seed=0, scenarios=("ncap/ccrs/30",))
    assert ok["collisions"] == 0 and ok["preventable_collisions"] == 0
