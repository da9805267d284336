"""UN R157's cut-out family: the staged geometry, the careful and competent driver's stopping
distance as its avoid/collide boundary, and preventable collisions of a controller that never
brakes."""

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the environments)
from acc_gym.evaluation.runner import run_episode
from acc_gym.scenarios.singlelane import LENGTH
from acc_gym.standards.r157 import (CUT_OUT_GRID, CUT_OUT_HEADWAY, CUT_OUT_ID, CUT_OUT_OTHER_LENGTH, CUT_OUT_REVEAL,
                                    ENV_ID, grid, plot_map, r157_cases, staged_cut_out)
from acc_gym_agents.controllers.cc_driver import CCDriver

DT = 0.2  # [s] the environment's step
K_REVEAL = int(round(CUT_OUT_REVEAL / DT))  # the reveal's step
KMH = 1 / 3.6  # [m/s] per km/h


class NeverBrakes:
    """Action 0 (no acceleration) whatever it sees: holds its initial speed."""

    def predict(self, obs, deterministic=True):
        return np.zeros(1, dtype=np.float32)


def cut_out_closing_distance(w: float, hold: float = 0.0) -> float:
    """How far [m] the C&C driver closes in on a vehicle w m/s slower (w = its speed for a stopped
    one) from the cut-out's reveal until it no longer closes: 0.4 s perception at the held
    acceleration ``hold`` [m/s^2], 0.75 s reaction at min(hold, -0.4 m/s^2), a ramp to 0.774 g
    in 0.6 s (jerk 12.65 m/s^3; it starts at the reaction's 0.4 m/s^2), then 0.774 g. By hand
    from the model's published numbers, not from the module."""
    t_p, t_r, b, ramp = 0.4, 0.75, 0.774 * 9.80665, 0.6
    d_r = max(-hold, 0.4)
    jerk = b / ramp
    s = w * t_p + 0.5 * hold * t_p ** 2
    w += hold * t_p
    s += w * t_r - 0.5 * d_r * t_r ** 2
    w -= d_r * t_r
    s1 = d_r / jerk  # [s] where the ramp passes the reaction's deceleration
    s += w * s1 - 0.5 * d_r * s1 ** 2
    w -= d_r * s1
    t = ramp - s1  # [s] the rest of the ramp: deceleration d_r + jerk t
    assert w > d_r * t + 0.5 * jerk * t ** 2  # (still closing at the end of the ramp at these speeds)
    s += w * t - 0.5 * d_r * t ** 2 - jerk * t ** 3 / 6
    w -= d_r * t + 0.5 * jerk * t ** 2
    return s + w * w / (2 * b)


@pytest.fixture(scope="module")
def env():
    e = gym.make(ENV_ID)
    yield e
    e.close()


def test_closing_distance_by_hand():
    # 60 km/h onto a stopped car: 6.667 m perceiving, 12.387 m reacting (down to 16.367 m/s),
    # about 9.36 m on the ramp (down to 14.09 m/s), 13.08 m at 7.59 m/s^2: 41.5 m, above 2 s x speed
    assert cut_out_closing_distance(60 * KMH) == pytest.approx(41.5, abs=0.1)
    assert cut_out_closing_distance(60 * KMH) > 2.0 * 60 * KMH
    # the larger the speed, the more the 1.15 s before braking alone costs
    for v in (60 * KMH, 90 * KMH, 120 * KMH):
        assert cut_out_closing_distance(v) > 1.15 * v + v * v / (2 * 0.774 * 9.80665)


def test_the_staged_cut_out_has_the_declared_geometry_at_the_reveal(env):
    for v, v_other, gap in ((60 * KMH, 0.0, 25.0), (90 * KMH, 20 * KMH, 62.5), (120 * KMH, 0.0, 116.0),
                            (25.0, 10.0, 40.0)):
        sc = staged_cut_out(v, CUT_OUT_HEADWAY, v_other, gap)
        assert [x.role for x in sc.vehicles] == ["SV", "POV", "POV2"] and sc.id == CUT_OUT_ID
        assert sc.params == {"ego_speed": v, "time_headway": CUT_OUT_HEADWAY, "other_speed": v_other, "gap": gap}
        ego, lead, other = sc.vehicles
        assert lead.x0 - lead.length - ego.x0 == pytest.approx(CUT_OUT_HEADWAY * v)  # [m] bumper gap at t = 0
        assert lead.lane == other.lane == ego.lane and lead.lane_change.to_lane == ego.lane + 1
        assert other.length == CUT_OUT_OTHER_LENGTH
        info, tr = run_episode(env, NeverBrakes(), scenario=sc)
        # the ego sees the lead up to the step before the reveal and the other vehicle from the reveal on
        assert tr.lead[K_REVEAL - 1, 0, 0] == 1 and tr.lead[K_REVEAL, 0, 0] == 2
        assert tr.gap[K_REVEAL, 0, 0] == pytest.approx(gap, abs=1e-6)  # [m]
        assert tr.v[K_REVEAL, 0, 0] == pytest.approx(v, abs=1e-9)  # [m/s]
        assert tr.v[K_REVEAL, 0, 2] == pytest.approx(v_other, abs=1e-9)  # [m/s]
        assert tr.v[K_REVEAL, 0, 1] == pytest.approx(v, abs=1e-9)  # the lead kept its speed
        # the lead's contour leaves the ego's lane half a step before the reveal: its offset is the
        # corridor half-width (lane 3.75 m + width 1.8 m) / 2 there, on the half-cosine move
        lc = lead.lane_change
        phase = (CUT_OUT_REVEAL - DT / 2 - lc.t_start) / lc.duration
        assert 3.75 * 0.5 * (1 - math.cos(math.pi * phase)) == pytest.approx((3.75 + lead.width) / 2, abs=1e-9)
        assert lc.duration == 3.0  # [s]: mean lateral speed 1.25 m/s
        # the lead never reached the other vehicle while they shared the lane
        shared = tr.lead[:, 0, 1] == 2
        assert shared[:K_REVEAL - 1].all() and not shared[K_REVEAL:].any()
        assert tr.gap[shared, 0, 1].min() > 0.0
        assert info["report"]["metrics"]["collision"]  # it never braked: it hits the slower vehicle


def test_staged_cut_out_rejects_bad_values_naming_them():
    v = 60 * KMH
    with pytest.raises(ValueError, match=r"gap 20\.0 m leaves the lead no room"):
        staged_cut_out(v, 1.0, 0.0, 20.0)  # the lead (front 16.7 + 4.7 m ahead) would reach it first
    with pytest.raises(ValueError, match=r"other_speed .* got 20\.0"):
        staged_cut_out(v, 1.0, 20.0, 40.0)  # not slower: nothing to reveal
    with pytest.raises(ValueError, match="gap must be a finite number, got nan"):
        staged_cut_out(v, 1.0, 0.0, float("nan"))
    with pytest.raises(ValueError, match="time_headway must be a finite number, got True"):
        staged_cut_out(v, True, 0.0, 40.0)
    with pytest.raises(ValueError, match=r"ego_speed must be in \(0, 70\] m/s, got 80"):
        staged_cut_out(80, 1.0, 0.0, 200.0)
    with pytest.raises(ValueError, match=r"time_headway must be in \(0, 10\] s, got -1"):
        staged_cut_out(v, -1, 0.0, 40.0)
    with pytest.raises(ValueError, match="r157_cases: families must name some of .* got \\['cut out'\\]"):
        r157_cases("constant", families="cut out")


def test_without_its_2s_gate_the_cc_driver_avoids_exactly_beyond_its_stopping_distance(env):
    """The C&C response alone (its 2 s headway gate lifted): onto a stopped vehicle it collides when
    the distance at the reveal is below the closed-form stopping distance and avoids above, the
    boundary within one step of the gap sweep."""
    step = 1.5  # [m] of the sweep
    for v in (60 * KMH, 90 * KMH):
        s_cc = cut_out_closing_distance(v)
        rows = []
        for gap in s_cc + np.arange(-6.0, 6.01, step) - 2.0:  # the law settles about 2 m farther back
            cc = CCDriver(headway_critical=100.0)  # [s] reacts to any reveal
            info, tr = run_episode(env, cc, scenario=staged_cut_out(v, CUT_OUT_HEADWAY, 0.0, gap))
            d, v_r = tr.gap[K_REVEAL, 0, 0], tr.v[K_REVEAL, 0, 0]  # [m], [m/s] at the reveal as it was
            assert tr.lead[K_REVEAL, 0, 0] == 2
            hold = tr.a[K_REVEAL, 0, 0]  # [m/s^2] the command the perception holds (about 0)
            rows.append((d, cut_out_closing_distance(v_r, hold), bool(info["report"]["metrics"]["collision"])))
        d, s, hit = map(np.array, zip(*rows))
        assert hit.any() and not hit.all(), (v, rows)
        assert np.all(np.diff(hit.astype(int)) <= 0), rows  # collides below, avoids above: monotone
        # the outcome is the closed form's everywhere but within one sweep step of the boundary
        assert np.all(hit[d < s - step]) and not np.any(hit[d > s + step]), rows
        first_avoided = d[~hit][0]
        assert abs(first_avoided - s[~hit][0]) <= step, rows


def test_the_cc_driver_collides_below_its_2s_gate_and_avoids_beyond_its_stopping_distance():
    """The default C&C driver on the grid's stopped-vehicle cases: a reveal under 2 s of headway
    cannot be survived by its response from 60 km/h up (stopping distance > 2 s x speed), so it
    collides; a reveal beyond its stopping distance by a margin it avoids."""
    res = r157_cases("cc-driver", families="cut-out")
    assert not res["errors"] and len(res["cases"]) == 18
    checked = {"below the gate": 0, "beyond the stopping distance": 0}
    for c in res["cases"]:
        p = c["params"]
        if p["other_speed"] != 0.0:
            continue
        v, gap = p["ego_speed"], p["gap"]
        s_cc = cut_out_closing_distance(v)
        assert s_cc > 2.0 * v
        if gap + 2.5 < 2.0 * v:  # under the gate even where the law settled 2.5 m farther back
            assert c["cc_driver_collides"], p
            checked["below the gate"] += 1
        elif gap > s_cc + 5.0:
            assert not c["cc_driver_collides"], p
            checked["beyond the stopping distance"] += 1
    assert checked == {"below the gate": 3, "beyond the stopping distance": 2}  # 1.5 s; 3.5 s at 60, 90 km/h


def test_a_controller_that_never_brakes_has_preventable_cut_out_collisions():
    res = r157_cases(NeverBrakes(), families=["cut-out"])
    cases = res["cases"]
    assert not res["errors"] and [c["family"] for c in cases] == ["cut-out"] * 18
    assert all(c["controller_collides"] for c in cases)  # holds its speed into every slower vehicle
    avoided_by_cc = [c for c in cases if not c["cc_driver_collides"]]
    assert len(avoided_by_cc) >= 10
    assert all(c["preventable"] is True for c in avoided_by_cc)
    assert all(c["preventable"] is False for c in cases if c["cc_driver_collides"])
    assert res["preventable_collisions"] == len(avoided_by_cc)
    assert res["non_preventable_collisions"] == 18 - len(avoided_by_cc)


def test_the_cut_out_grid_is_appended_with_its_documented_parameters():
    cases = grid()
    families = [c[0] for c in cases]
    assert families == ["lead deceleration"] * 18 + ["cut-in"] * 16 + ["cut-out"] * 18
    out = [c for c in cases if c[0] == "cut-out"]
    speeds = {round(c[1]["ego_speed"] * 3.6, 3) for c in out}
    assert speeds == {60.0, 90.0, 120.0}
    assert {round(c[1]["other_speed"] * 3.6, 3) for c in out} == {0.0, 20.0}
    assert {round(c[1]["gap"] / c[1]["ego_speed"], 3) for c in out} == set(CUT_OUT_GRID["reveal_headway"])
    for family, params, sid, sparams in out:
        assert set(params) == {"ego_speed", "other_speed", "gap", "time_headway"} and sid == CUT_OUT_ID
        assert params["time_headway"] == CUT_OUT_HEADWAY
        # every case leaves the lead room: it is out of the lane before it reaches the other vehicle
        assert params["gap"] - params["time_headway"] * params["ego_speed"] - LENGTH > 3.0  # [m]
        sc = staged_cut_out(**sparams)
        assert sc.params == pytest.approx(params, abs=1e-6)


def test_r157_json_carries_the_cut_out_family():
    res = r157_cases("acc", families=("cut-out",))
    d = json.loads(json.dumps(res))
    assert {c["family"] for c in d["cases"]} == {"cut-out"}
    for c in d["cases"]:
        assert set(c["params"]) == {"ego_speed", "other_speed", "gap", "time_headway"}
        assert {"controller_collides", "cc_driver_collides", "preventable"} <= set(c)
    # the linear ACC brakes as soon as it sees the slower vehicle: nothing the C&C driver avoids hits it
    assert d["preventable_collisions"] == 0


def test_the_map_has_a_cut_out_panel():
    cases = [{"family": f, "params": p, "controller_collides": k % 2 == 0, "cc_driver_collides": k % 3 == 0}
             for k, (f, p, _, _) in enumerate(grid())]
    fig = plot_map({"cases": cases})
    axes = fig.get_axes()
    assert len(axes) == 3 and "cut-out" in axes[2].get_title()
    assert len(axes[2].collections) == 18 and axes[2].get_xlabel() == "gap at the reveal / ego speed [s]"
    xs = sorted(float(col.get_offsets()[0, 0]) for col in axes[2].collections)
    assert 1.2 < xs[0] and xs[-1] < 3.8  # the reveal headways 1.5-3.5 s, the ego speeds side by side


def test_the_conformance_report_names_the_three_families(tmp_path):
    from acc_gym.standards.conformance import markdown, write_reports

    cases = [{"family": f, "params": p, "controller_collides": f == "cut-out" and p["other_speed"] == 0.0,
              "cc_driver_collides": False, "preventable": True if f == "cut-out" and p["other_speed"] == 0.0 else None}
             for f, p, _, _ in grid()]
    r157 = {"reference": "cc-driver", "cases": cases, "preventable_collisions": 9, "non_preventable_collisions": 0,
            "errors": []}
    result = {"controller": "x", "standards": {"r157": r157}}
    md = markdown(result)
    assert "52 cases (lead deceleration, cut-in and cut-out grids): **9 preventable**" in md
    assert md.count("| cut-out | ego_speed ") == 9
    paths = write_reports(result, tmp_path)
    assert tmp_path.joinpath("preventability.png").stat().st_size > 1000 and "map" in paths
