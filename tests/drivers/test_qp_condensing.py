"""The condensed QP built from cached products (``_condensing_basis``) and inverted by the
compiled Cholesky (``_spd_inverse``) equals a direct construction written here::

    M = -[Tp + c Tv; Tv]                   (stacked e_x rows 1..N, e_v rows 1..N)
    W = diag(q1 .. q1, P00, q2 .. q2, P11) + P01 between the two terminal rows
    H_uu = 2 (M'WM + r1 I + r_jerk D'D),   (D u)_k = u_k - u_{k-1}
    f_theta[:, :2] = 2 M'W s_theta,        s_theta rows [1, k dt] (e_x), [0, 1] (e_v)
    f_theta[0, 2] = -2 r_jerk
    f_lead = 2 M'W [Tp; Tv],  gain = -H^-1 f_theta,  gain_lead = -H^-1 f_lead
    hinv_sums = [cumsum(H^-1, axis=1), cumsum(H^-1 * arange(N), axis=1)]
"""

import numpy as np
import pytest

from acc_gym.drivers.qp import (SLACK_QUADRATIC, CondensedQP, Horizon, _condensing_basis, _spd_inverse,
                                riccati_terminal)

# (q1, q2, r1, c_tg, r_jerk): the paper-like driver, a cruise driver (q1 = 0), no time gap,
# heavy jerk weight, tiny and large weights
CASES = [(3.0, 1.0, 45.0, 1.5, 0.0), (3.0, 1.0, 45.0, 1.5, 10.0), (0.0, 2.0, 20.0, 1.2, 0.0),
         (0.0, 0.7, 5.0, 0.0, 3.0), (0.5, 4.0, 1.0, 0.0, 0.0), (12.0, 0.3, 150.0, 2.5, 40.0),
         (1e-3, 1e-2, 80.0, 0.9, 0.5)]
HORIZONS = [Horizon(), Horizon(discretisation="euler"), Horizon(8, 0.25), Horizon(3, 0.2, "euler"), Horizon(2, 0.5)]


def direct(q1, q2, r1, c, h, r_jerk):
    n = h.n_steps
    tv, tp = h.matrices
    M = -np.vstack([tp + c * tv, tv])
    P = riccati_terminal(q1, q2, r1, c, h)
    w = np.concatenate([np.full(n - 1, q1), [P[0, 0]], np.full(n - 1, q2), [P[1, 1]]])
    W = np.diag(w)
    W[n - 1, 2 * n - 1] = W[2 * n - 1, n - 1] = P[0, 1]
    D = np.eye(n) - np.eye(n, k=-1)
    H = 2.0 * (M.T @ W @ M + r1 * np.eye(n) + r_jerk * D.T @ D)
    k_dt = np.arange(1, n + 1) * h.dt
    s_theta = np.zeros((2 * n, 2))
    s_theta[:n, 0] = 1.0
    s_theta[:n, 1] = k_dt
    s_theta[n:, 1] = 1.0
    f_theta = np.zeros((n, 3))
    f_theta[:, :2] = 2.0 * M.T @ W @ s_theta
    f_theta[0, 2] = -2.0 * r_jerk
    f_lead = 2.0 * M.T @ W @ np.vstack([tp, tv])
    hinv = np.linalg.inv(H)
    idx = np.arange(n)
    return dict(huu=H, f_theta=f_theta, f_lead=f_lead, hinv=hinv, gain=-hinv @ f_theta, gain_lead=-hinv @ f_lead,
                hinv_sums=np.stack([np.cumsum(hinv, axis=1), np.cumsum(hinv * idx, axis=1)]), P=P)


def close(actual, desired, name, rtol=1e-10):
    # entries that cancel to ~0 are compared at the matrix's scale
    np.testing.assert_allclose(actual, desired, rtol=rtol, atol=rtol * np.max(np.abs(desired)), err_msg=name)


@pytest.mark.parametrize("h", HORIZONS, ids=lambda h: f"N{h.n_steps}-{h.dt}-{h.discretisation}")
def test_condensed_qp_equals_the_direct_construction(h):
    n = h.n_steps
    for q1, q2, r1, c, rj in CASES:
        qp = CondensedQP(q1, q2, r1, c, h, r_jerk=rj)
        ref = direct(q1, q2, r1, c, h, rj)
        np.testing.assert_array_equal(qp.terminal, ref["P"])
        close(qp.hessian[:n, :n], ref["huu"], "hessian")
        np.testing.assert_array_equal(qp.hessian[:n, :n], qp.hessian[:n, :n].T)  # symmetric exactly
        assert qp.hessian[n, n] == 2.0 * SLACK_QUADRATIC
        assert not qp.hessian[n, :n].any() and not qp.hessian[:n, n].any()
        close(qp.f_theta, ref["f_theta"], "f_theta")
        assert qp.f_theta[0, 2] == -2.0 * rj and not qp.f_theta[1:, 2].any()
        close(qp.hinv, ref["hinv"], "hinv", rtol=1e-9)
        close(qp.gain, ref["gain"], "gain", rtol=1e-9)
        close(qp.hinv_sums, ref["hinv_sums"], "hinv_sums", rtol=1e-9)
        close(qp.f_lead, ref["f_lead"], "f_lead")
        close(qp.gain_lead, ref["gain_lead"], "gain_lead", rtol=1e-9)
        # the inverse is an inverse of the Hessian the QP reports
        close(qp.hinv @ qp.hessian[:n, :n], np.eye(n), "H^-1 H", rtol=1e-9)


@pytest.mark.parametrize("kind", ["typical", "atypical", "malicious"])
def test_sampled_drivers_qps_equal_the_direct_construction(kind):
    """The QPs the drivers really get (paper 001's sampled weights, scaled by 1 / max(1, q1)
    as MPCDriver does; the follow and the cruise QP), against the dense construction."""
    from acc_gym.drivers.population import sample_drivers

    rng = np.random.default_rng(11)
    h = Horizon()
    p = sample_drivers(rng, 12, rng.uniform(3.0, 35.0, 12), kind)
    rj = np.broadcast_to(np.asarray(p.r_jerk, dtype=float), (12,))
    for i in range(12):
        k = 1.0 / max(1.0, p.q1[i])
        for q1 in (p.q1[i] * k, 0.0):
            args = (q1, p.q2[i] * k, p.r1[i] * k, p.c_tg[i], h)
            qp = CondensedQP(*args, r_jerk=rj[i] * k)
            ref = direct(*args, rj[i] * k)
            close(qp.hessian[:60, :60], ref["huu"], "hessian")
            close(qp.f_theta, ref["f_theta"], "f_theta")
            for name in ("hinv", "gain", "hinv_sums", "gain_lead"):
                close(getattr(qp, name), ref[name], name, rtol=1e-9)


def test_cruise_driver_ignores_the_spacing_error():
    """q1 = 0: no weight on e_x anywhere (P00 = P01 = 0), so the law does not use e_x0."""
    qp = CondensedQP(0.0, 2.0, 20.0, 1.2, Horizon(), r_jerk=1.0)
    assert qp.terminal[0, 0] == 0.0 and qp.terminal[0, 1] == 0.0
    assert not qp.f_theta[:, 0].any() and not qp.gain[:, 0].any()
    assert np.all(qp.gain[:, 1] > 0)  # positive speed error (target faster): accelerate


def test_basis_is_shared_and_qps_do_not_disturb_each_other():
    h = Horizon(12, 0.2)
    assert _condensing_basis(h) is _condensing_basis(Horizon(12, 0.2))
    a = CondensedQP(3.0, 1.0, 45.0, 1.5, h, r_jerk=2.0)
    first = {k: np.array(getattr(a, k)) for k in ("hessian", "f_theta", "gain", "hinv", "hinv_sums")}
    b = CondensedQP(0.0, 5.0, 3.0, 0.0, h, r_jerk=30.0)
    _ = b.f_lead, b.gain_lead
    ref = direct(3.0, 1.0, 45.0, 1.5, h, 2.0)
    close(a.f_lead, ref["f_lead"], "f_lead after another QP was built")
    again = CondensedQP(3.0, 1.0, 45.0, 1.5, h, r_jerk=2.0)
    for k, v in first.items():
        np.testing.assert_array_equal(getattr(again, k), v, err_msg=k)


def test_lazy_lead_terms():
    h = Horizon(10, 0.2)
    ref = direct(2.0, 1.0, 30.0, 1.4, h, 5.0)
    qp = CondensedQP(2.0, 1.0, 30.0, 1.4, h, r_jerk=5.0)
    assert "_f_lead" not in qp.__dict__  # not made until used
    close(qp.gain_lead, ref["gain_lead"], "gain_lead first")  # either property makes both
    assert qp.f_lead is qp.f_lead and qp.gain_lead is qp.gain_lead
    close(qp.f_lead, ref["f_lead"], "f_lead")
    theta, a_lead = np.array([5.0, -1.0, 0.3]), np.linspace(-1.0, 0.5, 10)
    q = qp.linear_term(theta, a_lead)
    u = -np.linalg.solve(ref["huu"], q[:-1])  # the unconstrained optimum of the full linear term
    close(qp.gain @ theta + qp.gain_lead @ a_lead, u, "unconstrained law", rtol=1e-9)


def test_exposed_arrays_are_read_only():
    qp = CondensedQP(3.0, 1.0, 45.0, 1.5, Horizon(6, 0.2), r_jerk=1.0)
    for name in ("hessian", "f_theta", "f_lead", "gain", "gain_lead", "hinv", "hinv_sums"):
        arr = getattr(qp, name)
        assert isinstance(arr, np.ndarray) and not arr.flags.writeable, name
        with pytest.raises(ValueError):
            arr[0, 0] = 1.0


# ----------------------------------------------------------------------------- _spd_inverse
@pytest.mark.parametrize("n", [1, 2, 5, 17, 60])
def test_spd_inverse_equals_numpy(n):
    rng = np.random.default_rng(n)
    for scale in (1e-3, 1.0, 1e4):
        x = rng.normal(size=(n, n))
        a = scale * (x @ x.T + 0.5 * n * np.eye(n))
        ok, inv = _spd_inverse(a)
        assert ok
        np.testing.assert_allclose(inv, np.linalg.inv(a), rtol=1e-9, atol=1e-12 * np.abs(np.linalg.inv(a)).max())
        np.testing.assert_array_equal(inv, inv.T)


def test_spd_inverse_of_an_ill_conditioned_matrix():
    """Condition number ~1e8 (like a long horizon's Hessian): still an inverse to working precision."""
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(30, 30)))
    a = q @ np.diag(np.logspace(0, 8, 30)) @ q.T
    a = 0.5 * (a + a.T)
    ok, inv = _spd_inverse(a)
    assert ok
    assert np.abs(inv @ a - np.eye(30)).max() < 1e-6


@pytest.mark.parametrize("a", [
    np.array([[1.0, 2.0], [2.0, 1.0]]),  # indefinite (eigenvalues 3, -1)
    np.array([[1.0, 1.0], [1.0, 1.0]]),  # singular: the second pivot is exactly 0
    np.array([[-1.0]]),
    np.zeros((3, 3)),
    np.diag([1.0, 2.0, -1e-9, 4.0]),
    np.array([[4.0, 0.0, 0.0], [0.0, np.nan, 0.0], [0.0, 0.0, 1.0]]),
], ids=["indefinite", "singular", "negative", "zero", "late-negative-pivot", "nan"])
def test_spd_inverse_refuses_a_matrix_that_is_not_positive_definite(a):
    ok, _ = _spd_inverse(a)
    assert ok is False


# ----------------------------------------------------------------------------- riccati_terminal
# (the zoh, q1 > 0 fixed point and the match with scipy are in test_qp.py / test_slots.py)
@pytest.mark.parametrize("q1, q2, r1, c, disc", [(0.0, 1.0, 45.0, 1.5, "zoh"), (0.0, 3.0, 2.0, 0.0, "euler"),
                                                 (3.0, 1.0, 45.0, 1.5, "euler"), (0.2, 5.0, 10.0, 0.8, "euler")])
def test_riccati_terminal_is_a_dare_fixed_point_for_cruise_and_euler(q1, q2, r1, c, disc):
    h = Horizon(discretisation=disc)
    dt = h.dt
    P = riccati_terminal(q1, q2, r1, c, h)
    a = np.array([[1.0, dt], [0.0, 1.0]])
    b = np.array([[-(c * dt + (0.5 * dt * dt if disc == "zoh" else 0.0))], [-dt]])
    q = np.diag([q1, q2])
    nxt = q + a.T @ P @ a - a.T @ P @ b @ np.linalg.inv(r1 + b.T @ P @ b) @ b.T @ P @ a
    np.testing.assert_allclose(nxt, P, rtol=1e-9, atol=1e-9 * np.abs(P).max())
    assert np.all(np.linalg.eigvalsh(P) >= -1e-12) and P[1, 1] > 0
    # stabilising: the closed loop a - b K has its eigenvalues inside the unit circle (when q1 > 0;
    # with q1 = 0 the e_x mode is unobserved and stays at 1)
    gain = np.linalg.inv(r1 + b.T @ P @ b) @ b.T @ P @ a
    radius = np.abs(np.linalg.eigvals(a - b @ gain))
    if q1 > 0:
        assert radius.max() < 1.0
    else:
        assert abs((a - b @ gain)[1, 1]) < 1.0  # the e_v loop alone


def test_the_kernels_layout_of_the_hinv_sums_holds_each_running_column_sum_contiguously():
    # the working-set solver reads H^-1 g of a row from hinv_columns[s][k, :]: the running sum of
    # H^-1's columns up to k (plain and index-weighted), as direct() builds them by column
    h = Horizon()
    q1, q2, r1, c, rj = CASES[1]
    qp = CondensedQP(q1, q2, r1, c, h, r_jerk=rj)
    ref = direct(q1, q2, r1, c, h, rj)["hinv_sums"]
    cols = qp.hinv_columns
    assert cols.shape == (2, h.n_steps, h.n_steps) and cols.flags.c_contiguous and not cols.flags.writeable
    for k in (0, 1, 30, h.n_steps - 1):
        close(cols[0][k], ref[0][:, k], f"plain sum to column {k}", rtol=1e-9)
        close(cols[1][k], ref[1][:, k], f"index-weighted sum to column {k}", rtol=1e-9)
    assert qp.hinv_columns is cols  # made once
