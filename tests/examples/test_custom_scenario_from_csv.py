"""examples/custom_scenario_from_csv.py: a recorded lead speed trace (CSV) becomes the lead's
driver in a built-in scenario, saved as JSON and driven by controllers, in quick mode."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from acc_gym import scenarios

DATA = Path(__file__).resolve().parents[2] / "examples" / "data" / "lead_trace.csv"


def test_the_shipped_trace_becomes_the_leads_profile_and_the_drive_is_scored(run_example, tmp_path):
    stdout = run_example("custom_scenario_from_csv.py", "--quick", "--out", str(tmp_path)).stdout
    sc = scenarios.Scenario.from_json((tmp_path / "recorded_lead.json").read_text(encoding="utf-8"))
    with open(DATA, newline="") as fh:
        rows = [(float(r["t"]), float(r["v"])) for r in csv.DictReader(fh)]
    t, v = np.array(rows).T
    lead = sc.vehicle("POV").driver
    keep = t <= 30.0  # --quick: the trace's first 30 s
    assert lead.model == "profile" and sc.drivers == "custom"
    np.testing.assert_array_equal(lead.times, t[keep])
    np.testing.assert_array_equal(lead.speeds, v[keep])
    assert sc.duration == 30.0 and sc.set_speed == v[0]
    m = re.search(r"^acc: score ([\d.]+) / 100, qualified (True|False), collision (True|False)", stdout, re.M)
    assert m, stdout
    assert 0.0 <= float(m[1]) <= 100.0


def test_a_steady_lead_from_a_users_csv_is_followed_without_a_collision(run_example, tmp_path):
    trace = tmp_path / "steady.csv"
    trace.write_text("t,v,note\n" + "".join(f"{k * 1.0},20.0,x\n" for k in range(41)), encoding="utf-8")
    stdout = run_example("custom_scenario_from_csv.py", "--trace", str(trace), "--controllers", "acc",
                         "--out", str(tmp_path)).stdout
    assert "trace: 41 samples over 40.0 s, speed 20.0-20.0 m/s" in stdout
    m = re.search(r"^acc: score [\d.]+ / 100, qualified \w+, collision (\w+), smallest gap ([\d.]+) m", stdout, re.M)
    assert m, stdout
    assert m[1] == "False" and float(m[2]) > 20.0  # started 30 m behind at the same speed: it keeps a gap


def test_a_csv_without_the_columns_is_refused_naming_the_file(run_example, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time,speed\n0,20\n1,20\n", encoding="utf-8")
    proc = run_example("custom_scenario_from_csv.py", "--trace", str(bad), check=False)
    assert proc.returncode != 0
    assert "the header must name columns 't' and 'v'" in proc.stderr and "bad.csv" in proc.stderr
