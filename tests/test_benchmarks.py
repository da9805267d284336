"""The benchmark scripts run and print the documented JSON keys (speed is not tested here)."""

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_bench_driver_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_driver.py"), "--json", "--repeats", "1",
                        "--batch", "8", "--batch-repeats", "1"], capture_output=True, text=True, check=True)
    out = json.loads(r.stdout)
    for key in ("driver_step_us_median", "driver_step_us_p99", "driver_step_us_max", "active_share",
                "batch_vehicle_steps_per_s"):
        assert key in out and out[key] > 0
    assert out["driver_step_us_median"] <= out["driver_step_us_p99"] <= out["driver_step_us_max"]
    assert 0.0 < out["active_share"] < 1.0


def test_bench_env_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_env.py"), "--json", "--repeats", "1",
                        "--steps", "100", "--vector-steps", "5", "--num-envs", "8"], capture_output=True, text=True,
                       check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    for case in ("env", "env_idm", "env_carfollowing", "env_ncap"):  # the ids as users make them
        for key in (f"{case}_steps_per_s", f"vector_{case}_steps_per_s"):
            assert out[key] > 0 and len(out[key + "_runs"]) == 1
    assert out["num_envs"] == 8 and out["cases"]["env_idm"] == {"id": "acc_gym/SingleLane-v0", "drivers": "idm"}
    if (os.cpu_count() or 1) > 1:  # by default the vector env over worker processes is timed too
        assert out["workers"] == os.cpu_count() and out["vector_env_workers_steps_per_s"] > 0


def test_bench_env_prices_the_typical_car_against_the_ideal_one_in_the_same_run():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_env.py"), "--json", "--repeats", "1",
                        "--steps", "100", "--vector-steps", "5", "--num-envs", "4", "--workers", "1",
                        "--cases", "env_v1", "env_v1_typical"], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    assert out["cases"]["env_v1_typical"] == {"id": "acc_gym/SingleLane-v1", "sensors": "typical",
                                              "actuators": "typical"}
    for prefix in ("", "vector_"):
        cost = out[f"{prefix}env_v1_typical_cost"]
        assert cost == 1.0 - out[f"{prefix}env_v1_typical_steps_per_s"] / out[f"{prefix}env_v1_steps_per_s"]
        typical, ideal = out[f"{prefix}env_v1_typical_steps_per_s_runs"], out[f"{prefix}env_v1_steps_per_s_runs"]
        assert out[f"{prefix}env_v1_typical_cost_paired"] == pytest.approx(1.0 - typical[0] / ideal[0], abs=2e-3)  # (runs rounded)


def test_bench_env_peers_times_sumo_on_the_same_work():
    pytest.importorskip("libsumo", reason="libsumo is not installed (pip install '.[bench]' or '.[test]'): no SUMO peer to time")
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_env.py"), "--json", "--repeats", "1",
                        "--steps", "200", "--vector-steps", "3", "--num-envs", "4", "--workers", "1", "--cases", "env",
                        "--peers"], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout)  # the whole of stdout: libsumo's import-time notices go to stderr
    assert out["sumo_steps_per_s"] > 0 and out["env_idm_steps_per_s"] > 0  # env_idm is added for the ratio
    assert out["sumo_ratio"] == pytest.approx(out["env_idm_steps_per_s"] / out["sumo_steps_per_s"])


def test_sumo_peer_drives_the_documented_column():
    """The peer is the same work: the ego follows POV at a finite gap, POV2 behind, 200-step episodes."""
    pytest.importorskip("libsumo", reason="libsumo is not installed (pip install '.[bench]' or '.[test]'): no SUMO peer to check")
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sumo_peer

    v, gap, v_lead = sumo_peer.episode()
    assert 15.0 < v < 35.0 and 0.0 < gap < 100.0 and v_lead > 0.0
    assert sumo_peer.episode() == (v, gap, v_lead)  # a reload restarts the same episode


def test_bench_score_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_score.py"), "--json", "--episodes", "2",
                        "--loops", "1", "--repeats", "1"], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    assert out["traces"] == 4 and out["samples_min"] >= 2
    for key in ("trace_us", "record_us"):
        assert out[key] > 0 and len(out[key + "_runs"]) == 1
    assert out["ratio"] == pytest.approx(out["trace_us"] / out["record_us"], rel=1e-6)


# a benchmark's JSON keys (tens of seconds): with the slow tests (python -m pytest -m slow)
@pytest.mark.slow
def test_bench_campaign_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_campaign.py"), "--json", "--repeats", "1",
                        "--suite", "ncap-v1", "--hours", "0.005", "--chunk-size", "1"], capture_output=True, text=True,
                       check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    assert out["scenarios"] == 2  # 0.005 h = 18 s: the first two NCAP tests
    for key in ("scenarios_per_s_1_worker", "scenarios_per_s_2_workers", "scenarios_per_s_dask_2_workers"):
        assert out[key] > 0 and len(out[key + "_runs"]) == 1


def test_reproducibility_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "reproducibility.py"), "--json", "--per-suite", "2",
                        "--trials", "1"], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    from acc_gym.suites import list_suites

    assert out["episodes"] == 2 * len(list_suites()) and out["trials"] == 1 and out["controller"] == "acc"
    assert 0.0 <= out["median_score_change"] <= out["max_score_change"] <= out["score_tolerance"]
    assert out["verdicts_changed"] == 0 and out["max_speed_change"] < 1e-6


def test_bench_env_against_another_checkout():
    """--against DIR (here: this checkout again) times both in worker processes, a fresh pair per
    repeat: every repeat gives one rate per checkout and kind, the medians and ratios follow
    from them, and a repeat's pair gives the paired ratio."""
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_env.py"), "--json", "--repeats", "3",
                        "--rounds", "2",
                        "--steps", "50", "--vector-steps", "2", "--num-envs", "4", "--workers", "1", "--cases",
                        "env_carfollowing", "--against", str(ROOT)], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert set(out["against"]) == {"env_carfollowing_steps_per_s", "vector_env_carfollowing_steps_per_s"}
    assert out["clock"] == "process_time" and out["repeats"] == 3 and out["rounds"] == 2
    for row in out["against"].values():
        assert len(row["this_runs"]) == len(row["other_runs"]) == 3
        assert row["this"] == pytest.approx(np.median(row["this_runs"]), rel=1e-3)  # the runs are rounded
        assert row["other"] == pytest.approx(np.median(row["other_runs"]), rel=1e-3)
        assert row["this"] > 0 and row["other"] > 0 and row["ratio"] == pytest.approx(row["this"] / row["other"])
        ratios = np.array(row["this_runs"]) / np.array(row["other_runs"])
        assert row["paired_ratio"] == pytest.approx(np.median(ratios), rel=1e-2)


def test_bench_env_against_refuses_what_it_does_not_time():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_env.py"), "--json", "--cases", "env",
                        "--against", str(ROOT), "--policy"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode != 0 and "--against times the single and vector envs only" in r.stderr


def test_paired_ratio_is_the_median_of_each_repeats_ratio():
    """Runs (10, 20, 40) against (5, 10, 40): pairwise ratios 2, 2, 1, median 2 (the medians'
    ratio, 20 / 10, agrees); (12, 10, 30) against (10, 20, 20): ratios 1.2, 0.5, 1.5, median
    1.2, where the medians' ratio is 12 / 20 = 0.6 -- a drift that slows both runs of a
    repeat moves the medians apart, not the pairs' ratios."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_env

    assert bench_env.paired_ratio([10, 20, 40], [5, 10, 40]) == 2.0
    assert bench_env.paired_ratio([12, 10, 30], [10, 20, 20]) == pytest.approx(1.2)
    assert bench_env.paired_ratio([3, 1], [1, 1]) == 2.0  # an even count: the mean of the middle two
    with pytest.raises(ValueError, match="one length"):
        bench_env.paired_ratio([1, 2], [1])


def test_bench_env_medians_keep_a_run_where_no_episode_ended():
    """A repeat too short for any episode to end reports infinitely many steps per episode; the
    summary keeps it (it used to raise converting infinity to an integer) and the median is the
    middle run's."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_env

    out = {}
    bench_env._median(out, "vector_env_v1_steps_per_episode", [float("inf"), 70.4, 64.6])
    assert out["vector_env_v1_steps_per_episode"] == 70.4
    assert out["vector_env_v1_steps_per_episode_runs"] == [float("inf"), 70, 65]
    bench_env._median(out, "env_v1_reset_share", [0.2468, 0.25])
    assert out["env_v1_reset_share_runs"] == [0.247, 0.25]


@pytest.mark.parametrize("settings", [{}, {"drivers": "idm"}], ids=["mpc-drivers", "idm-drivers"])
def test_bench_env_single_split_counts_every_reset_and_only_them(settings):
    """The single env's ``--split``: the resets it times are the episodes that ended in the
    run (counted on a second env driven with the same seed and actions), the decisions are
    timed on that env's world only (every driver decides in its ``decide``: a share strictly
    between 0 and 1) and the run's time is the steps' plus the resets'."""
    import gymnasium as gym
    import numpy as np

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_env

    steps = 400
    split = bench_env.single_env_split(steps, 3, "acc_gym/SingleLane-v1", **settings)
    env = gym.make("acc_gym/SingleLane-v1", **settings)
    env.reset(seed=3)
    actions = np.random.default_rng(3).uniform(-0.3, 0.3, (steps, 1)).astype(np.float32)
    ended = 0
    for k in range(steps):
        _, _, term, trunc, _ = env.step(actions[k])
        if term or trunc:
            env.reset()
            ended += 1
    assert "decide" not in vars(env.unwrapped.core.world)  # the timer was on the benchmark's env only
    env.close()
    assert ended >= 2  # single-lane episodes last 6-40 s: several end within 80 s
    assert split["steps_per_episode"] == pytest.approx(steps / ended)
    assert 0.0 < split["decide_share"] < 1.0
    assert 0.0 < split["reset_share"] < 1.0
    assert split["decide_share"] + split["reset_share"] < 1.0
    total = steps / split["steps_per_s"]  # [s]
    assert split["us_per_reset"] == pytest.approx(1e6 * split["reset_share"] * total / ended)
    assert total == pytest.approx(1e-6 * (steps * split["us_per_step"] + ended * split["us_per_reset"]))


def test_bench_env_split_counts_every_autoreset_and_only_them():
    """``--split``'s accounting: the rows it times restarting are exactly the episodes that ended
    before the run's last step (an episode ending at step k restarts at step k + 1), counted here
    on a second env driven with the same seed and actions; their time is part of the run's, so
    the rate without them is higher."""
    import gymnasium as gym
    import numpy as np

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_env

    num_envs, steps = 8, 150
    split = bench_env.vector_env_split(num_envs, steps, 3, env_id="acc_gym/SingleLane-v1")
    envs = gym.make_vec("acc_gym/SingleLane-v1", num_envs=num_envs, vectorization_mode="vector_entry_point")
    envs.reset(seed=3)
    actions = np.random.default_rng(3).uniform(-0.3, 0.3, (steps, num_envs, 1)).astype(np.float32)
    ended = 0
    for k in range(steps - 1):
        _, _, term, trunc, _ = envs.step(actions[k])
        ended += int(np.sum(term | trunc))
    envs.close()
    assert ended > 0  # single-lane episodes last 6-40 s (median 12): some of 8 end within 15 s
    assert split["resets"] == ended
    assert 0.0 < split["reset_share"] < 1.0
    assert split["steps_per_s_without_resets"] > split["steps_per_s"]
    assert split["steps_per_s"] == pytest.approx(split["steps_per_s_without_resets"] * (1.0 - split["reset_share"]))
    assert split["steps_per_episode"] == pytest.approx(num_envs * steps / ended)
    # the new scenes' MPC drivers are condensed (the cruise QP inside the resets, the follow QP
    # at a first real target) ...
    assert split["condensations"] >= 2 and 0.0 < split["condense_share"] < 1.0
    # the parameter draws happen inside the resets
    assert 0.0 < split["params_share"] < split["reset_share"]
    assert split["condensations_per_episode"] == pytest.approx(split["condensations"] / ended)
    total = num_envs * steps / split["steps_per_s"]  # [s]
    assert split["us_per_condensation"] == pytest.approx(1e6 * split["condense_share"] * total / split["condensations"])
    # ... and baseline drivers have none; the wrapper is gone after the run
    from acc_gym.drivers import qp

    idm = bench_env.vector_env_split(num_envs, 60, 3, env_id="acc_gym/SingleLane-v1", drivers="idm")
    assert idm["condensations"] == 0 and idm["condense_share"] == 0.0 and idm["resets"] > 0
    assert 0.0 < idm["params_share"] < idm["reset_share"]
    from acc_gym.scenarios import registry

    assert qp.CondensedQP.__init__.__name__ == "__init__"
    assert registry.scenario_rngs.__name__ == "scenario_rngs"
    assert registry.ScenarioType.sample_params.__name__ == "sample_params"


# a benchmark's JSON keys (tens of seconds): with the slow tests (python -m pytest -m slow)
@pytest.mark.slow
def test_bench_leaderboard_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_leaderboard.py"), "--json", "--repeats", "1",
                        "--rows", "4", "--round-trips", "20", "--leaderboard-args",
                        "--suite ncap-v1 --controllers constant --episodes 1 --no-report"],
                       capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    assert out["pipe_rows"] == 4
    for key in ("pipe_us_per_round_trip", "pipe_us_per_row", "predict_us_per_row", "leaderboard_wall_s"):
        assert out[key] > 0, key
    assert out["pipe_us_per_row"] == out["pipe_us_per_round_trip"] / 4
    assert len(out["leaderboard_wall_s_runs"]) == 1 and out["leaderboard_wall_s"] == out["leaderboard_wall_s_runs"][0]
    assert "ratio" not in out  # only with --against


# a benchmark's JSON keys (tens of seconds): with the slow tests (python -m pytest -m slow)
@pytest.mark.slow
def test_bench_risk_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_risk.py"), "--json", "--quick", "--workers",
                        "1"], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    keys = {"controller", "family", "method", "p", "ci_low", "ci_high", "episodes", "acceleration", "validates"}
    assert out["cases"] and all(keys <= set(c) for c in out["cases"])
    crude = {f"{c['controller']}/{c['family']}" for c in out["cases"] if c["method"] == "crude"}
    checked = [c for c in out["cases"] if c["validates"]]
    assert checked and all(c["method"] == "is" and c["validates"] in crude for c in checked)
    assert all(c["acceleration"] == 1.0 for c in out["cases"] if c["method"] == "crude")
    assert all(0.0 <= c["ci_low"] <= c["p"] <= c["ci_high"] <= 1.0 for c in out["cases"])
    assert 0.0 <= out["coverage"]["coverage"] <= 1.0 and out["coverage"]["runs"] == 2


def test_bench_env_column_case_runs():
    """The column case (simulate_column, a lead and 10 IDM followers, 3,000 steps of 0.1 s) runs to
    its end without a collision."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_env

    assert bench_env.column_rate() > 0


def test_bench_env_column_peer_cavsandbox_does_the_same_work():
    """cavsandbox's side of the column case (the peer is in the bench extra only, not in test: the
    default run has no column peer, and `pip install '.[bench]'` then this test exercises it)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_env

    missing = bench_env.cavsandbox_available()
    if missing is not None:
        pytest.skip(f"{missing}; it is in the bench extra only: pip install '.[bench]' to run the column peer")
    assert bench_env.cavsandbox_column_rate() > 0  # its log holds every step of every vehicle (asserted inside)


def test_bench_env_peers_reports_the_column_ratio_or_why_not():
    """--peers adds column_vehicle_steps_per_s and column_ratio_cavsandbox; without cavsandbox
    (here made unimportable) the ratio is null with the reason, and the script still runs."""
    pytest.importorskip("libsumo", reason="libsumo is not installed (pip install '.[bench]' or '.[test]'): "
                                          "--peers needs it")
    argv = ["bench_env.py", "--json", "--repeats", "1", "--steps", "200", "--vector-steps", "3", "--num-envs", "4",
            "--workers", "1", "--cases", "env_idm", "--peers"]
    code = ("import runpy, sys; sys.modules['cacc_sim'] = None; sys.argv = %r; "
            "runpy.run_path('benchmarks/bench_env.py', run_name='__main__')" % argv)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["column_vehicle_steps_per_s"] > 0 and len(out["column_vehicle_steps_per_s_runs"]) == 1
    assert out["column_ratio_cavsandbox"] is None
    assert "cavsandbox is not installed" in out["column_ratio_cavsandbox_reason"]
    assert "cavsandbox_column_vehicle_steps_per_s" not in out
    try:
        import cacc_sim  # noqa: F401
    except ImportError:
        return
    r = subprocess.run([sys.executable, *argv], capture_output=True, text=True, check=True, cwd=ROOT / "benchmarks")
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["cavsandbox_column_vehicle_steps_per_s"] > 0
    assert out["column_ratio_cavsandbox"] == pytest.approx(out["column_vehicle_steps_per_s"]
                                                          / out["cavsandbox_column_vehicle_steps_per_s"])


def test_rl_curves_twin_curve_equals_training_the_twin_id(tmp_path):
    """benchmarks/rl_curves.py --twins: a -v1 run's checkpoints scored on the other -v1 id's own
    scenarios give that id's curve as training it (same seed, same tuned entry) gives it."""
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is not installed (pip install '.[rl]' or '.[test]')")
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import rl_curves
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    kw = dict(seed=3, runs=tmp_path, eval_freq=4096, eval_episodes=3, heldout=None, heldout_episodes={},
              timesteps=4096)
    cf = rl_curves.curve("ppo", "acc_gym/CarFollowing-v1", **kw)
    sl = rl_curves.curve("ppo", "acc_gym/SingleLane-v1", **kw)
    twin = rl_curves.twin_curve(cf, "acc_gym/SingleLane-v1", tmp_path)
    assert twin["env_id"] == "acc_gym/SingleLane-v1" and twin["trained_as"] == "ppo_CarFollowing-v1_s3"
    assert twin["steps"] == sl["steps"] and twin["collisions"] == sl["collisions"]
    assert twin["mean_score"] == pytest.approx(sl["mean_score"], abs=0.05)
    assert twin["share_qualified"] == sl["share_qualified"]
    assert twin["mean_score"] != cf["mean_score"]  # scored on the single-lane scenarios, not car-following's
    with pytest.raises(SystemExit, match="different ppo entries"):
        rl_curves.twin_curve(cf, "acc_gym/CarFollowing-v0", tmp_path)


# a benchmark's JSON keys (tens of seconds): with the slow tests (python -m pytest -m slow)
@pytest.mark.slow
def test_bench_startup_json_keys():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_startup.py"), "--json", "--repeats", "1"],
                       capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout)
    for key in ("startup_import_s", "startup_env_s", "startup_env_scipy_integrate_s"):
        assert out[key] > 0 and out[key + "_runs"] == [out[key]]  # one round: the median is that run
    assert out["scipy_integrate_cost_s"] == out["startup_env_scipy_integrate_s"] - out["startup_env_s"]
    assert out["startup_import_s"] < out["startup_env_s"]  # making and stepping an env imports and loads more


def test_rl_curves_candidates_reads_every_per_seed_form_and_counts_by_hand():
    """benchmarks/rl_curves.py --candidates: one row per selection entry validated seed by seed,
    whichever of the search's three per-seed forms it used; entries without ``per_seed`` and
    other keys are left out. Counts, medians, minima and collisions as computed by hand."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import rl_curves
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    data = {
        "tried": {"per_seed": {"0": {"meets": True}}},  # not a selection entry
        "selection_rule_only": {"rule": "..."},
        "selection_new": {"validation_seed": 7, "per_seed": {
            "0": {"carfollowing_v1": 0.90, "singlelane_v1": 0.80, "collisions_carfollowing_v1": 0,
                  "collisions_singlelane_v1": 0, "meets": True},
            "1": {"carfollowing_v1": 0.70, "singlelane_v1": 0.95, "collisions_carfollowing_v1": 1,
                  "collisions_singlelane_v1": 2, "meets": False},
            "2": {"carfollowing_v1": 1.00, "singlelane_v1": 0.76, "collisions_carfollowing_v1": 0,
                  "collisions_singlelane_v1": 0, "meets": True}}},
        "selection_lists": {"validation_seed": 8, "per_seed": {
            "0": {"CarFollowing-v1": [0.5, 60.0, 4], "SingleLane-v1": [0.6, 70.0, 0], "meets": False}}},
        "selection_dicts": {"validation_seed": 9, "per_seed": {
            "3": {"acc_gym/CarFollowing-v1": {"share_qualified": 0.85, "collisions": 0},
                  "acc_gym/SingleLane-v1": {"share_qualified": 0.75, "collisions": 0}, "meets": True},
            "4": {"acc_gym/CarFollowing-v1": {"share_qualified": 0.95, "collisions": 0},
                  "acc_gym/SingleLane-v1": {"share_qualified": 0.65, "collisions": 1}, "meets": False}}},
    }
    lines = rl_curves.candidates(data).splitlines()
    assert len(lines) == 2 + 3
    assert lines[2] == "| `selection_new` | 7 | 2 of 3 (0, 2) | 90 % (70 %) | 80 % (76 %) | 3 |"
    assert lines[3] == "| `selection_lists` | 8 | 0 of 1 | 50 % (50 %) | 60 % (60 %) | 4 |"
    assert lines[4] == "| `selection_dicts` | 9 | 1 of 2 (3) | 90 % (85 %) | 70 % (65 %) | 1 |"


def test_ring_benchmark_times_this_checkout_against_another_with_the_documented_keys():
    """``benchmarks/ring.py --timing-only --against DIR`` (here: this checkout again, on short rings)."""
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "ring.py"), "--timing-only", "--json",
                        "--timing-rings", "2", "--timing-duration", "10", "--repeats", "2", "--against", str(ROOT)],
                       capture_output=True, text=True, check=True, cwd=ROOT)
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert set(out["against"]) == {"timing_one_ring_10min", "timing_100_rings_10min"} and out["repeats"] == 2
    for row in out["against"].values():
        assert len(row["this_runs"]) == len(row["other_runs"]) == 2 and min(row["this_runs"] + row["other_runs"]) > 0
        assert row["ratio"] == pytest.approx(row["this"] / row["other"])
