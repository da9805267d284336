"""The command line: acc-gym demo."""

import json
import subprocess
import sys

import pytest

from acc_gym.cli import main


def test_driver_demo_json_reports_what_the_driver_did(capsys):
    assert main(["driver-demo", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    modes = [m["mode"] for m in out["modes"]]
    # standing behind the stopped lead the brake holds the car (driver model 2); then it drives off
    assert modes[0] == "BRAKE" and modes[1] == "ACCELERATE" and "BRAKE" in modes[2:]
    assert not out["collided"]
    assert out["min_gap_m"] >= out["x_min_m"] - 1e-6
    assert out["max_abs_jerk_mps3"] <= 2.5 + 1e-6
    assert out["solver"]["fallback"] == 0
    assert sum(out["solve_paths"].values()) == out["solver"]["steps"]


def test_driver_demo_text_and_bad_arguments():
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "driver-demo", "--driver", "#13"], capture_output=True,
                       text=True)
    assert r.returncode == 0 and "modes:" in r.stdout and "#13" in r.stdout
    bad = subprocess.run([sys.executable, "-m", "acc_gym.cli", "driver-demo", "--driver", "#99"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "unknown MPC driver preset" in bad.stderr
    bad = subprocess.run([sys.executable, "-m", "acc_gym.cli", "driver-demo", "--speed", "nan"], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "--speed" in bad.stderr


def test_scenarios_command_lists_describes_and_prints_json(capsys):
    from acc_gym.scenarios import Scenario, build

    assert main(["scenarios", "--family", "ncap"]) == 0
    ids = capsys.readouterr().out.split()
    assert len(ids) == 9 + 11 + 4 and "ncap/ccrb/6-40" in ids
    assert main(["scenarios", "singlelane/2/cut-in"]) == 0
    text = capsys.readouterr().out
    assert "cuts in" in text and "lc_duration" in text
    assert main(["scenarios", "carfollowing/90", "--seed", "4", "--json"]) == 0
    assert Scenario.from_json(capsys.readouterr().out) == build("carfollowing/90", seed=4)


def test_score_command_scores_a_recorded_csv(tmp_path, capsys):
    import numpy as np

    from acc_gym.evaluation import EgoTrace, score_episode

    n = 60
    tr = EgoTrace(t=np.arange(n) * 0.2, v=np.full(n, 20.0), a=np.zeros(n), gap=np.full(n, 32.0),
                  v_lead=np.full(n, 20.0))
    path = tmp_path / "drive.csv"
    tr.to_csv(path)
    assert main(["score", str(path), "--time-gap", "1.5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    expected = score_episode(EgoTrace.from_csv(path, time_gap=1.5)).to_dict()
    assert out == expected and out["qualified"]  # G = 2 m in (0, 6 m)
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "score", str(tmp_path / "missing.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "missing.csv" in r.stderr


def test_demo_runs_a_scored_episode_and_saves_its_plot(tmp_path, capsys):
    from acc_gym.evaluation import EgoTrace, score_episode  # noqa: F401

    plot = tmp_path / "demo.png"
    assert main(["demo", "--scenario", "carfollowing/60", "--seed", "3", "--plot", str(plot), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["scenario"] == "carfollowing/60" and out["qualified"]  # the linear ACC qualifies there
    assert 60.0 < out["score"] <= 100.0 and out["score"] == out["report"]["score"]
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["demo", "--scenario", "ncap/ccrs/30", "--controller", "constant", "--plot", ""]) == 0
    text = capsys.readouterr().out
    assert "NOT qualified" in text and "collision True" in text


def test_evaluate_prints_the_summary_and_rejects_bad_controllers(capsys, tmp_path, monkeypatch):
    assert main(["evaluate", "acc", "--env", "acc_gym/NCAP-v0", "--episodes", "4", "--seed", "1", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["episodes"] == 4 and s["collisions"] == 0 and len(s["scores"]) == 4
    assert s["mean_score"] == sum(s["scores"]) / 4
    # a module:attribute controller, scored through the same path
    (tmp_path / "my_ctrl.py").write_text(
        "from acc_gym_agents.controllers import ConstantSpeed\nblind = ConstantSpeed()\nclass Bad:\n    pass\n"
        "class Wide:\n    def predict(self, obs, deterministic=True):\n        return [0.0, 0.0], None\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["evaluate", "my_ctrl:blind", "--env", "acc_gym/NCAP-v0", "--episodes", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["collisions"] >= 1
    for ref, message in [("nosuchmodule:x", "cannot import module"), ("my_ctrl:missing", "no attribute"),
                         ("my_ctrl:Bad", "no predict"), ("my_ctrl:Wide", "shape (2,)"), ("pid", "unknown controller")]:
        with pytest.raises(SystemExit):
            main(["evaluate", ref, "--episodes", "1"])
        assert message in capsys.readouterr().err
