"""``--event preventable-collision`` and UN R157's split of the collisions in risk estimates:
a collision counts when the careful and competent driver (cc-driver) avoids the same scenario.

Cut-ins at 10 m when the other vehicle enters the lane: 4 m/s slower, a controller that never
brakes hits it and cc-driver does not (preventable); 8 m/s slower, both hit it (not)."""

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from acc_gym.risk import estimate_risk
from acc_gym.risk.episodes import RiskChunk, draw_episodes, run_chunk
from acc_gym.risk.proposal import Proposal, tilted_keys
from acc_gym.risk.run import env_for
from acc_gym.scenarios.registry import scenario_type
from hold import Hold  # noqa: E402  (tests/risk/hold.py)

HERE = Path(__file__).resolve().parent
SID = "singlelane/2/cut-in"
PREVENTABLE = {"gap": 10.0, "v_rel": -4.0}
UNAVOIDABLE = {"gap": 10.0, "v_rel": -8.0}
CRUDE = dict(method="crude", budget=64, round_size=64)


def test_every_collision_preventable_gives_one_exactly():
    r = estimate_risk(Hold(), "cut-in", event="preventable-collision", params=PREVENTABLE, **CRUDE)
    assert r.event == r.estimate.event == "preventable-collision" and r.other.event == "collision"
    assert (r.estimate.p, r.estimate.ci_low, r.estimate.ci_high) == (1.0, 1.0, 1.0) and r.other.p == 1.0
    assert (r.preventable_collisions, r.non_preventable_collisions) == (64, 0)


def test_collisions_the_careful_driver_has_too_do_not_count():
    r = estimate_risk(Hold(), "cut-in", event="preventable-collision", params=UNAVOIDABLE, **CRUDE)
    assert r.other.p == 1.0  # it collides every time ...
    assert r.estimate.failures == 0 and r.estimate.p == 0.0
    assert r.estimate.upper_bound == pytest.approx(-np.log(0.05) / 64)  # exact bound: 64 nominal draws
    assert (r.preventable_collisions, r.non_preventable_collisions) == (0, 64)  # ... and so does cc-driver
    plain = estimate_risk(Hold(), "cut-in", params=UNAVOIDABLE, **CRUDE)  # the collision event reports the split too
    assert plain.estimate.p == 1.0 and (plain.preventable_collisions, plain.non_preventable_collisions) == (0, 64)
    assert estimate_risk(Hold(), "cut-in", event="ttc", params=UNAVOIDABLE, **CRUDE).preventable_collisions is None


def test_the_crude_estimate_is_a_hand_count_in_single_environments():
    """64 cut-ins at 10 m, the closing speed drawn: the estimate is the share of episodes where the
    controller collides and cc-driver, run by acc_gym.standards.r157.collides in a single
    environment, does not -- the same draws, judged another way (the risk run batches them)."""
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.standards.r157 import REFERENCE, collides

    kw = dict(params={"gap": 10.0}, root_seed=3, **CRUDE)
    r = estimate_risk(Hold(), "cut-in", event="preventable-collision", **kw)
    st = scenario_type(SID)
    keys = [k for k in tilted_keys(st.parameters) if k != "gap"]
    draws, _ = draw_episodes(Proposal(dict(st.parameters), {k: st.parameters[k] for k in keys}, 1.0), 3, 0, 0, 64)
    env, cc = gym.make(env_for(SID)), load_controller(REFERENCE)
    hits = preventable = 0
    for params, _, seed in draws:
        sc = st.build({"gap": 10.0, **params}, seed, "typical")
        if collides(env, Hold(), sc):
            hits += 1
            preventable += not collides(env, cc, sc)
    assert 0 < preventable < hits < 64  # both kinds and some misses: a real test of the split
    assert r.estimate.p == preventable / 64 and r.estimate.failures == preventable
    assert r.other.p == hits / 64 and r.estimate.p <= r.other.p
    assert (r.preventable_collisions, r.non_preventable_collisions) == (preventable, hits - preventable)
    plain = estimate_risk(Hold(), "cut-in", **kw)  # the collision event: the same split of the same episodes
    assert plain.estimate.p == hits / 64
    assert (plain.preventable_collisions, plain.non_preventable_collisions) == (preventable, hits - preventable)


def test_importance_sampling_estimates_no_more_than_the_collisions_of_the_same_run():
    r = estimate_risk(Hold(), "cut-in", event="preventable-collision", params={"gap": 10.0}, budget=384,
                      round_size=128, max_rounds=2, root_seed=1)
    assert r.estimate.failures > 0 and r.estimate.p <= r.other.p
    assert r.preventable_collisions == r.estimate.failures
    assert r.preventable_collisions + r.non_preventable_collisions == r.other.failures


def test_an_unknown_event_lists_the_known_ones(capsys):
    from acc_gym.cli import main

    with pytest.raises(ValueError, match=r"unknown event 'near-miss'; use one of \['collision', "
                                         r"'preventable-collision', 'ttc'\]"):
        estimate_risk("acc", "cut-in", event="near-miss")
    with pytest.raises(SystemExit):
        main(["risk", "--controller", "acc", "--event", "near-miss"])
    err = capsys.readouterr().err
    assert "invalid choice: 'near-miss'" in err and "preventable-collision" in err


def test_the_cli_names_the_event_in_text_and_json(capsys):
    from acc_gym.cli import main

    args = ["risk", "--controller", "constant", "--event", "preventable-collision", "--param", "gap=10",
            "--param", "v_rel=-4", "--method", "crude", "--budget", "64", "--round-size", "64", "--workers", "1"]
    assert main(args + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["event"] == out["estimate"]["event"] == "preventable-collision" and out["other"]["event"] == "collision"
    assert out["estimate"]["p"] == 1.0 and (out["preventable_collisions"], out["non_preventable_collisions"]) == (64, 0)
    assert main(args) == 0
    text = capsys.readouterr().out.splitlines()
    assert "crude, event preventable-collision: 64 episodes" in text[0]
    assert text[1].startswith("  P(preventable collision) per encounter 1 [1, 1]")
    assert any(line.startswith("  P(collision) per encounter 1") for line in text)
    assert any("of the 64 collisions in the estimation episodes, 64 preventable" in line for line in text)


def test_a_resumed_run_keeps_its_verdicts_and_refuses_a_chunk_without_them(tmp_path):
    kw = dict(event="preventable-collision", params={"gap": 10.0}, out=tmp_path, **CRUDE)
    first = estimate_risk("constant", "cut-in", **kw).to_dict()
    chunk = next(tmp_path.glob("r*-c*.json"))
    again = estimate_risk("constant", "cut-in", **kw).to_dict()
    for d in (first, again):
        d.pop("wall_time_s")
    assert again == first and first["preventable_collisions"] > 0
    data = json.loads(chunk.read_text())
    for rec in data["episodes"]:
        rec.pop("preventable")  # as an acc-gym before UN R157's split wrote them
    chunk.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=f"{chunk.name}: a chunk written without UN R157's preventability"):
        estimate_risk("constant", "cut-in", **kw)


# ----------------------------------------------------------------------------- through the leaderboard's isolation
def test_isolated_verdicts_come_from_the_simulation_process(monkeypatch, tmp_path):
    """Through the sandbox (acc_gym.risk.isolated) the verdicts are the simulation process's: a
    controller that never brakes, after patching cc-driver and r157.collides in its own
    process, gets the estimate and the split the in-process run gives ``constant`` on the
    same draws (one round of 64 from the untilted proposal: every weight 1, a plain share)."""
    from acc_gym.risk.isolated import leaderboard_risk
    from acc_gym.risk.proposal import DEFENSIVE

    monkeypatch.syspath_prepend(str(HERE))
    st = scenario_type(SID)
    prop = Proposal(dict(st.parameters), {k: st.parameters[k] for k in tilted_keys(st.parameters)}, DEFENSIVE)
    local = run_chunk(RiskChunk(SID, prop.to_dict(), "constant", 0, 0, 0, 64, env_for(SID), preventability=True))
    hits = sum(r["collision"] for r in local)
    k = sum(r["preventable"] is True for r in local)
    assert 0 < k < hits  # both kinds among these cut-ins
    board = leaderboard_risk("r157_tamper:PatchesCarefulDriver", "cut-in", event="preventable-collision", budget=64,
                             round_size=64, max_rounds=0, root_seed=0, run_kwargs={"log_dir": str(tmp_path)})
    assert "TAMPER patched" in "".join(f.read_text() for f in tmp_path.iterdir() if f.is_file())  # it did try
    assert (board["event"], board["failures"], board["p"]) == ("preventable-collision", k, k / 64)
    assert board["collision_p"] == hits / 64 and board["p"] <= board["collision_p"]
    assert (board["preventable_collisions"], board["non_preventable_collisions"]) == (k, hits - k)
    with pytest.raises(ValueError, match="unknown event 'ttc' for the isolated estimate"):
        leaderboard_risk("constant", "cut-in", event="ttc")
