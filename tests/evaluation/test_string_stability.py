"""String stability (acc_gym.evaluation.string_stability): measured gains against the analytic
transfer functions, the known verdicts, IDM against Treiber and Kesting's criterion, and what a
failing controller gives."""

import json
import math
from collections import deque

import numpy as np
import pytest

from acc_gym.cli import main
from acc_gym.controllers import make_controller
from acc_gym.evaluation.string_stability import (GUNTER_DROP, TOLERANCE, PlatoonConfig, StringStabilityError,
                                                 lead_trace, linear_transfer, string_stability, time_gap_threshold)
from acc_gym_agents.controllers.linear import ConstantSpeed, LinearACC, _Policy

FEW = np.geomspace(0.005, 0.5, 10)  # a coarser grid where the full one is not the point


class CopyLead(_Policy):
    """Asks for the acceleration that gives the vehicle ahead's speed after one step."""

    def _accel(self, o):
        return o[:, 3] / 0.2


class DelayedACC(LinearACC):
    """The linear ACC acting 1 s late (a reaction delay)."""

    def reset(self):
        self.buffer = None

    def _accel(self, o):
        a = super()._accel(o)
        if getattr(self, "buffer", None) is None:
            self.buffer = deque([np.zeros_like(a)] * 5)
        self.buffer.append(a)
        return self.buffer.popleft()


class RaisesWhenAccelerating(LinearACC):
    def _accel(self, o):
        if np.any(o[:, 1] > 0.2):
            raise RuntimeError("boom")
        return super()._accel(o)


class NaNAtSpeed(LinearACC):
    def _accel(self, o):
        a = super()._accel(o)
        return np.where(o[:, 0] > 20.3, np.nan, a)


class RamsWhenFast(LinearACC):
    """Full throttle above 20.2 m/s: the sweep's faster half-periods end in a collision."""

    def _accel(self, o):
        return np.where(o[:, 0] > 20.2, 3.0, super()._accel(o))


class Unbatched(LinearACC):
    vectorised = False


# -- the analytic reference -------------------------------------------------------------------------
@pytest.mark.parametrize("h", [1.5, 0.9, 0.6])
def test_linear_acc_gain_matches_the_sampled_transfer_function(h):
    """Every measured pair gain of the linear ACC within 2 % of |Gamma(exp(j w dt))| (module docstring)."""
    r = string_stability("acc", PlatoonConfig(vehicles=4, time_gap=h), disturbance=False)
    ref = np.abs(linear_transfer(r.frequencies, 0.3, 1.2, h))
    measured = np.isfinite(r.pair_gains)
    assert measured[:, 0].all()  # the first pair is measured at every frequency
    assert measured.sum() >= 0.8 * measured.size
    rel = np.abs(r.pair_gains / ref[:, None] - 1.0)[measured]
    assert rel.max() < 0.02
    assert np.nanmax(r.pair_gains) == pytest.approx(ref.max(), rel=0.01)


def test_cacc_gain_matches_its_transfer_function_with_the_feed_forward_one_step_old():
    r = string_stability("cacc", PlatoonConfig(vehicles=4, time_gap=0.6, v2v=True), disturbance=False)
    ref = np.abs(linear_transfer(r.frequencies, 0.3, 1.2, 0.6, k3=0.6))
    assert np.isfinite(r.pair_gains).all()
    assert np.abs(r.pair_gains / ref[:, None] - 1.0).max() < 0.02
    # without the feed-forward the same law is a different (the ACC's) transfer function
    acc_ref = np.abs(linear_transfer(r.frequencies, 0.3, 1.2, 0.6))
    assert np.abs(r.pair_gains / acc_ref[:, None] - 1.0).max() > 0.05


def test_transfer_function_tends_to_the_continuous_one_and_its_threshold_to_the_closed_form():
    f = np.geomspace(0.001, 0.5, 50)
    fine = linear_transfer(f, 0.3, 1.2, 1.5, dt=1e-4)
    assert np.abs(fine - linear_transfer(f, 0.3, 1.2, 1.5, dt=0)).max() < 1e-3
    # continuous ACC: string stable iff k1 h^2 + 2 k2 h - 2 >= 0
    for k1, k2 in ((0.3, 1.2), (0.2, 0.6), (1.0, 0.5)):
        closed = (-k2 + math.sqrt(k2 * k2 + 2 * k1)) / k1
        assert time_gap_threshold(k1, k2, dt=0) == pytest.approx(closed, abs=1e-3)
    assert time_gap_threshold(0.3, 1.2) == pytest.approx(0.761, abs=2e-3)
    assert time_gap_threshold(0.3, 1.2, k3=0.6) == pytest.approx(0.320, abs=2e-3)


# -- known verdicts ---------------------------------------------------------------------------------
def test_linear_acc_turns_string_unstable_below_the_analytic_time_gap_threshold():
    h_c = time_gap_threshold(0.3, 1.2)
    below = string_stability("acc", PlatoonConfig(vehicles=4, time_gap=round(h_c - 0.1, 3)), disturbance=False)
    above = string_stability("acc", PlatoonConfig(vehicles=4, time_gap=round(h_c + 0.1, 3)), disturbance=False)
    assert below.string_stable is False and below.max_gain > 1.0 + TOLERANCE
    assert below.unstable_bands and below.unstable_bands[0][0] < 0.05  # low frequencies amplify
    assert above.string_stable is True and above.max_gain <= 1.0


def test_cacc_is_string_stable_at_a_time_gap_where_acc_is_not():
    cfg = PlatoonConfig(vehicles=6, time_gap=0.6, v2v=True)
    acc, cacc = string_stability("acc", cfg), string_stability("cacc", cfg)
    assert acc.string_stable is False and cacc.string_stable is True
    # the disturbance agrees: it grows down the ACC column and shrinks down the CACC one
    assert acc.disturbance.drops[-1] > acc.disturbance.lead_drop
    assert cacc.disturbance.drops[-1] < cacc.disturbance.lead_drop
    assert np.all(np.diff(acc.disturbance.drops) > 0) and np.all(np.diff(cacc.disturbance.drops) < 0)
    assert acc.disturbance.lead_drop == pytest.approx(GUNTER_DROP, abs=1e-6)


def _idm_criterion(a, b, T, s0, v0, V, delta=4.0):
    """Treiber and Kesting: with alpha1 = da/ds, alpha3 = da/d(dv) (dv = v_lead - v),
    alpha2 = alpha3 - da/dv, string stable iff alpha2^2 - alpha3^2 - 2 alpha1 >= 0; IDM's
    partial derivatives by hand at its equilibrium gap s = s*/sqrt(1 - (V/v0)^delta)."""
    s_star = s0 + V * T
    s = s_star / math.sqrt(1.0 - (V / v0) ** delta)
    alpha1 = 2.0 * a * s_star ** 2 / s ** 3
    alpha3 = a * s_star * V / (s ** 2 * math.sqrt(a * b))
    da_dv = -a * (delta * V ** (delta - 1) / v0 ** delta + 2.0 * s_star * T / s ** 2)
    alpha2 = alpha3 - da_dv
    return alpha2 ** 2 - alpha3 ** 2 - 2.0 * alpha1, (alpha1, alpha3, -da_dv / alpha1)


@pytest.mark.parametrize("a,b,T", [(0.3, 3.0, 0.8), (0.3, 3.0, 1.5), (0.5, 4.0, 1.2), (0.3, 1.0, 1.5),
                                   (1.5, 1.0, 0.8), (1.5, 3.0, 1.5), (0.7, 1.0, 1.5)])
def test_idm_verdict_agrees_with_the_linear_criterion(a, b, T):
    V = 20.0
    cfg = PlatoonConfig(vehicles=3, speed=V, time_gap=T)
    crit, (k1, k2, h) = _idm_criterion(a, b, T, 2.0, cfg.cruise_speed, V)
    r = string_stability(make_controller("idm", a=a, b=b), cfg, frequencies=FEW, disturbance=False)
    assert r.string_stable is (crit >= 0.0)
    # the linearised model on the sampled vehicle is the linear law with k1 = alpha1, k2 = alpha3 and
    # k1 h = -da/dv: the measured largest gain is its largest gain on the grid
    assert r.max_gain == pytest.approx(np.abs(linear_transfer(FEW, k1, k2, h)).max(), rel=0.01)


# -- special controllers ----------------------------------------------------------------------------
def test_a_controller_that_copies_the_lead_speed_has_gain_one_everywhere():
    r = string_stability(CopyLead(), PlatoonConfig(vehicles=4))
    assert np.isfinite(r.pair_gains).all()
    assert np.abs(r.pair_gains - 1.0).max() < 1e-5
    assert r.string_stable is True
    assert np.abs(r.disturbance.drops - GUNTER_DROP).max() < 1e-3


def test_a_large_reaction_delay_makes_the_column_unstable():
    r = string_stability(DelayedACC(), PlatoonConfig(vehicles=4), frequencies=FEW)
    assert r.string_stable is False and r.max_gain > 1.2
    # 1 s late, the loop oscillates on its own: no steady sinusoid, the gain is the ratio of peaks
    assert not r.steady[:, 0].any() and np.all(r.pair_gains[:, 0] > 1.2)
    plain = string_stability(LinearACC(), PlatoonConfig(vehicles=4), frequencies=FEW)
    assert plain.string_stable is True


def test_a_controller_that_raises_mid_sweep_is_named_per_frequency_and_the_rest_reported():
    r = string_stability(RaisesWhenAccelerating(), PlatoonConfig(vehicles=3), frequencies=FEW)
    failed = {e.row for e in r.errors}
    assert failed and "disturbance" in failed
    for e in r.errors:
        assert e.vehicle == 1 and "RuntimeError: boom" in e.message and e.time_s > 0
        if e.row != "disturbance":
            i = [f"{f:.4g} Hz" for f in FEW].index(e.row)
            assert np.isnan(r.pair_gains[i]).all()
    ok = [i for i, f in enumerate(FEW) if f"{f:.4g} Hz" not in failed]
    assert ok and np.isfinite(r.pair_gains[ok, 0]).all()  # the frequencies that did not fail are measured
    ref = np.abs(linear_transfer(FEW[ok], 0.3, 1.2, 1.5))
    assert np.abs(r.pair_gains[ok, 0] / ref - 1).max() < 0.02
    out = r.to_dict()
    assert {e["row"] for e in out["errors"]} == failed
    assert all("vehicle" in e and "message" in e for e in out["errors"])


def test_nan_actions_and_collisions_fail_their_rows_by_name():
    r = string_stability(NaNAtSpeed(), PlatoonConfig(vehicles=2), frequencies=FEW)
    nan_rows = [e for e in r.errors if "NaN" in e.message]
    assert nan_rows and all(e.vehicle in (1, 2) for e in nan_rows)
    assert not any(e.row == "disturbance" for e in r.errors)  # the disturbance only slows down
    crash = string_stability(RamsWhenFast(), PlatoonConfig(vehicles=3), frequencies=[0.01, 0.02])
    assert [e.row for e in crash.errors] == ["0.01 Hz", "0.02 Hz"]  # not the disturbance: it never speeds up
    assert all("collided with vehicle" in e.message for e in crash.errors)
    assert crash.string_stable is None and crash.disturbance is not None


def test_a_controller_without_a_steady_state_is_a_clear_error():
    with pytest.raises(StringStabilityError, match="no steady state|does not follow"):
        string_stability(ConstantSpeed(), PlatoonConfig(vehicles=2))


def test_an_unbatched_controller_gives_the_same_numbers():
    cfg = PlatoonConfig(vehicles=3, time_gap=1.2)
    a = string_stability(LinearACC(), cfg, frequencies=FEW[:4])
    b = string_stability(Unbatched(), cfg, frequencies=FEW[:4])
    np.testing.assert_array_equal(a.pair_gains, b.pair_gains)
    np.testing.assert_array_equal(a.disturbance.v, b.disturbance.v)


# -- mixed traffic, humans, traces, determinism ----------------------------------------------------------
def test_mixed_traffic_places_the_controller_evenly_and_is_deterministic():
    cfg = PlatoonConfig(vehicles=8, penetration=0.25, drivers="naturalistic", seed=3)
    assert cfg.controlled == (4, 8)
    assert PlatoonConfig(vehicles=5, penetration=0.6).controlled == (2, 4, 5)
    a = string_stability("acc", cfg, frequencies=FEW[:3])
    b = string_stability("acc", cfg, frequencies=FEW[:3])
    np.testing.assert_array_equal(a.disturbance.v, b.disturbance.v)
    other = string_stability("acc", PlatoonConfig(vehicles=8, penetration=0.25, drivers="naturalistic", seed=4),
                             frequencies=FEW[:3])
    assert not np.array_equal(a.disturbance.v, other.disturbance.v)
    assert a.to_dict()["positions"] == [4, 8] and a.to_dict()["drivers"] == "naturalistic"


def test_human_columns_are_measured_and_damp_the_gunter_disturbance():
    r = string_stability("human", PlatoonConfig(vehicles=6, drivers="typical"), frequencies=FEW[:4])
    assert r.positions == () and r.controller == "human"
    d = r.disturbance
    assert np.all(d.min_gap > 0) and d.drops[-1] < d.lead_drop  # at 20 m/s these drivers damp it
    with pytest.raises(ValueError, match="human"):
        string_stability("acc", PlatoonConfig(penetration=0.0))


def test_a_stop_and_go_trace_starts_from_standstill_and_never_collides():
    trace = lead_trace("stopandgo", seed=1)
    assert trace.speeds[0] == 0.0
    r = string_stability("acc", PlatoonConfig(vehicles=4), frequencies=FEW[:2], disturbance=False, trace=trace)
    assert r.trace is not None and np.all(r.trace.min_gap > 0)
    assert r.trace.v.shape[1] == 5
    # the lead follows the trace: its speed never leaves it by more than one step's rounding
    t = r.trace.t
    assert np.abs(r.trace.v[:, 0] - trace.speed(t)).max() < 1e-6


def test_a_csv_lead_trace_and_its_errors(tmp_path):
    good = tmp_path / "lead.csv"
    good.write_text("t,v\n0,20\n10,20\n15,15\n25,15\n30,20\n60,20\n")
    prof = lead_trace(str(good))
    assert prof.speed(12.5) == pytest.approx(17.5)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,v\n0,20\n1,fast\n")
    with pytest.raises(ValueError, match="line 3"):
        lead_trace(str(bad))
    with pytest.raises(ValueError, match="columns 't' and 'v'"):
        (tmp_path / "h.csv").write_text("time,speed\n0,1\n")
        lead_trace(str(tmp_path / "h.csv"))
    with pytest.raises(ValueError, match="No such file"):
        lead_trace(str(tmp_path / "missing.csv"))


@pytest.mark.parametrize("field,value", [("vehicles", 0), ("vehicles", 101), ("time_gap", -1.0), ("speed", float("nan")),
                                         ("penetration", 1.5), ("drivers", "robots"), ("set_speed", 0.0),
                                         ("version", 2)])
def test_bad_configuration_is_named(field, value):
    with pytest.raises(ValueError, match=field):
        PlatoonConfig(**{field: value})


def test_bad_frequencies_are_named():
    with pytest.raises(ValueError, match="Nyquist"):
        string_stability("acc", PlatoonConfig(vehicles=1), frequencies=[0.1, 3.0])


# -- the command line --------------------------------------------------------------------------------
def test_cli_json_has_the_documented_keys_and_params_reach_the_controller(capsys, tmp_path):
    png = tmp_path / "ss.png"
    assert main(["string-stability", "acc", "--vehicles", "3", "--time-gap", "0.6", "--param", "k2=2.0",
                 "--frequencies", "0.01", "0.03", "0.1", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("controller", "vehicles", "speed", "max_gain", "string_stable", "frequencies", "disturbance"):
        assert key in out
    assert out["vehicles"] == 3 and out["params"] == {"k2": 2.0}
    assert [f["freq_hz"] for f in out["frequencies"]] == [0.01, 0.03, 0.1]
    assert out["max_gain"] == pytest.approx(max(f["gain"] for f in out["frequencies"]))
    assert len(out["disturbance"]["drops"]) == 3 and out["disturbance"]["lead_drop"] == pytest.approx(GUNTER_DROP)
    # k2 = 2 makes h = 0.6 s stable (threshold below 0.6 s), as the analysis says
    assert time_gap_threshold(0.3, 2.0) < 0.6 and out["string_stable"] is True
    assert png.stat().st_size > 10_000


def test_cli_names_bad_input(capsys):
    with pytest.raises(SystemExit):
        main(["string-stability", "acc", "--param", "kk=1"])
    assert "kk" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["string-stability", "acc", "--time-gap", "-1"])
    assert "time_gap" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["string-stability", "no-such-controller"])
    assert "unknown controller" in capsys.readouterr().err
