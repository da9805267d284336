"""The command line: acc-gym demo."""

import json
import subprocess
import sys

from acc_gym.cli import main


def test_demo_json_reports_what_the_driver_did(capsys):
    assert main(["demo", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    modes = [m["mode"] for m in out["modes"]]
    assert modes[0] == "ACCELERATE" and "BRAKE" in modes
    assert not out["collided"]
    assert out["min_gap_m"] >= out["x_min_m"] - 1e-6
    assert out["max_abs_jerk_mps3"] <= 2.5 + 1e-6
    assert out["solver"]["fallback"] == 0
    assert sum(out["solve_paths"].values()) == out["solver"]["steps"]


def test_demo_text_and_bad_arguments():
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "demo", "--driver", "#13"], capture_output=True,
                       text=True)
    assert r.returncode == 0 and "modes:" in r.stdout and "#13" in r.stdout
    bad = subprocess.run([sys.executable, "-m", "acc_gym.cli", "demo", "--driver", "#99"], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "unknown MPC driver preset" in bad.stderr
    bad = subprocess.run([sys.executable, "-m", "acc_gym.cli", "demo", "--speed", "nan"], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "--speed" in bad.stderr
