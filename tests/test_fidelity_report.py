"""benchmarks/fidelity.py --json --quick runs and reports every statistic against paper 001.

The report's shape is tested (which rows are there, with which keys and types), and the
counts the paper puts at 0 (brake releases on entering EMERGENCY, stops without braking,
EMERGENCY or braking beyond the driver's own limits in a benign approach, the Table 4
presets) are asserted to be within tolerance even on the quick run's 40 drivers per kind.
The statistics (Table A3's band medians, Fig. 7) need the full populations: the slow tests
run the default report on three seeds used nowhere else (about 5 minutes each) and assert
every ok flag (``python -m pytest -m slow tests/test_fidelity_report.py``).
"""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
KEYS = {"statistic", "condition", "kind", "model", "paper", "n", "scenario", "ok", "tolerance", "ci", "ci_inside"}
KINDS = ("typical", "atypical", "malicious", "naturalistic")
BANDS = ("<10", "10-20", "20-30", "30-40")
PRESETS = ("#23", "#57", "#61", "#13")


@pytest.fixture(scope="module")
def report():
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fidelity.py"), "--json", "--quick", "--seed", "7"],
                       capture_output=True, text=True, check=True, cwd=ROOT, timeout=600)
    return json.loads(r.stdout.strip().splitlines()[-1])


def rows(report, statistic, kind=None, condition=None):
    return [r for r in report["rows"] if r["statistic"] == statistic and (kind is None or r["kind"] == kind)
            and (condition is None or condition in r["condition"])]


def test_rows_have_the_documented_keys(report):
    assert report["seed"] == 7 and report["rows"]
    for r in report["rows"]:
        assert KEYS <= set(r), r
        assert isinstance(r["statistic"], str) and isinstance(r["condition"], str) and isinstance(r["kind"], str)
        assert isinstance(r["scenario"], str) and r["scenario"]
        assert isinstance(r["n"], int) and r["n"] >= 0
        assert r["ok"] in (True, False, None)
        if r["tolerance"] is None or r["paper"] is None or r["model"] is None:
            assert r["ok"] is None
        else:
            assert isinstance(r["ok"], bool)
        assert "0.2 s" in r["scenario"]  # the scenario names its step


def test_brake_release_and_stop_statistics_for_every_kind(report):
    for kind in KINDS:
        assert len(rows(report, "brake_release_on_emergency_entry", kind, "approach")) == 1
        assert len(rows(report, "brake_release_on_emergency_entry", kind, "lead brakes")) == 1
        (stop,) = rows(report, "stop_without_braking", kind)
        assert stop["paper"] == 0 and stop["tolerance"] == 0 and isinstance(stop["model"], int)
        for q in ("min", "median", "max"):
            assert len(rows(report, "final_gap_minus_x_min", kind, q)) == 1
    for r in rows(report, "brake_release_on_emergency_entry"):
        assert r["paper"] == 0 and isinstance(r["model"], int) and r["n"] > 0


def test_the_creep_before_each_stop_is_reported_per_kind(report):
    for kind in KINDS:
        found = rows(report, "creep_before_stop", kind)
        assert [r["condition"].split(", ")[-1] for r in found] == ["median", "90th percentile", "max"]
        values = [r["model"] for r in found]
        assert all(r["paper"] is None and r["ok"] is None and r["n"] > 0 for r in found)
        assert 0.0 <= values[0] <= values[1] <= values[2] < 200.0, (kind, values)


ZERO_COUNTS = ("brake_release_on_emergency_entry", "stop_without_braking", "emergency_in_benign_approach",
               "exceeds_own_limits_in_benign_approach", "exceeds_own_a_min", "exceeds_jerk_limit")


def test_the_counts_the_paper_puts_at_zero_are_zero(report):
    checked = [r for r in report["rows"] if r["statistic"] in ZERO_COUNTS]
    assert len(checked) == 8 + 4 + 3 + 3 + 4 * 3  # releases x2 and stops per kind, 3 kinds x2, presets x3
    assert all(r["ok"] is True and r["model"] == 0 for r in checked), [r for r in checked if r["model"] != 0]


# Seeds the report is checked on besides the README's (0): none of them is used anywhere else
# (not by the issue that sized the report, not by the calibration of the population).
FRESH_SEEDS = (31, 47, 83)


@pytest.mark.slow
@pytest.mark.parametrize("seed", FRESH_SEEDS)
def test_the_full_report_is_within_every_tolerance_on_other_seeds(seed):
    """The default report (4000 naturalistic drivers, 300 of each other kind; about 5 minutes)
    on seeds used nowhere else: every toleranced row within its tolerance, and the intervals
    printed beside Table A3's band medians narrow enough to tell the tolerance apart."""
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fidelity.py"), "--json", "--seed", str(seed)],
                       capture_output=True, text=True, check=True, cwd=ROOT, timeout=3600)
    full = json.loads(r.stdout.strip().splitlines()[-1])
    assert full["seed"] == seed and full["n_naturalistic"] == 4000
    toleranced = [row for row in full["rows"] if row["ok"] is not None]
    assert len(toleranced) >= 42
    assert all(row["ok"] for row in toleranced), [row for row in toleranced if not row["ok"]]
    medians = rows(full, "braking_onset_a_req_median", "naturalistic")
    assert len(medians) == 4
    for row in medians:
        assert row["n"] >= 300, row  # a few hundred drivers in every band
        low, high = row["ci"]
        assert low <= row["model"] <= high and high - low <= row["tolerance"], row


def test_emergency_in_benign_approach(report):
    for kind in ("typical", "atypical", "naturalistic"):
        (r,) = rows(report, "emergency_in_benign_approach", kind)
        assert r["paper"] == 0 and isinstance(r["model"], int)
        (r,) = rows(report, "exceeds_own_limits_in_benign_approach", kind)
        assert r["paper"] == 0 and r["tolerance"] == 0 and r["n"] == report["n"]
    for name in PRESETS:
        for stat in ("emergency_in_benign_approach", "exceeds_own_a_min", "exceeds_jerk_limit"):
            (r,) = rows(report, stat, f"preset {name}")
            assert r["n"] == 7 and 0 <= r["model"] <= 7 and r["paper"] == 0


def test_braking_onset_by_speed_band(report):
    from acc_gym.drivers.population import TABLE_A3_BRAKING_START

    for kind in ("typical", "naturalistic"):
        for b, band in enumerate(BANDS):
            for stat, col in (("braking_onset_a_req_median", 2), ("braking_onset_a_req_q25", 1),
                              ("braking_onset_a_req_q75", 3)):
                (r,) = rows(report, stat, kind, f"band {band} ")
                assert r["paper"] == pytest.approx(TABLE_A3_BRAKING_START[b, col])
                # Table A3 is the whole population's: toleranced for the naturalistic drivers; the
                # typical sub-population's medians are printed for context
                assert r["tolerance"] == (0.2 if stat.endswith("median") and kind == "naturalistic" else None)


def test_fig7_means_and_spreads(report):
    expected = {("fig7_braking_start_a_req", "mean"): -1.37, ("fig7_braking_start_a_req", "sd"): 0.55,
                ("fig7_sailing_start_a_req", "mean"): -0.89, ("fig7_sailing_start_a_req", "sd"): 0.44}
    for (stat, cond), paper in expected.items():
        (r,) = rows(report, stat, "naturalistic", cond)
        assert r["paper"] == pytest.approx(paper) and r["tolerance"] == pytest.approx(0.15)
        assert r["model"] is not None and r["n"] > 1


def test_calibration(report):
    kinds = {r["kind"] for r in rows(report, "calibration_q1")}
    assert kinds and kinds <= {f"preset {p}" for p in PRESETS}
    for kind in kinds:
        for stat in ("calibration_q1", "calibration_r1", "calibration_rmse", "calibration_correlation",
                     "calibration_profile_q1", "calibration_profile_r1"):
            (r,) = rows(report, stat, kind)
            assert r["model"] is not None
        for w in ("q1", "r1"):
            (r,) = rows(report, f"calibration_{w}", kind)
            assert r["tolerance"] == pytest.approx(0.01 * r["paper"])


def _fidelity_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("fidelity_report", ROOT / "benchmarks" / "fidelity.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_intervals_cover_the_truth_at_their_level():
    """The 95 % intervals printed beside the toleranced statistics: over 400 samples of 101
    standard normal values, the median's, the mean's and the sd's intervals hold the true
    value (0, 0, 1) about 95 % of the time; their widths match the textbook's."""
    f = _fidelity_module()
    rng = np.random.default_rng(5)
    hits = {"median": 0, "q25": 0, "mean": 0, "sd": 0}
    q25 = -0.6744897501960817  # standard normal quartile
    for _ in range(400):
        x = rng.standard_normal(101)
        lo, hi = f.quantile_ci(x, 0.5)
        hits["median"] += lo <= 0.0 <= hi
        lo, hi = f.quantile_ci(x, 0.25)
        hits["q25"] += lo <= q25 <= hi
        lo, hi = f.mean_ci(x)
        hits["mean"] += lo <= 0.0 <= hi
        lo, hi = f.sd_ci(x)
        hits["sd"] += lo <= 1.0 <= hi
    for name, k in hits.items():
        assert 0.92 <= k / 400 <= 0.99, (name, k)
    x = rng.standard_normal(4000)
    lo, hi = f.quantile_ci(x, 0.5)  # asymptotic width 2 * 1.96 * sqrt(pi / 2) / sqrt(n)
    assert (hi - lo) == pytest.approx(2 * 1.96 * np.sqrt(np.pi / 2) / np.sqrt(4000), rel=0.15)
    assert f.quantile_ci(x[:4], 0.5) is None and f.mean_ci(x[:1]) is None


def test_a_row_says_whether_its_interval_is_inside_the_tolerance():
    f = _fidelity_module()
    inside = f.row("s", "c", "k", -1.3, -1.36, 300, "scenario", tolerance=0.2, ci=(-1.4, -1.2))
    assert inside["ok"] is True and inside["ci"] == [-1.4, -1.2] and inside["ci_inside"] is True
    reaching = f.row("s", "c", "k", -1.3, -1.36, 300, "scenario", tolerance=0.2, ci=(-1.6, -1.2))
    assert reaching["ok"] is True and reaching["ci_inside"] is False
    assert f.row("s", "c", "k", -1.3, None, 3, "scenario", ci=(-1.4, -1.2))["ci_inside"] is None


def test_toleranced_statistics_carry_their_interval(report):
    assert report["n_naturalistic"] == report["n"] == 40  # --quick
    for r in rows(report, "braking_onset_a_req_median", "naturalistic") + rows(report, "fig7_braking_start_a_req"):
        if r["n"] >= 5:
            low, high = r["ci"]
            assert low <= r["model"] <= high, r
            assert r["ci_inside"] in (True, False)
