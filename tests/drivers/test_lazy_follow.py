"""An MPC driver's follow QP is installed at its first step with a real target (issue 35).

``MPCDriver.set_params`` installs the cruise QP only; the kernel reports the rows that meet a
vehicle ahead or a stop position while their follow QP is pending, and ``act`` installs those
and steps. The QP is the one an eager install would have condensed, so a driver's actions,
plans and modes equal, bit for bit, those of a batch built with the same parameters up front
(``MPCDriver.__init__`` installs both QPs), and a driver that never meets a target never
condenses its follow QP.
"""

from __future__ import annotations

import numpy as np

from acc_gym.drivers.base import Observation
from acc_gym.drivers.mpc import MPCDriver, MPCDriverParams
from acc_gym.drivers.population import sample_driver_values, sample_drivers
from acc_gym.drivers.qp import condensed_qp

DT = 0.2  # [s] MPCSettings' default step
STEPS = 60


def new_params(rng, n):
    """``n`` fresh drivers' parameters as plain numbers (configurations no cache holds)."""
    return [MPCDriverParams(**sample_driver_values(rng, float(rng.uniform(12.0, 30.0)))) for _ in range(n)]


def run(driver, steps=STEPS, idle=None, after=None):
    """Drive the batch closed loop, every row from 20 m/s: a lead 40 m ahead at 15 m/s from
    step 10 for rows 0 and 1, a stop position from step 25 for row 2, nothing ever for row 3;
    own speeds integrate the actions; ``after(k)`` is called after step ``k``. Returns the
    actions, plans and modes per step."""
    n = driver.n
    v = np.full(n, 20.0)  # [m/s]
    a = np.zeros(n)  # [m/s^2]
    x = np.zeros(n)  # [m]
    x_lead = np.full(n, 40.0)  # [m] the lead's rear
    if idle is not None:
        driver.set_idle(idle)
    out = []
    for k in range(steps):
        gap = np.full(n, np.inf)  # [m]
        stop = np.full(n, np.inf)  # [m]
        if k >= 10:
            gap[:2] = x_lead[:2] - x[:2]
        if k >= 25:
            stop[2] = 250.0 - x[2]
        u = driver.act(Observation(v.copy(), a.copy(), gap, np.full(n, 15.0), np.zeros(n), stop_gap=stop))
        out.append((u.copy(), driver.plan, driver.mode.copy()))
        if after is not None:
            after(k)
        a = u
        x = x + v * DT + 0.5 * a * DT * DT
        v = np.maximum(v + a * DT, 0.0)
        x_lead = x_lead + 15.0 * DT
    return out


def assert_same(got, want):
    assert len(got) == len(want)
    for k, ((u, plan, mode), (u_e, plan_e, mode_e)) in enumerate(zip(got, want)):
        assert np.array_equal(u, u_e), k
        assert np.array_equal(plan, plan_e), k
        assert np.array_equal(mode, mode_e), k


def test_lazy_follow_equals_the_eager_install_and_condenses_only_what_is_used():
    rng = np.random.default_rng(35)
    lazy = MPCDriver(sample_drivers(rng, 4, 25.0))
    fresh = new_params(rng, 4)
    start = condensed_qp.cache_info().misses
    for i, p in enumerate(fresh):
        lazy.set_params(i, p)
    assert condensed_qp.cache_info().misses == start + 4  # the four cruise QPs only
    assert lazy._state["follow_pending"].tolist() == [1, 1, 1, 1]
    misses = []
    got = run(lazy, after=lambda k: misses.append(condensed_qp.cache_info().misses - start))
    # nothing ahead before step 10; rows 0 and 1 meet their lead at step 10, row 2 its stop at 25
    assert misses[9] == 4 and misses[10] == 6 and misses[24] == 6 and misses[25] == 7 and misses[-1] == 7
    assert lazy._state["follow_pending"].tolist() == [0, 0, 0, 1]
    assert lazy._qp_follow[3] is None  # row 3 never had a target: its follow QP was never condensed

    eager = MPCDriver(MPCDriverParams.stack(fresh))  # both QPs installed up front
    assert eager._state["follow_pending"].tolist() == [0, 0, 0, 0]
    want = run(eager)
    assert_same(got, want)
    assert any(m[0] != 0 for _, _, m in want[10:]) and any(m[2] != 0 for _, _, m in want[25:])  # targets mattered
    assert not np.array_equal(want[20][0][:2], want[20][0][2:])  # and rows with a lead drove differently


def test_reset_keeps_the_pending_follow_qps():
    """``reset()`` starts the episode over, not the drivers: a row whose follow QP is still
    pending stays pending (its rows in the kernel arrays are the previous driver's)."""
    rng = np.random.default_rng(37)
    lazy = MPCDriver(sample_drivers(rng, 4, 25.0))
    fresh = new_params(rng, 4)
    for i, p in enumerate(fresh):
        lazy.set_params(i, p)
    eager = MPCDriver(MPCDriverParams.stack(fresh))
    for driver in (lazy, eager):  # the same history: five steps without a target, then reset()
        run(driver, steps=5)
        driver.reset()
    assert lazy._state["follow_pending"].tolist() == [1, 1, 1, 1]
    assert_same(run(lazy), run(eager))
    assert lazy._state["follow_pending"].tolist() == [0, 0, 0, 1]


def test_an_idle_row_does_not_install_its_follow_qp():
    """A row marked idle (no MPC driver this step) is not read: its finite gap installs nothing."""
    rng = np.random.default_rng(36)
    lazy = MPCDriver(sample_drivers(rng, 4, 25.0))
    for i, p in enumerate(new_params(rng, 4)):
        lazy.set_params(i, p)
    run(lazy, steps=20, idle=np.array([True, False, True, True]))
    assert lazy._state["follow_pending"].tolist() == [1, 0, 1, 1]  # only row 1 had a lead and was not idle
