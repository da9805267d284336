"""The leaderboard's uncertainty: intervals on its figures, paired comparisons of adjacent
rows, and both in results.json and the tables. Synthetic episode records (the shape
``isolation.episode_record`` gives them), no simulation."""

import csv
import io
import json

import numpy as np
import pytest

from acc_gym.leaderboard import load_results
from acc_gym.leaderboard import uncertainty as u
from acc_gym.leaderboard.results import (
    checksum,
    csv_text,
    markdown,
    rank,
    results_text,
    summarise_controller,
    text_table,
    write_files,
)

SUITES = {"ncap-v1": 20, "carfollowing-v1": 15}


def record(suite, k, score, *, collision=False, qualified=None, comfortable=1.0, safe=1.0, duration=60.0):
    """One episode record as isolation.episode_record builds it."""
    return {"suite": suite, "split": "test", "episode": k, "scenario": f"{suite.split('-')[0]}/s{k % 5}",
            "scenario_seed": 1000 + k, "group": f"{suite.split('-')[0]}/s{k % 5}", "duration": duration,
            "simulated": duration, "score": float(score), "points": 0.0 if collision else float(score),
            "qualified": bool(score >= 80 if qualified is None else qualified),
            "metrics": {"collision": collision, "share_comfortable": comfortable, "share_safe_spacing": safe,
                        "min_ttc": 2.0, "max_jerk": 5.0, "speed_overshoot": None}}


def episodes(scores: dict[str, list[float]], **kw) -> list[dict]:
    return [record(suite, k, s, **kw) for suite, xs in scores.items() for k, s in enumerate(xs)]


def base_scores(seed=0) -> dict[str, list[float]]:
    rng = np.random.default_rng(seed)
    return {suite: list(np.round(rng.uniform(40, 95, n), 3)) for suite, n in SUITES.items()}


def entry(name, eps, status="ok", reason=None):
    return {"name": name, "reference": name, "code": None, "status": status, "reason": reason, "traceback": None,
            "wall_time_s": 1.0, "notes": [], "log": None,
            "summary": summarise_controller(eps, list(SUITES)) if status == "ok" else None, "episodes": eps}


def results_of(entries) -> dict:
    ranking = rank(entries)
    suites = [{"name": s, "version": 1, "hash": "0" * 64, "root_seed": 1, "episodes_run": n,
               "episodes_defined": n, "hours": n / 60} for s, n in SUITES.items()]
    manifest = {"split": "test", "suites": suites, "versions": {"acc_gym": "test"}, "created": "2024-01-01",
                "platform": "test"}
    return {"manifest": manifest, "ranking": ranking, "controllers": entries}


# -- intervals --------------------------------------------------------------------------------------
def test_the_bootstrap_interval_of_a_constant_sample_is_a_point():
    lo, hi = u.bootstrap_mean_interval([73.25] * 40)
    assert lo == hi == pytest.approx(73.25)
    s = summarise_controller(episodes({s: [55.0] * n for s, n in SUITES.items()}), list(SUITES))
    for part in (s["overall"], *s["suites"].values()):
        lo, hi = part["mean_score_ci"]
        assert lo == hi == pytest.approx(55.0)


def test_a_bootstrap_interval_covers_the_mean_and_narrows_as_one_over_root_n():
    rng = np.random.default_rng(7)
    small = rng.normal(60, 15, 100)
    large = np.tile(small, 4)  # the same distribution, four times the episodes
    lo, hi = u.bootstrap_mean_interval(small)
    assert lo < small.mean() < hi
    # the normal theory half-width is 1.96 sigma / sqrt(n)
    assert (hi - lo) / 2 == pytest.approx(1.96 * small.std() / np.sqrt(small.size), rel=0.15)
    lo4, hi4 = u.bootstrap_mean_interval(large)
    assert lo4 < large.mean() < hi4
    assert (hi4 - lo4) / (hi - lo) == pytest.approx(0.5, abs=0.08)


def test_the_bootstrap_covers_the_true_mean_about_95_percent_of_the_time():
    rng = np.random.default_rng(11)
    hits = sum(lo <= 50 <= hi for lo, hi in (u.bootstrap_mean_interval(rng.exponential(50, 60), b=1000)
                                            for _ in range(200)))
    assert 0.88 <= hits / 200 <= 0.99


def test_no_collision_in_n_episodes_has_the_clopper_pearson_upper_bound():
    for n in (15, 35, 365):
        lo, hi = u.clopper_pearson(0, n)
        assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-9)  # the closed form
        assert 3.0 / n < hi < 4.0 / n
        lo, hi = u.clopper_pearson(n, n)
        assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / n), rel=1e-9)
    eps = episodes({s: [90.0] * n for s, n in SUITES.items()})  # no collision, all qualified
    s = summarise_controller(eps, list(SUITES))
    n, hours = len(eps), len(eps) * 60.0 / 3600
    o = s["overall"]
    assert o["collisions"] == 0 and o["collision_rate"] == 0.0 and o["collisions_per_hour"] == 0.0
    assert o["collision_rate_ci"] == [0.0, pytest.approx(1 - 0.025 ** (1 / n))]
    assert o["collisions_per_hour_ci"] == [0.0, pytest.approx((1 - 0.025 ** (1 / n)) * n / hours)]
    for suite, k in SUITES.items():
        assert s["suites"][suite]["collision_rate_ci"][1] == pytest.approx(1 - 0.025 ** (1 / k))
        assert s["suites"][suite]["share_qualified_ci"] == [pytest.approx(0.025 ** (1 / k)), 1.0]


def test_clopper_pearson_matches_the_beta_quantiles_and_covers_the_share():
    from scipy.stats import beta

    lo, hi = u.clopper_pearson(7, 40)
    assert lo == pytest.approx(beta.ppf(0.025, 7, 34)) and hi == pytest.approx(beta.ppf(0.975, 8, 33))
    assert lo < 7 / 40 < hi


def test_rates_use_clopper_pearson_and_collisions_per_hour_scale_with_the_hours():
    scores = base_scores()
    eps = [record(e["suite"], e["episode"], e["score"], collision=e["episode"] < 2, duration=120.0)
           for e in episodes(scores)]
    s = summarise_controller(eps, list(SUITES))
    n = len(eps)
    o = s["overall"]
    assert o["collisions"] == 4 and o["collision_rate"] == pytest.approx(4 / n)
    assert o["collision_rate_ci"] == pytest.approx(u.clopper_pearson(4, n))
    assert o["collisions_per_hour_ci"] == pytest.approx([x * n / o["hours"] for x in u.clopper_pearson(4, n)])
    lo, hi = o["collisions_per_hour_ci"]
    assert lo < o["collisions_per_hour"] < hi
    for part in (o, *s["suites"].values()):
        for key in ("mean_points", "mean_score", "share_qualified", "share_comfortable", "share_safe_spacing"):
            lo, hi = part[f"{key}_ci"]
            assert lo <= part[key] <= hi, key


def test_the_overall_interval_resamples_within_each_suite():
    """Overall: each suite weighs the same in every resample, as in the figure itself."""
    scores = {"ncap-v1": [20.0] * 20, "carfollowing-v1": [80.0] * 15}  # constant within each suite
    s = summarise_controller(episodes(scores), list(SUITES))
    assert s["overall"]["mean_score"] == pytest.approx(50.0)
    lo, hi = s["overall"]["mean_score_ci"]
    assert lo == hi == pytest.approx(50.0)  # no variation within a suite: no uncertainty


def test_missing_values_count_in_no_mean():
    eps = episodes(base_scores())
    for e in eps[:5]:
        e["metrics"]["share_safe_spacing"] = None
    s = summarise_controller(eps, list(SUITES))
    lo, hi = s["suites"]["ncap-v1"]["share_safe_spacing_ci"]
    assert lo == hi == pytest.approx(1.0)


def test_a_full_size_board_gets_every_interval_and_comparison():
    """10 controllers x 365 episodes over four suites (speed is not tested here)."""
    rng = np.random.default_rng(3)
    big = {"carfollowing-v1": 15, "malicious-v3": 40, "ncap-v1": 40, "singlelane-v3": 270}
    runs = [[record(suite, k, rng.uniform(0, 100), collision=rng.random() < 0.02) for suite, n in big.items()
             for k in range(n)] for _ in range(10)]
    entries = [{"name": f"c{i}", "status": "ok", "summary": summarise_controller(eps, list(big)), "episodes": eps}
               for i, eps in enumerate(runs)]
    rank(entries)
    assert all(e["vs_above"] is not None and e["vs_above"]["pairs"] == 365 for e in entries if e["rank"] != 1)
    assert all(e["summary"]["overall"]["mean_points_ci"][0] <= e["summary"]["overall"]["mean_points"]
               <= e["summary"]["overall"]["mean_points_ci"][1] for e in entries)


def test_the_generator_is_seeded_by_name_and_the_global_one_is_untouched():
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    a = u.bootstrap_mean_interval(np.arange(30.0), name="ncap-v1")
    assert np.array_equal(np.random.get_state()[1], before)  # the global generator is not used
    assert u.bootstrap_mean_interval(np.arange(30.0), name="ncap-v1") == a
    assert u.bootstrap_mean_interval(np.arange(30.0), name="malicious-v3") != a


# -- paired comparisons -----------------------------------------------------------------------------
def test_identical_controllers_are_a_tie():
    scores = base_scores()
    entries = [entry("zeta", episodes(scores)), entry("alpha", episodes(scores))]
    r = results_of(entries)
    by = {c["name"]: c for c in entries}
    assert r["ranking"] == ["alpha", "zeta"] and by["alpha"]["vs_above"] is None
    vs = by["zeta"]["vs_above"]
    assert vs == {"controller": "alpha", "diff": 0.0, "ci": [0.0, 0.0], "significant": False, "pairs": 35}
    assert by["alpha"]["summary"] == by["zeta"]["summary"]  # the intervals do not depend on the name


def test_a_controller_better_on_every_paired_episode_is_significantly_better():
    scores = base_scores()
    better = {s: [x + 3.0 for x in xs] for s, xs in scores.items()}
    entries = [entry("b", episodes(scores)), entry("a", episodes(better))]
    rank(entries)
    by = {c["name"]: c for c in entries}
    vs = by["b"]["vs_above"]
    assert vs["controller"] == "a" and vs["diff"] == pytest.approx(-3.0) and vs["significant"]
    assert vs["ci"] == pytest.approx([-3.0, -3.0])
    assert u.verdict(vs) == "worse"


def test_a_small_noisy_difference_is_a_tie_and_a_large_one_is_not():
    rng = np.random.default_rng(5)
    scores = base_scores()
    noisy = {s: [x + rng.normal(0.2, 8.0) for x in xs] for s, xs in scores.items()}
    far = {s: [x - 15 + rng.normal(0, 8.0) for x in xs] for s, xs in scores.items()}
    entries = [entry("base", episodes(scores)), entry("noisy", episodes(noisy)), entry("far", episodes(far))]
    ranking = rank(entries)
    by = {c["name"]: c for c in entries}
    assert ranking[-1] == "far"
    middle = by[ranking[1]]
    assert not middle["vs_above"]["significant"] and middle["vs_above"]["ci"][0] < 0 < middle["vs_above"]["ci"][1]
    assert by["far"]["vs_above"]["significant"] and by["far"]["vs_above"]["ci"][1] < 0


def test_pairs_are_matched_by_episode_not_by_position():
    scores = base_scores()
    shuffled = list(reversed(episodes(scores)))
    vs = u.compare({"name": "a", "episodes": episodes(scores)}, {"name": "b", "episodes": shuffled})
    assert vs["diff"] == 0.0 and vs["ci"] == [0.0, 0.0] and vs["pairs"] == 35


def test_the_ranking_order_is_the_points_order_whatever_the_comparison():
    scores = base_scores()
    lower = {s: [x - 0.01 for x in xs] for s, xs in scores.items()}
    entries = [entry("x-low", episodes(lower)), entry("y-high", episodes(scores))]
    assert rank(entries) == ["y-high", "x-low"]
    by = {c["name"]: c for c in entries}
    assert by["y-high"]["rank"] == 1 and by["x-low"]["rank"] == 2  # the rank is the points rank


def test_failed_controllers_have_no_intervals_and_break_nothing(tmp_path):
    scores = base_scores()
    entries = [entry("ok", episodes(scores)), entry("broken", [], "failed", "crashed"),
               entry("half", episodes(scores)[:3], "failed", "killed")]
    r = results_of(entries)
    assert r["ranking"] == ["ok", "broken", "half"]
    assert all(c["vs_above"] is None for c in entries)
    text = text_table(r)
    assert "failed: broken: crashed" in text
    write_files(r, tmp_path, key=None)
    assert load_results(tmp_path) == json.loads(json.dumps(r))


# -- the tables and results.json ----------------------------------------------------------------------
@pytest.fixture()
def three():
    scores = base_scores()
    worse = {s: [x - 20.0 for x in xs] for s, xs in scores.items()}
    return results_of([entry("first", episodes(scores)), entry("twin", episodes(scores)),
                       entry("third", episodes(worse)), entry("broken", [], "failed", "crashed")])


def test_ties_and_intervals_show_in_every_table(three):
    by = {c["name"]: c for c in three["controllers"]}
    o = by["first"]["summary"]["overall"]
    lo, hi = o["mean_points_ci"]
    shown = f"{o['mean_points']:.1f} [{lo:.1f}, {hi:.1f}]"
    lines = text_table(three).splitlines()
    assert "vs above" in lines[0]
    rows = {line.split()[1]: line for line in lines[2:5]}
    assert shown in rows["first"] and " tie " in rows["twin"] and " worse " in rows["third"]
    assert " tie " not in rows["first"] and " worse " not in rows["first"]
    q = o["share_qualified_ci"]
    assert f"{o['share_qualified']:.0%} [{100 * q[0]:.0f}, {100 * q[1]:.0f}]" in rows["first"]
    md = {cells[2].strip(): [c.strip() for c in cells] for cells in (line.split("|") for line in
                                                                      markdown(three).splitlines()
                                                                      if line.startswith("| ")
                                                                      and not line.startswith("| # |"))}
    header = next(line for line in markdown(three).splitlines() if line.startswith("| # |"))
    col = [c.strip() for c in header.split("|")].index("vs above")
    assert md["twin"][col] == "tie" and md["third"][col] == "worse" and md["first"][col] == "-"
    assert shown in md["first"]
    table = {row["controller"]: row for row in csv.DictReader(io.StringIO(csv_text(three)))}
    assert table["twin"]["vs_above"] == "tie" and table["third"]["vs_above"] == "worse"
    assert table["first"]["vs_above"] == "" and table["broken"]["vs_above"] == ""
    assert float(table["first"]["points_ci_low"]) == pytest.approx(lo)
    assert float(table["first"]["points_ci_high"]) == pytest.approx(hi)
    assert float(table["third"]["vs_above_diff"]) == pytest.approx(-20.0)
    assert table["first"]["points[ncap-v1]_ci_low"] != ""


def test_the_html_report_shows_them_too(three):
    from acc_gym.leaderboard.report import render_html

    html = render_html(three)
    assert "<th>vs above</th>" in html and "<td>tie</td>" in html and "<td>worse</td>" in html


def test_the_same_records_give_byte_identical_files(three, tmp_path):
    again = results_of([entry(c["name"], c["episodes"], c["status"], c["reason"]) for c in three["controllers"]])
    assert results_text(three, key=None) == results_text(again, key=None)
    write_files(three, tmp_path / "a", key=None)
    write_files(again, tmp_path / "b", key=None)
    for name in ("results.json", "results.csv", "leaderboard.md"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


def test_results_with_intervals_survive_write_and_load(three, tmp_path):
    write_files(three, tmp_path, key=None)
    loaded = load_results(tmp_path)
    assert loaded == json.loads(json.dumps(three))
    by = {c["name"]: c for c in loaded["controllers"]}
    assert by["twin"]["vs_above"]["significant"] is False and by["third"]["vs_above"]["significant"] is True
    assert len(by["first"]["summary"]["suites"]["ncap-v1"]["mean_score_ci"]) == 2
    assert markdown(loaded) == markdown(three)


def test_an_edited_interval_fails_the_checksum(three, tmp_path):
    path = tmp_path / "results.json"
    path.write_text(results_text(three, key=None))
    doc = json.loads(path.read_text())
    c = next(c for c in doc["results"]["controllers"] if c["name"] == "third")
    c["summary"]["overall"]["mean_points_ci"] = [0.0, 100.0]
    path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="checksum does not match"):
        load_results(path)


@pytest.mark.parametrize("edit, words", [
    (lambda c: c["summary"]["overall"].__setitem__("mean_score_ci", [80.0, 70.0]),
     r"'third': summary\.overall\.mean_score_ci has its low end above its high end"),
    (lambda c: c["summary"]["suites"]["ncap-v1"].__setitem__("share_qualified_ci", [0.2, 1.4]),
     r"'third': summary\.suites\.ncap-v1\.share_qualified_ci is the interval of a share"),
    (lambda c: c["summary"]["overall"].__setitem__("collision_rate_ci", "narrow"),
     r"'third': summary\.overall\.collision_rate_ci is not an interval"),
    (lambda c: c["vs_above"].__setitem__("significant", False),
     r"'third': vs_above\.significant is false, but its interval .* excludes 0"),
    (lambda c: c["vs_above"].__setitem__("ci", [-1.0]),
     r"'third': vs_above\.ci is not an interval"),
    (lambda c: c["vs_above"].pop("diff"), r"'third': vs_above must be null or an object"),
])
def test_a_malformed_interval_with_a_valid_checksum_is_refused_by_name(three, tmp_path, edit, words):
    forged = json.loads(json.dumps(three))
    edit(next(c for c in forged["controllers"] if c["name"] == "third"))
    path = tmp_path / "results.json"
    path.write_text(results_text(forged, key=None))
    assert json.loads(path.read_text())["sha256"] == checksum(forged)
    with pytest.raises(ValueError, match="results.json.* are malformed: controller " + words):
        load_results(path)
