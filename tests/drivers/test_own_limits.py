"""Driver models 3 and 4 (issue 23): a driver at its own limits brakes there instead of escalating,
an emergency brakes at least as hard as the stop needs, and a creeping driver arrives."""

import numpy as np
import pytest

from acc_gym.drivers import MPCDriver, MPCSettings, preset, sample_drivers
from acc_gym.drivers._mpc_kernel import BRAKE, EMERGENCY
from acc_gym.drivers.base import Observation

DT = 0.2


def approach(params, v0, gap0, steps=5000):
    """One driver closing on a stopped vehicle (exact zero-order hold); rows (v, a, gap, u, mode)."""
    d = MPCDriver(params)
    v, a, gap, rows = v0, 0.0, gap0, []
    for _ in range(steps):
        u = float(d.act(Observation.build(v=[v], a=[a], gap=[gap], v_lead=[0.0], a_lead=[0.0]))[0])
        rows.append((v, a, gap, u, int(d.info["mode"][0])))
        gap -= v * DT + 0.5 * u * DT * DT if v + u * DT >= 0 else v * v / (-2.0 * u)
        v, a = max(v + u * DT, 0.0), u
        if v == 0.0:
            break
    return np.array(rows), d


@pytest.mark.parametrize("name,v0", [("#13", 15.0), ("#13", 35.0), ("#57", 25.0), ("#57", 35.0), ("#23", 35.0)])
def test_table4_presets_stop_within_their_own_limits_without_an_emergency(name, v0):
    """#13 (a_min -1.0) from 15 m/s used to enter EMERGENCY and brake at -1.19: its plan,
    braking at a_min to x_min, needed a few centimetres of slack on the conservative terminal
    chords. Now it brakes at its limit, in BRAKE. #57 (a_min -2.5) from 35 m/s carried out
    such a plan 1.2 cm into x_min at 0.29 m/s, was screened into EMERGENCY and braked at the
    vehicle's -8.6 m/s^2 for one step (driver model 3); now it eases off at its jerk bound.
    Every stop ends clear of x_min less a braking plan's tolerance (brake_slack_tol plus the
    jerk-bounded release b^3 / (24 jerk_max^2)), the jerk bound holds while moving."""
    p = preset(name, v_desired=v0)
    rows, d = approach(p, v0, max(300.0, v0 ** 2 / 0.2))
    v, u, gap, mode = rows[:, 0], rows[:, 3], rows[:, 2], rows[:, 4]
    assert not np.any(mode == EMERGENCY)
    assert np.all(u[v > 0.0] >= float(p.a_min) - 1e-6)  # never harder than its own a_min while moving
    a = rows[:, 1]
    assert np.all(np.abs(np.diff(np.append(a, u[-1]))[v > 0.0]) <= float(p.jerk_max) * DT + 1e-6)
    assert np.any(mode == BRAKE)
    tol = float(MPCSettings().stop_tolerance(p))
    b, jerk = -float(p.a_min), float(p.jerk_max)
    assert tol == pytest.approx(0.05 + b ** 3 / (24.0 * jerk ** 2))  # e.g. 0.154 m for #57
    final = gap[-1] - v[-1] ** 2 / (-2.0 * u[-1]) if u[-1] < 0 else gap[-1]
    assert float(p.x_min) - tol - 1e-9 <= final <= float(p.x_min) + 1.0
    assert d.stats["fallback"].sum() == 0


def test_an_emergency_brakes_at_least_as_hard_as_the_stop_needs():
    """Entering EMERGENCY (a stopped vehicle suddenly 40 m ahead at 20 m/s: -5.4 m/s^2 needed,
    beyond every typical a_min) the first input is at most a_need = -(v^2) / (2 (gap - x_min))
    (reachable at the emergency jerk): the plan cannot hold milder braking and postpone the rest."""
    rng = np.random.default_rng(3)
    params = sample_drivers(rng, 50, 20.0)
    d = MPCDriver(params)
    v, gap = np.full(50, 20.0), np.full(50, 40.0)
    u = d.act(Observation.build(v=v, a=np.full(50, -0.5), gap=gap, v_lead=np.zeros(50), a_lead=np.zeros(50)))
    a_need = -v ** 2 / (2.0 * (gap - np.asarray(params.x_min)))
    assert np.all(d.info["mode"] == EMERGENCY)
    assert np.all(u <= a_need + 1e-9)


def test_a_weak_distance_weight_still_arrives_at_the_queue():
    """A sampled typical driver with a weak distance weight (q1 = 0.004 at 38 m/s) approaching
    a stopped car from 7.3 km brakes early and then rolls on towards the queue; it used to
    slow down exponentially in ACCELERATE (0.22 m/s, still 3.4 m short after the whole run) and
    never arrive. Now it keeps at least its speed at creep speed until coasting reaches the
    stopping point, and stops braking within the stop-short margin of x_min."""
    from acc_gym.drivers import MPCDriverParams

    p = MPCDriverParams(a_max=2.0, a_min=-2.426, a_req_sail=-0.814, a_sail=-0.448, q1=0.004, r1=44.985, q2=1.0,
                        c_tg=1.193, x_min=2.66, v_desired=38.11, jerk_max=2.5, jerk_emergency=50.0)
    gap0 = 38.11 ** 2 / 0.2
    rows, _ = approach(p, 38.11, gap0, steps=int((gap0 / 38.11 + 60.0) / DT))
    gap, mode = rows[:, 2], rows[:, 4]
    assert rows[-1, 0] + rows[-1, 3] * DT <= 0.0  # the last step stops it
    assert 0.0 <= gap[-1] - rows[-1, 0] ** 2 / (-2.0 * rows[-1, 3]) - float(p.x_min) <= 1.0 + 1e-6
    assert mode[-1] == BRAKE
