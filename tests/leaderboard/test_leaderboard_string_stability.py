"""The leaderboard's string-stability column: measured in the controller's sandbox, the same
numbers as acc-gym string-stability, failures confined to the cell."""

import csv
import io
from pathlib import Path

import pytest

from acc_gym.evaluation.string_stability import (LEADERBOARD_CONFIG, LEADERBOARD_FREQUENCIES, PlatoonConfig,
                                                 string_stability)
from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard.results import csv_text, markdown, text_table

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def board():
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        yield run_leaderboard("ncap-v1", "test", ["acc", "bad_controllers:ShortGapACC", "constant",
                                                  "bad_controllers:FailsInAColumn"], episodes=1, workers=2,
                              allow_root=True, waves=False, robustness=False)


def cell(results, name):
    return {c["name"]: c for c in results["controllers"]}[name]["string_stability"]


def test_the_sandboxed_verdict_is_the_local_one_to_the_bit(board):
    acc = cell(board, "acc")
    local = string_stability("acc", LEADERBOARD_CONFIG, frequencies=LEADERBOARD_FREQUENCIES)
    assert acc["string_stable"] is True and acc["max_gain"] == round(local.max_gain, 6)
    assert acc["disturbance_growth"] == round(float(local.disturbance.drops[-1] / local.disturbance.lead_drop), 6)
    short = cell(board, "bad_controllers:ShortGapACC")
    local = string_stability("acc", PlatoonConfig(time_gap=0.6), frequencies=LEADERBOARD_FREQUENCIES)
    assert short["string_stable"] is False and short["time_gap"] == 0.6  # its declared time gap is used
    assert short["max_gain"] == round(local.max_gain, 6) and short["unstable_bands_hz"]


def test_failures_stay_in_the_cell_and_the_episodes_stand(board):
    by_name = {c["name"]: c for c in board["controllers"]}
    constant = by_name["constant"]
    reason = constant["string_stability"]["failed"]  # it ignores the lead: into it, at its set speed
    assert constant["status"] == "ok" and reason.startswith("the controller does not follow a lead")
    fails = by_name["bad_controllers:FailsInAColumn"]
    assert fails["status"] == "ok" and len(fails["episodes"]) == 1
    assert "deliberate failure on a batch" in fails["string_stability"]["failed"]


def test_tables_show_the_column_and_the_rule(board):
    text, md = text_table(board), markdown(board)
    assert "string stability (max gain)" in md and "stable when it is at most 1 + 0.005" in md
    assert "UNSTABLE (" in md and "stable (0.99" in md and "failed" in md
    # the terminal's 120 columns: the rule in the notes, the column shown or named among those left to the files
    flat = " ".join(text.split())
    assert "string stability (max gain)" in flat and "stable when it is at most 1 + 0.005" in flat
    rows = {r["controller"]: r for r in csv.DictReader(io.StringIO(csv_text(board)))}
    assert rows["acc"]["string_stable"] == "True" and float(rows["acc"]["string_max_gain"]) < 1.0
    assert rows["constant"]["string_max_gain"] == ""
    st = board["manifest"]["settings"]["string_stability"]
    assert st["vehicles"] == LEADERBOARD_CONFIG.vehicles and st["frequencies_hz"] == list(LEADERBOARD_FREQUENCIES)


def test_the_column_can_be_left_out():
    r = run_leaderboard("ncap-v1", "test", ["acc"], episodes=1, workers=1, string_stability=False, waves=False, robustness=False)
    assert "string_stability" not in r["controllers"][0]
    assert r["manifest"]["settings"]["string_stability"] is None
    assert "string stability" not in text_table(r)
