"""The leaderboard: isolation and budgets, deterministic ranking, results files, the CLI.

The misbehaving controllers live in ``bad_controllers.py`` next to this file and are
named ``bad_controllers:NAME``; the leaderboard loads them in spawned child processes,
which inherit the parent's ``sys.path`` -- the fixture below puts this directory on it.
"""

import json
import os
from pathlib import Path

import pytest

from acc_gym.cli import main
from acc_gym.leaderboard import load_results, run_leaderboard
from acc_gym.leaderboard.results import atomic_write, checksum, results_text

HERE = Path(__file__).resolve().parent
FILES = ("results.json", "results.csv", "leaderboard.md", "report.html")


@pytest.fixture(scope="module", autouse=True)
def importable_helpers():
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        yield


def scores(results: dict) -> dict:
    return {c["name"]: (c["status"], [(e["suite"], e["episode"], e["scenario"], e["score"]) for e in c["episodes"]],
                        c["summary"]) for c in results["controllers"]}


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory, importable_helpers):
    """One CLI run with two workers (shared by the CLI, files and determinism tests)."""
    out = tmp_path_factory.mktemp("lb") / "board"
    import io
    from contextlib import redirect_stdout

    buf = io.StringIO()
    with redirect_stdout(buf):
        code = main(["leaderboard", "--suite", "ncap-v1,carfollowing-v1", "--controllers", "acc", "idm",
                     "bad_controllers:Brakes", "--episodes", "2", "--workers", "2", "--out", str(out)])
    return code, buf.getvalue(), out


def test_cli_prints_the_ranking_and_writes_four_files(cli_run):
    code, text, out = cli_run
    assert code == 0
    results = load_results(out / "results.json")
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES + ("logs",))  # no temporary files left behind
    assert [p.name for p in out.parent.iterdir()] == ["board"]  # nor a staging directory beside it
    lines = text.splitlines()
    header = next(k for k, line in enumerate(lines) if line.startswith("#  controller"))
    for k, name in enumerate(results["ranking"]):  # printed in ranking order, with rank numbers
        assert lines[header + 2 + k].split()[:2] == [str(k + 1), name]
    for column in ("score", "qualified", "collisions/h", "comfortable", "safe spacing", "min TTC", "max jerk"):
        assert column in lines[header]
    md = (out / "leaderboard.md").read_text()
    assert "| # | controller |" in md and all(f"| {n} |" in md for n in results["ranking"])
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert csv_lines[0].startswith("rank,controller,status,points,score")
    assert [line.split(",")[1] for line in csv_lines[1:]] == results["ranking"]
    html = (out / "report.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and html.count("data:image/png;base64,") >= 2 + 3
    assert "http" not in html.replace("http-equiv", "")  # self-contained


def test_results_manifest_and_ranking(cli_run):
    _, _, out = cli_run
    r = load_results(out)
    m = r["manifest"]
    assert {"acc_gym", "numpy", "gymnasium", "python"} <= set(m["versions"]) and m["versions"]["numpy"]
    assert [s["name"] for s in m["suites"]] == ["ncap-v1", "carfollowing-v1"]
    from acc_gym.suites import get_suite

    for s in m["suites"]:
        suite = get_suite(s["name"])
        assert s["hash"] == suite.hash("test") and s["root_seed"] == suite.root_seed("test")
        assert s["episodes_run"] == 2 and s["content_matches"]
    assert m["split"] == "test" and m["episodes_cap"] == 2 and m["settings"]["workers"] == 2
    assert m["controllers"] == ["acc", "idm", "bad_controllers:Brakes"]
    by_name = {c["name"]: c for c in r["controllers"]}
    means = [by_name[n]["summary"]["overall"]["mean_score"] for n in r["ranking"]]
    assert means == sorted(means, reverse=True)
    for c in r["controllers"]:
        assert c["status"] == "ok" and len(c["episodes"]) == 4 and c["wall_time_s"] > 0
        o = c["summary"]["overall"]
        per_suite = [c["summary"]["suites"][s]["mean_score"] for s in ("ncap-v1", "carfollowing-v1")]
        assert o["mean_score"] == pytest.approx(sum(per_suite) / 2)  # every suite weighs the same
        hours = sum(e["duration"] for e in c["episodes"]) / 3600
        collisions = sum(e["metrics"]["collision"] for e in c["episodes"])
        assert o["collisions_per_hour"] == pytest.approx(collisions / hours)


def test_ranking_is_deterministic_and_independent_of_workers(cli_run):
    _, _, out = cli_run
    two = load_results(out)
    one = run_leaderboard(["ncap-v1", "carfollowing-v1"], "test", ["acc", "idm", "bad_controllers:Brakes"],
                          episodes=2, workers=1)
    assert one["ranking"] == two["ranking"]
    assert scores(one) == scores(two)


def test_failing_controllers_are_reported_and_the_others_finish():
    good = ["acc", "idm"]
    bad = {"bad_controllers:Raises": "deliberate failure in predict",
           "bad_controllers:Hangs": "step budget of 1.5 s",
           "bad_controllers:ReturnsNaN": "NaN",
           "bad_controllers:WrongShape": "shape",
           "bad_controllers:BadTimeGap": "its time_gap (the controller's declared time gap) must be a finite number",
           "no_such_module_xyz:Thing": "no_such_module_xyz"}
    r = run_leaderboard("ncap-v1", "test", ["acc", *bad, "idm"], episodes=3, workers=2, step_budget=1.5,
                        budget=120)
    by_name = {c["name"]: c for c in r["controllers"]}
    for name in good:
        c = by_name[name]
        assert c["status"] == "ok" and c["reason"] is None and len(c["episodes"]) == 3
        assert c["summary"]["overall"]["episodes"] == 3
    for name, words in bad.items():
        c = by_name[name]
        assert c["status"] == "failed" and words in c["reason"], (name, c["reason"])
        assert c["summary"] is None and c["rank"] is None
    assert "ncap-v1 episode 0" in by_name["bad_controllers:Raises"]["reason"]  # where it failed
    assert "RuntimeError" in by_name["bad_controllers:Raises"]["traceback"]
    assert "killed" in by_name["bad_controllers:Hangs"]["reason"]
    assert by_name["bad_controllers:Hangs"]["wall_time_s"] < 60  # killed, not waited for
    assert r["ranking"][:2] == sorted(good, key=lambda n: -by_name[n]["summary"]["overall"]["mean_score"])
    assert set(r["ranking"][2:]) == set(bad)


def test_a_controller_past_its_total_budget_is_killed():
    r = run_leaderboard("ncap-v1", "test", ["bad_controllers:Slow"], episodes=1, workers=1, step_budget=5,
                        budget=4)
    (c,) = r["controllers"]
    assert c["status"] == "failed" and "total budget of 4 s" in c["reason"] and c["wall_time_s"] < 30


def test_results_json_is_checked_when_read(cli_run, tmp_path):
    _, _, out = cli_run
    text = (out / "results.json").read_text()
    results = load_results(out / "results.json")
    path = tmp_path / "results.json"
    for damaged, words in ((text[: len(text) // 2], "truncated or corrupted"), ("", "truncated or corrupted"),
                           (text.replace('"acc"', '"acx"', 1), "checksum does not match"),
                           (json.dumps({"results": results}), "not an acc_gym.leaderboard/1 file")):
        path.write_text(damaged)
        with pytest.raises(ValueError, match=words) as err:
            load_results(path)
        assert str(path) in str(err.value)
    doc = json.loads(text)
    assert doc["sha256"] == checksum(doc["results"])
    path.write_text(results_text(results))
    assert load_results(path) == results


def test_files_are_replaced_atomically(tmp_path, monkeypatch):
    target = tmp_path / "results.json"
    atomic_write(target, "old")
    replaced = []
    real_replace = os.replace

    def spy(src, dst):
        replaced.append((Path(src).parent, Path(dst)))
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", spy)
    atomic_write(target, "new")
    assert target.read_text() == "new" and replaced == [(tmp_path, target)]  # a temporary file in the same dir

    def broken(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken)
    with pytest.raises(OSError, match="disk full"):
        atomic_write(target, "newer")
    assert target.read_text() == "new"  # the old content stays whole
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]  # and no temporary file is left


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="'nope-v1'"):
        run_leaderboard("nope-v1", controllers=["acc"])
    with pytest.raises(ValueError, match="'train'"):
        run_leaderboard("ncap-v1", "train", ["acc"])
    with pytest.raises(ValueError, match="workers"):
        run_leaderboard("ncap-v1", controllers=["acc"], workers=0)
    with pytest.raises(ValueError, match="step_budget"):
        run_leaderboard("ncap-v1", controllers=["acc"], step_budget=float("nan"))
    with pytest.raises(ValueError, match=r"\['acc'\] given more than once"):
        run_leaderboard("ncap-v1", controllers=["acc", "acc"])
    with pytest.raises(SystemExit):
        main(["leaderboard", "--suite", "nope-v1", "--controllers", "acc"])


def test_builtins_and_the_shipped_policy_score_as_under_evaluate():
    """Through the trusted simulation and the sandboxed controller, every built-in and
    ppo-acc score each episode exactly as run_episode does in one process."""
    import gymnasium as gym

    from acc_gym.evaluation.runner import run_episode
    from acc_gym.leaderboard.run import default_controllers
    from acc_gym.suites import get_suite

    names = default_controllers()
    assert "ppo-acc" in names and "acc" in names
    suites = ["malicious-v1", "carfollowing-v1"]
    r = run_leaderboard(suites, "test", names, episodes=2, workers=2)
    for c in r["controllers"]:
        assert c["status"] == "ok", (c["name"], c["reason"])
        for e in c["episodes"]:
            suite = get_suite(e["suite"])
            sc = suite.episodes("test")[e["episode"]]
            env = gym.make(suite.env_id)
            info, _ = run_episode(env, c["name"], seed=sc.seed, scenario=sc, record=False)
            env.close()
            assert e["score"] == info["score"], (c["name"], e["suite"], e["episode"])
            assert e["points"] == (0.0 if info["report"]["metrics"]["collision"] else info["score"])
