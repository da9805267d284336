"""evaluate()'s per-scenario breakdown: which scenarios a controller fails, and which score item."""

import numpy as np
import pytest

from acc_gym.cli import main
from acc_gym.evaluation.runner import by_scenario, evaluate


def report(score, qualified, failed=(), collision=False, band_applicable=True):
    items = {name: {"qualified": name not in failed, "applicable": name != "car_following" or band_applicable}
             for name in ("safety", "car_following", "road_edge", "boundary_line")}
    return {"score": score, "qualified": qualified, "items": items, "metrics": {"collision": collision}}


def test_counts_per_id_by_hand():
    reports = [report(80.0, True), report(30.0, False, ("safety",)), report(45.0, False, ("safety", "car_following")),
               report(0.0, False, ("safety",), collision=True), report(15.0, False, ("car_following",),
                                                                      band_applicable=False)]
    ids = ["carfollowing/60", "carfollowing/90", "carfollowing/60", "singlelane/2/cut-in", "carfollowing/90"]
    got = by_scenario(reports, ids)
    assert list(got) == ["carfollowing/60", "carfollowing/90", "singlelane/2/cut-in"]  # first appearance
    assert got["carfollowing/60"] == {"episodes": 2, "mean_score": 62.5, "share_qualified": 0.5, "collisions": 0,
                                      "failed": {"safety": 1, "car_following": 1, "road_edge": 0,
                                                 "boundary_line": 0}}
    # an item that was not applicable is not counted as failed, even if marked unqualified
    assert got["carfollowing/90"]["failed"] == {"safety": 1, "car_following": 0, "road_edge": 0, "boundary_line": 0}
    assert got["carfollowing/90"]["mean_score"] == 22.5 and got["carfollowing/90"]["share_qualified"] == 0.0
    assert got["singlelane/2/cut-in"]["collisions"] == 1 and got["singlelane/2/cut-in"]["failed"]["safety"] == 1


def test_mismatched_lengths_are_an_error():
    with pytest.raises(ValueError, match="2 reports for 1 scenario ids"):
        by_scenario([report(1.0, False), report(2.0, False)], ["carfollowing/60"])


class Tailgater:
    """Holds about 3 m behind the vehicle ahead and never brakes harder than 1.5 m/s^2."""

    def predict(self, obs, deterministic=True):
        v, _, gap, v_rel, seen = (float(x) for x in np.asarray(obs)[:5])
        acc = 1.0 * v_rel + 0.5 * (gap - 3.0) if seen > 0.5 else 1.0
        acc = float(np.clip(acc, -1.5, 3.0))
        return np.array([acc / 3.0 if acc >= 0 else acc / 8.0], dtype=np.float32), None


def test_the_breakdown_adds_up_to_the_summary_and_names_the_failed_item():
    s = evaluate(Tailgater(), "acc_gym/CarFollowing-v0", episodes=6, seed=4)
    groups = s["by_scenario"]
    assert set(groups) == set(s["scenarios"]) and set(groups) <= {"carfollowing/60", "carfollowing/90",
                                                                  "carfollowing/120"}
    assert sum(g["episodes"] for g in groups.values()) == 6
    assert sum(g["collisions"] for g in groups.values()) == s["collisions"]
    weighted = sum(g["mean_score"] * g["episodes"] for g in groups.values()) / 6
    assert weighted == pytest.approx(s["mean_score"], abs=1e-9)
    # a 3 m tailgater fails paper 003's safety item in every episode (Q < 0 at speed without braking)
    assert s["share_qualified"] == 0.0
    assert all(g["failed"]["safety"] == g["episodes"] for g in groups.values())


class FullThrottle:
    def predict(self, obs, deterministic=True):
        return np.ones(1, dtype=np.float32), None


def test_a_collision_counts_as_a_failed_safety_item():
    s = evaluate(FullThrottle(), "acc_gym/CarFollowing-v0", episodes=2, seed=4)
    assert s["collisions"] == 2
    for g in s["by_scenario"].values():
        assert g["collisions"] == g["episodes"] and g["failed"]["safety"] == g["episodes"]
        assert g["share_qualified"] == 0.0


def test_acc_gym_evaluate_prints_the_breakdown(capsys):
    assert main(["evaluate", "acc", "--env", "acc_gym/SingleLane-v1", "--episodes", "4", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    header = next(line for line in out.splitlines() if "by scenario" in line)
    assert "unqualified items" in header
    s = evaluate("acc", "acc_gym/SingleLane-v1", episodes=4, seed=3)
    for sid, g in s["by_scenario"].items():
        line = next(line for line in out.splitlines() if line.strip().startswith(sid + " "))
        assert f"{g['mean_score']:.1f}" in line and f"{g['share_qualified']:.0%}" in line
