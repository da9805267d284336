"""The drivers' fast paths equal the slow paths they short-cut, bit for bit.

* :func:`acc_gym.drivers.qp._spd_inverse` (sums run four at a time) equals the textbook
  Cholesky inverse loops written here, exactly;
* :attr:`CondensedQP.f_lead` (compiled entry by entry) equals its numpy expression and
  :attr:`CondensedQP.gain_lead_sums` the running sums the driver kernel used to build;
* :class:`MPCDriverParams` batches whose array fields come with plain-number fields
  (``r_jerk`` left at its default by the population sampler) take the stacked check and
  still raise the field-by-field messages when invalid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from acc_gym.drivers.mpc import MPCDriverParams
from acc_gym.drivers.population import sample_drivers
from acc_gym.drivers.qp import CondensedQP, Horizon, _condensing_basis, _spd_inverse


def textbook_spd_inverse(a):
    """The Cholesky inverse with one sum at a time, every sum in ascending ``k``."""
    n = a.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False, None
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    Mt = np.zeros((n, n))
    for j in range(n):
        Mt[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, n):
            s = 0.0
            for k in range(j, i):
                s += L[i, k] * Mt[j, k]
            Mt[j, i] = -s / L[i, i]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = 0.0
            for k in range(i, n):
                s += Mt[i, k] * Mt[j, k]
            out[i, j] = out[j, i] = s
    return True, out


def test_spd_inverse_equals_the_textbook_loops_exactly():
    rng = np.random.default_rng(0)
    mats = []
    for n in list(range(1, 14)) + [17, 30]:
        m = rng.normal(size=(n, n))
        mats.append(m @ m.T + rng.uniform(0.01, 2.0) * n * np.eye(n))
    for q1 in (0.0, 0.3, 4.0):  # the driver's own Hessians (N = 60)
        mats.append(CondensedQP(q1, 1.0, 42.0, 1.4, Horizon(), r_jerk=0.5).hessian[:60, :60].copy())
    for a in mats:
        ok, inv = _spd_inverse(a)
        ok_ref, inv_ref = textbook_spd_inverse(a)
        assert ok and ok_ref
        assert np.array_equal(inv, inv_ref)
    assert not _spd_inverse(-np.eye(6))[0]


@pytest.mark.parametrize("horizon", [Horizon(), Horizon(discretisation="euler"), Horizon(25, 0.3)],
                         ids=["zoh", "euler", "short"])
def test_lead_terms_equal_their_numpy_expressions(horizon):
    rng = np.random.default_rng(1)
    for _ in range(5):
        qp = CondensedQP(float(np.exp(rng.uniform(-4.0, 2.0))), 1.0, rng.uniform(40.0, 45.0), rng.uniform(0.3, 3.0),
                         horizon, r_jerk=float(rng.choice([0.0, 1.5])))
        (q1, q2, _, c_tg, _, p00, p01, p11), x_n = qp._lead_args
        b = _condensing_basis(horizon)
        mw_lead = -(q1 * (b.pp + c_tg * b.vp) + q2 * b.vv + p00 * np.outer(x_n, b.p_n) + p11 * b.vv_n
                    + p01 * (np.outer(x_n, b.v_n) + np.outer(b.v_n, b.p_n)))
        assert np.array_equal(qp.f_lead, 2.0 * mw_lead)
        assert np.array_equal(qp.gain_lead, -qp.hinv @ (2.0 * mw_lead))
        sums = np.concatenate([np.zeros((horizon.n_steps, 1)), np.cumsum(qp.gain_lead, axis=1)], axis=1)
        assert np.array_equal(qp.gain_lead_sums, sums)
        assert qp.gain_lead_sums is qp.gain_lead_sums and not qp.gain_lead_sums.flags.writeable


def test_batches_with_plain_number_fields_are_checked_against_them():
    rng = np.random.default_rng(2)
    p = sample_drivers(rng, 5, 20.0)
    assert type(p.r_jerk) is float  # the sampler's batches: arrays beside plain numbers
    with pytest.raises(ValueError, match="r_jerk must be >= 0"):
        MPCDriverParams(**{**p.__dict__, "r_jerk": -1.0})
    with pytest.raises(ValueError, match="a_max must be > 0"):
        MPCDriverParams(**{**p.__dict__, "a_max": np.array([1.0, -1.0, 1.0, 1.0, 1.0])})
    with pytest.raises(ValueError, match="finite"):
        MPCDriverParams(**{**p.__dict__, "r_jerk": math.inf})
    with pytest.raises(ValueError, match=r"a_sail must be above a_min, got array\(\[-3\.\]\)"):
        MPCDriverParams(**{**p.__dict__, "a_sail": np.array([-0.1, -0.1, -3.0, -0.1, -0.1]), "a_min": -2.5})
    with pytest.raises(ValueError, match="jerk_emergency must be >= jerk_max, got 1.0"):
        MPCDriverParams(**{**p.__dict__, "jerk_emergency": 1.0})


# ----------------------------------------------------------------------------- this release's fast paths
from acc_gym.drivers.base import Observation  # noqa: E402
from acc_gym.drivers.mpc import MPCDriver  # noqa: E402
from acc_gym.drivers.population import sample_driver_values  # noqa: E402
from acc_gym.drivers.slots import SlotDrivers  # noqa: E402
from acc_gym.scenarios.spec import DriverSpec  # noqa: E402

DRIVER_STATE = ("_drivers", "_alpha", "_beta", "_gain_f", "_gain_c", "_hinv_f", "_hinv_c", "_gain_lead", "_state", "_active", "_stats", "_out",
                "_plan", "_aseq")


def random_rows(rng, n):
    """Observation rows ``(8, n)`` as the world lays them out: v, a, gap, v_lead, a_lead, gap2, ..."""
    rows = np.empty((8, n))
    rows[0] = rng.uniform(0.0, 35.0, n)
    rows[1] = rng.uniform(-6.0, 2.0, n)
    rows[2] = np.where(rng.random(n) < 0.8, rng.uniform(0.5, 150.0, n), np.inf)
    rows[3] = rng.uniform(0.0, 35.0, n)
    rows[4] = rng.uniform(-6.0, 2.0, n)
    rows[5:] = np.inf
    return rows


def test_act_rows_equals_act_on_the_observation():
    """The world's path (one float64 array of rows) gives what act() gives on an Observation
    of the same rows, step after step (modes, plans, hard QPs and fallbacks included)."""
    rng = np.random.default_rng(0)
    n = 40
    params = sample_drivers(np.random.default_rng(1), n, rng.uniform(8.0, 35.0, n))
    fast, ref = MPCDriver(params), MPCDriver(params)
    for _ in range(60):
        rows = random_rows(rng, n)
        a_fast = fast.act_rows(rows)
        a_ref = ref.act(Observation(*rows))
        assert np.array_equal(a_fast, a_ref)
        assert np.array_equal(fast.mode, ref.mode) and np.array_equal(fast.plan, ref.plan)
    assert fast.stats["qp"].sum() > 0  # some steps needed the QP backend
    for name, value in fast.stats.items():
        assert np.array_equal(value, ref.stats[name]), name


def test_act_rows_rejects_invalid_values_naming_the_field():
    driver = MPCDriver(sample_drivers(np.random.default_rng(1), 3, 20.0))
    rows = random_rows(np.random.default_rng(2), 3)
    rows[0, 1] = np.nan
    with pytest.raises(ValueError, match="observation.v "):
        driver.act_rows(rows)
    rows = random_rows(np.random.default_rng(2), 3)
    rows[3, 2] = -1.0
    rows[2, 2] = 10.0
    with pytest.raises(ValueError, match="v_lead"):
        driver.act_rows(rows)
    # anything but a float64 (>= 5, n) array takes act() and its checks
    with pytest.raises(ValueError, match="shape"):
        driver.act_rows(random_rows(np.random.default_rng(3), 4))


def test_plain_number_params_restart_a_driver_as_one_element_arrays_do():
    """``set_params`` of one driver given plain numbers (a reset's) and given one-element arrays
    (converted by ``MPCDriverParams.broadcast``) leave the same kernel rows and QPs."""
    rng = np.random.default_rng(5)
    batch = sample_drivers(rng, 6, rng.uniform(5.0, 35.0, 6))
    fast, ref = MPCDriver(batch), MPCDriver(batch)
    for k in range(20):
        values = sample_driver_values(rng, float(rng.uniform(3.0, 40.0)), ("typical", "atypical", "malicious")[k % 3])
        if k % 4:  # the first draw leaves v_max unset (the driver's limit is then v_desired)
            values["v_max"] = values["v_desired"] + (1.0 if k % 2 else 0.0)
        i = int(rng.integers(0, 6))
        fast.set_params(i, MPCDriverParams(**values))  # plain numbers
        ref.set_params(np.array([i]), MPCDriverParams(**{key: np.array([v]) for key, v in values.items()}))
        for name in DRIVER_STATE:
            assert np.array_equal(getattr(fast, name), getattr(ref, name)), (k, name)
        assert fast._qp_follow[i] is ref._qp_follow[i] and fast._qp_cruise[i] is ref._qp_cruise[i]


@pytest.mark.parametrize("kind", ["typical", "atypical", "malicious", "naturalistic"])
def test_one_driver_sampler_equals_sample_drivers(kind):
    """``sample_driver_values`` (plain numbers) draws what ``sample_drivers(rng, 1, ...)`` draws,
    bit for bit and field by field, and leaves the generator in the same state; speeds on
    the band edges and an exhausted retry budget included."""
    speeds = [0.5, 9.999, 10.0, 15.0, 20.0, 25.0, 30.0, 30.001, 44.0]
    for seed in range(300):
        for max_tries in (50, 1):
            speed = speeds[seed % len(speeds)] if seed < 2 * len(speeds) else float(
                np.random.default_rng(seed).uniform(0.5, 45.0))
            r_ref, r_fast = np.random.default_rng(seed), np.random.default_rng(seed)
            ref = DriverSpec.mpc(sample_drivers(r_ref, 1, speed, kind, max_tries=max_tries)).params
            fast = sample_driver_values(r_fast, speed, kind, max_tries=max_tries)
            assert list(fast) == list(ref)
            assert np.array_equal(np.array(list(fast.values())).view(np.int64),
                                  np.array(list(ref.values())).view(np.int64)), (seed, speed)
            assert r_fast.bit_generator.state == r_ref.bit_generator.state


def test_slot_act_rows_equals_act_and_falls_back_for_mixed_slots():
    rng = np.random.default_rng(7)
    specs = [DriverSpec("mpc", sample_driver_values(rng, float(v))) for v in rng.uniform(8.0, 30.0, 4)]
    fast, ref = SlotDrivers(4, 0.2), SlotDrivers(4, 0.2)
    for slot in (fast, ref):
        for row, spec in enumerate(specs):
            slot.assign(row, spec)
    for _ in range(30):
        rows = random_rows(rng, 4)
        assert np.array_equal(fast.act_rows(rows), ref.act(Observation(*rows)))
        assert np.array_equal(fast.info["mode"], ref.info["mode"]) and np.array_equal(fast.fallbacks, ref.fallbacks)
    profile = DriverSpec("profile", {}, (0.0, 10.0), (20.0, 25.0))
    for slot in (fast, ref):
        slot.assign(2, profile)
    for _ in range(5):
        rows = random_rows(rng, 4)
        assert np.array_equal(fast.act_rows(rows), ref.act(Observation(*rows)))
        assert fast.info["mode"][2] == -1


def test_prepare_condenses_ahead_what_set_params_then_installs():
    """``MPCDriver.prepare`` puts the QP that ``set_params`` installs (the cruise QP; the
    follow QP waits for the driver's first real target, tests/drivers/test_lazy_follow.py) in
    the shared cache, so the later ``set_params`` installs that very object (no new
    condensation) and ends with the rows of a driver that was never prepared; what it cannot
    take it leaves to set_params."""
    from acc_gym.drivers.qp import condensed_qp

    rng = np.random.default_rng(11)
    batch = sample_drivers(rng, 4, 25.0)
    ahead, ref = MPCDriver(batch), MPCDriver(batch)
    for k in range(6):
        params = MPCDriverParams(**sample_driver_values(rng, float(rng.uniform(5.0, 35.0))))
        assert ahead.prepare(params)
        misses = condensed_qp.cache_info().misses
        ahead.set_params(k % 4, params)
        assert condensed_qp.cache_info().misses == misses  # it came from the cache
        ref.set_params(k % 4, params)
        for name in DRIVER_STATE:
            assert np.array_equal(getattr(ahead, name), getattr(ref, name)), (k, name)
    bad = MPCDriverParams(**sample_driver_values(rng, 20.0))
    object.__setattr__(bad, "r1", 0.0)  # past the params' own checks: the QP's check refuses it
    assert not ahead.prepare(bad)  # not raised ahead of time ...
    with pytest.raises(ValueError, match="r1"):
        ahead.set_params(0, bad)  # ... but where it is installed
    assert not ahead.prepare(sample_drivers(rng, 2, 20.0))  # a batch: nothing done ahead
