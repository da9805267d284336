"""What a new user meets first: paths and modules resolved from their directory, the exit
status, a table that fits a terminal, reports that people can read."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from acc_gym.leaderboard import load_results
from acc_gym.leaderboard.results import TEXT_WIDTH, text_table

REPO = Path(__file__).resolve().parents[2]
SHIPPED_PPO = REPO / "agents" / "policies" / "ppo"


@pytest.fixture(scope="module")
def user_run(tmp_path_factory):
    """The CLI, run from a user's directory holding a copied run directory (``runs/ppo``) and a
    module file (``mycontroller.py``, the built-in ``acc`` under another name), with a failing
    controller among them."""
    cwd = tmp_path_factory.mktemp("user")
    shutil.copytree(SHIPPED_PPO, cwd / "runs" / "ppo")
    (cwd / "mycontroller.py").write_text("from acc_gym_agents.controllers import LinearACC as Gap  # noqa: F401\n")
    cmd = [sys.executable, "-m", "acc_gym.cli", "leaderboard", "--suite", "ncap-v2", "--controllers", "acc", "ppo",
           "runs/ppo", "mycontroller:Gap", "mycontroller:Nope", "--episodes", "2", "--no-string-stability",
           "--no-iso15622", "--no-waves", "--no-robustness", "--allow-root", "--out", "board"]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=900, env=env)
    return cwd, done


def test_relative_paths_and_module_files_resolve_from_the_users_directory(user_run):
    cwd, done = user_run
    r = load_results(cwd / "board")
    by = {c["name"]: c for c in r["controllers"]}
    for copy, builtin in (("runs/ppo", "ppo"), ("mycontroller:Gap", "acc")):
        assert by[copy]["status"] == "ok", (copy, by[copy]["reason"])
        assert [e["score"] for e in by[copy]["episodes"]] == [e["score"] for e in by[builtin]["episodes"]], copy
    assert by["runs/ppo"]["reference"] == str(cwd / "runs" / "ppo")  # handed to the sandbox as an absolute path


def test_a_failing_controller_exits_3_and_the_results_are_written(user_run):
    cwd, done = user_run
    assert done.returncode == 3, done.stderr[-2000:]
    r = load_results(cwd / "board")  # written, whole, checksum verified
    by = {c["name"]: c for c in r["controllers"]}
    assert by["mycontroller:Nope"]["status"] == "failed" and "Nope" in by["mycontroller:Nope"]["reason"]
    assert sum(c["status"] == "ok" for c in r["controllers"]) == 4
    assert "mycontroller:Nope" in done.stdout and "exit status 3" in done.stderr


def test_the_printed_table_fits_120_columns(user_run):
    cwd, done = user_run
    r = load_results(cwd / "board")
    assert max(len(line) for line in done.stdout.splitlines()) <= TEXT_WIDTH
    long = json.loads(json.dumps(r))
    for c in long["controllers"]:  # names far longer than a column, still within the width
        c["name"] = c["name"] + "/" + "x" * 90
    long["ranking"] = [n + "/" + "x" * 90 for n in long["ranking"]]
    text = text_table(long)
    assert max(len(line) for line in text.splitlines()) <= TEXT_WIDTH
    header = text.splitlines()[0]
    assert "collisions" in header and "preventable" in header  # collisions beside the points


def _results_with_groups(groups, suite="s"):
    return {"ranking": ["a", "b"],
            "controllers": [{"name": n, "status": "ok", "summary": {"suites": {suite: {"by_group": {
                g: float(k % 100) for k, g in enumerate(groups)}}}}} for n in ("a", "b")]}


def test_heatmap_columns_sorted_numerically_and_split_into_rows():
    from acc_gym.leaderboard.report import heatmap_groups, score_heatmap

    r = _results_with_groups(["carfollowing/120", "carfollowing/60", "carfollowing/90"])
    assert heatmap_groups(r, "s") == ["carfollowing/60", "carfollowing/90", "carfollowing/120"]
    fig = score_heatmap(r, "s")
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["60", "90", "120"]  # common prefix in title
    many = [f"ncap2026/acc/ccrs/{v}" for v in range(10, 580, 10)]  # 57 columns, as ncap-v2
    fig = score_heatmap(_results_with_groups(list(reversed(many))), "s")
    maps = [ax for ax in fig.axes if ax.get_images()]
    assert len(maps) == 2  # 30 + 27 columns
    labels = [int(t.get_text()) for ax in maps for t in ax.get_xticklabels()]
    assert labels == sorted(labels) and len(labels) == 57


def test_captions_name_what_cost_the_points():
    import gymnasium as gym

    from acc_gym.evaluation.runner import run_episode
    from acc_gym.evaluation.scoring import score_world
    from acc_gym.leaderboard.report import points_lost
    from acc_gym.suites import get_suite

    suite = get_suite("ncap-v2")
    sc = suite.episodes("test")[0]
    env = gym.make(suite.env_id)
    info, trace = run_episode(env, "constant", seed=sc.seed, scenario=sc, record=True)  # drives into the target
    env.close()
    report = score_world(trace, [sc])[0]
    assert report.score == info["score"] == 45.0
    record = {"score": info["score"], "qualified": info["qualified"], "metrics": info["report"]["metrics"],
              "preventable": True, "points": 0.0}
    lines = points_lost(record, report)
    assert lines[0].startswith("preventable collision") and "45.0 points" in lines[0]
    assert "item safety" in lines[1] and lines[1].endswith("-15")
    assert "not counted" in lines[2]
    acc, acc_trace = run_episode(gym.make(suite.env_id), "acc", seed=sc.seed, scenario=sc, record=True)
    qualified = {"score": acc["score"], "qualified": True, "metrics": acc["report"]["metrics"]}
    r1, r2 = acc["report"]["r1"], acc["report"]["r2"]
    text = " ".join(points_lost(qualified, score_world(acc_trace, [sc])[0]))
    assert (f"comfort R2 = {r2:.1f} of 20: -{20 - r2:.1f}" in text) == (r2 < 20)
    assert (f"efficiency R1 = {r1:.1f}" in text) == (r1 < 20)
    # without a re-scored report: what the score alone says
    assert points_lost({**record, "preventable": None, "metrics": {"collision": False}}) == \
        ["1 of the 4 items not qualified: -15; efficiency and comfort (40) not counted"]


def test_the_report_reads_at_1400_px(user_run, tmp_path):
    """Headless Chromium lays the report out in a 1400 px window: no table is wider than the
    window and the page does not scroll sideways (a screenshot is kept beside it)."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if exe is None:
        pytest.skip("no Chromium here to lay the report out (apt-get install chromium)")
    cwd, _ = user_run
    html = (cwd / "board" / "report.html").read_text()
    assert "What cost the points" in html
    probe = ("<script>window.addEventListener('load', () => { const w = [...document.querySelectorAll('table')]"
             ".map(t => Math.ceil(t.getBoundingClientRect().right)); const p = document.createElement('pre');"
             " p.id = 'measure'; p.textContent = JSON.stringify({page: document.documentElement.scrollWidth,"
             " tables: w}); document.body.appendChild(p); });</script></body>")
    page = tmp_path / "report.html"
    page.write_text(html.replace("</body>", probe))
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--window-size=1400,1000"]
    dom = subprocess.run([exe, *flags, "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    measured = json.loads(dom.split('<pre id="measure">', 1)[1].split("</pre>", 1)[0])
    subprocess.run([exe, *flags, f"--screenshot={tmp_path / 'report.png'}", page.as_uri()], capture_output=True,
                   timeout=120)
    assert (tmp_path / "report.png").stat().st_size > 10_000
    assert measured["tables"] and max(measured["tables"]) <= 1400, measured
    assert measured["page"] <= 1400, measured
