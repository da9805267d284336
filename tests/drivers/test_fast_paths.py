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
        q1, q2, c_tg, p00, p01, p11, x_n = qp._lead_args
        b = _condensing_basis(horizon)
        mw_lead = -(q1 * (b.pp + c_tg * b.vp) + q2 * b.vv + p00 * np.outer(x_n, b.p_n) + p11 * b.vv_n
                    + p01 * (np.outer(x_n, b.v_n) + np.outer(b.v_n, b.p_n)))
        assert np.array_equal(qp.f_lead, 2.0 * mw_lead)
        assert np.array_equal(qp.gain_lead, -qp.hinv @ (2.0 * mw_lead))
        sums = np.concatenate([np.zeros((horizon.n_steps, 1)), np.cumsum(qp.gain_lead, axis=1)], axis=1)
        assert np.array_equal(qp.gain_lead_sums, sums)
        assert qp.gain_lead_sums is qp.gain_lead_sums and not qp.gain_lead_sums.flags.writeable


def test_batches_with_plain_number_fields_take_the_stacked_check():
    rng = np.random.default_rng(2)
    p = sample_drivers(rng, 5, 20.0)
    assert type(p.r_jerk) is float and p._arrays_valid()  # the sampler's batches: no field-by-field pass
    with pytest.raises(ValueError, match="r_jerk must be >= 0"):
        MPCDriverParams(**{**p.__dict__, "r_jerk": -1.0})
    with pytest.raises(ValueError, match="a_max must be > 0"):
        MPCDriverParams(**{**p.__dict__, "a_max": np.array([1.0, -1.0, 1.0, 1.0, 1.0])})
    with pytest.raises(ValueError, match="finite"):
        MPCDriverParams(**{**p.__dict__, "r_jerk": math.inf})
    assert not MPCDriverParams(**{**p.__dict__, "r_jerk": True})._arrays_valid()  # bools are not numbers here
