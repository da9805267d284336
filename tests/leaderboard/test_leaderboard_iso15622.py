"""The leaderboard's ISO 15622 column: measured in the controller's sandbox, the verdict
``iso15622_report`` gives locally, in results.json, the CSV and the tables; a controller's failure
in the battery confined to the cell; the column can be left out; it changes no points or rank."""

import csv
import io
from pathlib import Path

import pytest

from acc_gym.leaderboard import load_results, run_leaderboard
from acc_gym.leaderboard.iso15622 import HEADER, SHORT_NAMES, cell, format_cell
from acc_gym.leaderboard.results import csv_text, markdown, text_table
from acc_gym.standards.battery import SEEDS, iso15622_report

HERE = Path(__file__).resolve().parent
FAILS = "bad_controllers:FailsAtSpeed"


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    out = tmp_path_factory.mktemp("iso") / "board"
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        results = run_leaderboard("ncap-v1", "test", ["acc", "idm", FAILS], out=out, episodes=1, workers=2,
                                  allow_root=True, string_stability=False, report=True, waves=False, robustness=False)
    return results, out


def entry(results, name):
    return {c["name"]: c for c in results["controllers"]}[name]


@pytest.fixture(scope="module")
def local():
    return {name: cell(iso15622_report(name)) for name in ("acc", "idm")}


def test_results_json_holds_the_local_verdict(board, local):
    results, out = board
    stored = load_results(out)
    for name in ("acc", "idm"):
        got = entry(stored, name)["iso15622"]
        assert got == local[name]  # measured in the sandbox, the same numbers as acc-gym conformance
        assert set(got) == {"passed", "failed", "requirements"} and len(got["requirements"]) == 6
        assert got["failed"] == [r["name"] for r in got["requirements"] if r["passed"] is False]
    st = stored["manifest"]["settings"]["iso15622"]
    assert st["battery"] == "iso15622-v1" and st["seeds"] == list(SEEDS) and st["drives"] == 30


def test_a_failure_in_the_battery_stays_in_the_cell_and_the_episodes_stand(board):
    results, _ = board
    fails = entry(results, FAILS)
    assert fails["status"] == "ok" and fails["rank"] is not None and len(fails["episodes"]) == 1
    reason = fails["iso15622"]["failed_to_run"]
    assert "too fast for me" in reason and "the ISO 15622 column (iso15622-v1)" in reason
    assert set(fails["iso15622"]) == {"failed_to_run"}


def test_csv_and_tables_show_the_column(board, local):
    results, out = board
    rows = {r["controller"]: r for r in csv.DictReader(io.StringIO((out / "results.csv").read_text()))}
    for name in ("acc", "idm"):
        assert rows[name]["iso15622_passed"] == {True: "True", False: "False", None: ""}[local[name]["passed"]]
        assert rows[name]["iso15622_failed"] == ";".join(local[name]["failed"])
        assert rows[name]["iso15622_failed_to_run"] == ""
    assert rows[FAILS]["iso15622_passed"] == "" and "too fast for me" in rows[FAILS]["iso15622_failed_to_run"]
    assert "iso15622" not in rows["acc"]  # the nested cell is not a CSV column
    md = (out / "leaderboard.md").read_text()
    assert md == markdown(results)
    header = next(line for line in md.splitlines() if line.startswith("| #"))
    assert f"| {HEADER} |" in header
    column = [c.strip() for c in header.strip("|").split("|")].index(HEADER)
    cells = {}
    for line in md.splitlines():
        parts = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| ") and len(parts) > column and parts[1] in ("acc", "idm", FAILS):
            cells[parts[1]] = parts[column]
    for name in ("acc", "idm"):
        assert cells[name] == format_cell(local[name])
        if local[name]["passed"] is False:
            assert cells[name] == "fails: " + ", ".join(SHORT_NAMES[n] for n in local[name]["failed"])
    assert cells[FAILS] == "failed"
    for text in (md, text_table(results), (out / "report.html").read_text()):
        assert HEADER in text and "not part of the points or the rank" in text


def test_the_column_changes_no_points_or_rank(board):
    results, _ = board
    plain = run_leaderboard("ncap-v1", "test", ["acc", "idm"], episodes=1, workers=2, string_stability=False,
                            allow_root=True, iso15622=False, waves=False, robustness=False)
    assert plain["ranking"] == [n for n in results["ranking"] if n != FAILS]
    for name in ("acc", "idm"):
        a, b = entry(plain, name), entry(results, name)
        assert a["summary"]["overall"]["mean_points"] == b["summary"]["overall"]["mean_points"]
    # --no-iso15622: no cell, no setting, no column
    assert all("iso15622" not in c for c in plain["controllers"])
    assert plain["manifest"]["settings"]["iso15622"] is None
    assert HEADER not in text_table(plain) and HEADER not in markdown(plain)
    assert "iso15622_passed" not in csv_text(plain)


def test_formatting_of_each_kind_of_cell():
    assert format_cell(None) == "-"
    assert format_cell({"failed_to_run": "RuntimeError: x"}) == "failed"
    assert format_cell({"passed": None, "failed": [], "requirements": []}) == "not exercised"
    assert format_cell({"passed": True, "failed": [], "requirements": []}) == "passes"
    two = ["mean jerk over 1 s", "standstill gap behind a stopped target"]
    assert format_cell({"passed": False, "failed": two, "requirements": []}) == "fails: jerk, standstill gap"
    assert format_cell({"passed": False, "failed": ["a new one"], "requirements": []}) == "fails: a new one"


def test_after_a_failure_in_the_string_stability_column_the_battery_runs_on_a_fresh_controller():
    # FailsInAColumn raises in the string-stability column (several rows at once) and ends its process
    # there; the ISO column starts it again and measures it as acc-gym conformance does
    name = "bad_controllers:FailsInAColumn"
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        results = run_leaderboard("ncap-v1", "test", [name], allow_root=True, episodes=1, workers=1)
        expected = cell(iso15622_report(name))
    c = entry(results, name)
    assert c["status"] == "ok" and "deliberate failure on a batch" in c["string_stability"]["failed"]
    assert c["iso15622"] == expected
    # the wave column sends the five rings' rows of its one position at once: it fails there too, on its own
    assert "deliberate failure on a batch" in c["waves"]["failed_to_run"] and "the wave column" in c["waves"]["failed_to_run"]
    # the robustness column gives each episode a copy of its own (one row each): measured on a fresh
    # controller after the failures, as the linear ACC it is
    from acc_gym.leaderboard.robustness import local_cell

    assert c["robustness"] == local_cell("acc")
