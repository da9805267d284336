"""Compiled per-step kernel of the MPC driver: input checks, targets, modes, bounds and
the unconstrained fast path, for a whole batch of drivers in one call.

Everything here is plain arithmetic over arrays so that numba compiles it once; the
logic it implements is documented in :mod:`acc_gym.drivers.mpc`. The bounds are
written in the layout the QP backends take (:mod:`acc_gym.drivers.qp`)::

    [ box u_0..u_{N-1} | box s | gap rows (N) | v>=0 rows (N) | v<=v_max rows (N) | rate rows (N-1) ]

so the kernel's feasibility check and the QP solvers read the same numbers.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.core import types
from numba.experimental import structref

from acc_gym.drivers.qp import K_TERM
from acc_gym.vehicle import accel_lower_core, accel_upper_core

_accel_upper = numba.njit(cache=True, error_model="numpy")(accel_upper_core)
_accel_lower = numba.njit(cache=True, error_model="numpy")(accel_lower_core)

INF = 1e30

# Modes (mirrored by acc_gym.drivers.mpc.Mode)
ACCELERATE, SAIL, BRAKE, EMERGENCY = 0, 1, 2, 3
# Targets
LEAD, STOP, CRUISE = 0, 1, 2
# Paths (how a step's input was obtained)
FAST, ACTIVE_SET, QP, HOLD, FALLBACK = 0, 1, 2, 3, 4
# Statistics columns
ST_STEPS, ST_FAST, ST_ACTIVE_SET, ST_QP, ST_HOLD, ST_FALLBACK, ST_SLACK, ST_EMERGENCY = range(8)
N_STATS = 8
MAX_ACTIVE = 64  # working-set size of the kernel's QP solver (>= the default horizon's 60 inputs)
DUAL_STEPS_PER_INPUT = 4  # the kernel's QP solver hands over after 4 N + 16 steps (traffic: <= 82, N = 60)
DEPENDENT = 1e-12  # a row whose Schur pivot is below this (relative) depends on the working set
N_SF = 10  # rows of the per-thread float scratch: u_unc (row 0, _one), then _active_set_solve's

EMERGENCY_MARGIN = 1.25  # emergency plans may brake 25 % harder than kinematically needed

# ---------------------------------------------------------------------------------------
# The kernel's records: named fields (numpy structured dtypes for what is per driver, one
# numba structref holding them and the shared settings), one argument of every kernel
# ---------------------------------------------------------------------------------------

_F = np.float64
# one driver's parameters (MPCDriverParams' names; v_max: its speed limit) and its vehicle's
# (acc_gym.vehicle.VEHICLE_COLUMNS)
DRIVER = np.dtype([
    ("a_max", _F), ("a_min", _F), ("a_req_sail", _F), ("a_sail", _F),  # [m/s^2]
    ("c_tg", _F),  # [s]
    ("x_min", _F),  # [m]
    ("v_desired", _F), ("v_max", _F),  # [m/s]
    ("jerk_max", _F), ("jerk_emergency", _F),  # [m/s^3]
    ("c_r0", _F), ("c_r1", _F), ("c_r2", _F), ("c_d", _F), ("area", _F), ("rho", _F), ("mass", _F),
    ("traction_accel", _F), ("power", _F), ("mu_brake", _F),
])
DRIVER_PARAMS = DRIVER.names[:10]  # the MPCDriverParams fields of a DRIVER record
DRIVER_VEHICLE = DRIVER.names[10:]
# one driver's state between steps
DRIVER_STATE = np.dtype([
    ("mode", np.int64),
    ("n_active", np.int64),  # the size of its working set (its codes: the record's ``active`` rows)
    ("idle", np.int64),  # 1: the row has no driver this step (skipped: output 0, path -1, no statistics)
    ("follow_pending", np.int64),  # 1: its follow QP (gains, H^-1 sums) is not installed yet
])
# one driver's step: what prepare found and the backend's solve reads
STEP = np.dtype([
    ("u0", _F),  # [m/s^2] the first input (nan: the backend must solve)
    ("path", np.int64),  # FAST, ACTIVE_SET, QP, HOLD, FALLBACK (-1: idle)
    ("target", np.int64),  # LEAD, STOP, CRUISE
    ("mode_pre", np.int64),  # the mode the bounds are of
    ("a_req", _F),  # [m/s^2] Eq. (10) over the real targets
    ("d_range", _F),  # [m/s] the most demanding target's range rate
    ("th0", _F), ("th1", _F),  # the law's parameters (distance [m] and speed [m/s] errors; u_prev is the third)
    ("lower0", _F), ("upper0", _F),  # [m/s^2] the first input's bounds
    ("viol", _F),  # the unconstrained plan's largest violation
    ("slack", _F),  # [m] the backend's slack
    ("iterations", np.int64),  # the backend's
    ("a_need", _F),  # [m/s^2] need_decel's
    ("floor0", _F),  # [m/s^2] the least first input in ACCELERATE (-inf: none)
])


class _Fields(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


@structref.register
class MPCType(_Fields):
    """numba's type of an :data:`MPC_FIELDS` record."""


class MPCRecord(structref.StructRefProxy):
    """A batch of MPC drivers as the kernels read it (fields: :data:`MPC_FIELDS`); Python
    keeps its own references to the same arrays (:class:`acc_gym.drivers.mpc.MPCDriver`)."""


structref.define_boxing(MPCType, MPCRecord)

_F1, _F2, _F3, _F4 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1], types.float64[:, :, :, ::1]
_I1, _I2 = types.int64[::1], types.int64[:, ::1]
# the settings, the scalars first (MPCSettings' names)
MPC_SETTINGS = (
    ("dt", types.float64),  # [s]
    ("zoh", types.bool_),  # the exact (zero-order hold) discretisation, else Euler
    ("hysteresis", types.float64),  # [m/s^2]
    ("creep_speed", types.float64), ("pull_away_speed", types.float64),  # [m/s]
    ("feas_tol", types.float64),
    ("use_lead_accel", types.bool_),
    ("slack_linear", types.float64),
    ("warm_active_set", types.bool_),
    ("coast_fade_speed", types.float64),  # [m/s]
    ("stop_short_margin", types.float64),  # [m]
    ("stop_speed", types.float64),  # [m/s]
    ("brake_slack_tol", types.float64),  # [m]
    ("follow_in_range", types.bool_),
)
MPC_FIELDS = MPC_SETTINGS + (
    ("drivers", types.Array(numba.from_dtype(DRIVER), 1, "C")),  # (n,)
    ("alpha", _F2), ("beta", _F2),  # (n, K_TERM) [m], [s] terminal chords (acc_gym.drivers.qp.terminal_chords)
    ("gain_f", _F3),  # (n, N, 3) the follow law's gains (theta = e_x, e_v, u_prev)
    ("gain_c", _F3),  # (n, N, 2) the cruise law's (e_v, u_prev)
    ("gain_lead", _F3),  # (n, N, N + 1) running row sums of the lead-acceleration gains ((n, 1, 1) unused)
    ("hinv_f", _F4), ("hinv_c", _F4),  # (n, 2, N, N) the follow and cruise H^-1 column sums by column
    ("lower", _F2), ("upper", _F2),  # (n, M) the bounds (layout above)
    ("plan", _F2),  # (n, N) [m/s^2]
    ("aseq", _F2),  # (n, N) [m/s^2] the lead's predicted accelerations
    ("state", types.Array(numba.from_dtype(DRIVER_STATE), 1, "C")),  # (n,)
    ("active", _I2),  # (n, MAX_ACTIVE) working sets, codes 2 c + side (side 1: upper bound)
    ("stats", _I2),  # (n, N_STATS) running counts, ST_* order
    ("out", types.Array(numba.from_dtype(STEP), 1, "C")),  # (n,)
    ("hard", _I1),  # (n,) prepare's list of rows (its second return value counts them)
    ("sf", _F2), ("sc", _I2),  # per-thread scratch (scratch())
)
MPC = MPCType(list(MPC_FIELDS))


@numba.njit(cache=True)
def make_mpc(s, a):  # pragma: no cover - compiled
    """An :data:`MPC` record of the settings ``s`` and arrays ``a``, in :data:`MPC_FIELDS` order."""
    r = structref.new(MPC)
    r.dt, r.zoh, r.hysteresis, r.creep_speed, r.pull_away_speed, r.feas_tol, r.use_lead_accel = (
        s[0], s[1], s[2], s[3], s[4], s[5], s[6])
    r.slack_linear, r.warm_active_set, r.coast_fade_speed, r.stop_short_margin, r.stop_speed = s[7], s[8], s[9], s[10], s[11]
    r.brake_slack_tol, r.follow_in_range = s[12], s[13]
    r.drivers, r.alpha, r.beta, r.gain_f, r.gain_c, r.gain_lead, r.hinv_f, r.hinv_c = (
        a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7])
    r.lower, r.upper, r.plan, r.aseq, r.state, r.active, r.stats, r.out, r.hard, r.sf, r.sc = (
        a[8], a[9], a[10], a[11], a[12], a[13], a[14], a[15], a[16], a[17], a[18])
    return r


def record(settings: tuple, arrays: dict) -> MPCRecord:
    """The :data:`MPC` record of ``settings`` (:data:`MPC_SETTINGS` order) and ``arrays`` by
    name: the one place the fields' order is read (the arrays are shared, not copied)."""
    out = []
    for name, t in MPC_FIELDS[len(MPC_SETTINGS):]:
        value = arrays[name]
        if not (isinstance(value, np.ndarray) and value.flags.c_contiguous and value.ndim == t.ndim):
            raise ValueError(f"MPC record field {name} must be a C-contiguous {t.ndim}-d array, got {value!r}")
        out.append(value)
    return make_mpc(tuple(settings), tuple(out))


@numba.njit(cache=True, error_model="numpy")
def vehicle_limits(p, v):
    """``(a_U(v), a_L(v))`` [m/s^2] of the vehicle of driver record ``p`` (a :data:`DRIVER`)."""
    a_up = _accel_upper(v, p.c_r0, p.c_r1, p.c_r2, p.c_d, p.area, p.rho, p.mass, p.traction_accel, p.power)
    a_lo = _accel_lower(v, p.c_r0, p.c_r1, p.c_r2, p.c_d, p.area, p.rho, p.mass, p.mu_brake)
    return a_up, a_lo


@numba.njit(cache=True, error_model="numpy")
def release_distance(p):
    """[m] How much further a stop at ``a_min`` rolls when the brake is released at the jerk
    bound before the standstill than braking at ``a_min`` to it: ``b^3 / (24 jerk_max^2)``,
    ``b = -a_min``."""
    b = -p.a_min
    return b * b * b / (24.0 * p.jerk_max * p.jerk_max)


@numba.njit(cache=True, error_model="numpy")
def only_chords_short(r, i, u, G, ends, v, gap, v_lead, stop_gap):
    """Whether driver ``i``'s plan ``u`` ``(N,)`` (no slack) keeps every bound row but the
    terminal chords (``(u, 0)``, then ``G (u, 0)``: ``G`` the general rows but the chords,
    against the driver's bounds ``r.lower[i]``, ``r.upper[i]``) within the braking plan's
    tolerance (``r.brake_slack_tol`` plus :func:`release_distance`), and the exact terminal
    condition: from the plan's end (``ends``: the last rows of the position and speed prediction
    matrices), braking at ``a_min`` (reached at ``jerk_max``) stops clear of the vehicle ahead
    (``gap``, ``v_lead``, its predicted accelerations ``r.aseq[i]``) and of the stop position
    ``stop_gap``, within that tolerance (:meth:`acc_gym.drivers.mpc.MPCDriver._only_chords_short`
    says why)."""
    n = u.shape[0]
    p = r.drivers[i]
    lower, upper, aseq = r.lower[i], r.upper[i], r.aseq[i]
    tol = r.brake_slack_tol + release_distance(p)
    tn = n * r.dt
    tp_n = ends[0]
    tv_n = ends[1]
    for k in range(n):
        if u[k] < lower[k] - tol or u[k] > upper[k] + tol:
            return False
    if 0.0 < lower[n] - tol or 0.0 > upper[n] + tol:  # the slack, 0
        return False
    for row in range(G.shape[0]):
        acc = 0.0
        for k in range(n):
            acc += G[row, k] * u[k]
        if acc < lower[n + 1 + row] - tol or acc > upper[n + 1 + row] + tol:
            return False
    b, jerk = -p.a_min, p.jerk_max
    x_min = p.x_min
    dp = 0.0
    dv = 0.0
    for k in range(n):
        dp += tp_n[k] * u[k]
        dv += tv_n[k] * u[k]
    v_n = v + dv
    if math.isfinite(gap):
        dpl = 0.0
        dvl = 0.0
        for k in range(n):
            dpl += tp_n[k] * aseq[k]
            dvl += tv_n[k] * aseq[k]
        room = gap + tn * v_lead + dpl - tn * v - dp - x_min
        w = max(v_n - (v_lead + dvl), 0.0)
        if room < w * w / (2.0 * b) + w * b / (2.0 * jerk) - tol:
            return False
    if math.isfinite(stop_gap):
        w = max(v_n, 0.0)
        if stop_gap - tn * v - dp < w * w / (2.0 * b) + w * b / (2.0 * jerk) - tol:
            return False
    return True


@numba.njit(cache=True, error_model="numpy")
def ramp_stop_distance(v, a0, step, a_brake, dt):
    """[m] Distance to a standstill from speed ``v`` [m/s] applying ``a0`` [m/s^2] this step,
    then moving the input by at most ``step`` [m/s^2] per step towards ``a_brake`` (< 0) and
    holding it (exact zero-order hold; inf if it never stops within 1000 steps)."""
    d = 0.0
    a = a0
    for _ in range(1000):
        if v + a * dt <= 0.0:
            return d + v * v / (-2.0 * a)
        d += v * dt + 0.5 * a * dt * dt
        v += a * dt
        a += min(max(a_brake - a, -step), step)
    return np.inf


@numba.njit(cache=True, error_model="numpy")
def need_decel(v, room, v_lead, a_l, stop_gap, extra):
    """[m/s^2] The constant deceleration that stops clear of every real target (<= 0):
    closing on a lead (``room`` = gap - x_min [m], inf without one), a braking lead
    (``a_l`` < 0, predicted to stop: the gap plus its own stopping distance) and a stop
    position ``stop_gap`` [m]; ``extra`` [m] is added to each room."""
    a_need = 0.0
    if room < np.inf and v > v_lead:
        a_need = min(a_need, -((v - v_lead) ** 2) / (2.0 * max(room + extra, 1e-3)))
    if room < np.inf and a_l < 0.0 and v > 0.0:
        a_need = min(a_need, -v * v / (2.0 * max(room + extra + v_lead * v_lead / (-2.0 * a_l), 1e-3)))
    if stop_gap < np.inf and v > 0.0:
        a_need = min(a_need, -v * v / (2.0 * max(stop_gap + extra, 1e-3)))
    return a_need


@numba.njit(cache=True, error_model="numpy")
def alarmed(r, v, gap, v_lead, a_lead, out):
    """``out[i]``: braking at its own ``a_min`` from now cannot keep driver ``i``'s ``x_min``
    behind the vehicle ahead as it is (:func:`need_decel`; the EMERGENCY screen's test on the
    true scene, which a driver with a perception sees at once)."""
    drivers = r.drivers
    for i in range(v.size):
        p = drivers[i]
        out[i] = need_decel(v[i], gap[i] - p.x_min, v_lead[i], a_lead[i], np.inf, 0.0) < p.a_min
    return out


@numba.njit(cache=True, error_model="numpy")
def required_decel(R, dR):
    """Eq. (10): ``sign(dR) dR^2 / (2R)``; an overlap (R <= 0) needs an infinite deceleration."""
    if R <= 0.0:
        return -np.inf
    s = 1.0 if dR > 0.0 else (-1.0 if dR < 0.0 else 0.0)
    return s * dR * dR / (2.0 * R)


@numba.njit(cache=True, error_model="numpy")
def coast_decel(r, i, v):
    """Driver ``i``'s deceleration with the pedals released at speed ``v`` [m/s^2]: its
    ``a_sail`` (engine drag and resistance) fading linearly to 0 below the coasting fade
    speed, so that coasting alone never brings a car to a standstill (near idle the
    drivetrain no longer brakes it; an automatic even creeps): only the brake stops a car."""
    fade = r.coast_fade_speed
    a_sail = r.drivers[i].a_sail
    if fade > 0.0 and v < fade:
        return a_sail * max(v, 0.0) / fade
    return a_sail


@numba.njit(cache=True, error_model="numpy")
def coast_distance(r, i, v):
    """Distance [m] a car at ``v`` rolls with the pedals released (:func:`coast_decel`) before
    it stops (above the fade speed) or all but stops (below it: the exponential tail)."""
    a_s = -r.drivers[i].a_sail
    if a_s <= 0.0:
        return np.inf
    fade = r.coast_fade_speed
    if v <= fade:
        return v * fade / a_s
    return (v * v - fade * fade) / (2.0 * a_s) + fade * fade / a_s


@numba.njit(cache=True, error_model="numpy")
def decel_label(u0, coast, tol):
    """The label of a decelerating mode's applied first input ``u0`` [m/s^2]: SAIL at the
    coasting deceleration ``coast`` (pedals released), BRAKE below it, and ACCELERATE above
    it (the throttle still on, ramping down at the jerk bound after an escalation)."""
    if u0 < coast - tol:
        return BRAKE
    if u0 > coast + tol:
        return ACCELERATE
    return SAIL


@numba.njit(cache=True, error_model="numpy")
def mode_limits(r, i, m, v, u_prev, a_need, floor0):
    """``(lower0, upper0, env_lo, env_hi, rate)`` of driver ``i`` in mode ``m``: the first
    input's range (mode, ramp and vehicle), the plan's range and its per-step change bound.

    ``a_need`` [m/s^2]: the constant deceleration that would stop the closing on the most
    demanding real target at ``x_min`` (0 if not closing); it sets the emergency range.
    ``floor0`` [m/s^2]: in ACCELERATE, the least first input (reached at the jerk bound):
    0 while rolling on at creep speed towards a stopped target (see ``_one``), else -inf."""
    dt = r.dt
    p = r.drivers[i]
    a_up, a_lo = vehicle_limits(p, v)
    a_max, a_min, a_sail = p.a_max, p.a_min, coast_decel(r, i, v)
    if m == EMERGENCY:
        # brake as hard as the situation needs (with a margin), not harder: the range
        # reaches down to 1.25 times the kinematically needed deceleration, at the
        # emergency jerk; a_need = -inf opens the vehicle's whole braking range
        env_lo = max(a_lo, min(a_min, EMERGENCY_MARGIN * a_need))
        rate = p.jerk_emergency * dt
        rate0 = rate
        mode_lo, mode_hi = env_lo, min(a_sail, a_up)
    else:
        env_lo = max(a_min, a_lo)
        rate = p.jerk_max * dt
        # recovering from braking harder than the driver's own limit: release at the emergency rate
        rate0 = p.jerk_emergency * dt if u_prev < a_min - 1e-9 else rate
        if m == ACCELERATE:
            mode_lo, mode_hi = max(a_sail, a_lo), min(a_max, a_up)
        else:
            mode_lo, mode_hi = env_lo, min(a_sail, a_up)
    env_hi = min(a_max, a_up)
    # ramp: move towards the mode's range at the rate limit, never jump
    lower0 = max(min(mode_lo, u_prev + rate0), u_prev - rate0)
    upper0 = min(max(mode_hi, u_prev - rate0), u_prev + rate0)
    if m == EMERGENCY:
        # no driver lets go of the brake when it realises it needs more: in an emergency the
        # first input keeps at least the current braking and at least the constant deceleration
        # a_need that stops clear (reached at the emergency jerk; the plan cannot postpone it),
        # unless that is harder than the emergency range itself, whose lower edge then rules
        upper0 = max(lower0, min(upper0, u_prev, a_need))
    elif m == ACCELERATE and floor0 > lower0:
        lower0 = max(lower0, min(floor0, u_prev + rate0, upper0))
    return lower0, upper0, env_lo, env_hi, rate


@numba.njit(cache=True, error_model="numpy")
def fill_bounds(r, i, m, v, u_prev, a_need, floor0):
    """Input box, speed and rate rows of driver ``i`` in mode ``m`` (into ``r.lower``,
    ``r.upper``); returns (lower0, upper0)."""
    lower, upper = r.lower, r.upper
    n = (lower.shape[1] - 2 * K_TERM) // 5
    dt = r.dt
    lower0, upper0, env_lo, env_hi, rate = mode_limits(r, i, m, v, u_prev, a_need, floor0)
    lower[i, 0] = lower0
    upper[i, 0] = upper0
    for k in range(1, n):
        lower[i, k] = env_lo
        upper[i, k] = env_hi
    lower[i, n] = 0.0
    upper[i, n] = INF
    r0 = n + 1
    # speed above v_max (e.g. v_desired lowered): the bound follows the slowest reachable speed
    slowest = 0.0
    ulow = lower0
    vmax = r.drivers[i].v_max - v
    for k in range(n):
        if k > 0:
            ulow = max(env_lo, ulow - rate)
        slowest += dt * ulow
        lower[i, r0 + n + k] = -INF
        upper[i, r0 + n + k] = v
        lower[i, r0 + 2 * n + k] = -INF
        upper[i, r0 + 2 * n + k] = max(vmax, slowest)
    for k in range(n - 1):
        lower[i, r0 + 3 * n + k] = -rate
        upper[i, r0 + 3 * n + k] = rate
    return lower0, upper0


@numba.njit(cache=True, error_model="numpy")
def fill_target_rows(r, i, v, gap, v_lead, stop_gap):
    """Gap rows (every real target, predicted at constant speed or with the lead's predicted
    deceleration ``r.aseq[i]``) and terminal stoppability rows of driver ``i``."""
    lower, upper, aseq = r.lower, r.upper, r.aseq[i]
    n = (lower.shape[1] - 2 * K_TERM) // 5
    dt = r.dt
    zoh = r.zoh
    p = r.drivers[i]
    alpha, beta = r.alpha[i], r.beta[i]
    x_min = p.x_min
    has_lead = gap < np.inf
    has_stop = stop_gap < np.inf
    r0 = n + 1
    dvl = 0.0
    dpl = 0.0
    for k in range(n):
        ub = INF
        tk = (k + 1) * dt
        if has_lead:
            a = aseq[k]
            dpl += dt * dvl + (0.5 * dt * dt * a if zoh else 0.0)
            dvl += dt * a
            ub = gap - x_min + tk * (v_lead - v) + dpl
        if has_stop:
            ub = min(ub, stop_gap - tk * v)
        lower[i, r0 + k] = -INF
        upper[i, r0 + k] = ub
    # terminal: dp_N + beta_j dv_N <= gap_N(free) - x_min - alpha_j - beta_j w_N(free)
    tn = n * dt
    for j in range(K_TERM):
        al = alpha[j]
        be = beta[j]
        cl = 5 * n + j
        cs = 5 * n + K_TERM + j
        lower[i, cl] = -INF
        lower[i, cs] = -INF
        upper[i, cl] = INF
        upper[i, cs] = INF
        if has_lead:
            upper[i, cl] = gap + tn * v_lead + dpl - tn * v - x_min - al - be * (v - (v_lead + dvl))
        if has_stop:
            upper[i, cs] = stop_gap - tn * v - al - be * v


@numba.njit(cache=True, error_model="numpy")
def _fast_violation(r, i, v, u, limits, gap, v_lead, stop_gap):
    """Largest violation of the plan ``u`` (s = 0), from the same quantities that
    :func:`fill_bounds` and :func:`fill_target_rows` write, without writing them (the
    unconstrained fast path never needs the bounds in memory); ``limits``:
    :func:`mode_limits`' ``(lower0, upper0, env_lo, env_hi, rate)``."""
    lower0, upper0, env_lo, env_hi, rate = limits
    n = u.shape[0]
    dt = r.dt
    half = 0.5 * dt * dt if r.zoh else 0.0
    p = r.drivers[i]
    aseq, alpha, beta = r.aseq[i], r.alpha[i], r.beta[i]
    x_min = p.x_min
    has_lead = gap < np.inf
    has_stop = stop_gap < np.inf
    vmax = p.v_max - v
    worst = max(lower0 - u[0], u[0] - upper0)
    dv = 0.0
    dp = 0.0
    dvl = 0.0
    dpl = 0.0
    slowest = 0.0
    ulow = lower0
    for k in range(n):
        z = u[k]
        if k > 0:
            worst = max(worst, env_lo - z, z - env_hi, abs(z - u[k - 1]) - rate)
            ulow = max(env_lo, ulow - rate)
        slowest += dt * ulow
        dp += dt * dv + half * z
        dv += dt * z
        tk = (k + 1) * dt
        if has_lead:
            a = aseq[k]
            dpl += dt * dvl + half * a
            dvl += dt * a
            worst = max(worst, dp - (gap - x_min + tk * (v_lead - v) + dpl))
        if has_stop:
            worst = max(worst, dp - (stop_gap - tk * v))
        worst = max(worst, -dv - v, dv - max(vmax, slowest))
    tn = n * dt
    for j in range(K_TERM):
        al = alpha[j]
        be = beta[j]
        if has_lead:
            worst = max(worst, dp + be * dv - (gap + tn * v_lead + dpl - tn * v - x_min - al - be * (v - (v_lead + dvl))))
        if has_stop:
            worst = max(worst, dp + be * dv - (stop_gap - tn * v - al - be * v))
    return worst


@numba.njit(cache=True, error_model="numpy")
def _check_inputs(obs, state):
    """0 if fine, else 1 + index of the offending field of ``obs`` (``v, u_prev, gap, v_lead,
    a_lead, stop_gap``; FIELDS in mpc.py); rows whose ``state`` is idle are not read (their
    values are nobody's input)."""
    v0, u_prev, gap, v_lead, a_lead, stop_gap = obs
    for i in range(v0.shape[0]):
        if state[i].idle != 0:
            continue
        if not (np.isfinite(v0[i]) and v0[i] >= 0.0):
            return 1
        if not np.isfinite(u_prev[i]):
            return 2
        if np.isnan(gap[i]) or gap[i] == -np.inf:
            return 3
        if not np.isfinite(v_lead[i]) or v_lead[i] < 0.0:
            return 4
        if not np.isfinite(a_lead[i]):
            return 5
        if np.isnan(stop_gap[i]) or stop_gap[i] == -np.inf:
            return 6
    return 0


# --------------------------------------------------------------------------------------
# Constraint rows as structured vectors (no dense G needed inside the kernel)
# Constraint index c in the bounds layout; kinds: 0 box, 1 gap, 2 v>=0, 3 v<=v_max, 4 rate,
# 5 slack box. An active constraint is stored as code = 2 c + side (side 1: upper bound).
# --------------------------------------------------------------------------------------

@numba.njit(cache=True)
def _kind(c, n):
    if c < n:
        return 0, c
    if c == n:
        return 5, 0
    r = c - n - 1
    if r < 3 * n:
        return 1 + r // n, r % n
    if r < 4 * n - 1:
        return 4, r - 3 * n
    t = r - (4 * n - 1)
    return 6 + t // K_TERM, t % K_TERM


@numba.njit(cache=True)
def _prefix(x, p0, p1):
    """Running sums ``p0[k] = sum_{j<=k} x_j`` and ``p1[k] = sum_{j<=k} j x_j``."""
    a0 = 0.0
    a1 = 0.0
    for j in range(x.shape[0]):
        a0 += x[j]
        a1 += j * x[j]
        p0[j] = a0
        p1[j] = a1


# The helpers called once per row or member take scalars only: numba passes an array argument
# with reference-count updates that cost about 0.1 us a call (measured: a row's product through
# array arguments 146 ns, from the values at its index 3 ns), which made these loops 10-50 times
# slower than their arithmetic. The callers read the values at the row's index.

@numba.njit(cache=True, inline="always")
def _at(code, n):
    """``(kind, k, k1, kb)`` of the active constraint ``code``: its kind and index, and the
    indices :func:`_row_value`'s ``x[k + 1]`` and ``beta[k]`` are read at (in range for
    every kind; used only by the rate and terminal rows)."""
    kind, k = _kind(code >> 1, n)
    return kind, k, (k + 1 if k + 1 < n else k), (k if kind >= 6 else 0)


@numba.njit(cache=True, inline="always")
def _row_value(kind, k, eh, xk, xk1, p0k, p1k, p0e, p1e, bk, dt, h):
    """``g_c . x`` for the row of constraint (kind, k), in O(1) from the prefix sums of ``x``
    (``p0[k] = sum_{j<=k} x_j``, ``p1[k] = sum_{j<=k} j x_j``), given the values at its
    index: ``x[k]``, ``x[k + 1]``, ``p0[k]``, ``p1[k]``, at the horizon's end ``e = N - 1``
    ``p0[e]``, ``p1[e]`` (``eh = e + h``), and the terminal row's slope ``beta[k]``.

    Position rows use ``sum_{j<=k} dt^2 (k - j + h) x_j = dt^2 ((k + h) p0[k] - p1[k])``
    (``h = 1/2`` for the exact discretisation, 0 for Euler)."""
    if kind == 0:
        return xk
    if kind == 4:
        return xk1 - xk
    if kind >= 6:  # terminal row k: position plus beta_k times speed at the horizon's end
        return dt * dt * (eh * p0e - p1e) + bk * dt * p0e
    if kind == 1:
        return dt * dt * ((k + h) * p0k - p1k)
    if kind == 2:
        return -dt * p0k
    return dt * p0k


@numba.njit(cache=True, inline="always")
def _signed(code, d):
    """``n_a . x`` of the active constraint ``code`` written as ``n_a . u >= b_a`` from its
    row's ``g_c . x`` = ``d``: the row on a lower bound, minus it on an upper bound."""
    return -d if (code & 1) else d


@numba.njit(cache=True, inline="always")
def _bound(code, lo_c, up_c):
    """``b_a`` of ``n_a . u >= b_a`` from constraint ``code``'s bounds: the lower bound, or
    minus the upper bound."""
    return -up_c if (code & 1) else lo_c


@numba.njit(cache=True)
def _row_hinv(kind, k, hc, out, dt, zoh, beta):
    """``out = H^-1 g_c`` in O(N) from the column sums laid out by column
    (:attr:`CondensedQP.hinv_columns <acc_gym.drivers.qp.CondensedQP.hinv_columns>`):
    ``hc[0][k, :] = sum_{j<=k} H^-1[:, j]`` and ``hc[1][k, :] = sum_{j<=k} j H^-1[:, j]``."""
    c0 = hc[0]
    c1 = hc[1]
    n = out.shape[0]
    h = 0.5 if zoh else 0.0
    if kind == 0:
        for r in range(n):
            out[r] = c0[k, r] - (c0[k - 1, r] if k > 0 else 0.0)
    elif kind == 4:
        for r in range(n):
            out[r] = (c0[k + 1, r] - c0[k, r]) - (c0[k, r] - (c0[k - 1, r] if k > 0 else 0.0))
    elif kind >= 6:
        e = n - 1
        for r in range(n):
            out[r] = dt * dt * ((e + h) * c0[e, r] - c1[e, r]) + beta[k] * dt * c0[e, r]
    elif kind == 1:
        for r in range(n):
            out[r] = dt * dt * ((k + h) * c0[k, r] - c1[k, r])
    else:
        sgn = -dt if kind == 2 else dt
        for r in range(n):
            out[r] = sgn * c0[k, r]


@numba.njit(cache=True)
def _scan(u, lo, up, rows, members, n_members):
    """Largest violation of the plan ``u`` (s = 0) and its code (2c + side); the constraints
    of the working set (``members[:n_members]``, codes) ignored; ``rows`` the rows' geometry
    ``(n, dt, zoh, beta)`` (:func:`_active_set_solve`).

    Straight-line over the rows: the box and rate rows are two-sided, the gap, speed and
    terminal rows one-sided (upper bounds only). Each row is compared in place (a helper
    taking the array of skipped rows cost more than the scan's arithmetic)."""
    n, dt, zoh, beta = rows
    skip = np.zeros(lo.shape[0], dtype=np.bool_)
    for q in range(n_members):
        skip[members[q] >> 1] = True
    worst = -np.inf
    code = -1
    dv = 0.0
    dp = 0.0
    r0 = n + 1
    half = 0.5 * dt * dt if zoh else 0.0
    for k in range(n):
        z = u[k]
        dp += dt * dv + half * z
        dv += dt * z
        if not skip[k]:
            d = z - up[k]
            if d > worst:
                worst, code = d, 2 * k + 1
            d = lo[k] - z
            if d > worst:
                worst, code = d, 2 * k
        c = r0 + k
        d = dp - up[c]
        if d > worst and not skip[c]:
            worst, code = d, 2 * c + 1
        d = -dv - up[c + n]
        if d > worst and not skip[c + n]:
            worst, code = d, 2 * (c + n) + 1
        d = dv - up[c + 2 * n]
        if d > worst and not skip[c + 2 * n]:
            worst, code = d, 2 * (c + 2 * n) + 1
        if k < n - 1:
            c += 3 * n
            du = u[k + 1] - z
            if not skip[c]:
                d = du - up[c]
                if d > worst:
                    worst, code = d, 2 * c + 1
                d = lo[c] - du
                if d > worst:
                    worst, code = d, 2 * c
    for j in range(2 * K_TERM):
        c = 5 * n + j
        d = dp + beta[j % K_TERM] * dv - up[c]
        if d > worst and not skip[c]:
            worst, code = d, 2 * c + 1
    return worst, code


@numba.njit(cache=True)
def _load(code, hc, rows, w, p0, p1):
    """``w = H^-1 n_a`` of the constraint ``code`` (O(N)), and its running sums."""
    n, dt, zoh, beta = rows
    kind, k = _kind(code >> 1, n)
    _row_hinv(kind, k, hc, w, dt, zoh, beta)
    if code & 1:
        for r in range(n):
            w[r] = -w[r]
    _prefix(w, p0, p1)


@numba.njit(cache=True)
def _forward(L, m, d, spp, l):
    """``l = L^-1 d`` over the first ``m`` rows of the Cholesky factor ``L`` of the working
    set's ``S = N' H^-1 N``; returns the pivot ``spp - l . l`` a new row ``d`` (with diagonal
    entry ``spp``) would add: ``n_p' z``, 0 when the row depends on the working set."""
    piv = spp
    for a in range(m):
        acc = d[a]
        for t in range(a):
            acc -= L[a, t] * l[t]
        l[a] = acc / L[a, a]
        piv -= l[a] * l[a]
    return piv


@numba.njit(cache=True)
def _backward(L, m, l, r):
    """``r = L^-T l`` (with :func:`_forward`: ``r = S^-1 d``)."""
    for a in range(m - 1, -1, -1):
        acc = l[a]
        for t in range(a + 1, m):
            acc -= L[t, a] * r[t]
        r[a] = acc / L[a, a]


@numba.njit(cache=True)
def _drop(j, m, ws, n):
    """Member ``j`` leaves the working set ``ws`` (:func:`_active_set_solve`'s): the members
    after it move up one place (their rows of ``H^-1 N``, rows and columns of ``S``,
    multipliers) and the Cholesky factor is recomputed from row and column ``j`` on (the
    entries left of column ``j`` belong to the same members as before: the same numbers).
    Returns the new size."""
    codes, lam, wbuf, p0buf, p1buf, sbuf, lbuf = ws
    for a in range(j, m - 1):
        codes[a] = codes[a + 1]
        lam[a] = lam[a + 1]
        for r in range(n):
            wbuf[a, r] = wbuf[a + 1, r]
            p0buf[a, r] = p0buf[a + 1, r]
            p1buf[a, r] = p1buf[a + 1, r]
        for b in range(m):
            sbuf[a, b] = sbuf[a + 1, b]
    m -= 1
    for a in range(m):
        for b in range(j, m):
            sbuf[a, b] = sbuf[a, b + 1]
    for a in range(j, m):
        for b in range(j):
            lbuf[a, b] = lbuf[a + 1, b]
    for a in range(j, m):
        for b in range(j, a + 1):
            acc = sbuf[a, b]
            for t in range(b):
                acc -= lbuf[a, t] * lbuf[b, t]
            if a == b:
                lbuf[a, a] = np.sqrt(max(acc, 1e-300))
            else:
                lbuf[a, b] = acc / lbuf[b, b]
    return m


@numba.njit(cache=True)
def _join(m, code, lam_p, row, ws, n):
    """Constraint ``code`` joins the working set ``ws`` at position ``m`` with multiplier
    ``lam_p``; ``row``: its ``H^-1 n`` and running sums, Schur row, diagonal entry, factor row
    and pivot ``(w, p0, p1, d, spp, l, piv)``, already computed. Returns the new size."""
    codes, lam, wbuf, p0buf, p1buf, sbuf, lbuf = ws
    w, p0, p1, d, spp, l, piv = row
    codes[m] = code
    lam[m] = lam_p
    for r in range(n):
        wbuf[m, r] = w[r]
        p0buf[m, r] = p0[r]
        p1buf[m, r] = p1[r]
    for b in range(m):
        sbuf[m, b] = d[b]
        sbuf[b, m] = d[b]
        lbuf[m, b] = l[b]
    sbuf[m, m] = spp
    lbuf[m, m] = np.sqrt(piv)
    return m + 1


@numba.njit(cache=True)
def _equality_optimum(u_unc, u_p0, u_p1, lo, up, m, rows, ws, d, l):
    """``lam = S^-1 (b_A - N_A' u_unc)``: the multipliers of the plan that meets the working
    set's rows with equality (``u_p0``, ``u_p1``: the running sums of ``u_unc``; ``d``,
    ``l``: work vectors)."""
    n, dt, zoh, beta = rows
    codes, lam, lbuf = ws[0], ws[1], ws[6]
    h = 0.5 if zoh else 0.0
    e = n - 1
    eh = e + h
    for a in range(m):
        ca = codes[a]
        kind, k, k1, kb = _at(ca, n)
        g = _row_value(kind, k, eh, u_unc[k], u_unc[k1], u_p0[k], u_p1[k], u_p0[e], u_p1[e], beta[kb], dt, h)
        d[a] = _bound(ca, lo[ca >> 1], up[ca >> 1]) - _signed(ca, g)
    _forward(lbuf, m, d, 0.0, l)
    _backward(lbuf, m, l, lam)


@numba.njit(cache=True)
def _plan(u_unc, lam, wbuf, m, out):
    """``out = u_unc + H^-1 N_A lam``."""
    for k in range(out.shape[0]):
        acc = u_unc[k]
        for a in range(m):
            acc += lam[a] * wbuf[a, k]
        out[k] = acc


@numba.njit(cache=True)
def _active_set_solve(u_unc, hc, lo, up, m0, rows, tol, out, scratch):
    """Exact QP optimum with ``s = 0`` by a dual active-set method (Goldfarb and Idnani,
    1983) warm-started from a working set, verified by the KKT conditions.

    Every constraint is written ``n_a . u >= b_a`` (an upper bound negated). The working set
    ``A`` keeps its ``H^-1 n_a``, ``S = N_A' H^-1 N_A`` and the Cholesky factor of ``S``
    (a row appended in O(|A|^2) when a constraint joins; recomputed from the leaver's place on
    when one leaves).

    1. Warm start: the members of ``codes[:m0]`` whose rows are independent of those before
       them; the multipliers of the plan that holds them with equality are ``S^-1 (b_A -
       N_A' u_unc)``; while one is negative the most negative member leaves. The plan
       ``u = u_unc + H^-1 N_A lam`` is then dual feasible (multipliers >= 0).
    2. Dual steps: while a row is violated by more than ``feas``, take the most violated,
       ``p``, and raise its multiplier: the plan moves along ``z = H^-1 n_p - H^-1 N_A r``
       (``r = S^-1 N_A' H^-1 n_p``) and the members' multipliers by ``-r`` per unit, as
       far as ``p``'s row is met (``p`` joins) or a member's multiplier reaches 0 first
       (that member leaves, and the step goes on). A row dependent on the working set
       (``n_p' z = 0``) moves only the multipliers. No step that leaves a multiplier < 0.

    The answer is checked as the QP's optimum by the KKT conditions of the final working
    set alone: its multipliers and plan computed afresh (not the sum of the steps), no
    multiplier below ``-1e-9`` of the largest, no row violated by more than ``feas``, and
    the state rows' multipliers summing below the slack's exact-penalty weight (then ``s =
    0`` is optimal too); the plan returned is that fresh one. Returns ``(ok, m)``: whether
    it is, and the size of the final working set (in ``codes``; a warm start for the backend
    if not ok): not ok when the QP needs the slack, is infeasible without it, the working set
    would outgrow ``wbuf``, or after ``4 N + 16`` steps (``DUAL_STEPS_PER_INPUT``; a
    degenerate optimum -- more active rows than inputs, a braking ramp held by both its box
    and its rate rows -- started far from its working set can take longer).

    Arguments: ``u_unc`` (N,) the unconstrained plan; ``hc`` the law's H^-1 column sums
    (:func:`_row_hinv`); ``lo``, ``up`` the bounds; ``m0`` the warm start's size; ``rows`` the
    rows' geometry ``(N, dt, zoh, beta)`` (``beta``: the terminal chords' slopes); ``tol``:
    ``(feas, slack_linear)``; ``out`` (N,) the plan; ``scratch``: the thread's ``(sf, sw, ss,
    codes)`` (:func:`prepare`'s layout; ``codes[:m0]`` the warm start, on return the final
    working set). The working set ``ws`` is ``(codes, lam, wbuf, p0buf, p1buf, sbuf, lbuf)``:
    codes, multipliers, rows of ``H^-1 N`` and their running sums, ``S`` and its factor.
    """
    n, dt, zoh, beta = rows
    feas, slack_lin = tol
    sf, sw, ss, codes = scratch
    wbuf, p0buf, p1buf, sbuf, lbuf = sw[0], sw[1], sw[2], ss[0], ss[1]
    u_p0 = sf[1, :n]  # running sums of u_unc, then of the plan
    u_p1 = sf[2, :n]
    lam = sf[3]  # the members' multipliers
    w = sf[4, :n]  # the violated row's H^-1 n and its running sums
    w0 = sf[5, :n]
    w1 = sf[6, :n]
    d = sf[7]  # a Schur column N_A' H^-1 n (or a right-hand side), its L^-1 image, and S^-1 of it
    l = sf[8]
    r = sf[9]
    ws = (codes, lam, wbuf, p0buf, p1buf, sbuf, lbuf)
    cap = wbuf.shape[0]
    h = 0.5 if zoh else 0.0
    e = n - 1
    eh = e + h
    _prefix(u_unc, u_p0, u_p1)
    # --- 1. warm start
    m = 0
    for a in range(m0):
        code = codes[a]
        if _kind(code >> 1, n)[0] == 5 or m >= cap or abs(_bound(code, lo[code >> 1], up[code >> 1])) >= 0.5 * INF:
            continue  # the slack's bound, no room, or a row without that bound this step
        _load(code, hc, rows, wbuf[m], p0buf[m], p1buf[m])
        for b in range(m):
            cb = codes[b]
            kind, k, k1, kb = _at(cb, n)
            d[b] = _signed(cb, _row_value(kind, k, eh, wbuf[m, k], wbuf[m, k1], p0buf[m, k], p1buf[m, k], p0buf[m, e],
                                          p1buf[m, e], beta[kb], dt, h))
        kind, k, k1, kb = _at(code, n)
        spp = _signed(code, _row_value(kind, k, eh, wbuf[m, k], wbuf[m, k1], p0buf[m, k], p1buf[m, k], p0buf[m, e],
                                       p1buf[m, e], beta[kb], dt, h))
        piv = _forward(lbuf, m, d, spp, l)
        if piv <= DEPENDENT * max(1.0, spp):
            continue  # its row depends on the members before it
        m = _join(m, code, 0.0, (wbuf[m], p0buf[m], p1buf[m], d, spp, l, piv), ws, n)
    while m > 0:
        _equality_optimum(u_unc, u_p0, u_p1, lo, up, m, rows, ws, d, l)
        j = -1
        worst = 0.0
        for a in range(m):
            if lam[a] < worst:
                worst, j = lam[a], a
        if j < 0:
            break
        m = _drop(j, m, ws, n)
    _plan(u_unc, lam, wbuf, m, out)
    # --- 2. dual steps
    steps = 0
    _prefix(out, u_p0, u_p1)  # the plan's running sums (the violated row's distance), kept with every move
    while True:
        viol, code = _scan(out, lo, up, rows, codes, m)
        if viol <= feas:
            if steps > 0:  # (without dual steps, the plan and multipliers are the warm start's fresh ones)
                _prefix(u_unc, u_p0, u_p1)
                _equality_optimum(u_unc, u_p0, u_p1, lo, up, m, rows, ws, d, l)
                _plan(u_unc, lam, wbuf, m, out)
                viol, code = _scan(out, lo, up, rows, codes, m)
            big = 0.0
            low = 0.0
            state = 0.0
            for a in range(m):
                big = max(big, abs(lam[a]))
                low = min(low, lam[a])
                kind = _kind(codes[a] >> 1, n)[0]
                if kind != 0 and kind != 4:
                    state += max(lam[a], 0.0)
            return viol <= feas and low >= -1e-9 * (1.0 + big) and state < slack_lin, m
        if m >= cap:
            return False, m
        _load(code, hc, rows, w, w0, w1)
        kind, k, k1, kb = _at(code, n)
        spp = _signed(code, _row_value(kind, k, eh, w[k], w[k1], w0[k], w1[k], w0[e], w1[e], beta[kb], dt, h))
        bp = _bound(code, lo[code >> 1], up[code >> 1])
        p_kind, p_k, p_k1, p_kb = kind, k, k1, kb  # the violated row's indices (its distance below)
        lam_p = 0.0
        while True:
            steps += 1
            if steps > DUAL_STEPS_PER_INPUT * n + 16:
                return False, m
            for b in range(m):
                cb = codes[b]
                kind, k, k1, kb = _at(cb, n)
                d[b] = _signed(cb, _row_value(kind, k, eh, w[k], w[k1], w0[k], w1[k], w0[e], w1[e], beta[kb], dt, h))
            piv = _forward(lbuf, m, d, spp, l)
            _backward(lbuf, m, l, r)
            t1 = np.inf  # dual step: the first member whose multiplier would reach 0
            j = -1
            for a in range(m):
                if r[a] > 1e-12:
                    t = lam[a] / r[a]
                    if t < t1:
                        t1, j = t, a
            dependent = piv <= DEPENDENT * max(1.0, spp)
            if dependent:
                t2 = np.inf
            else:
                dist = _signed(code, _row_value(p_kind, p_k, eh, out[p_k], out[p_k1], u_p0[p_k], u_p1[p_k], u_p0[e],
                                                u_p1[e], beta[p_kb], dt, h))
                t2 = -(dist - bp) / piv
            t = min(t1, t2)
            if t == np.inf:
                return False, m  # infeasible without the slack
            t = max(t, 0.0)
            if not dependent:
                for k in range(n):
                    acc = w[k]
                    for a in range(m):
                        acc -= r[a] * wbuf[a, k]
                    out[k] += t * acc
                _prefix(out, u_p0, u_p1)
            for a in range(m):
                lam[a] = max(lam[a] - t * r[a], 0.0)
            lam_p += t
            if t2 <= t1:
                m = _join(m, code, lam_p, (w, w0, w1, d, spp, l, piv), ws, n)
                break
            m = _drop(j, m, ws, n)


@numba.njit(cache=True)
def _shift_active(codes, m, n):
    """Receding horizon: constraints of step k become those of step k-1 (input 0 stays)."""
    out = 0
    for a in range(m):
        c = codes[a] >> 1
        side = codes[a] & 1
        kind, k = _kind(c, n)
        if kind == 5:
            continue
        if kind == 0:
            nk = 0 if k == 0 else k - 1
            nc = nk
        elif kind >= 6:
            nc = c
        else:
            if k == 0:
                continue
            nc = c - 1
        dup = False
        for b in range(out):
            if codes[b] >> 1 == nc:
                dup = True
                break
        if not dup:
            codes[out] = 2 * nc + side
            out += 1
    return out


@numba.njit(cache=True)
def _lead_term(c_ks, c_next, a_l, ks, a_part, n):
    """``sum_j gain_lead[k, j] aseq_j`` from the running row sums ``cum[i, k, j] = sum_{j'<j}
    gain_lead[k, j']`` at ``j = ks`` (``c_ks``) and ``j = ks + 1`` (``c_next``, read only if
    ``ks < n``): scalars, as the kernel's per-row helpers take (see :func:`_at`)."""
    out = a_l * c_ks
    if ks < n:
        out += a_part * (c_next - c_ks)
    return out


@numba.njit(cache=True, error_model="numpy", inline="always")
def _one(i, r, obs, scratch):
    """Driver ``i``'s step (``r`` the :data:`MPC` record, ``obs`` :func:`prepare`'s, ``scratch``
    the thread's ``(sf, sw, ss, codes)``); returns its path (QP: the backend must solve it)."""
    v0, u_prev, gap, v_lead, a_lead, stop_gap = obs
    sf, sw, ss, codes = scratch
    p = r.drivers[i]
    st = r.state[i]
    o = r.out[i]
    plan, aseq, lower, upper = r.plan, r.aseq, r.lower, r.upper
    gain_f, gain_c, gain_lead = r.gain_f, r.gain_c, r.gain_lead
    n = plan.shape[1]
    u_unc = sf[0, :n]
    dt = r.dt
    zoh = r.zoh
    use_acc = r.use_lead_accel
    warm = r.warm_active_set
    stats = r.stats[i]
    stats[ST_STEPS] += 1
    v = v0[i]
    up = u_prev[i]
    c = p.c_tg
    x_min = p.x_min
    has_lead = gap[i] < np.inf
    has_stop = stop_gap[i] < np.inf
    # predicted lead accelerations: its measured *deceleration* held until it would stop
    # (then the partial step that stops it, then 0); an accelerating lead is predicted at
    # constant speed (conservative: predicted positions never run ahead of a braking or
    # cruising lead). Zero unless enabled. The sequence is (a, ..., a, a_part, 0, ...):
    # ks full steps; the gains use running row sums.
    ks = 0
    a_part = 0.0
    a_l = min(a_lead[i], 0.0) if (has_lead and use_acc) else 0.0
    if a_l != 0.0:
        vl = v_lead[i]
        ks = n
        for k in range(n):
            if vl + a_l * dt < 0.0:
                ks = k
                a_part = -vl / dt
                break
            vl += a_l * dt
    for k in range(n):
        aseq[i, k] = a_l if k < ks else (a_part if k == ks else 0.0)
    # --- required deceleration over the real targets (Eq. 10); R: gap, or distance to the stop
    areq = np.inf
    dR = np.inf
    v_t = np.inf  # speed of the most demanding real target
    if has_lead:
        a = required_decel(gap[i], v_lead[i] - v)
        if a < areq:
            areq, dR, v_t = a, v_lead[i] - v, v_lead[i]
    if has_stop:
        a = required_decel(stop_gap[i], -v)
        if a < areq:
            areq, dR, v_t = a, -v, 0.0
    # --- mode logic (before solving); decelerating modes are 'BRAKE' until labelled
    m = st.mode
    # a (nearly) stopped target: where the driver must stop (room [m] to it) and whether
    # coasting would leave it short of there by more than the stop-short margin
    creep = r.creep_speed
    room = np.inf
    if has_lead:
        room = gap[i] - x_min
    if has_stop:
        room = min(room, stop_gap[i])
    short = v_t <= creep and room - coast_distance(r, i, v) > r.stop_short_margin
    if m == ACCELERATE:
        # to the decelerating modes when the required deceleration reaches the driver's
        # sailing threshold (Eq. 10), or, creeping towards a (nearly) stopped target, once
        # coasting would carry it there (within the stop-short margin): it lifts off
        if areq <= p.a_req_sail or (v <= creep and v_t <= r.pull_away_speed and not short):
            m = BRAKE
    elif m == SAIL or m == BRAKE:
        # back to the throttle only once the brake is released (the applied acceleration is
        # at least the coasting one; until then the upper bound ramps the release), and only
        # if the target really pulls away, or, sailing above creep speed, behind a target that
        # itself moves faster than creep speed, or if coasting would leave the driver short of
        # a (nearly) stopped target by more than the stop-short margin (a driver rolls on
        # towards the queue instead of stopping short of it on engine drag)
        released = up >= coast_decel(r, i, v) - 1e-9
        if released and ((areq > p.a_req_sail + r.hysteresis and (dR > r.pull_away_speed or (m == SAIL and v > creep and v_t > creep)))
                         or short):
            m = ACCELERATE
        else:
            m = BRAKE
    # EMERGENCY screen (kinematic, against every real target predicted at constant speed
    # like the QP's gap rows): if even braking at a_min at once cannot keep x_min, the
    # comfortable QP is infeasible, so go straight to EMERGENCY; an emergency ends only
    # when braking at 80 % of a_min would do (hysteresis), then the QP decides.
    a_need = need_decel(v, gap[i] - x_min, v_lead[i], a_l, stop_gap[i], 0.0)
    o.a_need = a_need
    # a braking driver is screened with a braking plan's tolerance (MPCSettings.brake_slack_tol
    # plus the jerk-bounded release before a standstill; see MPCDriver._only_chords_short):
    # the plans it accepts may end that far inside x_min, and carrying one out is no emergency
    # (the extra room only makes the need milder: recomputed only when the plain need escalates)
    a_screen = a_need
    if m == BRAKE and a_need < p.a_min:
        a_screen = need_decel(v, gap[i] - x_min, v_lead[i], a_l, stop_gap[i], r.brake_slack_tol + release_distance(p))
    if a_screen < p.a_min * (0.8 if m == EMERGENCY else 1.0):
        m = EMERGENCY
    elif m == EMERGENCY:
        m = BRAKE
    # --- controlling law: the nearer real target's; in ACCELERATE the free-driving law
    # instead if it asks for less acceleration (as in ACC and IDM; compared on the
    # unconstrained first input). Decelerating, the driver deals with its target.
    target = CRUISE
    th0, th1 = 0.0, p.v_desired - v
    best = gain_c[i, 0, 0] * th1 + gain_c[i, 0, 1] * up
    t_real, t0, t1 = -1, 0.0, 0.0
    if has_lead:
        t_real, t0, t1 = LEAD, gap[i] - x_min - c * v, v_lead[i] - v
    if has_stop and (not has_lead or stop_gap[i] + x_min < gap[i]):
        t_real, t0, t1 = STOP, stop_gap[i] - c * v, -v
    if t_real >= 0:
        u0 = gain_f[i, 0, 0] * t0 + gain_f[i, 0, 1] * t1 + gain_f[i, 0, 2] * up
        if t_real == LEAD and a_l != 0.0:
            u0 += _lead_term(gain_lead[i, 0, ks], gain_lead[i, 0, min(ks + 1, n)], a_l, ks, a_part, n)
        # creeping towards a (nearly) stopped vehicle or a stop position, the driver deals
        # with it, not with its desired speed (the free-driving law, held back by the gap
        # constraint, would coast it to a stop short of the queue)
        queue = t_real == STOP or v_lead[i] <= r.pull_away_speed
        if u0 <= best or m != ACCELERATE or queue:
            target, th0, th1 = t_real, t0, t1
    # rolling on towards a stopped target at creep speed (coasting would stop it short), the
    # driver no longer slows down: a weak distance weight would otherwise approach the queue
    # exponentially, never arriving; it rolls on until coasting reaches the stopping point
    floor0 = 0.0 if (m == ACCELERATE and short and v <= creep) else -np.inf
    o.floor0 = floor0
    lower0, upper0, env_lo, env_hi, rate = mode_limits(r, i, m, v, up, a_need, floor0)
    o.target = target
    o.a_req = areq
    o.d_range = dR
    o.th0 = th0
    o.th1 = th1
    o.lower0 = lower0
    o.upper0 = upper0
    o.mode_pre = m
    o.slack = 0.0
    o.iterations = 0
    # --- the final stop: decelerating at walking pace towards a stopped target that coasting
    # would not leave it short of, the driver brakes to a standstill, no QP: within this step
    # if that needs no more than one jerk step of braking (so that the deceleration's drop to
    # 0 at standstill is within the jerk bound too), else at that braking (at most a_min),
    # reached at the jerk bound; a stopping distance of a few centimetres
    final = (m == BRAKE or m == SAIL) and 0.0 < v < r.stop_speed and v_t <= r.pull_away_speed and not short
    step = p.jerk_max * dt  # [m/s^2] one step's input change at the jerk bound
    final_brake = max(-step, p.a_min)  # the final stop's braking
    if final:
        upper0 = min(upper0, min(max(max(-v / dt, final_brake), up - step), up + step))
    # --- stopping inside this step (or standing) under the mode's least braking: no QP
    if final or v + dt * upper0 <= 0.0:
        # ... unless that least braking would roll past x_min: then the exact stop, if the
        # driver's own limits reach it (a_min, and one jerk step from its current braking).
        # If they do not, and braking at those limits stops within a braking plan's tolerance
        # of x_min (MPCSettings.brake_slack_tol plus the jerk-bounded release before the
        # standstill, as accepted in MPCDriver._only_chords_short), it brakes at them and
        # stops a few centimetres inside x_min rather than jolting at the vehicle's limit
        # (jolting, Table 4's #57 from 35 m/s braked at -8.6 m/s^2 at 0.29 m/s); else the
        # exact stop at whatever the vehicle can do.
        # A final stop still ramping (the throttle easing off, or the brake being released
        # towards its final braking at the jerk bound) is checked along that ramp, not at this
        # step's input held: if the ramp stops short of x_min it goes on (no jolt).
        if v > 0.0 and v * v > -2.0 * upper0 * room and not (
                final and ramp_stop_distance(v, upper0, step, final_brake, dt) <= room):
            a_exact = -v * v / (2.0 * max(room, 1e-9))
            a_own = min(upper0, max(p.a_min, up - step))
            if (m != EMERGENCY and a_exact < a_own < 0.0
                    and v * v / (-2.0 * a_own) - room <= r.brake_slack_tol + release_distance(p)):
                upper0 = a_own
            else:
                upper0 = max(a_exact, vehicle_limits(p, v)[1])
            m = BRAKE
        o.u0 = upper0
        o.path = HOLD
        o.viol = 0.0
        # standing still, or stopping inside this step: the brake holds the car (no car comes to
        # a standstill on engine drag at a chosen point), unless in an emergency; a final stop's
        # ramp that does not stop in this step is labelled by its input (decel_label)
        if m == EMERGENCY:
            st.mode = EMERGENCY
        elif v + dt * upper0 > 0.0:
            st.mode = decel_label(upper0, coast_decel(r, i, v), 1e-9)
        else:
            st.mode = BRAKE
        for k in range(n):
            plan[i, k] = 0.0
        plan[i, 0] = upper0
        st.n_active = 0
        stats[ST_HOLD] += 1
        return HOLD
    # --- unconstrained law
    for k in range(n):
        if target == CRUISE:
            z = gain_c[i, k, 0] * th1 + gain_c[i, k, 1] * up
        else:
            z = gain_f[i, k, 0] * th0 + gain_f[i, k, 1] * th1 + gain_f[i, k, 2] * up
            if target == LEAD and a_l != 0.0:
                z += _lead_term(gain_lead[i, k, ks], gain_lead[i, k, min(ks + 1, n)], a_l, ks, a_part, n)
        u_unc[k] = z
    beta = r.beta[i]
    viol = _fast_violation(r, i, v, u_unc, (lower0, upper0, env_lo, env_hi, rate), gap[i], v_lead[i],
                           stop_gap[i])
    # driver model 6 (MPCSettings.follow_in_range): below its desired speed, a driver whose
    # free-driving plan would break the constraints of the moving vehicle ahead follows that
    # vehicle (its law controls), as a human closes up to the car it is stuck behind; without
    # it the free law, held back by those constraints, settles far behind a slow vehicle
    # (at 2 m/s 8-13 m beyond x_min + c_TG v) and a dense column crawls
    if (r.follow_in_range and target == CRUISE and t_real == LEAD and m == ACCELERATE
            and v < p.v_desired and viol > r.feas_tol):
        target, th0, th1 = LEAD, t0, t1
        o.target = target
        o.th0 = th0
        o.th1 = th1
        for k in range(n):
            z = gain_f[i, k, 0] * th0 + gain_f[i, k, 1] * th1 + gain_f[i, k, 2] * up
            if a_l != 0.0:
                z += _lead_term(gain_lead[i, k, ks], gain_lead[i, k, min(ks + 1, n)], a_l, ks, a_part, n)
            u_unc[k] = z
        viol = _fast_violation(r, i, v, u_unc, (lower0, upper0, env_lo, env_hi, rate), gap[i], v_lead[i],
                               stop_gap[i])
    o.viol = viol
    path = -1
    if viol <= r.feas_tol:
        for k in range(n):
            plan[i, k] = u_unc[k]
        st.n_active = 0
        path = FAST
    else:  # some constraint is active: the bounds are needed in memory from here on
        fill_bounds(r, i, m, v, up, a_need, floor0)
        fill_target_rows(r, i, v, gap[i], v_lead[i], stop_gap[i])
    if path < 0 and warm:
        # --- warm active set: last step's, shifted along the horizon
        m0 = min(st.n_active, MAX_ACTIVE)
        for a in range(m0):
            codes[a] = r.active[i, a]
        m0 = _shift_active(codes, m0, n)
        hc = r.hinv_c[i] if target == CRUISE else r.hinv_f[i]
        ok, ma = _active_set_solve(u_unc, hc, lower[i], upper[i], m0, (n, dt, zoh, beta), (r.feas_tol, r.slack_linear),
                                   plan[i], scratch)
        # remember the working set either way: the solution's, or a warm start for the backend
        for a in range(ma):
            r.active[i, a] = codes[a]
        st.n_active = ma
        if ok:
            path = ACTIVE_SET
    if path >= 0:
        o.u0 = min(max(plan[i, 0], lower0), upper0)
        o.path = path
        stats[ST_FAST if path == FAST else ST_ACTIVE_SET] += 1
        if m == ACCELERATE or m == EMERGENCY:
            st.mode = m
            if m == EMERGENCY:
                stats[ST_EMERGENCY] += 1
        else:
            # SAIL: the pedals released (the coasting deceleration); harder: BRAKE; above it: still ACCELERATE
            st.mode = decel_label(min(max(plan[i, 0], lower0), upper0), coast_decel(r, i, v), 1e-7)
    else:
        o.u0 = np.nan
        o.path = QP
        st.mode = m
    return path


def _make_prepare(parallel):
    rng = numba.prange if parallel else range

    def prepare(r, obs):
        err = _check_inputs(obs, r.state)
        if err != 0:
            return BAD_INPUT, err
        v0, gap, stop_gap = obs[0], obs[2], obs[5]
        state, out, hard = r.state, r.out, r.hard
        nd = v0.shape[0]
        # a driver's follow QP is installed at its first step with a real target (MPCDriver's
        # lazy install): list the rows that need it now and return before writing anything
        n_need = 0
        for i in range(nd):
            s = state[i]
            if s.follow_pending != 0 and s.idle == 0 and (gap[i] < np.inf or stop_gap[i] < np.inf):
                hard[n_need] = i
                n_need += 1
        if n_need > 0:
            return NEED_FOLLOW, n_need
        n = r.plan.shape[1]
        width = max(n, MAX_ACTIVE + 1)
        o1 = N_SF * width
        o2 = o1 + 3 * MAX_ACTIVE * n
        o3 = o2 + 2 * MAX_ACTIVE * MAX_ACTIVE
        SF, SC = r.sf, r.sc
        for i in rng(nd):
            if state[i].idle != 0:  # a row without an MPC driver (SlotDrivers' absent and profile rows)
                out[i].u0 = 0.0
                out[i].path = -1
                continue
            t = numba.get_thread_id() if parallel else 0  # scratch: one set per thread
            _one(i, r, obs, (SF[t, :o1].reshape((N_SF, width)), SF[t, o1:o2].reshape((3, MAX_ACTIVE, n)),
                             SF[t, o2:o3].reshape((2, MAX_ACTIVE, MAX_ACTIVE)), SC[t]))
        n_hard = 0
        for i in range(nd):
            if out[i].path == QP:
                hard[n_hard] = i
                n_hard += 1
        return SOLVED, n_hard

    prepare.__doc__ = """One step for every driver of the :data:`MPC` record ``r``; ``obs`` the
    observed ``(v, u_prev, gap, v_lead, a_lead, stop_gap)``, arrays ``(n,)``.

    Returns ``(status, k)``: ``(BAD_INPUT, field)`` for invalid inputs (``field``: 1 + the
    offending field's index, :func:`_check_inputs`; nothing written); ``(NEED_FOLLOW, k)`` when
    ``k`` drivers whose state is ``follow_pending`` have a real target (a vehicle ahead or a
    stop position) this step, their indices in ``r.hard[:k]`` and nothing else written: the
    caller installs their follow QPs and calls again; else ``(SOLVED, k)``, ``k`` the number of
    drivers whose QP the warm active-set solver could not settle (their indices in
    ``r.hard[:k]``): the caller solves those with the backend. Idle rows are skipped, their
    inputs unread (output 0, path -1, nothing else written): rows do not interact, so the
    others' numbers are the same with or without them. Each driver's step is in ``r.out``
    (:data:`STEP`), its state in ``r.state`` (:data:`DRIVER_STATE`), its plan and bounds in
    ``r.plan``, ``r.lower``, ``r.upper``.
    """
    # each variant its own name, hence its own numba cache index: under one index (the same
    # qualname and line) two processes compiling both variants at once can cross an index entry
    # and a data file, and a process would then run the other variant's code
    prepare.__name__ = prepare.__qualname__ = "prepare_parallel" if parallel else "prepare"
    return prepare


prepare = numba.njit(cache=True, error_model="numpy")(_make_prepare(False))
prepare_parallel = numba.njit(cache=True, error_model="numpy", parallel=True)(_make_prepare(True))
PARALLEL_MIN_BATCH = 128  # below this many drivers the thread pool costs more than it saves
# prepare's statuses (its first return value; the second is a count or a field, see prepare)
SOLVED = 0  # the step is done but for k drivers the backend must solve
BAD_INPUT = 1  # an input field is invalid (the second value: 1 + its index); nothing written
NEED_FOLLOW = 2  # k pending drivers need their follow QP first; nothing else written


def scratch(n_steps: int, parallel: bool):
    """Per-thread work arrays for :func:`prepare`: floats ``SF`` and ints ``SC``."""
    rows = numba.config.NUMBA_NUM_THREADS if parallel else 1
    width = max(n_steps, MAX_ACTIVE + 1)
    size = N_SF * width + 3 * MAX_ACTIVE * n_steps + 2 * MAX_ACTIVE * MAX_ACTIVE
    return np.zeros((rows, size)), np.zeros((rows, MAX_ACTIVE + 1), dtype=np.int64)


@numba.njit(cache=True)
def store_active(r, i, lam, tol):
    """Remember the active set of a backend solution ``lam`` (lam > 0: upper, < 0: lower
    bound; the slack's entry, at index N, skipped) as driver ``i``'s working set."""
    st = r.state[i]
    active = r.active[i]
    n = r.plan.shape[1]
    m = 0
    for c in range(lam.shape[0]):
        if c == n:
            continue
        if abs(lam[c]) > tol and m < MAX_ACTIVE:
            active[m] = 2 * c + (1 if lam[c] > 0 else 0)
            m += 1
    st.n_active = m
