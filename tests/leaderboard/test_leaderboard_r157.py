"""The leaderboard counts each collision as preventable or not (UN R157's careful and competent
driver, run in the trusted simulation process on the same scenario)."""

import csv
import io

from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard.isolation import Job, preventable
from acc_gym.leaderboard.results import COLLISIONS_NOTE, R157_NOTE, _text_cells, csv_text, markdown, text_table


def test_collisions_are_split_into_preventable_and_not():
    r = run_leaderboard("ncap-v1", "test", ["constant", "acc"], episodes=4, workers=2, string_stability=False,
                        iso15622=False, waves=False, robustness=False)
    by = {c["name"]: c for c in r["controllers"]}
    hits = [e for e in by["constant"]["episodes"] if e["metrics"]["collision"]]
    assert len(hits) == 4 and all(e["preventable"] is True for e in hits)  # CCRs: the careful driver stops
    assert all("preventable" not in e for e in by["acc"]["episodes"])  # no collision, no verdict
    o = by["constant"]["summary"]["overall"]
    assert o["preventable_collisions"] == 4 and o["non_preventable_collisions"] == 0
    assert "4 / 0" in markdown(r) and R157_NOTE in markdown(r)
    # the terminal: collisions and preventable ones as columns (constant: 4 and 4), the rule in its note
    _, headers, cells, _ = _text_cells(r)
    row = next(c for c in cells if "constant" in c)
    assert row[headers.index("collisions")] == "4" and row[headers.index("preventable")] == "4"
    assert " ".join(COLLISIONS_NOTE.split()) in " ".join(text_table(r).split())
    rows = {row["controller"]: row for row in csv.DictReader(io.StringIO(csv_text(r)))}
    assert rows["constant"]["preventable_collisions"] == "4" and rows["acc"]["preventable_collisions"] == "0"


def test_a_staged_unavoidable_cut_in_is_not_preventable():
    from acc_gym.standards.r157 import staged_cut_in

    job = Job("staged", "test", 0, "acc_gym/SingleLane-v0", staged_cut_in())
    assert preventable(job, {}) is False


def test_a_non_preventable_collision_keeps_its_score_in_the_points():
    from acc_gym.leaderboard.isolation import run_isolated
    from acc_gym.standards.r157 import staged_cut_in

    jobs = [Job("staged", "test", 0, "acc_gym/SingleLane-v0", staged_cut_in()),
            Job("staged", "test", 1, "acc_gym/NCAP-v0", _ccrs())]
    out = run_isolated(["constant"], jobs, workers=1, step_budget=1.0, budget=120.0)["constant"]
    unavoidable, avoidable = sorted(out.episodes, key=lambda e: e["episode"])
    assert unavoidable["metrics"]["collision"] and unavoidable["preventable"] is False
    assert unavoidable["points"] == unavoidable["score"] > 0.0
    assert avoidable["metrics"]["collision"] and avoidable["preventable"] is True and avoidable["points"] == 0.0


def _ccrs():
    import numpy as np

    from acc_gym.scenarios.registry import scenario_type

    st = scenario_type("ncap/ccrs/30")
    return st.build(st.sample_params(np.random.default_rng(0)), 0, "typical")
