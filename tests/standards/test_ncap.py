"""Euro NCAP 2026: the test points are the calculator's, the scenarios have the declared
geometry, and the score is the calculator's rule (checked by hand)."""

import json
import math
import sys

import numpy as np
import pytest

from acc_gym.scenarios import build, simulate
from acc_gym.scenarios import ncap2026 as sc
from acc_gym.standards import ncap

def _has_calculator() -> bool:
    return ncap.calculator_version() is not None


needs_calculator = pytest.mark.skipif(not _has_calculator(),
                                      reason="Euro NCAP's rating calculator is not installed (pip install '.[ncap]' or '.[test]')")


@needs_calculator
def test_the_acc_points_are_the_calculators_template_rows():
    template = ncap.template_points("acc")
    for name in ncap.SCORED:
        ours = [(p.vut_speed, p.target_speed, p.ttc) for p in ncap.ACC_POINTS if p.scenario == name]
        assert ours == template[name], name
    # every matrix the calculator has is either scored here or named out of scope
    named = " / ".join(ncap.OUT_OF_SCOPE)
    for name in template:
        assert name in ncap.SCORED or name in named, name


@needs_calculator
def test_the_frontal_collision_points_are_the_calculators_template_rows():
    template = ncap.template_points("fc")
    for name in ("CCRs", "CCRm", "CCRb"):
        ours = [(p.vut_speed, p.target_speed, None) for p in ncap.FC_POINTS if p.scenario == name]
        assert ours == template[name], name


def _run_constant(scenario, v):
    """The scenario with an ego that holds ``v`` [m/s] (asks for 0 m/s^2): the world trace."""
    class Hold:
        n = 1

        def act(self, obs):
            return np.zeros_like(np.asarray(obs.v, dtype=float))

    return simulate(scenario, Hold())


def _first_target_step(trace, slot):
    lead = trace.lead[:, 0, 0]
    k = int(np.flatnonzero(lead == slot)[0])
    return k, float(trace.gap[k, 0, 0])


@pytest.mark.parametrize("v, vt, ttc", [(120, 70, 1.5), (90, 30, 2.0)])
def test_a_cut_in_enters_the_lane_at_its_time_to_collision(v, vt, ttc):
    scenario = build(f"ncap2026/acc/cut-in/{120}-{70}", {"v_ego": v, "v_target": vt, "ttc": ttc})
    trace = _run_constant(scenario, v / 3.6)
    k, gap = _first_target_step(trace, 1)
    closing = (v - vt) / 3.6
    # it becomes the target in the first step whose end is past the intrusion time
    t_in = scenario.params["t_lc"] + sc.intrusion_fraction() * scenario.params["lc_duration"]
    assert trace.t[k - 1] < t_in <= trace.t[k] + 1e-9
    assert gap == pytest.approx(ttc * closing - closing * (trace.t[k] - t_in), abs=1e-6)


@pytest.mark.parametrize("sid", ["ncap2026/acc/cut-out/70-50", "ncap2026/acc/cut-out/90-70"])
def test_a_cut_out_reveals_the_stopped_vehicle_at_its_time_to_collision(sid):
    scenario = build(sid)
    vt = scenario.params["v_target"] / 3.6
    trace = _run_constant(scenario, vt)
    k, gap = _first_target_step(trace, 2)
    assert trace.lead[k - 1, 0, 0] == 1  # the lead was the target until then
    t_rev = scenario.params["t_lc"] + sc.reveal_fraction() * scenario.params["lc_duration"]
    assert trace.t[k - 1] < t_rev <= trace.t[k] + 1e-9
    assert gap == pytest.approx(scenario.params["ttc"] * vt - vt * (trace.t[k] - t_rev), abs=1e-6)
    assert trace.v[k, 0, 2] == 0.0


def test_ccrb_follows_at_one_second_and_the_target_brakes_at_four():
    scenario = build("ncap2026/fc/ccrb/100")
    trace = _run_constant(scenario, 100 / 3.6)
    assert trace.gap[0, 0, 0] == pytest.approx(100 / 3.6 * 1.0)
    a_lead = trace.a[1:, 0, 1]
    braking = a_lead[(trace.t[1:] > 2.2) & (trace.v[1:, 0, 1] > 0.5)]
    assert braking.size and np.allclose(braking, -4.0, atol=1e-9)


def _row(point, collision, impact=None):
    red = point.conflict_speed if not collision else max(point.conflict_speed - impact, 0.0)
    return {**ncap.asdict(point), "collision": collision, "impact_speed": impact, "v_reduction": red}


@needs_calculator
def test_the_score_is_the_calculators_rule_by_hand():
    ccrs = [p for p in ncap.ACC_POINTS if p.scenario == "CCRs straight"]
    cut_out = [p for p in ncap.ACC_POINTS if p.scenario == "CCR cut-out"]
    ccrb = [p for p in ncap.ACC_POINTS if p.scenario == "CCRb"]
    rows = [_row(p, False) for p in ccrs[:6]]
    rows.append(_row(ccrs[6], True, 120 - 20))  # v_reduction 20 > 15: half the row
    rows.append(_row(ccrs[7], True, 130 - 10))  # 10 km/h: nothing
    rows.append(_row(ccrb[0], True, 3.0))  # 55 - 3 = 52 <= 53 (v_VUT - 2): half
    rows.append(_row(cut_out[0], True, 1.0))  # 50 - 1 = 49 > 48 (v_lead - 2): whole
    rows.append(_row(cut_out[1], True, 3.0))  # 70 - 3 = 67 <= 68: half
    result = ncap.score(rows)
    types = result["test_types"]
    assert types["CCRs straight"]["score"] == pytest.approx(6 / 8 + 1 / 16)
    assert types["CCRb"]["score"] == pytest.approx(0.5)
    assert types["CCR cut-out"]["score"] == pytest.approx(0.5 + 0.25)
    assert types["CCRm"]["score"] == 0.0 and types["CCR cut-in"]["score"] == 0.0
    assert result["score_percent"] == pytest.approx(100 * (6 / 8 + 1 / 16 + 0.5 + 0.75) / 5, abs=0.01)
    by_id = {t["scenario_id"]: t for t in result["tests"]}
    assert by_id["ncap2026/acc/ccrs/60"]["green_threshold"] == 58.0
    assert by_id["ncap2026/acc/ccrb/55-50"]["green_threshold"] == 53.0
    assert by_id["ncap2026/acc/cut-out/70-50"]["green_threshold"] == 48.0
    assert [by_id[p.scenario_id]["colour"] for p in ccrs[5:]] == ["Green", "Orange", "Red"]


def test_a_fast_ego_that_drives_through_a_stopped_car_within_one_step_collides():
    """At 130 km/h the ego covers 7.2 m in a 0.2 s step, more than the gap before the step plus
    the target's length: the end-of-step gaps alone would not see it."""
    trace = _run_constant(build("ncap2026/acc/ccrs/130"), 130 / 3.6)
    gaps = trace.gap[:, 0, 0]
    k = int(np.flatnonzero(gaps <= 0.0)[0])
    assert gaps[k - 1] > 0 and trace.x[k, 0, 0] > trace.x[k, 0, 1]  # its front is past the car's front
    assert trace.collided[0, 0]


@needs_calculator
def test_a_controller_that_never_brakes_scores_little_and_the_linear_acc_well():
    constant = ncap.ncap_report("constant")
    acc = ncap.ncap_report("acc")
    assert all(t["collision"] for t in constant["tests"] if t["scenario"] == "CCRs straight")
    assert constant["score_percent"] < 10.0
    assert acc["score_percent"] >= 80.0 and not acc["errors"]
    assert not any(t["collision"] for t in acc["tests"] if t["scenario"] in ("CCRs straight", "CCRm"))
    assert acc["calculator"].startswith("euroncap-rating-2026 ")


def test_without_the_calculator_the_tests_are_still_driven(monkeypatch):
    monkeypatch.setattr(ncap, "calculator_version", lambda: None)
    for name in [m for m in sys.modules if m.split(".")[0] == "euroncap_rating_2026"] + ["euroncap_rating_2026"]:
        monkeypatch.setitem(sys.modules, name, None)  # as if not installed
    points = ncap.ACC_POINTS[:1] + ncap.ACC_POINTS[-1:]
    monkeypatch.setattr(ncap, "ACC_POINTS", points)
    monkeypatch.setattr(ncap, "FC_POINTS", ncap.FC_POINTS[:1])
    out = ncap.ncap_report("acc")
    assert out["score_percent"] is None and "pip install 'acc-gym[ncap]'" in out["calculator"]
    assert [t["scenario_id"] for t in out["tests"]] == [p.scenario_id for p in points]
    assert all(isinstance(t["v_reduction"], float) for t in out["tests"])
    with pytest.raises(ImportError, match=r"acc-gym\[ncap\]"):
        ncap.score(out["tests"])


def test_a_controller_that_fails_is_named_and_the_rest_still_runs(monkeypatch):
    class FailsAtSpeed:
        def predict(self, obs, deterministic=True):
            if obs[0] > 100 / 3.6:
                raise RuntimeError("too fast for me")
            return np.zeros(1, dtype=np.float32), None

    monkeypatch.setattr(ncap, "FC_POINTS", ())
    rows, errors = ncap.run_points(FailsAtSpeed(), ncap.ACC_POINTS[:8])
    assert [e["scenario_id"] for e in errors] == [f"ncap2026/acc/ccrs/{v}" for v in (110, 120, 130)]
    assert "too fast for me" in errors[0]["reason"]
    assert all(r["v_reduction"] is not None for r in rows[:5])


def test_conformance_json_has_the_ncap_section(monkeypatch, capsys):
    from acc_gym.cli import main

    monkeypatch.setattr(ncap, "ACC_POINTS", ncap.ACC_POINTS[:2])
    monkeypatch.setattr(ncap, "FC_POINTS", ncap.FC_POINTS[:1])
    assert main(["conformance", "acc", "--standard", "ncap", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    section = out["standards"]["ncap"]
    assert set(section) >= {"protocol", "score_percent", "tests", "calculator", "frontal_collisions", "out_of_scope"}
    assert [t["scenario_id"] for t in section["tests"]] == ["ncap2026/acc/ccrs/60", "ncap2026/acc/ccrs/70"]
    if _has_calculator():
        assert math.isfinite(section["score_percent"])


def test_an_unknown_standard_is_named(capsys):
    from acc_gym.cli import main

    with pytest.raises(SystemExit):
        main(["conformance", "acc", "--standard", "ncap2030"])
    assert "ncap2030" in capsys.readouterr().err
