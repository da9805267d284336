"""examples/hand_written_controller.py: a hand-written controller scored by the evaluator and
ranked on the leaderboard beside the linear ACC, in quick mode."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np

from acc_gym.leaderboard import load_results

REF = "hand_written_controller:TimeGapACC"


def test_the_controller_is_evaluated_and_ranked_beside_the_linear_acc(run_example, tmp_path):
    out = tmp_path / "board"
    stdout = run_example("hand_written_controller.py", "--quick", "--out", str(out)).stdout
    m = re.search(r"evaluate: mean score ([\d.]+) / 100, qualified (\d+)%, collisions (\d+) in (\d+) episodes", stdout)
    assert m, stdout
    assert 0.0 <= float(m[1]) <= 100.0 and 0 <= int(m[2]) <= 100 and int(m[4]) == 2
    # the leaderboard's files are written and verify; both controllers finished and are ranked
    results = load_results(out / "results.json")
    assert sorted(results["ranking"]) == sorted(["acc", REF])
    entries = {c["name"]: c for c in results["controllers"]}
    assert all(c["status"] == "ok" for c in entries.values()), {n: c["reason"] for n, c in entries.items()}
    assert {s["name"] for s in results["manifest"]["suites"]} == {"carfollowing-v1", "ncap-v1"}
    assert all(s["episodes_run"] == 2 for s in results["manifest"]["suites"])
    points = entries[REF]["summary"]["overall"]["mean_points"]
    assert 0.0 <= points <= 100.0
    assert f"leaderboard: {REF} rank {entries[REF]['rank']}, mean points {points:.1f}" in stdout
    assert (out / "leaderboard.md").is_file() and (out / "results.csv").is_file()


def test_the_controller_holds_the_set_time_gap_and_cruises_without_a_lead():
    path = Path(__file__).resolve().parents[2] / "examples" / "hand_written_controller.py"
    spec = importlib.util.spec_from_file_location("hand_written_controller", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    c = module.TimeGapACC()

    def obs(v, gap, dv, in_range, v_set=25.0, tau=1.5):
        return np.array([v, 0.0, gap, dv, in_range, v_set, tau], dtype=np.float32)

    action, state = c.predict(obs(20.0, 4.0 + 1.5 * 20.0, 0.0, 1.0, v_set=20.0))
    assert action.shape == (1,) and action.dtype == np.float32 and state is None
    assert action[0] == 0.0  # at the set speed and gap: hold
    assert c.predict(obs(20.0, 15.0, -5.0, 1.0))[0][0] < -0.5  # too close and closing: brake (8 m/s^2 at -1)
    assert c.predict(obs(20.0, 0.0, 0.0, 0.0))[0][0] == np.float32(0.5 * 5.0 / 3.0)  # no lead: towards the set speed
    assert c.predict(obs(0.0, 500.0, 30.0, 1.0, v_set=30.0))[0][0] == 1.0  # clipped to [-1, 1]
