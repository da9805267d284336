"""``--risk``: each controller's accelerated collision estimate, run through the sandbox."""

import json
from pathlib import Path

import pytest

from acc_gym.leaderboard import load_results, run_leaderboard
from acc_gym.leaderboard.results import csv_text, markdown, text_table

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module", autouse=True)
def importable_helpers():
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        yield


@pytest.fixture(scope="module")
def risk_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("lb") / "board"
    r = run_leaderboard("ncap-v1", "test", ["gm", "acc", "bad_controllers:ReturnsNaN"], episodes=1, workers=2,
                        out=out, report=False, risk={"budget": 512}, string_stability=False, iso15622=False, waves=False, robustness=False,
                        allow_root=True)
    return r, out


def test_each_controller_gets_an_estimate_or_an_upper_bound(risk_run):
    r, _ = risk_run
    by = {c["name"]: c for c in r["controllers"]}
    gm, acc = by["gm"]["risk"], by["acc"]["risk"]
    assert gm["family"] == "cut-in" and gm["failures"] > 0 and 0 <= gm["ci_low"] < gm["p"] < gm["ci_high"] < 0.05
    assert acc["failures"] == 0 and acc["p"] == 0.0 and acc["upper_bound"] > 0  # never collides: a bound, not 0
    assert gm["episodes"] >= 512 and acc["episodes"] >= 512
    assert by["bad_controllers:ReturnsNaN"].get("risk") is None  # failed on the suites: no estimate to make
    assert r["manifest"]["settings"]["risk"] == {"family": "cut-in", "budget": 512, "target_rhw": 0.2}


def test_the_estimate_is_the_in_process_estimate(risk_run):
    """The sandboxed rounds are the same episodes as estimate_risk's (same draws, same seeds)."""
    from acc_gym.risk import estimate_risk

    r, _ = risk_run
    gm = next(c for c in r["controllers"] if c["name"] == "gm")["risk"]
    local = estimate_risk("gm", "cut-in", budget=512, target_rhw=0.2)  # the same defaults
    assert (gm["p"], gm["failures"], gm["episodes"]) == (local.estimate.p, local.estimate.failures, local.episodes)


def test_tables_and_files_carry_the_estimate(risk_run):
    r, out = risk_run
    table, md = text_table(r), markdown(r)
    assert "P(collision) per cut-in" in md and "< " in md  # acc's upper bound
    # the terminal's 120 columns show the column or name it among those left to the files
    assert "P(collision) per cut-in" in " ".join(table.split())
    rows = csv_text(r).splitlines()
    header = rows[0].split(",")
    assert {"risk_p", "risk_ci_low", "risk_ci_high", "risk_upper_bound", "risk_episodes"} <= set(header)
    loaded = load_results(out / "results.json")
    assert loaded["controllers"][0]["risk"] == r["controllers"][0]["risk"]
    assert json.loads((out / "results.json").read_text())  # well-formed


@pytest.mark.parametrize("risk, match", [
    ({"family": "merge"}, "unknown family 'merge'"),
    ({"budget": 0}, "risk budget must be a positive integer"),
    ({"colour": 1}, "unknown risk option"),
    ("yes", "risk must be a dict"),
])
def test_bad_risk_options_are_named_before_anything_runs(risk, match):
    with pytest.raises(ValueError, match=match):
        run_leaderboard("ncap-v1", controllers=["acc"], episodes=1, risk=risk, waves=False, robustness=False)
