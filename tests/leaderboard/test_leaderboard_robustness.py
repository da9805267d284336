"""The leaderboard's robustness column: measured in the controller's sandbox, the cell a local run
of the same episodes gives, in results.json, the CSV and the tables; a failure in the column stays
in its cell; the column can be left out; it changes no points or rank."""

import csv
import io
from pathlib import Path

import pytest

from acc_gym.leaderboard import load_results, run_leaderboard
from acc_gym.leaderboard.results import csv_text, text_table
from acc_gym.leaderboard.robustness import HEADER, format_cell, local_cell, slots

HERE = Path(__file__).resolve().parent
FAILS = "bad_controllers:FailsAtSpeed"  # fine in ncap-v1's first episode, raises above 20 m/s


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    out = tmp_path_factory.mktemp("robust") / "board"
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        results = run_leaderboard("ncap-v1", "test", ["acc", "ppo", FAILS], out=out, episodes=1, workers=2,
                                  allow_root=True, string_stability=False, iso15622=False, waves=False, report=True)
    return results, out


def entry(results, name):
    return {c["name"]: c for c in results["controllers"]}[name]


def test_results_json_holds_the_cell_a_local_run_gives(board):
    results, out = board
    stored = load_results(out)
    for name in ("acc", "ppo"):
        got = entry(stored, name)["robustness"]
        assert got == local_cell(name)
        assert got["episodes"] == slots() == 57 and 0 <= got["preventable"] <= got["collisions"]
    st = stored["manifest"]["settings"]["robustness"]
    assert st["suite"] == "ncap-v2" and st["preset"] == "typical" and st["actuators"] == {"lag": 0.5, "dead_time": 0.1}


def test_a_failure_in_the_column_stays_in_its_cell_and_the_episodes_stand(board):
    results, _ = board
    fails = entry(results, FAILS)
    assert fails["status"] == "ok" and fails["rank"] is not None and len(fails["episodes"]) == 1
    assert "too fast for me" in fails["robustness"]["failed_to_run"]
    assert "the robustness column" in fails["robustness"]["failed_to_run"]


def test_csv_and_tables_show_the_column_and_it_can_be_left_out(board):
    results, out = board
    rows = {r["controller"]: r for r in csv.DictReader(io.StringIO((out / "results.csv").read_text()))}
    acc = entry(results, "acc")["robustness"]
    assert float(rows["acc"]["robustness_qualified"]) == acc["qualified"]
    assert int(rows["acc"]["robustness_collisions"]) == acc["collisions"] and "robustness" not in rows["acc"]
    assert "too fast for me" in rows[FAILS]["robustness_failed_to_run"]
    md = (out / "leaderboard.md").read_text()
    assert f"| {HEADER} |" in md and format_cell(acc) in md
    for text in (md, text_table(results), (out / "report.html").read_text()):
        assert HEADER in text
    plain = run_leaderboard("ncap-v1", "test", ["acc", "ppo"], episodes=1, workers=2, string_stability=False,
                            allow_root=True, iso15622=False, waves=False, robustness=False)
    assert plain["ranking"] == [n for n in results["ranking"] if n != FAILS]
    for name in ("acc", "ppo"):
        assert entry(plain, name)["summary"] == entry(results, name)["summary"]
    assert plain["manifest"]["settings"]["robustness"] is None and all("robustness" not in c for c in plain["controllers"])
    assert HEADER not in text_table(plain) and "robustness_qualified" not in csv_text(plain)


def test_formatting_of_each_kind_of_cell():
    assert format_cell(None) == "-"
    assert format_cell({"failed_to_run": "x"}) == "failed"
    assert format_cell({"qualified": 0.714, "collisions": 0, "preventable": 0, "score": 70.0}) == "71%"
    assert format_cell({"qualified": 0.5, "collisions": 3, "preventable": 2, "score": 50.0}) == \
        "COLLIDES 3 (2 preventable), 50%"


def test_a_leaderboard_in_a_car_scores_each_episode_as_a_local_run_in_that_car():
    import gymnasium as gym

    from acc_gym.evaluation.runner import run_episode
    from acc_gym.suites import get_suite

    car = {"sensors": "degraded", "actuators": {"lag": 0.6, "dead_time": 0.3}}
    r = run_leaderboard("ncap-v2", "test", ["acc"], episodes=3, workers=1, allow_root=True, string_stability=False,
                        iso15622=False, waves=False, robustness=False, car=car)
    suite = get_suite("ncap-v2")
    env = gym.make(suite.env_id, **car)
    local = [run_episode(env, "acc", seed=sc.seed, scenario=sc, record=False)[0]["score"]
             for sc in suite.episodes("test")[:3]]
    assert [e["score"] for e in entry(r, "acc")["episodes"]] == pytest.approx(local, abs=1e-9)
    plain = run_leaderboard("ncap-v2", "test", ["acc"], episodes=3, workers=1, allow_root=True, string_stability=False,
                            iso15622=False, waves=False, robustness=False)
    assert [e["score"] for e in entry(plain, "acc")["episodes"]] != [e["score"] for e in entry(r, "acc")["episodes"]]
    st = r["manifest"]["settings"]["car"]
    assert st["actuators"] == {"lag": 0.6, "dead_time": 0.3} and st["sensors"]["far_range"] == 100.0
    assert plain["manifest"]["settings"]["car"] is None
    note = " ".join(text_table(r).split())
    assert "actuators lag 0.6, dead_time 0.3; the ranking is that car's" in note and "far_range 100" in note
    with pytest.raises(ValueError, match=r"car settings \['wings'\] unknown"):
        run_leaderboard("ncap-v2", "test", ["acc"], episodes=1, car={"wings": 1})
