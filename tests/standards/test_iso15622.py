"""ISO 15622's envelope on hand-made drives: just inside passes, just outside fails (with the time
and speed of the failure), window averaging, steady time gap, automatic stop; and the battery."""

import numpy as np
import pytest

from acc_gym.standards import iso15622
from acc_gym.standards.iso15622 import LIMITS, Drive, check_drives

DT = 0.2


def drive(a, v0, label="hand", gap=None, v_lead=None):
    """A drive from applied accelerations ``a`` (over each step), starting at ``v0``."""
    a = np.concatenate([[0.0], np.asarray(a, float)])
    t = np.arange(a.size) * DT
    v = v0 + np.concatenate([[0.0], np.cumsum(a[1:] * DT)])
    gap = np.full(t.size, np.inf) if gap is None else np.asarray(gap, float)
    v_lead = np.zeros(t.size) if v_lead is None else np.asarray(v_lead, float)
    return Drive(label, t, v, a, gap, v_lead)


def req(report, word):
    return next(r for r in report.requirements if word in r.name)


def test_limits_are_the_documented_lines():
    d, j, a = LIMITS["deceleration"], LIMITS["jerk"], LIMITS["acceleration"]
    assert d.at(25.0) == 3.5 and d.at(3.0) == 5.0 and d.at(12.5) == pytest.approx(4.25)
    for v in (5.0, 8.0, 12.5, 17.0, 20.0):
        assert j.at(v) == pytest.approx(5.8333333 - v / 6.0, abs=1e-6)  # the cited 5.83 - v/6
    assert a.at(30.0) == 2.0 and a.at(0.0) == 4.0


@pytest.mark.parametrize("decel,passes", [(3.45, True), (3.6, False)])
def test_deceleration_at_highway_speed_just_inside_and_just_outside(decel, passes):
    # 30 m/s, then 3 s of constant braking: every 2 s window inside it averages `decel`, at 24-29 m/s
    a = [0.0] * 10 + [-decel] * 15 + [0.0] * 10
    r = check_drives([drive(a, 30.0, "brake")])
    d = req(r, "deceleration")
    assert d.passed is passes and d.measured == pytest.approx(decel, rel=1e-9)
    assert d.limit == pytest.approx(3.5)
    if not passes:
        assert d.failures > 0 and d.where.startswith("brake at t = ") and "m/s" in d.where
        t_fail = float(d.where.split("t = ")[1].split(" s")[0])
        assert 2.0 + 2.0 - 1e-9 <= t_fail <= 2.0 + 3.0 + 1e-9  # a full window inside the braking


def test_deceleration_limit_is_taken_at_the_window_speed():
    # the same 4.5 m/s^2 for 2 s: outside the limit at highway speed (3.5), inside it from 9 m/s to a
    # stop (window mean speed 4.5 m/s: limit 5)
    fast = req(check_drives([drive([0.0] * 5 + [-4.5] * 10, 25.0)]), "deceleration")
    slow = req(check_drives([drive([0.0] * 5 + [-4.5] * 10, 9.0)]), "deceleration")
    assert fast.passed is False and fast.measured == pytest.approx(4.5) and fast.limit == pytest.approx(3.5)
    assert slow.passed is True and slow.measured == pytest.approx(4.5) and slow.limit == pytest.approx(5.0)


@pytest.mark.parametrize("rate,passes", [(2.4, True), (2.6, False)])
def test_jerk_sustained_over_a_second_just_inside_and_just_outside(rate, passes):
    # at 30 m/s, acceleration ramps down at `rate` m/s^3 for 1.2 s: a 1 s window's mean jerk = rate
    ramp = [-rate * DT * (k + 1) for k in range(6)]
    a = [0.0] * 10 + ramp + [ramp[-1]] * 5
    j = req(check_drives([drive(a, 30.0, "ramp")]), "jerk")
    assert j.passed is passes and j.measured == pytest.approx(rate, rel=1e-9)
    if not passes:
        assert "ramp at t = " in j.where


def test_a_one_step_jerk_spike_is_averaged_over_the_window_and_a_sustained_one_is_not():
    # one step at -1 m/s^2 and back: per-step jerk 5 m/s^3, but the 1 s windows see at most 1 m/s^3
    spike = [0.0] * 10 + [-1.0] + [0.0] * 10
    j = req(check_drives([drive(spike, 30.0)]), "jerk")
    assert j.passed is True and j.measured == pytest.approx(1.0)
    # the same step held: the acceleration stays at -1 + ... a 3 m/s^2 change within 1 s fails
    held = [0.0] * 10 + [-3.0] * 10
    j = req(check_drives([drive(held, 30.0)]), "jerk")
    assert j.passed is False and j.measured == pytest.approx(3.0)


def test_acceleration_just_inside_and_just_outside():
    assert req(check_drives([drive([1.95] * 15, 22.0)]), "acceleration").passed is True
    r = req(check_drives([drive([2.05] * 15, 22.0)]), "acceleration")
    assert r.passed is False and r.measured == pytest.approx(2.05)


def test_steady_time_gap():
    n = 40  # 8 s of steady following at 25 m/s
    for h, passes in ((0.85, True), (0.75, False)):
        d = drive([0.0] * n, 25.0, gap=np.full(n + 1, 25.0 * h), v_lead=np.full(n + 1, 25.0))
        r = req(check_drives([d]), "time gap")
        assert r.passed is passes and r.measured == pytest.approx(h)
    short = drive([0.0] * 20, 25.0, gap=np.full(21, 10.0), v_lead=np.full(21, 25.0))  # 4 s: not steady
    assert req(check_drives([short]), "time gap").passed is None


def _stop(gap_at_stop, creep):
    """The ego brakes from 10 m/s to a stop behind a stopped target, then creeps ``creep`` m."""
    a = [0.0] * 5 + [-2.0] * 25 + [0.0] * 20
    d = drive(a, 10.0)
    d.v = np.maximum(d.v, 0.0)
    x = d.position()
    stop = int(np.argmax(d.v <= 0.0))
    target = x[stop] + gap_at_stop  # the target's rear, stopped from the start of the braking
    if creep:
        x = x.copy()
        x[stop + 10:] += creep
        d.x = x
    d.gap = target - d.position()
    d.v_lead = np.where(np.arange(d.t.size) >= 5, 0.0, 10.0)
    return d


@pytest.mark.parametrize("gap,passes", [(2.5, True), (1.5, False), (6.0, False)])
def test_standstill_gap(gap, passes):
    r = req(check_drives([_stop(gap, 0.0)]), "standstill")
    assert r.passed is passes and r.measured == pytest.approx(gap)


def test_automatic_go_while_the_target_stays_stopped_fails():
    assert req(check_drives([_stop(3.0, 0.3)]), "automatic go").passed is True
    r = req(check_drives([_stop(3.0, 1.0)]), "automatic go")
    assert r.passed is False and r.measured == pytest.approx(1.0)


def test_unknown_limit_is_named_and_own_limits_apply():
    with pytest.raises(ValueError, match="speedd"):
        check_drives([], {"speedd": LIMITS["jerk"]})
    strict = iso15622.SpeedDependentLimit("mean jerk over 1 s", "m/s^3", 0.5, 0.5, 1.0, "user", "[Q]")
    r = req(check_drives([drive([0.0] * 10 + [-1.0] + [0.0] * 10, 30.0)], {"jerk": strict}), "jerk")
    assert r.passed is False and r.limit == 0.5


def test_the_battery_runs_every_case_and_names_failures():
    from acc_gym.standards.battery import BATTERIES, ISO15622_V1, iso15622_report

    class Breaks:
        """The linear ACC that raises once its speed passes 31 m/s (only the 120 km/h cases)."""

        def __init__(self):
            from acc_gym_agents.controllers.linear import LinearACC

            self.law = LinearACC()

        def predict(self, obs, deterministic=True):
            if obs[0] > 31.0:
                raise RuntimeError("too fast for me")
            return self.law.predict(obs, deterministic)

    r = iso15622_report(Breaks(), seeds=(0,))
    assert len(r.drives) + len(r.errors) == len(BATTERIES[ISO15622_V1])
    assert r.errors and all("too fast for me" in reason for _, reason in r.errors)
    assert any("120 km/h" in name for name, _ in r.errors)
    assert all(q.passed is not None for q in r.requirements)  # the rest of the battery still decides
    out = r.to_dict()
    assert out["standard"] == "ISO 15622:2018" and out["errors"][0]["reason"].startswith("RuntimeError")


def test_collisions_are_reported_beside_the_envelope():
    n = 20
    gap = np.linspace(10.0, -1.0, n + 1)  # closes in and touches
    r = check_drives([drive([0.0] * n, 20.0, "crash", gap=gap, v_lead=np.full(n + 1, 15.0)),
                      drive([0.0] * n, 20.0, "clear")])
    assert r.collisions == ["crash"] and r.to_dict()["collisions"] == ["crash"]
