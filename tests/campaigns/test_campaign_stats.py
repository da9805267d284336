"""The confidence intervals against known values, and the summary against the rows."""

import math

import numpy as np
import pytest
from scipy import stats as st

from acc_gym.campaigns import stats
from acc_gym.campaigns.summary import format_summary


def test_poisson_exact_interval():
    # Garwood: 0 events -> [0, 3.689]; 9 events (paper 004's CACC in 1 h) -> [4.115, 17.08]
    assert stats.poisson_rate_ci(0, 1.0) == pytest.approx((0.0, 0.0, 3.6889), abs=1e-4)
    assert stats.poisson_rate_ci(9, 1.0) == pytest.approx((9.0, 4.1154, 17.0848), abs=1e-4)
    assert stats.poisson_rate_ci(9, 2.0) == pytest.approx((4.5, 2.0577, 8.5424), abs=1e-4)
    assert all(math.isnan(x) for x in stats.poisson_rate_ci(0, 0.0))


def test_wilson_interval():
    assert stats.wilson_ci(0, 10) == pytest.approx((0.0, 0.0, 0.2775), abs=1e-4)
    assert stats.wilson_ci(8, 10) == pytest.approx((0.8, 0.4902, 0.9433), abs=1e-4)
    with pytest.raises(ValueError, match="successes must be within \\[0, n=3\\], got 4"):
        stats.wilson_ci(4, 3)


def test_t_interval_and_bounds():
    x = np.array([60.0, 70.0, 80.0, 90.0, np.nan])
    m, lo, hi = stats.mean_ci(x)
    half = st.t.ppf(0.975, 3) * np.std(x[:4], ddof=1) / 2
    assert (m, lo, hi) == pytest.approx((75.0, 75.0 - half, 75.0 + half))
    assert stats.mean_ci([0.9, 1.0, 1.0], bounds=(0.0, 1.0))[2] == 1.0
    assert math.isnan(stats.mean_ci([1.0])[1]) and math.isnan(stats.mean_ci([])[0])


def test_weighted_share_pools_time():
    est, lo, hi = stats.weighted_share_ci([1.0, 0.5], [30.0, 10.0])
    assert est == pytest.approx(35.0 / 40.0) and 0.0 <= lo <= est <= hi <= 1.0
    assert stats.weighted_share_ci([0.2, 0.4, 0.6], [1, 1, 1])[0] == pytest.approx(0.4)
    assert stats.weighted_share_ci([np.nan, 0.5], [5.0, 5.0])[0] == 0.5


def test_summary_matches_the_rows(reference):
    _, s, campaign = reference
    rows = campaign.rows()
    hours = sum(r["duration"] for r in rows) / 3600
    k = sum(r["collision"] for r in rows)
    assert s["episodes"] == len(rows) and s["complete"] and s["traffic_hours"] == pytest.approx(hours)
    assert s["collisions"]["count"] == k
    assert s["collisions"]["per_hour"]["high"] == pytest.approx(stats.poisson_rate_ci(k, hours)[2])
    assert s["mean_score"]["estimate"] == pytest.approx(np.mean([r["score"] for r in rows]))
    q = sum(r["qualified"] for r in rows)
    assert (s["share_qualified"]["low"], s["share_qualified"]["high"]) == \
        pytest.approx(stats.wilson_ci(q, len(rows))[1:])
    sim = np.array([r["simulated"] for r in rows])
    comf = np.array([r["share_comfortable"] for r in rows])
    assert s["share_comfortable"]["estimate"] == pytest.approx(np.sum(sim * comf) / sim.sum())
    assert s["min_ttc"] == pytest.approx(min(r["min_ttc"] for r in rows))
    assert s["max_jerk"] == pytest.approx(max(r["max_jerk"] for r in rows))
    with_os = [r["speed_overshoot"] for r in rows if r["speed_overshoot"] is not None]
    assert s["speed_overshoot"]["n"] == len(with_os)
    table = format_summary(s)
    for label in ("collisions per hour", "share comfortable", "share safe spacing", "speed overshoot",
                  "damping ratio", "mean score", "share qualified", "95% CI"):
        assert label in table
