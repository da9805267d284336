"""The shipped trained policy: installed with the package, runs without torch, and meets its bar."""

import json
import subprocess
import sys

import numpy as np
import pytest

from acc_gym.evaluation.runner import evaluate, load_controller
from acc_gym_agents.policies import SHIPPED, load_shipped, shipped_path
from acc_gym.reproducibility import SCORE_TOLERANCE
from acc_gym_agents.policies.heldout import FAMILIES, heldout, meets_bar
from acc_gym_agents.rl.mlp import NumpyActor
from acc_gym_agents.rl.policy import SB3Policy


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_a_shipped_policy_is_a_complete_run_directory(name):
    run = shipped_path(name)
    for f in ("model.zip", "policy.npz", "obs_rms.npz", "manifest.json", "heldout.json", "README.md"):
        assert (run / f).is_file(), f"{name}: {f} is not installed with the package"
    manifest = json.loads((run / "manifest.json").read_text())
    policy = load_controller(name)
    assert isinstance(policy, SB3Policy) and isinstance(policy.model, NumpyActor)
    assert (policy.residual, policy.residual_scale, policy.shield, policy.max_overspeed) == (
        manifest["residual"], manifest["residual_scale"], manifest["shield"], manifest["max_overspeed"])


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_the_numpy_actor_is_the_trained_model(name):
    rng = np.random.default_rng(0)
    obs = np.column_stack([rng.uniform(0, 40, 1000), rng.uniform(-8, 3, 1000), rng.uniform(0, 200, 1000),
                           rng.uniform(-15, 15, 1000), rng.integers(0, 2, 1000), rng.uniform(8, 36, 1000),
                           np.full(1000, 1.5)]).astype(np.float32)
    np.testing.assert_allclose(load_shipped(name).predict(obs)[0], load_shipped(name, "sb3").predict(obs)[0],
                               atol=1e-6)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_the_shipped_policy_runs_on_the_core_install_without_torch(name):
    code = ("import sys\n"
            "sys.modules['torch'] = sys.modules['stable_baselines3'] = None  # importing them now fails\n"
            "from acc_gym.evaluation.runner import evaluate\n"
            f"s = evaluate({name!r}, 'acc_gym/CarFollowing-v0', episodes=2, seed=5)\n"
            "print(s['collisions'], repr(s['mean_score']))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert out.returncode == 0, out.stderr
    here = evaluate(name, "acc_gym/CarFollowing-v0", episodes=2, seed=5)  # this process has torch
    assert out.stdout.split() == ["0", repr(here["mean_score"])]


def test_on_paper_003_it_qualifies_without_collision_and_beats_the_linear_acc():
    for speed in (60, 90, 120):
        kw = {"scenarios": (f"carfollowing/{speed}",)}
        policy = evaluate("ppo-acc", "acc_gym/CarFollowing-v0", episodes=3, seed=77, **kw)
        acc = evaluate("acc", "acc_gym/CarFollowing-v0", episodes=3, seed=77, **kw)
        assert policy["collisions"] == 0 and policy["share_qualified"] == 1.0
        assert policy["mean_score"] > acc["mean_score"]


def test_it_stops_for_every_ncap_target_it_never_trained_on():
    # stationary, slower and braking targets (CCRs / CCRm / CCRb); trained without them, it keeps
    # the linear ACC's braking inside Gapsafe (shield="base") and so never creeps into them
    from acc_gym.scenarios import list_scenarios

    for sid in [i for i in list_scenarios() if i.startswith("ncap/")]:
        s = evaluate("ppo-acc", "acc_gym/NCAP-v0", episodes=1, seed=3, scenarios=(sid,))
        assert s["collisions"] == 0, sid


def test_meets_bar_names_each_miss():
    good = {"episodes": 10, "mean_score": 85.0, "share_qualified": 0.95, "collisions": 0, "max_jerk": 9.0}
    results = {"p": {f: dict(good) for f in FAMILIES}, "acc": {f: dict(good, mean_score=80.0) for f in FAMILIES}}
    assert meets_bar(results, "p") == []
    results["p"]["single-lane"].update(share_qualified=0.85, collisions=1)
    results["p"]["car-following 90 km/h"]["mean_score"] = 79.0
    assert meets_bar(results, "p") == ["car-following 90 km/h: mean score 79.0 <= acc's 80.0",
                                       "single-lane: qualified 85.0% < 90%", "single-lane: 1 collisions"]


@pytest.mark.slow
def test_the_recorded_heldout_results_reproduce():
    recorded = json.loads((shipped_path("ppo-acc") / "heldout.json").read_text())
    results = heldout(list(recorded["results"]), recorded["episodes"], recorded["singlelane_episodes"],
                      recorded["seed"])
    for name, families in recorded["results"].items():
        for family, s in families.items():
            # across machines scores agree to the documented tolerance, not to the bit
            assert results[name][family]["mean_score"] == pytest.approx(s["mean_score"], abs=SCORE_TOLERANCE)
            assert results[name][family]["share_qualified"] == s["share_qualified"]
    assert meets_bar(results, "ppo-acc") == []


def test_ppo_drives_a_v0_id_exactly_as_its_v1_twin():
    # given the -v0 fields it computes the margin features itself: the same episodes score the same
    kw = {"scenarios": ("carfollowing/90", "singlelane/2/cut-in")}
    v0 = evaluate("ppo", "acc_gym/SingleLane-v0", episodes=3, seed=5, **kw)
    v1 = evaluate("ppo", "acc_gym/SingleLane-v1", episodes=3, seed=5, **kw)
    assert v0["scores"] == v1["scores"] and v0["scenarios"] == v1["scenarios"]


def test_ppo_follows_paper_003s_test_without_collision():
    for speed in (60, 90, 120):
        s = evaluate("ppo", "acc_gym/CarFollowing-v1", episodes=2, seed=77, scenarios=(f"carfollowing/{speed}",))
        assert s["collisions"] == 0 and s["share_qualified"] == 1.0, (speed, s)


@pytest.mark.slow
def test_ppos_recorded_heldout_results_reproduce():
    recorded = json.loads((shipped_path("ppo") / "heldout.json").read_text())
    for env_id, s in recorded["results"].items():
        got = evaluate("ppo", env_id, episodes=s["episodes"], seed=recorded["seed"])
        assert got["mean_score"] == pytest.approx(s["mean_score"], abs=SCORE_TOLERANCE)
        assert (got["share_qualified"], got["collisions"]) == (s["share_qualified"], s["collisions"])
