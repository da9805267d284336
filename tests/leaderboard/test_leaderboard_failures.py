"""The leaderboard writes each controller's failing worst episode as OpenSCENARIO beside its
results (acc_gym.leaderboard.failures), and the file replays the failure."""

import json

import numpy as np
import pytest

from acc_gym.evaluation.runner import load_controller
from acc_gym.leaderboard.failures import file_stem
from acc_gym.leaderboard.run import run_leaderboard

pytest.importorskip("scenariogeneration", reason="scenariogeneration is not installed (pip install '.[osc]' or '.[test]'): nothing writes OpenSCENARIO")


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    out = tmp_path_factory.mktemp("lb") / "board"
    r = run_leaderboard("ncap-v1", "test", ["constant", "acc"], episodes=2, workers=1, out=out,
                        string_stability=False, iso15622=False, waves=False, robustness=False)
    return out, r


def test_a_collision_is_written_and_its_file_collides_again(board):
    from acc_gym.scenarios.openscenario import read, run_file

    out, r = board
    entry = next(e for e in r["controllers"] if e["name"] == "constant")
    fail = entry["failing_episode"]
    assert fail["collision"] is True and fail["xosc"] == "failures/constant.xosc"
    assert (out / fail["xodr"]).is_file()
    ep = next(e for e in entry["episodes"] if (e["suite"], e["episode"]) == (fail["suite"], fail["episode"]))
    assert ep["metrics"]["collision"]
    sc = read(out / fail["xosc"])
    assert "constant" in sc.description and f"seed {ep['scenario_seed']}" in sc.description
    result, trace = run_file(out / fail["xosc"], load_controller("constant"))
    assert result["collided"] and result["score"] == pytest.approx(ep["score"], abs=1e-6)
    assert np.all(np.isfinite(trace.s))
    # results.json keeps the pointer
    saved = json.loads((out / "results.json").read_text())["results"]
    assert next(e for e in saved["controllers"] if e["name"] == "constant")["failing_episode"] == fail


def test_a_controller_whose_worst_episode_qualifies_writes_none(board):
    out, r = board
    entry = next(e for e in r["controllers"] if e["name"] == "acc")
    worst = min(entry["episodes"], key=lambda e: e["score"])
    assert worst["qualified"] and not worst["metrics"]["collision"]
    assert "failing_episode" not in entry
    assert sorted(p.name for p in (out / "failures").iterdir()) == ["constant.xodr", "constant.xosc"]


@pytest.mark.parametrize("name, stem", [
    ("mycontroller:Gap", "mycontroller_Gap"), ("runs/ppo", "runs_ppo"), ("../../etc/passwd", "etc_passwd"),
    ("...", "controller"), ("a" * 200, "a" * 80),
])
def test_a_controllers_name_becomes_a_safe_file_name(name, stem):
    assert file_stem(name) == stem
