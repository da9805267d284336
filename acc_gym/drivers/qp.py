"""The condensed MPC quadratic program of the human-like driver, and its solvers.

Formulation (paper 001 Eqs. 4-6 and 11, condensed once per driver configuration)
---------------------------------------------------------------------------------
Decision vector ``z = (u_0 .. u_{N-1}, s)``: the planned accelerations [m/s^2] and one
slack ``s >= 0`` [m, m/s] shared by every state constraint. The ego's predicted speed
and position relative to the free response are linear in ``u``::

    v_k - v_0            = (Tv u)_k   = dt * sum_{j<k} u_j
    p_k - k dt v_0       = (Tp u)_k   (exact zero-order hold: the same model the vehicle
                                        integrates; ``discretisation="euler"`` drops the
                                        dt^2/2 term as the paper's Euler form does)

The errors of Eq. (4) with the constant-time-gap policy and the standstill distance
``d0`` (see :mod:`acc_gym.drivers.mpc`) are ``e_x,k = gap_k - d0 - c_TG v_k`` and
``e_v,k = v_L,k - v_k``; with a target moving at constant speed their free response is
``(e_x0 + k dt e_v0, e_v0)``, so the linear term of the QP is ``F @ theta`` with
``theta = (e_x0, e_v0, u_prev)``. Cost: ``sum_{k=1}^{N-1} q1 e_x^2 + q2 e_v^2 + e_N' P e_N +
sum_k r1 u_k^2 + r_jerk (u_k - u_{k-1})^2 + rho1 s + rho2 s^2`` (``u_{-1} = u_prev``, the
acceleration applied last step), with ``P`` the discrete algebraic Riccati solution of
the paper's cost (so the 12 s horizon approximates the infinite-horizon law).

Constraints (all rows are the same for every driver; only their bounds change):

* box: ``lo_k <= u_k <= hi_k`` (mode, ramp and vehicle limits, set by the driver), ``s >= 0``;
* gap:  ``gap_k + s >= x_min``                      (k = 1..N)
* speed: ``v_k + s >= 0`` and ``v_k - s <= v_max``   (k = 1..N)
* rate: ``|u_k - u_{k-1}| <= r``                      (k = 1..N-1; k = 0 is in the box)
* terminal stoppability, per real target (vehicle ahead, stop position): at the end
  of the horizon the driver must still be able to shed its closing speed
  ``w_N = v_N - v_target`` with its own braking ``b = -a_min`` reached at ``jerk_max``:
  ``gap_N - s >= x_min + f(w_N)``, ``f(w) = w^2 / (2b) + w b / (2 jerk_max)``. ``f`` is
  convex, so ``K_TERM`` chords of it over ``[0, v_max]`` (linear rows, above ``f``)
  give a sufficient linear condition. Without it a 12 s plan that does not contain the
  whole stop (30 m/s at -2 m/s^2 takes 15 s) can end committed to a collision that the
  next step's longer view cannot avoid comfortably.

Solving
-------
On most steps no constraint is active and the optimum is the unconstrained linear law
``u = Z @ theta`` (``s = 0``), exact; the driver kernel checks it against every
constraint with a few recurrences, batched over drivers. Where a constraint binds, the
kernel's dual active-set solver (Goldfarb and Idnani's method, on the rows' ``H^-1 g`` in
O(N) each from the running sums of ``H^-1``) starts from the working set of the driver's
step before and accepts its answer only where the KKT conditions of its final working set
hold; it hands over the QPs that need the slack (or that it does not settle within ``4 N +
16`` steps). Those go to an exact QP backend kept warm between steps: DAQP (a dual
active-set solver, default), ProxQP from proxsuite, or any qpsolvers backend (no
workspace; for cross-checks). Backends never raise: a failure is returned as ``ok=False`` and the
driver falls back (counted).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import math

import numba
import numpy as np

INF = 1e30  # "no bound" for the backends

# Default slack penalties: linear (exact-penalty) and quadratic weights of s.
SLACK_LINEAR = 1e9
SLACK_QUADRATIC = 1e4


@dataclass(frozen=True)
class Horizon:
    """Prediction structure shared by every driver with the same ``(N, dt, discretisation)``."""

    n_steps: int = 60  # N
    dt: float = 0.2  # [s]
    discretisation: str = "zoh"

    def __post_init__(self) -> None:
        if int(self.n_steps) != self.n_steps or self.n_steps < 2:
            raise ValueError(f"horizon n_steps must be an integer >= 2, got {self.n_steps!r}")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"horizon dt must be > 0, got {self.dt!r}")
        if self.discretisation not in ("zoh", "euler"):
            raise ValueError(f"discretisation must be 'zoh' or 'euler', got {self.discretisation!r}")

    @property
    def n_rows(self) -> int:
        """Number of general constraint rows (gap N, speed 2N, rate N-1, terminal 2 K_TERM)."""
        return 4 * self.n_steps - 1 + 2 * K_TERM

    @property
    def n_bounds(self) -> int:
        """Length of a driver's ``lower``/``upper`` vectors: N + 1 variables plus the rows."""
        return self.n_steps + 1 + self.n_rows

    def predict(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Tv u, Tp u)`` for plans ``u`` shaped ``(..., N)``: speed and position offsets."""
        dv = self.dt * np.cumsum(u, axis=-1)
        dp = self.dt * (np.cumsum(dv, axis=-1) - dv)
        if self.discretisation == "zoh":
            dp = dp + 0.5 * self.dt * dv
        return dv, dp

    @property
    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        return _horizon_matrices(self)

    @property
    def general_rows(self) -> np.ndarray:
        """The general rows but the terminal chords (gap N, speed 2N, rate N-1), ``(4N-1, N+1)``,
        columns ``(u, s)``: the same for every driver (read-only, cached)."""
        return _constraint_matrix(self)

    @property
    def terminal_rows(self) -> np.ndarray:
        """``(2, N)``: the last rows of the position and speed prediction matrices (the plan's
        end: position and speed change per input), read-only, cached."""
        return _terminal_rows(self)

    def constraint_matrix(self, beta: np.ndarray) -> np.ndarray:
        """General rows ``G`` ``(n_rows, N+1)``, columns ``(u, s)``, for chord slopes ``beta`` ``(K_TERM,)``."""
        n = self.n_steps
        tv, tp = self.matrices
        beta = np.asarray(beta, dtype=float)
        term = np.zeros((K_TERM, n + 1))
        term[:, :n] = tp[-1] + beta[:, None] * tv[-1]
        term[:, n] = -1.0
        return np.vstack([_constraint_matrix(self), term, term])


@lru_cache(maxsize=16)
def _horizon_matrices(h: Horizon) -> tuple[np.ndarray, np.ndarray]:
    tv, tp = h.predict(np.eye(h.n_steps))  # columns: response to a unit input at j
    tv, tp = tv.T.copy(), tp.T.copy()
    tv.setflags(write=False)
    tp.setflags(write=False)
    return tv, tp


@lru_cache(maxsize=16)
def _terminal_rows(h: Horizon) -> np.ndarray:
    tv, tp = h.matrices
    rows = np.ascontiguousarray(np.stack([tp[-1], tv[-1]]))
    rows.setflags(write=False)
    return rows


K_TERM = 4  # chords of the terminal stoppability condition, per real target


def terminal_chords(a_min, jerk_max, v_max) -> tuple[np.ndarray, np.ndarray]:
    """``(alpha, beta)`` ``(..., K_TERM)``: chords ``alpha_j + beta_j w`` of
    ``f(w) = w^2/(2b) + w b/(2 jerk_max)`` (``b = -a_min``) on ``K_TERM`` equal intervals of ``[0, v_max]``."""
    b = -np.asarray(a_min, dtype=float)[..., None]
    jerk = np.asarray(jerk_max, dtype=float)[..., None]
    w = np.asarray(v_max, dtype=float)[..., None] * np.arange(K_TERM + 1) / K_TERM
    f = w * w / (2.0 * b) + w * b / (2.0 * jerk)
    beta = np.diff(f, axis=-1) / np.diff(w, axis=-1)
    alpha = f[..., :-1] - beta * w[..., :-1]
    return alpha, beta


@lru_cache(maxsize=16)
def _constraint_matrix(h: Horizon) -> np.ndarray:
    n = h.n_steps
    tv, tp = h.matrices
    g = np.zeros((4 * n - 1, n + 1))
    g[0:n, :n] = tp
    g[0:n, n] = -1.0
    g[n:2 * n, :n] = -tv
    g[n:2 * n, n] = -1.0
    g[2 * n:3 * n, :n] = tv
    g[2 * n:3 * n, n] = -1.0
    idx = np.arange(n - 1)
    g[3 * n + idx, idx + 1] = 1.0
    g[3 * n + idx, idx] = -1.0
    g.setflags(write=False)
    return g


def riccati_terminal(q1: float, q2: float, r1: float, c_tg: float, h: Horizon) -> np.ndarray:
    """Terminal weight ``P``: the DARE solution for the error dynamics (Eq. 5, discretised)."""
    dt = h.dt
    if q1 == 0.0:
        # Only e_v is penalised and it evolves on its own: scalar DARE, closed form.
        b2 = dt * dt
        p = (q2 * b2 + np.sqrt((q2 * b2) ** 2 + 4.0 * b2 * q2 * r1)) / (2.0 * b2)
        return np.array([[0.0, 0.0], [0.0, p]])
    bx = -(c_tg * dt + (0.5 * dt * dt if h.discretisation == "zoh" else 0.0))
    return _dare_2x1((1.0, dt, 0.0, 1.0), (bx, -dt), (q1, 0.0, 0.0, q2), r1)


@numba.njit(cache=True, inline="always")
def _mm(x, y):
    return (x[0] * y[0] + x[1] * y[2], x[0] * y[1] + x[1] * y[3], x[2] * y[0] + x[3] * y[2], x[2] * y[1] + x[3] * y[3])


@numba.njit(cache=True)
def _add(x, y):
    return (x[0] + y[0], x[1] + y[1], x[2] + y[2], x[3] + y[3])


@numba.njit(cache=True)
def _sda(a, b, q, r, tol, max_iter):  # pragma: no cover - compiled
    A = a
    G = (b[0] * b[0] / r, b[0] * b[1] / r, b[1] * b[0] / r, b[1] * b[1] / r)
    H = q
    for _ in range(max_iter):
        w = _mm(G, H)
        w = (1.0 + w[0], w[1], w[2], 1.0 + w[3])
        d = w[0] * w[3] - w[1] * w[2]
        wi = (w[3] / d, -w[1] / d, -w[2] / d, w[0] / d)
        wia = _mm(wi, A)
        at = (A[0], A[2], A[1], A[3])
        h_new = _add(H, _mm(_mm(at, H), wia))
        G = _add(G, _mm(_mm(A, _mm(wi, G)), at))
        A = _mm(A, wia)
        change = max(max(abs(h_new[0] - H[0]), abs(h_new[1] - H[1])), max(abs(h_new[2] - H[2]), abs(h_new[3] - H[3])))
        scale = max(1.0, max(max(abs(h_new[0]), abs(h_new[1])), max(abs(h_new[2]), abs(h_new[3]))))
        H = h_new
        if change <= tol * scale:
            break
    return H


def _dare_2x1(a, b, q, r: float, tol: float = 1e-14, max_iter: int = 100) -> np.ndarray:
    """The stabilising solution of the DARE for two states and one input by the structured
    doubling algorithm, on 2x2 matrices as row-major tuples, compiled (equal to scipy's
    ``solve_discrete_are`` to ~1e-13 relative on this problem and far faster: a driver's
    QP is rebuilt at every environment reset)."""
    H = _sda(tuple(map(float, a)), tuple(map(float, b)), tuple(map(float, q)), float(r), float(tol), int(max_iter))
    s = 0.5 * (H[1] + H[2])
    return np.array([[H[0], s], [s, H[3]]])


@numba.njit(cache=True)
def _spd_inverse(a):  # pragma: no cover - compiled
    """``(ok, a^-1)`` of a symmetric positive definite matrix by Cholesky, in plain loops.

    Compiled loops rather than LAPACK on purpose: OpenBLAS threads its factorisations, and
    with more busy processes than cores (vector envs in subprocesses, campaign workers)
    a 60 x 60 inverse took milliseconds instead of tens of microseconds.

    Every entry is one sequential sum (``k`` ascending), as in the textbook loops; the
    loops run four independent sums side by side (four rows of ``L``, four rows of
    ``(L^-1)'``, four entries of the inverse) so that the processor overlaps their
    additions -- the same operations in the same order, hence the same values exactly, in about
    half the time. In the ``(L^-1)'`` sweep the sums of a block start at its first row
    ``j0``; the extra terms are products with the zeros below the diagonal, which leave
    a sum that starts at +0.0 unchanged."""
    n = a.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False, L
        d = math.sqrt(s)
        L[j, j] = d
        i = j + 1
        while i + 3 < n:  # four rows at a time: independent sums, each in the same order
            s0, s1, s2, s3 = a[i, j], a[i + 1, j], a[i + 2, j], a[i + 3, j]
            for k in range(j):
                ljk = L[j, k]
                s0 -= L[i, k] * ljk
                s1 -= L[i + 1, k] * ljk
                s2 -= L[i + 2, k] * ljk
                s3 -= L[i + 3, k] * ljk
            L[i, j], L[i + 1, j], L[i + 2, j], L[i + 3, j] = s0 / d, s1 / d, s2 / d, s3 / d
            i += 4
        for r in range(i, n):
            s = a[r, j]
            for k in range(j):
                s -= L[r, k] * L[j, k]
            L[r, j] = s / d
    Mt = np.zeros((n, n))
    for j in range(n):
        Mt[j, j] = 1.0 / L[j, j]
    for j0 in range(0, n, 4):
        jb = min(j0 + 4, n)
        for i in range(j0 + 1, n):
            if i >= jb and jb == j0 + 4:
                s0 = s1 = s2 = s3 = 0.0
                for k in range(j0, i):
                    lik = L[i, k]
                    s0 += lik * Mt[j0, k]
                    s1 += lik * Mt[j0 + 1, k]
                    s2 += lik * Mt[j0 + 2, k]
                    s3 += lik * Mt[j0 + 3, k]
                lii = L[i, i]
                Mt[j0, i], Mt[j0 + 1, i], Mt[j0 + 2, i], Mt[j0 + 3, i] = -s0 / lii, -s1 / lii, -s2 / lii, -s3 / lii
            else:
                for j in range(j0, min(jb, i)):
                    s = 0.0
                    for k in range(j0, i):
                        s += L[i, k] * Mt[j, k]
                    Mt[j, i] = -s / L[i, i]
    out = np.empty((n, n))
    for i in range(n):
        j = 0
        while j + 3 <= i:
            s0 = s1 = s2 = s3 = 0.0
            for k in range(i, n):
                m = Mt[i, k]
                s0 += m * Mt[j, k]
                s1 += m * Mt[j + 1, k]
                s2 += m * Mt[j + 2, k]
                s3 += m * Mt[j + 3, k]
            out[i, j], out[i, j + 1], out[i, j + 2], out[i, j + 3] = s0, s1, s2, s3
            out[j, i], out[j + 1, i], out[j + 2, i], out[j + 3, i] = s0, s1, s2, s3
            j += 4
        for c in range(j, i + 1):
            s = 0.0
            for k in range(i, n):
                s += Mt[i, k] * Mt[c, k]
            out[i, c] = s
            out[c, i] = s
    return True, out


@numba.njit(cache=True)
def _assemble_hessian(pp, pv_sym, vv, dd, x_n, v_n, w):  # pragma: no cover - compiled
    """``2 (M'WM + r1 I + r_jerk D'D)``, symmetrised, from the horizon's products (see CondensedQP);
    ``w``: the weights ``(q1, q2, r1, c_tg, r_jerk, p00, p01, p11)`` (``p..``: the terminal cost's)."""
    q1, q2, r1, c_tg, r_jerk, p00, p01, p11 = w
    n = pp.shape[0]
    h = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            m = (q1 * (pp[i, j] + c_tg * pv_sym[i, j] + c_tg * c_tg * vv[i, j]) + q2 * vv[i, j]
                 + p00 * (x_n[i] * x_n[j]) + p11 * (v_n[i] * v_n[j]) + p01 * (x_n[i] * v_n[j] + v_n[i] * x_n[j]))
            h[i, j] = 2.0 * (m + (r1 if i == j else 0.0) + r_jerk * dd[i, j])
    for i in range(n):
        for j in range(i):
            s = 0.5 * (h[i, j] + h[j, i])
            h[i, j] = s
            h[j, i] = s
    return h


@numba.njit(cache=True)
def _lead_linear_term(pp, vp, vv, vv_n, x_n, p_n, v_n, w):  # pragma: no cover - compiled
    """:attr:`CondensedQP.f_lead`, ``2 M'W [Tp; Tv]`` with the sign of ``-M``: entry by entry the
    numpy expression ``2 * -(q1 (pp + c vp) + q2 vv + p00 x_n p_n' + p11 vv_n + p01 (x_n v_n' + v_n p_n'))``,
    each operation in the same order (so the same values exactly), without its dozen ``N x N`` temporaries;
    ``w`` the weights as :func:`_assemble_hessian` takes them."""
    q1, q2, _, c_tg, _, p00, p01, p11 = w
    n = pp.shape[0]
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            m = (q1 * (pp[i, j] + c_tg * vp[i, j]) + q2 * vv[i, j] + p00 * (x_n[i] * p_n[j]) + p11 * vv_n[i, j]
                 + p01 * (x_n[i] * v_n[j] + v_n[i] * p_n[j]))
            out[i, j] = 2.0 * -m
    return out


@numba.njit(cache=True)
def _running_sums(hinv):  # pragma: no cover - compiled
    """``[sum_{j<=k} H^-1[:, j], sum_{j<=k} j H^-1[:, j]]`` (the driver kernel's column sums)."""
    n = hinv.shape[0]
    out = np.empty((2, n, n))
    for i in range(n):
        s0 = 0.0
        s1 = 0.0
        for k in range(n):
            s0 += hinv[i, k]
            s1 += hinv[i, k] * k
            out[0, i, k] = s0
            out[1, i, k] = s1
    return out


@numba.njit(cache=True)
def _row_cumsums(g):  # pragma: no cover - compiled
    """``(N, N+1)``: a zero column, then ``np.cumsum(g, axis=1)`` (numpy's accumulate: each row
    summed in order from its first entry, so the same values exactly) without its strided output."""
    n, m = g.shape
    out = np.zeros((n, m + 1))
    for i in range(n):
        s = g[i, 0]
        out[i, 1] = s
        for j in range(1, m):
            s += g[i, j]
            out[i, j + 1] = s
    return out


@numba.njit(cache=True)
def _condense(basis, x_n, w, slack_quadratic):  # pragma: no cover - compiled
    """``(ok, hessian, f_theta, hinv, hinv_sums, gain)`` of :class:`CondensedQP` in one call, from
    the horizon's products ``basis`` (``(pp, pv_sym, vv, dd, v_n, tp_t, tv_t, k_dt)`` of
    :func:`_condensing_basis`), the last row ``x_n`` of ``Tp + c Tv`` and the weights ``w`` (as
    :func:`_assemble_hessian` takes them).

    ``f_theta[:, :2] = -2 (Tp' + c Tv') W_x s - 2 Tv' W_v s`` with ``W s_theta`` written out
    (stage rows ``(q1, q1 k dt)`` and ``(0, q2)``, the terminal row from ``P``), and
    ``gain = -H^-1 f_theta``: the sums run in ascending ``k`` (plain loops, not BLAS, so the
    last bits can differ from numpy's products; tests/drivers/test_qp_condensing.py holds
    them to 1e-9 of the direct dense construction)."""
    pp, pv_sym, vv, dd, v_n, tp_t, tv_t, k_dt = basis
    q1, q2, _, c_tg, r_jerk, p00, p01, p11 = w
    n = pp.shape[0]
    huu = _assemble_hessian(pp, pv_sym, vv, dd, x_n, v_n, w)
    wx0 = np.empty(n)  # W s_theta, e_x rows (columns e_x0, e_v0)
    wx1 = np.empty(n)
    wv1 = np.empty(n)  # W s_theta, e_v rows (the e_x0 column is zero but on the terminal row)
    for k in range(n):
        wx0[k] = q1
        wx1[k] = q1 * k_dt[k]
        wv1[k] = q2
    wx0[n - 1] = p00
    wx1[n - 1] = p00 * k_dt[n - 1] + p01
    wv1[n - 1] = p01 * k_dt[n - 1] + p11
    wv0_last = p01
    f_theta = np.zeros((n, 3))
    for i in range(n):
        px0 = 0.0
        px1 = 0.0
        vx0 = 0.0
        vx1 = 0.0
        vv1 = 0.0
        for k in range(n):
            tp = tp_t[i, k]
            tv = tv_t[i, k]
            px0 += tp * wx0[k]
            px1 += tp * wx1[k]
            vx0 += tv * wx0[k]
            vx1 += tv * wx1[k]
            vv1 += tv * wv1[k]
        vv0 = tv_t[i, n - 1] * wv0_last
        f_theta[i, 0] = 2.0 * -(px0 + c_tg * vx0 + vv0)
        f_theta[i, 1] = 2.0 * -(px1 + c_tg * vx1 + vv1)
    f_theta[0, 2] = -2.0 * r_jerk
    hessian = np.zeros((n + 1, n + 1))
    hessian[:n, :n] = huu
    hessian[n, n] = 2.0 * slack_quadratic
    ok, hinv = _spd_inverse(huu)
    if not ok:
        return False, hessian, f_theta, hinv, np.zeros((2, n, n)), np.zeros((n, 3))
    sums = _running_sums(hinv)
    gain = np.empty((n, 3))
    for i in range(n):
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        for k in range(n):
            h = hinv[i, k]
            g0 += h * f_theta[k, 0]
            g1 += h * f_theta[k, 1]
            g2 += h * f_theta[k, 2]
        gain[i, 0] = -g0
        gain[i, 1] = -g1
        gain[i, 2] = -g2
    return True, hessian, f_theta, hinv, sums, gain


class CondensedQP:
    """The QP of one driver configuration ``(q1, q2, r1, c_TG)``, condensed once.

    Attributes (read-only arrays):

    * ``hessian`` ``(N+1, N+1)``: ``0.5 z' H z`` with the slack block.
    * ``f_theta`` ``(N, 3)``: linear term of ``u`` is ``f_theta @ theta``,
      ``theta = (e_x0, e_v0, u_prev)``.
    * ``f_lead`` ``(N, N)``: extra linear term ``f_lead @ a_lead_seq`` when the target's
      predicted accelerations are used (zero sequence by default).
    * ``gain`` ``(N, 3)`` and ``gain_lead`` ``(N, N)``: the unconstrained law
      ``u = gain @ theta + gain_lead @ a_lead_seq``.
    * ``hinv`` ``(N, N)``: the inverse of the input block of the Hessian, and
      ``hinv_sums`` ``(2, N, N)`` its running column sums (plain and index-weighted),
      from which the driver kernel's warm active-set solver forms ``H^-1 g`` of any
      constraint row in O(N).
    """

    def __init__(self, q1: float, q2: float, r1: float, c_tg: float, horizon: Horizon,
                 slack_linear: float = SLACK_LINEAR, slack_quadratic: float = SLACK_QUADRATIC,
                 r_jerk: float = 0.0):
        for name, value in (("q1", q1), ("q2", q2), ("c_tg", c_tg), ("r_jerk", r_jerk)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0, got {value!r}")
        if not (math.isfinite(r1) and r1 > 0):
            raise ValueError(f"r1 must be > 0, got {r1!r}")
        self.q1, self.q2, self.r1, self.c_tg = float(q1), float(q2), float(r1), float(c_tg)
        self.r_jerk = float(r_jerk)
        self.horizon = horizon
        self.slack_linear = float(slack_linear)
        self.terminal = P = riccati_terminal(q1, q2, r1, c_tg, horizon)
        p00, p01, p11 = float(P[0, 0]), float(P[0, 1]), float(P[1, 1])
        b = _condensing_basis(horizon)
        # Cost weights W on the stacked errors (e_x rows 1..N, e_v rows 1..N): q1, q2 on the
        # stages, P on the terminal pair. With e = free - M u, M = [Tp + c Tv; Tv], the
        # Hessian is M'WM, expanded in c over products of Tp and Tv cached per horizon:
        # only scaled sums of N x N matrices per driver (resets build two QPs per driver).
        x_n = b.p_n + c_tg * b.v_n  # last row of Tp + c Tv
        # one compiled call (_condense): the Hessian M'WM + r1 I + r_jerk D'D from the cached
        # products, the linear term M'W s_theta (free response of the errors to theta, with
        # the sign of -M), the inverse, its running column sums and the unconstrained gain
        w = (float(q1), float(q2), float(r1), float(c_tg), float(r_jerk), p00, p01, p11)
        ok, hessian, f_theta, hinv, hinv_sums, gain = _condense(
            (b.pp, b.pv_sym, b.vv, b.dd, b.v_n, b.tp_t, b.tv_t, b.k_dt), x_n, w, float(slack_quadratic))
        if not ok:
            raise np.linalg.LinAlgError("the condensed Hessian is not positive definite")
        self.hessian, self.f_theta, self.hinv, self.hinv_sums, self.gain = hessian, f_theta, hinv, hinv_sums, gain
        self._lead_args = (w, x_n)  # f_lead and gain_lead are made on first use
        for arr in (self.f_theta, self.gain, self.hessian, self.hinv, self.hinv_sums, self.terminal):
            arr.setflags(write=False)  # shared: condensed_qp caches one instance per configuration

    @property
    def f_lead(self) -> np.ndarray:
        """``(N, N)``: the linear term's response to the target's predicted accelerations (made
        on first use: only the car-following law of a driver that predicts them needs it)."""
        if "_f_lead" not in self.__dict__:
            w, x_n = self._lead_args
            b = _condensing_basis(self.horizon)
            f_lead = _lead_linear_term(b.pp, b.vp, b.vv, b.vv_n, x_n, b.p_n, b.v_n, w)
            gain_lead = -self.hinv @ f_lead
            f_lead.setflags(write=False)
            gain_lead.setflags(write=False)
            self._f_lead, self._gain_lead = f_lead, gain_lead
        return self._f_lead

    @property
    def gain_lead(self) -> np.ndarray:
        """``(N, N)``: the unconstrained law's response to the target's predicted accelerations."""
        self.f_lead  # noqa: B018  (makes both)
        return self._gain_lead

    @property
    def gain_lead_sums(self) -> np.ndarray:
        """``(N, N+1)``: running row sums of :attr:`gain_lead` with a leading zero column (the
        driver kernel's form: the predicted lead accelerations are piecewise constant). Made
        on first use and kept, like :attr:`gain_lead` (the QP is immutable and shared)."""
        if "_gain_lead_sums" not in self.__dict__:
            sums = _row_cumsums(self.gain_lead)
            sums.setflags(write=False)
            self._gain_lead_sums = sums
        return self._gain_lead_sums

    @property
    def hinv_columns(self) -> np.ndarray:
        """``(2, N, N)``: :attr:`hinv_sums` laid out as the driver kernel reads it, each running
        column sum contiguous (``hinv_columns[s][k, :] = hinv_sums[s][:, k]``: a constraint row's
        ``H^-1 g`` then reads 2 N consecutive numbers instead of a strided column, which missed the
        cache on every number). Made on first use and kept (the QP is immutable and shared)."""
        if "_hinv_columns" not in self.__dict__:
            cols = np.ascontiguousarray(self.hinv_sums.transpose(0, 2, 1))
            cols.setflags(write=False)
            self._hinv_columns = cols
        return self._hinv_columns

    @property
    def key(self) -> tuple:
        return (self.q1, self.q2, self.r1, self.c_tg, self.horizon, self.slack_linear,
                float(self.hessian[-1, -1]), self.r_jerk)

    def linear_term(self, theta: np.ndarray, a_lead_seq: np.ndarray | None = None) -> np.ndarray:
        """Full linear term ``(q_u, rho1)`` of length ``N+1`` for one driver."""
        q = self.f_theta @ theta
        if a_lead_seq is not None:
            q = q + self.f_lead @ a_lead_seq
        return np.append(q, self.slack_linear)

    def objective(self, z: np.ndarray, q: np.ndarray) -> float:
        return float(0.5 * z @ self.hessian @ z + q @ z)


@dataclass(frozen=True)
class _Basis:
    """Products of a horizon's prediction matrices that every condensed QP is built from.

    Stage rows are ``1..N-1`` (weights q1, q2), the terminal row ``N`` (weight P)::

        pp = Tp_s' Tp_s,  vp = Tv_s' Tp_s,  pv_sym = vp + vp',  vv = Tv_s' Tv_s
        p_n, v_n = last rows of Tp, Tv;  vv_n = v_n v_n'
    """

    pp: np.ndarray
    vp: np.ndarray
    pv_sym: np.ndarray
    vv: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    vv_n: np.ndarray
    tp_t: np.ndarray  # Tp'
    tv_t: np.ndarray  # Tv'
    k_dt: np.ndarray  # (k dt) for k = 1..N [s]
    eye: np.ndarray
    dd: np.ndarray  # D'D, (D u)_k = u_k - u_{k-1}


@lru_cache(maxsize=16)
def _condensing_basis(h: Horizon) -> _Basis:
    n = h.n_steps
    tv, tp = h.matrices
    tp_s, tv_s = tp[: n - 1], tv[: n - 1]
    vp = tv_s.T @ tp_s
    diff = np.eye(n) - np.eye(n, k=-1)
    return _Basis(pp=tp_s.T @ tp_s, vp=vp, pv_sym=vp + vp.T, vv=tv_s.T @ tv_s, p_n=tp[-1].copy(),
                  v_n=tv[-1].copy(), vv_n=np.outer(tv[-1], tv[-1]), tp_t=np.ascontiguousarray(tp.T),
                  tv_t=np.ascontiguousarray(tv.T), k_dt=np.arange(1, n + 1) * h.dt, eye=np.eye(n),
                  dd=diff.T @ diff)


@lru_cache(maxsize=256)  # ~230 kB each: sampled drivers rarely repeat, presets do
def condensed_qp(q1: float, q2: float, r1: float, c_tg: float, horizon: Horizon,
                 slack_linear: float = SLACK_LINEAR, slack_quadratic: float = SLACK_QUADRATIC,
                 r_jerk: float = 0.0) -> CondensedQP:
    """A shared, cached :class:`CondensedQP` per configuration."""
    return CondensedQP(q1, q2, r1, c_tg, horizon, slack_linear, slack_quadratic, r_jerk)


# --------------------------------------------------------------------------------------
# Bounds layout
# --------------------------------------------------------------------------------------
# One driver's bounds are two vectors ``lower``/``upper`` of length 5N + 2 K_TERM:
#   [ box u_0..u_{N-1} | box s | gap rows (N) | v>=0 rows (N) | v<=v_max rows (N) | rate rows (N-1)
#     | terminal rows, vehicle ahead (K_TERM) | terminal rows, stop position (K_TERM) ]
# The first N+1 entries bound the variables, the rest bound ``G @ z`` (Horizon.constraint_matrix).


def constraint_violation(z: np.ndarray, lower: np.ndarray, upper: np.ndarray, g: np.ndarray) -> float:
    """Largest violation of ``lower <= (z, G z) <= upper`` for one solution ``z`` (<= 0: feasible).

    A reference written with the explicit matrix ``G`` (the kernel uses recurrences).
    """
    vals = np.concatenate([z, g @ z])
    return float(max(np.max(lower - vals), np.max(vals - upper)))


# --------------------------------------------------------------------------------------
# Backends
# --------------------------------------------------------------------------------------

@dataclass
class QPResult:
    z: np.ndarray | None  # (N+1,) solution (u, s) or None
    ok: bool
    iterations: int
    n_active: int
    status: str
    duals: np.ndarray | None = None  # multipliers in the bounds layout (> 0: upper bound active)


class QPBackend:
    """A warm QP solver for one driver and one configuration. Never raises from ``solve``."""

    name = "base"

    def __init__(self, qp: CondensedQP, g: np.ndarray, max_iter: int = 1000):
        self.qp = qp
        self.g = np.array(g, dtype=float)  # the driver's constraint rows (writable copy)
        self.max_iter = int(max_iter)

    def solve(self, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
              start: np.ndarray | None = None) -> QPResult:  # pragma: no cover
        """Solve ``min 0.5 z'Hz + q'z`` s.t. ``lower <= (z, G z) <= upper`` (layout above).

        ``start``: optional guess of the active set, codes ``2 c + side`` (side 1: upper
        bound), used by backends that take a working set; otherwise they warm-start
        from their own previous solve."""
        raise NotImplementedError


class DaqpBackend(QPBackend):
    """DAQP dual active-set solver through its ``Model`` workspace (warm-started)."""

    name = "daqp"

    def __init__(self, qp: CondensedQP, g: np.ndarray, max_iter: int = 1000):
        super().__init__(qp, g, max_iter)
        self._model = None

    def solve(self, q, lower, upper, start=None):
        try:
            import daqp

            blower, bupper = lower, upper
            sense = None
            if start is not None:
                sense = np.zeros(lower.shape[0], dtype=np.int32)
                c = np.asarray(start, dtype=np.int64) >> 1
                sense[c] = np.where(np.asarray(start) & 1, 1, 3)  # DAQP: 1 active upper, 3 active lower
            if self._model is None:
                self._model = daqp.Model()
                code, _ = self._model.setup(np.array(self.qp.hessian), q, self.g,
                                            bupper, blower, sense)
                if code < 0:
                    self._model = None
                    return QPResult(None, False, 0, 0, f"daqp setup failed ({code})")
                settings = self._model.settings
                settings["iter_limit"] = self.max_iter
                self._model.settings = settings
            elif sense is not None:
                self._model.update(f=q, bupper=bupper, blower=blower, sense=sense)
            else:
                self._model.update(f=q, bupper=bupper, blower=blower)
            x, _, flag, info = self._model.solve()
            x = np.asarray(x, dtype=float)
            ok = flag >= 1 and bool(np.all(np.isfinite(x)))
            lam = np.asarray(info.get("lam", ()), dtype=float)
            if not ok:
                self._model = None  # rebuild the workspace cold next time
            return QPResult(x if ok else None, ok, int(info.get("iterations", 0)),
                            int(np.count_nonzero(lam)), f"daqp exitflag {flag}", lam if ok else None)
        except Exception as exc:  # a backend must never raise mid-simulation
            self._model = None
            return QPResult(None, False, 0, 0, f"daqp error: {exc}")


class ProxsuiteBackend(QPBackend):
    """ProxQP (proxsuite, dense), warm-started from its previous result.

    ProxQP is an augmented-Lagrangian method and does not converge reliably with the
    exact-penalty weight of the slack (a multiplier near 1e9). So it solves in two
    phases: first with the slack fixed at 0 (the hard-constrained QP, which is the
    answer whenever it is feasible); only if that is primal infeasible, with the slack
    free, its penalty lowered to ``phase2_penalty`` if the exact weight does not
    converge. Bounds beyond +-1e20 are passed as +-1e20.
    """

    name = "proxsuite"

    def __init__(self, qp: CondensedQP, g: np.ndarray, max_iter: int = 1000, eps_abs: float = 1e-9,
                 phase2_penalty: float = 1e5):
        super().__init__(qp, g, max_iter)
        self.eps_abs = eps_abs
        self.phase2_penalty = phase2_penalty
        self._qps: dict = {}
        n = qp.horizon.n_steps
        self._c = np.vstack([np.eye(n + 1), self.g])

    def _run(self, key, q, l, u):
        import proxsuite

        dense = proxsuite.proxqp.dense
        qp = self._qps.get(key)
        if qp is None:
            qp = dense.QP(self._c.shape[1], 0, self._c.shape[0])
            qp.settings.eps_abs = self.eps_abs
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = self.max_iter
            qp.settings.verbose = False
            # its infeasibility test fires falsely on these QPs near convergence: tighten it
            qp.settings.eps_primal_inf = 1e-14
            qp.settings.eps_dual_inf = 1e-14
            if key == "soft":  # the exact-penalty phase converges quickly or not at all
                qp.settings.max_iter = min(self.max_iter, 200)
                qp.settings.max_iter_in = 200
            qp.init(np.array(self.qp.hessian), q, None, None, self._c, l, u)
            self._qps[key] = qp
        else:
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp.update(g=q, l=l, u=u)
        qp.solve()
        res = qp.results
        x = np.array(res.x, dtype=float)
        status = res.info.status
        ok = status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED and bool(np.all(np.isfinite(x)))
        if not ok:
            self._qps.pop(key, None)  # restart cold next time
        return ok, x, res, status

    def solve(self, q, lower, upper, start=None):
        try:
            n = self.qp.horizon.n_steps
            l = np.maximum(lower, -1e20)
            u = np.minimum(upper, 1e20)
            u1 = u.copy()
            u1[n] = 0.0  # phase 1: no slack
            q1 = q.copy()
            q1[n] = 0.0
            ok, x, res, status = self._run("hard", q1, l, u1)
            iters = int(res.info.iter)
            if not ok:
                ok, x, res, status = self._run("soft", q, l, u)
                iters += int(res.info.iter)
                if not ok:
                    q2 = q.copy()
                    q2[n] = min(q[n], self.phase2_penalty)
                    ok, x, res, status = self._run("soft-weak", q2, l, u)
                    iters += int(res.info.iter)
            zi = np.array(res.z, dtype=float)
            return QPResult(x if ok else None, ok, iters, int(np.count_nonzero(np.abs(zi) > 1e-9)), str(status),
                            zi if ok else None)
        except Exception as exc:
            self._qps = {}
            return QPResult(None, False, 0, 0, f"proxsuite error: {exc}")


class QpsolversBackend(QPBackend):
    """Any backend of the qpsolvers package (cold, rebuilt every call: for cross-checks)."""

    def __init__(self, qp: CondensedQP, g: np.ndarray, solver: str, max_iter: int = 1000):
        super().__init__(qp, g, max_iter)
        self.solver = solver
        self.name = f"qpsolvers:{solver}"

    def solve(self, q, lower, upper, start=None):
        try:
            import qpsolvers

            n = self.qp.horizon.n_steps
            lo, hi = lower[: n + 1], upper[: n + 1]
            rlo, rhi = lower[n + 1:], upper[n + 1:]
            g = self.g
            # two-sided rate rows -> one-sided pairs; infinite bounds dropped
            rate = slice(3 * n, 4 * n - 1)
            rows_g = [g, -g[rate]]
            rows_h = [rhi, -rlo[rate]]
            G = np.vstack(rows_g)
            h = np.concatenate(rows_h)
            keep = h < INF / 2
            kwargs = {}
            if self.solver == "proxqp":
                kwargs = dict(eps_abs=1e-10, eps_rel=0.0, max_iter=self.max_iter)
            hi_box = np.where(hi >= INF / 2, np.inf, hi)
            x = qpsolvers.solve_qp(np.array(self.qp.hessian), q, G[keep], h[keep], lb=lo, ub=hi_box,
                                   solver=self.solver, **kwargs)
            ok = x is not None and bool(np.all(np.isfinite(x)))
            return QPResult(np.asarray(x, float) if ok else None, ok, 0, 0, "ok" if ok else "failed")
        except Exception as exc:
            return QPResult(None, False, 0, 0, f"{self.name} error: {exc}")


def make_backend(name: str, qp: CondensedQP, g: np.ndarray, max_iter: int = 1000) -> QPBackend:
    """Backend by name: ``"daqp"`` (default), ``"proxsuite"`` or ``"qpsolvers:<solver>"``;
    ``g`` is the driver's constraint matrix (:meth:`Horizon.constraint_matrix`)."""
    if name == "daqp":
        return DaqpBackend(qp, g, max_iter)
    if name == "proxsuite":
        return ProxsuiteBackend(qp, g, max_iter)
    if name.startswith("qpsolvers:"):
        return QpsolversBackend(qp, g, name.split(":", 1)[1], max_iter)
    raise ValueError(f"unknown QP backend {name!r}; use 'daqp', 'proxsuite' or 'qpsolvers:<solver>'")


BACKENDS = ("daqp", "proxsuite", "qpsolvers:<solver>")
