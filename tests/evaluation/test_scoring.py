"""Paper 003's score against hand computations on small trajectories.

Unless a test says otherwise: dt = 1 s, tau1 = 1 s, b0 = b1 = 8 m/s^2, no start transient,
so with both vehicles at 20 m/s Gapsafe = 20 m and the band is 20 < D1 < 24 m.
"""

import math

import numpy as np
import pytest

from acc_gym.evaluation import EgoTrace, ScoringConfig, gap_safe, score_episode

N = 11
CFG = ScoringConfig(tau1=1.0, transient=0.0)


def trace(gap=22.0, v=20.0, v_lead=20.0, a=0.0, **kw):
    t = np.arange(N, dtype=float)

    def arr(x):
        return np.broadcast_to(np.asarray(x, dtype=float), (N,)).copy()

    return EgoTrace(t=t, v=arr(v), a=arr(a), gap=arr(gap), v_lead=arr(v_lead), **kw)


def test_gapsafe_formula():
    assert gap_safe(20.0, 20.0, 1.0, 8.0, 8.0) == pytest.approx(20.0)
    # v1 tau1 + v1^2/(2 b1) - v0^2/(2 b0) with different decelerations
    assert gap_safe(30.0, 10.0, 1.5, 6.0, 4.0) == pytest.approx(45.0 + 900 / 8 - 100 / 12)


def test_all_four_items_qualified_gives_60_plus_r1_plus_r2():
    a = np.zeros(N)
    a[5] = 1.5  # j_x = 1.5 / 3 = 0.5
    r = score_episode(trace(gap=22.0, a=a), CFG)
    # G = 2 m in (0, 4): u_t = 2 / 4 = 0.5 at every sample -> R1 = 10; R2 = (1 - 0.5) 10 + 10 = 15
    assert r.qualified
    assert r.u == pytest.approx(0.5)
    assert r.r1 == pytest.approx(10.0)
    assert r.j_x == pytest.approx(0.5) and r.j_y == 0.0
    assert r.r2 == pytest.approx(15.0)
    assert r.score == pytest.approx(85.0)


@pytest.mark.parametrize("case, expected, qualified_items", [
    ("band", 45.0, 3),  # too far: G = 10 >= 4 everywhere
    ("safety+band", 30.0, 2),  # too close and not braking
    ("safety+band+edge", 15.0, 1),
    ("all", 0.0, 0),
])
def test_unqualified_scores_are_15_per_qualified_item(case, expected, qualified_items):
    d2 = np.full(N, 0.5)
    d3 = np.full(N, 0.5)
    gap = 30.0 if case == "band" else 15.0
    if "edge" in case or case == "all":
        d2[3] = -0.1
    if case == "all":
        d3[7] = -0.2
    r = score_episode(trace(gap=gap, d2=d2, d3=d3), CFG)
    assert not r.qualified
    assert sum(it.qualified for it in r.items) == qualified_items
    assert r.score == expected


def test_proper_response_tolerates_a_braking_ego_but_literal_does_not():
    gap = np.full(N, 22.0)
    gap[3:8] = 18.0  # Q = -2 for 5 s
    a = np.zeros(N)
    a[4:8] = -3.0  # braking within tau1 = 1 s of Q turning negative, until Q >= 0 again
    t = trace(gap=gap, a=a)
    assert score_episode(t, CFG).item("safety").qualified
    lit = score_episode(t, ScoringConfig.literal(tau1=1.0))
    assert not lit.item("safety").qualified
    assert lit.item("safety").detail["violations"] == 5


def test_proper_response_fails_mild_braking_and_the_threshold_is_a_setting():
    gap = np.full(N, 22.0)
    gap[3:8] = 18.0
    a = np.zeros(N)
    a[3:8] = -1.0  # braking, but gentler than response_decel = 2
    t = trace(gap=gap, a=a)
    r = score_episode(t, CFG)
    safety = r.item("safety")
    assert not safety.qualified
    # samples 3..7 are negative; grace covers t - 3 <= 1 (samples 3, 4): 5, 6, 7 violate
    assert safety.detail["violations"] == 3
    assert safety.detail["first_violation_t"] == 5.0
    assert score_episode(t, ScoringConfig(tau1=1.0, transient=0.0, response_decel=1.0)).item("safety").qualified


def test_short_dip_below_gapsafe_within_the_grace_time_is_tolerated():
    gap = np.full(N, 22.0)
    gap[4] = 19.0  # Q = -1 for one sample, no braking
    assert score_episode(trace(gap=gap), CFG).item("safety").qualified
    assert not score_episode(trace(gap=gap), ScoringConfig.literal(tau1=1.0)).item("safety").qualified
    # a longer grace tolerates longer dips
    gap[4:7] = 19.0
    assert not score_episode(trace(gap=gap), CFG).item("safety").qualified
    assert score_episode(trace(gap=gap), ScoringConfig(tau1=1.0, transient=0.0, response_time=3.0)).item(
        "safety").qualified


def test_a_standing_ego_counts_as_responding():
    # stopped behind a stopped lead, closer than Gapsafe = 0.3 + 0.3^2/16 m
    r = score_episode(trace(gap=0.2, v=0.3, v_lead=0.0), CFG)
    assert r.item("safety").qualified
    assert r.item("safety").detail["min_q"] == pytest.approx(0.2 - (0.3 + 0.09 / 16))


def test_collision_is_never_safe_even_where_literal_q_is_positive():
    # lead much faster: Gapsafe = 10 + 100/16 - 900/16 = -40 m, so Q = D1 + 40 > 0 even at D1 = 0
    gap = np.full(N, 5.0)
    gap[6] = 0.0
    t = trace(gap=gap, v=10.0, v_lead=30.0)
    r = score_episode(t, CFG)
    assert r.metrics["collision"]
    assert not r.item("safety").qualified and r.item("safety").detail["collision"]
    assert not r.qualified and r.score <= 45.0
    assert score_episode(t, ScoringConfig.literal(tau1=1.0)).item("safety").qualified  # the literal reading


def test_gapsafe_non_positive_samples_are_outside_band_and_efficiency():
    # v1 = 10, v0 = 30: Gapsafe = -40 m at every sample
    r = score_episode(trace(gap=50.0, v=10.0, v_lead=30.0), CFG)
    assert r.item("safety").qualified  # Q = 90 m
    band = r.item("car_following")
    assert band.detail["samples"] == 0
    assert not band.qualified  # a followable lead that the ego never follows steadily
    assert math.isnan(r.u) and r.r1 == 0.0
    # with a set speed of 12 m/s the 30 m/s lead is not followable: the band does not apply,
    # and efficiency becomes speed keeping: u_t = (12 - 10) / (0.2 * 12)
    r = score_episode(trace(gap=50.0, v=10.0, v_lead=30.0, set_speed=12.0), CFG)
    assert r.item("car_following").qualified and not r.item("car_following").applicable
    assert r.u == pytest.approx(2.0 / 2.4)
    assert r.score == pytest.approx(60 + (1 - 2.0 / 2.4) * 20 + 20)


def test_an_approach_cut_short_by_the_end_of_the_test_is_not_hanging_back():
    # at its set speed of 25 m/s, 150 m behind a 20 m/s lead: 5 m/s closing, 100 m left at the end
    t = np.arange(N, dtype=float)
    approach = dict(gap=150.0 - 5.0 * t, v=25.0, v_lead=20.0)
    r = score_episode(trace(set_speed=25.0, **approach), CFG)
    band = r.item("car_following")
    assert band.applicable and band.qualified and band.detail["approaching"] and band.detail["samples"] == 0
    # efficiency is then speed keeping: u_t = (25 - 25) / 5 = 0, so R1 = 20, R2 = 20
    assert r.u == 0.0 and r.score == pytest.approx(100.0)
    # without a set speed nothing shows that 25 m/s was as fast as it should close in: it fails as before
    assert not score_episode(trace(**approach), CFG).item("car_following").qualified
    # the literal band judges every sample with a vehicle ahead: 100 m is far outside it
    assert not score_episode(trace(set_speed=25.0, **approach), ScoringConfig.literal(tau1=1.0)).item(
        "car_following").qualified


def test_dawdling_behind_a_followable_lead_still_fails_the_band():
    t = np.arange(N, dtype=float)
    # 1.5 m/s faster than the lead but 3.5 m/s below the set speed, 150 m back: it could close in
    r = score_episode(trace(gap=150.0 - 1.5 * t, v=21.5, v_lead=20.0, set_speed=25.0), CFG)
    assert not r.item("car_following").qualified and not r.item("car_following").detail["approaching"]
    assert r.score == 45.0
    # slower than the lead: falling back
    r = score_episode(trace(gap=30.0 + 1.5 * t, v=18.5, v_lead=20.0, set_speed=25.0), CFG)
    assert not r.item("car_following").qualified


@pytest.mark.parametrize("margin, closing_in", [(-0.1, True), (0.1, False)])
def test_below_the_set_speed_an_approach_counts_once_it_must_brake_to_stop_at_the_band(margin, closing_in):
    # braking from 25 to 21.25 m/s behind a 20 m/s lead, set speed 30 m/s (so never cruising):
    # closing in iff (v1 - v0)^2 >= 2 * 0.5 m/s^2 * (D1 - 1.2 Gapsafe)
    v = 25.0 - 0.375 * np.arange(N)
    gs = gap_safe(v, 20.0, 1.0, 8.0, 8.0)
    gap = 1.2 * gs + (v - 20.0) ** 2 / (2 * 0.5) + margin
    r = score_episode(trace(gap=gap, v=v, v_lead=20.0, a=-0.375, set_speed=30.0), CFG)
    assert r.item("car_following").qualified is closing_in
    assert r.item("car_following").detail["approaching"] is closing_in
    with pytest.raises(ValueError, match="approach_decel"):
        ScoringConfig(approach_decel=0.0)


def test_a_lead_above_the_set_speed_is_not_followable():
    # the ego holds its set speed of 25 m/s, 60 m behind a lead at 25.5 m/s (time gap 2.4 s, beyond the band)
    t = np.arange(N, dtype=float)
    holding = trace(gap=60.0 + 0.5 * t, v=25.0, v_lead=25.5, set_speed=25.0)
    r = score_episode(holding, CFG)
    assert not r.item("car_following").applicable and r.qualified
    assert r.u == 0.0 and r.score == pytest.approx(100.0)  # speed keeping: at the set speed
    # lead_margin = 1 m/s (as in 0.1.0) counted that lead: holding the set speed failed the band
    old = score_episode(holding, ScoringConfig(tau1=1.0, transient=0.0, lead_margin=1.0))
    assert not old.item("car_following").qualified and old.score == 45.0


def test_no_vehicle_ahead():
    t = trace(gap=np.inf, v=25.0, v_lead=0.0, set_speed=25.0)
    r = score_episode(t, CFG)
    assert r.qualified and not r.item("car_following").applicable
    assert r.item("safety").detail["min_q"] is None
    assert r.u == 0.0 and r.score == pytest.approx(100.0)
    assert math.isnan(r.metrics["share_safe_spacing"]) and r.metrics["min_ttc"] == math.inf
    # without a set speed there is nothing to measure efficiency against: R1 = 0
    r = score_episode(trace(gap=np.inf, v=25.0, v_lead=0.0), CFG)
    assert math.isnan(r.u) and r.score == pytest.approx(80.0)


def test_band_share_default_and_literal():
    gap = np.full(N, 22.0)
    gap[:5] = 30.0  # 5 of 11 samples beyond the band
    r = score_episode(trace(gap=gap), CFG)
    assert r.item("car_following").detail["share_in_band"] == pytest.approx(6 / 11)
    assert r.item("car_following").qualified
    assert not score_episode(trace(gap=gap), ScoringConfig.literal(tau1=1.0)).item("car_following").qualified
    gap[:6] = 30.0  # 5 of 11 in the band: below half
    assert not score_episode(trace(gap=gap), CFG).item("car_following").qualified
    assert score_episode(trace(gap=gap), ScoringConfig(tau1=1.0, transient=0.0, band_share=0.4)).item(
        "car_following").qualified


def test_band_counts_only_steady_following_after_transients():
    gap = np.full(N, 22.0)
    v_lead = np.full(N, 20.0)
    gap[:4] = 40.0
    v_lead[:4] = 15.0  # approaching (|dv| = 5 > 1): not car-following samples
    r = score_episode(trace(gap=gap, v_lead=v_lead), CFG)
    assert r.item("car_following").detail["samples"] == 7
    assert r.item("car_following").detail["share_in_band"] == 1.0
    # a new vehicle ahead at t = 5 (cut-in) starts a transient: out-of-band samples right after it don't count
    lead_id = np.where(np.arange(N) < 5, 1.0, 2.0)
    gap = np.full(N, 22.0)
    gap[5:8] = 30.0
    cfg = ScoringConfig(tau1=1.0, transient=3.0)
    r = score_episode(trace(gap=gap, lead_id=lead_id), cfg)
    assert r.item("car_following").detail["samples"] == 5  # t = 3, 4 and 8, 9, 10
    assert r.item("car_following").detail["share_in_band"] == 1.0


def test_clipping_of_u_and_j_is_a_setting():
    gap = np.full(N, 22.0)  # u_t = 0.5
    gap[6:] = 30.0  # u_t = 10 / 4 = 2.5 on 5 samples
    a = np.zeros(N)
    a[2] = -4.5  # j_x = 1.5
    t = trace(gap=gap, a=a)
    r = score_episode(t, CFG)
    assert r.u == pytest.approx((6 * 0.5 + 5 * 1.0) / 11)
    assert r.j_x == 1.0 and r.r2 == pytest.approx(10.0)
    assert r.score == pytest.approx(60 + (1 - 8 / 11) * 20 + 10)
    raw = score_episode(t, ScoringConfig(tau1=1.0, transient=0.0, clip=False))
    assert raw.u == pytest.approx((6 * 0.5 + 5 * 2.5) / 11)
    assert raw.j_x == pytest.approx(1.5) and raw.r2 == pytest.approx(5.0)


def test_tau1_defaults_to_the_scenario_time_gap():
    t = trace(gap=22.0, time_gap=2.0)  # Gapsafe = 40: now far too close
    r = score_episode(t, ScoringConfig(transient=0.0))
    assert r.tau1 == 2.0
    assert not r.item("safety").qualified
    assert score_episode(t, ScoringConfig(tau1=1.0, transient=0.0)).tau1 == 1.0
    assert score_episode(trace(gap=22.0), ScoringConfig()).tau1 == 1.5


def test_lateral_comfort_uses_a_y():
    a_y = np.zeros(N)
    a_y[4] = 2.0
    r = score_episode(trace(a_y=a_y), CFG)
    assert r.j_y == pytest.approx(0.4) and r.r2 == pytest.approx(10 + 6)


def test_report_serialises_to_json():
    import json
    r = score_episode(trace(gap=np.inf, v=25.0, v_lead=0.0), CFG)
    d = json.loads(json.dumps(r.to_dict()))
    assert d["score"] == pytest.approx(80.0)
    assert d["items"]["safety"]["qualified"] is True
    assert d["u"] is None and d["metrics"]["min_ttc"] == "inf"
    assert "score 80.0" in r.summary()


@pytest.mark.parametrize("kwargs, name", [
    (dict(tau1=-1.0), "tau1"), (dict(b0=0.0), "b0"), (dict(b1=float("nan")), "b1"),
    (dict(safety="strict"), "safety"), (dict(band="all"), "band"), (dict(band_share=0.0), "band_share"),
    (dict(transient=-1.0), "transient"), (dict(clip="yes"), "clip"), (dict(response_decel=-2.0), "response_decel"),
])
def test_bad_settings_name_the_value(kwargs, name):
    with pytest.raises(ValueError, match=name):
        ScoringConfig(**kwargs)


def test_config_from_dict_rejects_misspelt_keys():
    assert ScoringConfig.from_dict({"tau1": 1.2}).tau1 == 1.2
    with pytest.raises(ValueError, match="tau"):
        ScoringConfig.from_dict({"tau": 1.2})
    assert ScoringConfig.from_dict(ScoringConfig.literal().to_dict()) == ScoringConfig.literal()


def test_a_declared_time_gap_is_judged_floored_and_capped():
    """tau1 = min(max(declared, 0.8 s), nominal): by hand for each branch, and in Gapsafe."""
    from acc_gym.evaluation.scoring import judged_tau1

    cfg = ScoringConfig()
    assert judged_tau1(1.5, None, cfg) == 1.5  # nothing declared: the scenario's gap
    assert judged_tau1(None, None, cfg) == 1.5  # nothing known: DEFAULT_TAU1
    assert judged_tau1(1.5, 0.9, cfg) == 0.9  # Gipps's reaction time
    assert judged_tau1(1.5, 0.3, cfg) == 0.8  # ISO 15622's shortest gap: no lenient Gapsafe by declaring
    assert judged_tau1(1.5, 3.0, cfg) == 1.5  # not longer than the driver asked: no "efficient" hanging back
    assert judged_tau1(1.5, 0.3, ScoringConfig(tau1_floor=0.5)) == 0.5
    assert judged_tau1(1.5, 0.9, ScoringConfig(tau1=1.2)) == 1.2  # an explicit tau1 wins
    n = 50
    t = np.arange(n) * 0.2
    v = np.full(n, 20.0)
    for declared, gap, safe in ((None, 25.0, False), (1.0, 25.0, True), (0.3, 15.0, False)):
        tr = EgoTrace(t=t, v=v, a=np.zeros(n), gap=np.full(n, gap), v_lead=v.copy(), set_speed=25.0,
                      time_gap=1.5, declared_time_gap=declared)
        r = score_episode(tr)
        assert r.tau1 == judged_tau1(1.5, declared, ScoringConfig())
        # steady following at 20 m/s, gap 25 m: Q = 25 - 20 tau1 (>= 0 at tau1 = 1.0, < 0 at 1.5); 15 m < 0.8 x 20
        assert r.item("safety").qualified == safe
    with pytest.raises(ValueError, match="declared_time_gap must be > 0"):
        EgoTrace(t=t, v=v, a=np.zeros(n), gap=np.full(n, 25.0), v_lead=v.copy(), declared_time_gap=-1.0)
    with pytest.raises(ValueError, match="tau1_floor must be > 0"):
        ScoringConfig(tau1_floor=0.0)
