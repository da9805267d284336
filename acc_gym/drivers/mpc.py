"""The MPC human-like driver of paper 001 (Section 3 and 4.4; SPEC section 3).

Each step, every driver solves the condensed QP of :mod:`acc_gym.drivers.qp` and applies
the first planned acceleration. Decisions this module makes where the paper is silent
(each is a parameter or a setting, and is tested):

Targets
    A driver has up to three candidate targets: the vehicle ahead (if within range), a
    **virtual stopped vehicle** whose rear is ``x_min`` beyond a stop position (so the
    front bumper stops at the position), and a **virtual free-driving target** moving at
    ``v_desired``. The free-driving law is the same QP with ``q1 = 0`` (only the speed
    error is penalised): following a virtual vehicle with a distance error would make the
    driver overshoot its desired speed to "catch up". The nearer real target's law
    controls the cost; in ACCELERATE the free-driving law controls instead when it asks
    for less acceleration (compared on the unconstrained first input, as ACC and IDM take
    the minimum of their free and interaction terms), so a driver does not chase a fast
    or distant vehicle beyond its desired speed. In the decelerating modes the driver
    deals with the target that made it decelerate. The **gap and terminal constraints
    hold against every real target** whichever law controls.
Spacing policy
    ``e_x = gap - x_min - c_TG v``: the paper's Eq. (4) with the standstill distance
    ``x_min`` added, so that the unconstrained equilibrium at standstill is the minimum
    gap rather than a gap of zero held only by the constraint.
Lead prediction
    The paper assumes the target keeps its speed over the horizon. Here the measured
    deceleration of the vehicle ahead is held until that vehicle would stop (an
    accelerating vehicle is predicted at constant speed, which is conservative)
    (``MPCSettings(use_lead_accel=False)`` restores the paper's assumption). The paper
    itself notes the lead's acceleration should be considered for sudden speed changes;
    with the constant-speed assumption every Table 4 driver behind a lead braking at
    -2 m/s^2 to a stop under-brakes step after step and ends in repeated emergency
    braking below x_min, while with it they follow at their own a_min without an
    emergency (measured with ``acc-gym demo``'s scenario).
Discretisation
    Exact zero-order hold (the vehicle's own integration) by default; the paper's Euler
    form is ``MPCSettings(discretisation="euler")``. Terminal weight: the Riccati solution.
Modes (paper Figure 9)
    ``ACCELERATE``: ``u_0`` in ``[a_sail, a_max]``. Decelerating: ``u_0`` in
    ``[a_min, a_sail]``, labelled ``SAIL`` while the optimum is the coasting deceleration
    (pedals released) and ``BRAKE`` below it. ``EMERGENCY``: ``u_0`` down to the
    vehicle's braking limit with the emergency jerk. The mode restricts the current
    input; the rest of the plan may use the driver's whole range ``[a_min, a_max]``
    (a human in the sailing phase anticipates braking later).

    * ACCELERATE -> decelerating when the required deceleration ``a_req`` (Eq. 10) to
      the most demanding real target is ``<= a_req_sail``. ``R`` is the gap to the
      vehicle ahead, or the distance to the stop position (the paper's data definitions).
    * decelerating -> ACCELERATE only when ``a_req > a_req_sail + hysteresis`` **and**
      the target is really pulling away (``dR > pull_away_speed``), or, from SAIL, above
      ``creep_speed``. The literal rule would re-accelerate while still closing on a
      stopped vehicle at creep speed, because ``a_req -> 0`` as the speed does.
    * Mode semantics: ``a_sail`` is the coasting deceleration (pedals released:
      engine drag and resistance; ``MPCSettings.coast_fade_speed`` can fade it out at low
      speed, off by default). ACCELERATE never decelerates harder than coasting; SAIL is
      coasting; anything harder is BRAKE (the label follows the applied first input, not
      the ramped bound). A braking driver returns to ACCELERATE only once the brake is
      released (the first input is back at coasting; the release itself ramps at the jerk
      bound inside the decelerating mode, labelled BRAKE).
    * Queues and stops: towards a (nearly) stopped vehicle or a stop position
      (speed <= ``pull_away_speed``) the target's law controls even in ACCELERATE (the
      free-driving law, held back only by the gap constraint, coasted 7-8 % of typical
      drivers to a standstill 7-15 m short of their standstill gap); at or below
      ``creep_speed`` a driver lifts off (decelerating modes) once coasting would carry it
      to its stopping point, and rolls on (ACCELERATE, brake released) while coasting would
      leave it more than ``stop_short_margin`` short. Below ``stop_speed`` it brakes to a
      standstill at its jerk bound, and every step that ends in a standstill is BRAKE:
      the brake holds the car. So every stop behind a stopped vehicle ends braking, within
      ``stop_short_margin`` of ``x_min`` (tests/drivers/test_modes.py).
    * At its own limits: a braking driver's plan that keeps every row but the conservative
      terminal chords, and the exact terminal condition, within ``brake_slack_tol`` plus
      the jerk-bounded release before the standstill (``b^3 / (24 jerk_max^2)``) is
      accepted; the EMERGENCY screen of a braking driver and its final stop use the same
      tolerance, so such a stop ends at most that far inside ``x_min``, easing off at the
      jerk bound (tests/drivers/test_own_limits.py).
    * Escalation: if the QP needs slack (the gap or speed constraint cannot hold within
      the mode's bounds), an ACCELERATE driver is re-solved decelerating, and a
      decelerating one in ``EMERGENCY``; an emergency ends on the first step the
      comfortable decelerating QP needs no slack.
Jerk (humans bound it)
    ``|u_k - u_{k-1}| <= jerk_max * dt`` over the whole plan, from the acceleration
    actually applied last step. A mode switch whose range excludes the current
    acceleration **ramps** towards it at that rate instead of jumping. In ``EMERGENCY``,
    and when releasing braking harder than ``a_min``, the rate is ``jerk_emergency``.
Standstill
    A driver that would stop inside the step under its mode's least braking is given
    that input without a QP (it stops there; at standstill the brakes hold: ``BRAKE``).
Failures
    Inputs are checked before any solve (``ValueError`` naming the field). A backend
    failure, iteration cap or non-finite result never raises: the driver falls back to
    the deceleration that stops it behind its target at ``x_min`` (or the previous plan,
    whichever is lower), limited to the vehicle, and the fallback is counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from enum import IntEnum

import numpy as np

from acc_gym._validation import check_finite
from acc_gym.drivers import _mpc_kernel as K
from acc_gym.drivers.base import Observation
from acc_gym.drivers.qp import Horizon, condensed_qp, make_backend, terminal_chords
from acc_gym.vehicle import VehicleParams, accel_lower


# The behaviour's version: it goes up whenever the same parameters give other trajectories
# (CHANGELOG.md says what each version changed). DRIVER_MODELS holds the versions a user can
# select:
# 5: the law this module describes, with MPCSettings()'s defaults; sampled populations' distance
#    weight q1 = q1n (20/v)^4, q1n log-uniform in [0.02, 2.8] (population.py says how the range
#    was chosen).
# 6: model 5 plus what real drivers have and paper 001's MPC leaves out, for dense traffic:
#    a reaction time (acc_gym.drivers.perception: 1.0 s, with HDM's temporal anticipation and
#    the driver's own motion known; an imminent collision seen at once) and, below its desired
#    speed, a driver whose free plan breaks the moving lead's constraints follows that lead
#    (MPCSettings.follow_in_range; docs/design/driver-model-6.md). The env ids, suites and
#    leaderboards drive model 5 (ENV_DRIVER_MODEL); the ring drives model 6.
MODEL_VERSION = 6  # the newest driver model
ENV_DRIVER_MODEL = 5  # the driver model of the environments' MPC drivers and so of every suite and leaderboard


class Mode(IntEnum):
    """Driving mode of an MPC driver (visible in ``driver.mode`` and ``info["mode"]``)."""

    ACCELERATE = K.ACCELERATE
    SAIL = K.SAIL
    BRAKE = K.BRAKE
    EMERGENCY = K.EMERGENCY


class Target(IntEnum):
    """Which law controls the cost this step."""

    LEAD = K.LEAD
    STOP = K.STOP
    CRUISE = K.CRUISE


class SolvePath(IntEnum):
    """How the step's input was obtained (``info["path"]``)."""

    UNCONSTRAINED = K.FAST  # the unconstrained law, checked against every constraint: exact
    ACTIVE_SET = K.ACTIVE_SET  # the kernel's dual active-set solver from last step's active set, KKT-verified: exact
    QP = K.QP  # the backend solved the QP
    HOLD = K.HOLD  # standing or stopping inside the step: no QP needed
    FALLBACK = K.FALLBACK  # the backend failed; safe fallback used




@dataclass(frozen=True)
class MPCDriverParams:
    """Parameters of one MPC driver or, with array fields of shape ``(n,)``, of ``n`` drivers.

    Defaults are driver #57 of paper 001's Table 4 with a 1.5 s time gap.
    """

    a_max: float | np.ndarray = 2.0  # [m/s^2] largest acceleration the driver uses
    a_min: float | np.ndarray = -2.5  # [m/s^2] hardest braking outside emergencies
    a_req_sail: float | np.ndarray = -0.5  # [m/s^2] required deceleration that starts sailing
    a_sail: float | np.ndarray = -0.1  # [m/s^2] deceleration with the pedals released
    q1: float | np.ndarray = 5.0  # [-] weight of the distance error
    r1: float | np.ndarray = 45.0  # [-] weight of the acceleration
    q2: float | np.ndarray = 1.0  # [-] weight of the speed error (the paper fixes it at 1)
    c_tg: float | np.ndarray = 1.5  # [s] constant time gap
    x_min: float | np.ndarray = 2.5  # [m] minimum (standstill) gap
    v_desired: float | np.ndarray = 25.0  # [m/s] free-driving speed
    v_max: float | np.ndarray | None = None  # [m/s] speed never exceeded; None: v_desired
    r_jerk: float | np.ndarray = 0.0  # [-] weight of (u_k - u_{k-1})^2 in the cost
    jerk_max: float | np.ndarray = 2.5  # [m/s^3] bound on |du/dt| outside emergencies
    jerk_emergency: float | np.ndarray = 50.0  # [m/s^3] bound on |du/dt| in emergencies

    def __post_init__(self) -> None:
        """Every value finite and every rule of :data:`_RULES` met, for plain numbers and arrays
        alike (broadcast against each other); the first failure raises naming the field and the
        values that break it."""
        d = {}
        for name in _FIELD_NAMES:
            value = self.__dict__[name]
            if value is not None and type(value) not in _PLAIN_NUMBERS:
                value = np.asarray(value, dtype=float)
                if not np.isfinite(value).all():
                    check_finite(f"MPCDriverParams.{name}", value)  # raises, naming it
            elif value is not None and not math.isfinite(value):
                check_finite(f"MPCDriverParams.{name}", value)
            d[name] = value
        for name, rule, message in _RULES:
            ok = rule(d)
            if not (ok if type(ok) is bool else ok.all()):
                value = np.asarray(d[name], dtype=float)
                got = value[~np.broadcast_to(ok, value.shape)] if value.ndim else d[name]
                raise ValueError(f"MPCDriverParams: {message}, got {got!r}")

    @property
    def speed_limit(self):
        """``v_max`` or, when unset, ``v_desired`` [m/s]."""
        return np.asarray(self.v_desired, float) if self.v_max is None else self.v_max

    @property
    def size(self) -> int:
        """Batch size implied by the array fields (1 if all are scalars)."""
        shape = np.broadcast_shapes(*(np.shape(getattr(self, f.name)) for f in fields(self)
                                      if getattr(self, f.name) is not None))
        return int(np.prod(shape)) if shape else 1

    @classmethod
    def _validated(cls, values: dict) -> "MPCDriverParams":
        """Build from values taken from already validated parameters (no re-check: resets are hot)."""
        obj = object.__new__(cls)
        for name, value in values.items():
            object.__setattr__(obj, name, value)
        return obj

    def broadcast(self, n: int) -> "MPCDriverParams":
        """The same parameters as arrays of shape ``(n,)``."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = None if value is None else np.broadcast_to(np.asarray(value, float), (n,)).copy()
        return MPCDriverParams._validated(out)

    def take(self, index) -> "MPCDriverParams":
        n = self.size
        b = self.broadcast(n)
        return MPCDriverParams._validated({f.name: (None if getattr(b, f.name) is None else getattr(b, f.name)[index])
                                           for f in fields(b)})

    def replace(self, **changes) -> "MPCDriverParams":
        return replace(self, **changes)

    @staticmethod
    def stack(drivers: list["MPCDriverParams"]) -> "MPCDriverParams":
        """Concatenate single or batched parameter sets into one batch."""
        out = {}
        for f in fields(MPCDriverParams):
            if all(getattr(d, f.name) is None for d in drivers):
                out[f.name] = None
                continue
            out[f.name] = np.concatenate([np.broadcast_to(np.asarray(d.speed_limit if f.name == "v_max" else getattr(d, f.name), float), (d.size,))
                                          for d in drivers])
        return MPCDriverParams(**out)


_FIELD_NAMES = tuple(f.name for f in fields(MPCDriverParams))
_PLAIN_NUMBERS = (float, int, np.float64)  # kept as given; anything else becomes a float array
# MPCDriverParams' rules: (the field a failure names, the check over the values, the message)
_RULES = (
    ("a_max", lambda d: d["a_max"] > 0, "a_max must be > 0"),
    ("a_min", lambda d: d["a_min"] < 0, "a_min must be < 0"),
    ("a_sail", lambda d: d["a_sail"] < 0, "a_sail must be < 0"),
    ("a_req_sail", lambda d: d["a_req_sail"] < 0, "a_req_sail must be < 0"),
    ("a_sail", lambda d: d["a_sail"] > d["a_min"], "a_sail must be above a_min"),
    ("q1", lambda d: d["q1"] >= 0, "q1 must be >= 0"),
    ("q2", lambda d: d["q2"] > 0, "q2 must be > 0"),
    ("r1", lambda d: d["r1"] > 0, "r1 must be > 0"),
    ("r_jerk", lambda d: d["r_jerk"] >= 0, "r_jerk must be >= 0"),
    ("c_tg", lambda d: d["c_tg"] >= 0, "c_tg (time gap) must be >= 0"),
    ("x_min", lambda d: d["x_min"] > 0, "x_min must be > 0"),
    ("v_desired", lambda d: d["v_desired"] > 0, "v_desired must be > 0"),
    ("jerk_max", lambda d: d["jerk_max"] > 0, "jerk_max must be > 0"),
    ("jerk_emergency", lambda d: d["jerk_emergency"] >= d["jerk_max"], "jerk_emergency must be >= jerk_max"),
    ("v_max", lambda d: d["v_max"] is None or d["v_max"] >= d["v_desired"], "v_max must be >= v_desired"),
)

# Paper 001, Table 4 (a_max, a_min, a_req_sail, a_sail, q1, r1). The paper gives no time
# gap, minimum gap or desired speed for them: the defaults of MPCDriverParams apply.
PRESETS: dict[str, dict[str, float]] = {
    "#23": dict(a_max=2.0, a_min=-2.1, a_req_sail=-0.5, a_sail=-0.4, q1=3.0, r1=45.0),
    "#57": dict(a_max=2.0, a_min=-2.5, a_req_sail=-0.5, a_sail=-0.1, q1=5.0, r1=45.0),
    "#61": dict(a_max=2.0, a_min=-2.7, a_req_sail=-0.8, a_sail=-0.5, q1=2.0, r1=40.0),
    "#13": dict(a_max=2.0, a_min=-1.0, a_req_sail=-0.5, a_sail=-0.1, q1=5.0, r1=40.0),
}


def preset(name: str, **overrides) -> MPCDriverParams:
    """A Table 4 driver by name (``"#23"``, ``"#57"``, ``"#61"``, ``"#13"``; the ``#`` is optional)."""
    key = name if name.startswith("#") else f"#{name}"
    if key not in PRESETS:
        raise ValueError(f"unknown MPC driver preset {name!r}; known: {sorted(PRESETS)}")
    return MPCDriverParams(**{**PRESETS[key], **overrides})


@dataclass(frozen=True)
class MPCSettings:
    """Numerical and behavioural settings shared by a batch of MPC drivers."""

    dt: float = 0.2  # [s] sampling time (paper: 0.2 s)
    horizon: int = 60  # [steps] N (paper: 12 s)
    discretisation: str = "zoh"  # "zoh" (exact) or "euler" (paper)
    backend: str = "daqp"  # "daqp", "proxsuite" or "qpsolvers:<solver>"
    max_iter: int = 1000  # iteration cap of the backend
    use_lead_accel: bool = True  # predict the lead with its measured acceleration (paper: False)
    hysteresis: float = 0.2  # [m/s^2] a_req margin above a_req_sail to re-accelerate
    creep_speed: float = 2.0  # [m/s] SAIL -> ACCELERATE only above this speed ...
    pull_away_speed: float = 0.3  # [m/s] ... or when the target pulls away faster than this
    coast_fade_speed: float = 0.0  # [m/s] below it the coasting deceleration fades to 0 (a_sail v / this); 0: none
    stop_short_margin: float = 1.0  # [m] coasting would stop the driver this far short of a stopped target: roll on
    stop_speed: float = 0.3  # [m/s] below it, closing on a stopped target, the driver brakes to a standstill
    feas_tol: float = 1e-7  # accept the unconstrained law if no constraint is violated by more
    slack_tol: float = 1e-3  # [m or m/s] slack above this escalates the mode
    # [m or m/s] ... except a decelerating plan that keeps every row but the terminal chords
    # within this, and the exact terminal condition the chords approximate: the driver brakes
    # at its own limits (riding a_min to x_min), not in an emergency (see _only_chords_short)
    brake_slack_tol: float = 0.05
    # Below its desired speed, a driver whose free-driving plan would break the constraints of
    # the moving vehicle ahead follows that vehicle (its law controls in ACCELERATE even when
    # the free law asks for less; driver model 6). False: the free law controls whenever it
    # asks for less, held back only by the gap and terminal constraints (driver model 5).
    follow_in_range: bool = False
    slack_linear: float = 1e9  # exact-penalty weight of the slack (above any multiplier of a far target)
    slack_quadratic: float = 1e4  # quadratic weight of the slack
    warm_active_set: bool = True  # the kernel's active-set solver (KKT-verified) before the backend
    # Threads for batches of >= 128 drivers: True, False, or None (auto: on for those batches).
    # Off by default: they pay only on an otherwise idle machine; with other busy processes
    # (RL training, vector envs in subprocesses, campaign workers, tests) the thread pool
    # made a 512-driver step 4.4 times slower (12.4 ms against 2.8 ms, 2 cores).
    parallel: bool | None = False

    def __post_init__(self) -> None:
        Horizon(self.horizon, self.dt, self.discretisation)  # validates these three
        make_backend_name_check(self.backend)
        if self.parallel not in (True, False, None):
            raise ValueError(f"MPCSettings.parallel must be True, False or None, got {self.parallel!r}")
        for name in ("max_iter",):
            if int(getattr(self, name)) <= 0:
                raise ValueError(f"MPCSettings.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("hysteresis", "creep_speed", "pull_away_speed", "coast_fade_speed", "stop_short_margin", "stop_speed",
                     "feas_tol", "slack_tol", "brake_slack_tol"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"MPCSettings.{name} must be >= 0, got {value!r}")
        for name in ("slack_linear", "slack_quadratic"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"MPCSettings.{name} must be > 0, got {value!r}")

    @property
    def horizon_structure(self) -> Horizon:
        return Horizon(self.horizon, self.dt, self.discretisation)

    def stop_tolerance(self, params: MPCDriverParams) -> np.ndarray:
        """[m] How far inside ``x_min`` a driver braking at its own limits may end a stop
        (per driver): ``brake_slack_tol`` plus the jerk-bounded release before the standstill,
        ``b^3 / (24 jerk_max^2)`` with ``b = -a_min``. A braking plan within it is accepted
        (``MPCDriver._only_chords_short``), a braking driver is screened for EMERGENCY with
        it, and its final stop uses it: at its own limits such a stop ends
        a few centimetres inside ``x_min`` rather than with a jolt at the vehicle's limit."""
        b, jerk = -np.asarray(params.a_min, float), np.asarray(params.jerk_max, float)
        return self.brake_slack_tol + b ** 3 / (24.0 * jerk * jerk)


def make_backend_name_check(name: str) -> None:
    if name not in ("daqp", "proxsuite") and not name.startswith("qpsolvers:"):
        raise ValueError(f"unknown QP backend {name!r}; use 'daqp', 'proxsuite' or 'qpsolvers:<solver>'")


_FIELDS = ("v", "a", "gap", "v_lead", "a_lead", "stop_gap")
_F64 = np.dtype(np.float64)
_STAT_NAMES = ("steps", "unconstrained", "active_set", "qp", "hold", "fallback", "slack", "emergency")


class MPCDriver:
    """A batch of ``n`` MPC human-like drivers (one QP each per step).

    ``act(obs)`` returns the desired accelerations ``(n,)`` [m/s^2]; ``mode`` holds each
    driver's :class:`Mode`; ``info`` the last step's diagnostics (mode, target, a_req,
    solve path, slack, backend iterations, the first input's bounds); ``stats`` running
    counts per driver of steps, of each :class:`SolvePath`, of steps that needed slack
    and of steps in EMERGENCY. The vehicle parameters give the acceleration envelope the
    plan respects (``a_U(v)``, ``a_L(v)`` at the current speed).

    Solving: the unconstrained law when it is feasible; else the kernel's dual active-set
    solver, warm-started from last step's active set shifted along the horizon, accepted
    only when the KKT conditions hold (so it is exact); else (the QP needs the slack) the
    backend (DAQP by default).
    """

    def __init__(self, params: MPCDriverParams | None = None, n: int | None = None,
                 vehicle: VehicleParams | None = None, settings: MPCSettings | None = None,
                 perception=None):
        params = params if params is not None else MPCDriverParams()
        n = params.size if n is None else int(n)
        if n < 1:
            raise ValueError(f"n must be >= 1, got {n}")
        self.n = n
        self.params = params.broadcast(n)
        self.vehicle = (vehicle if vehicle is not None else VehicleParams()).broadcast(n)
        self.settings = settings if settings is not None else MPCSettings()
        s = self.settings
        self.horizon = s.horizon_structure
        p = self.params
        # the kernel's records (acc_gym.drivers._mpc_kernel.MPC_FIELDS): one DRIVER record per
        # driver, its DRIVER_STATE and STEP, the laws' arrays and the settings
        self._drivers = np.zeros(n, K.DRIVER)
        for c in K.DRIVER_PARAMS:
            self._drivers[c] = p.speed_limit if c == "v_max" else getattr(p, c)
        for c in K.DRIVER_VEHICLE:
            self._drivers[c] = getattr(self.vehicle, c)
        self._alpha, self._beta = terminal_chords(p.a_min, p.jerk_max, p.speed_limit)
        self._settings = tuple(s.dt if name == "dt" else (s.discretisation == "zoh") if name == "zoh"
                               else getattr(s, name) for name, _ in K.MPC_SETTINGS)
        pairs = [self._condensed(float(p.q1[i]), float(p.q2[i]), float(p.r1[i]), float(p.c_tg[i]), float(p.r_jerk[i]))
                 for i in range(n)]
        self._qp_follow = [f for f, _ in pairs]
        self._qp_cruise = [c for _, c in pairs]
        N = self.horizon.n_steps
        # unconstrained laws: follow (theta = e_x, e_v, u_prev), cruise (e_v, u_prev)
        self._gain_f = np.ascontiguousarray(np.stack([q.gain for q in self._qp_follow]))
        self._gain_c = np.ascontiguousarray(np.stack([q.gain[:, 1:] for q in self._qp_cruise]))
        self._hinv_f = np.ascontiguousarray(np.stack([q.hinv_columns for q in self._qp_follow]))
        self._hinv_c = np.ascontiguousarray(np.stack([q.hinv_columns for q in self._qp_cruise]))
        # running row sums of the lead-acceleration gains (the predicted sequence is piecewise constant)
        self._gain_lead = (np.ascontiguousarray(np.stack([q.gain_lead_sums for q in self._qp_follow]))
                           if s.use_lead_accel else np.zeros((n, 1, 1)))
        self._lower = np.zeros((n, self.horizon.n_bounds))
        self._upper = np.zeros((n, self.horizon.n_bounds))
        self._plan = np.zeros((n, N))
        self._aseq = np.zeros((n, N))
        self._state = np.zeros(n, K.DRIVER_STATE)
        self._active = np.zeros((n, K.MAX_ACTIVE), dtype=np.int64)  # working sets (codes; counts in _state)
        self._stats = np.zeros((n, K.N_STATS), dtype=np.int64)  # running counts, _STAT_NAMES order
        self._out = np.zeros(n, K.STEP)
        self._hard = np.zeros(n, dtype=np.int64)
        self._parallel = n >= K.PARALLEL_MIN_BATCH and s.parallel is not False
        self._prepare = K.prepare_parallel if self._parallel else K.prepare
        self._SF, self._SC = K.scratch(N, self._parallel)
        self._views()
        self._inf = np.full(n, np.inf)
        # what the drivers see: the scene as it is (None), or through a perception layer
        # (acc_gym.drivers.perception.Perception: reaction time, anticipation, estimation errors)
        if perception is not None and getattr(perception, "n", None) != n:
            raise ValueError(f"perception serves {getattr(perception, 'n', None)} drivers, not {n}")
        self.perception = perception
        self._alarm = np.zeros(n, dtype=np.bool_)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Back to ACCELERATE with zeroed statistics; solvers restart cold."""
        pending = self._state["follow_pending"].copy()
        self._state[:] = 0  # modes (ACCELERATE = 0), working-set sizes, idle marks
        self._state["follow_pending"] = pending  # which follow QPs are installed is the drivers', not the episode's
        self._active[:] = 0  # working sets
        self._stats[:] = 0  # statistics
        self._plan[:] = 0.0
        self._aseq[:] = 0.0
        self._out[:] = 0
        self._out["path"] = -1
        # backend workspaces survive a reset (their factorisations depend only on the
        # driver), but every one restarts cold from the kernel's working set, so an
        # episode never depends on the previous one
        if not hasattr(self, "_backends"):
            self._backends: dict = {}
        self._last_used = {key: -2 for key in self._backends}
        self._step = 0
        if getattr(self, "perception", None) is not None:
            self.perception.reset()

    def set_idle(self, idle: np.ndarray) -> None:
        """Mark the rows whose output nobody reads (``idle``, booleans ``(n,)``): :meth:`act`
        skips them -- their inputs are not read (nor checked), their action is 0 and their
        mode, plan and statistics are left as they were -- until :meth:`set_params` restarts
        them (which clears the mark) or this is called again. The other rows' numbers are the same either way (rows do not
        interact). :class:`~acc_gym.drivers.slots.SlotDrivers` marks its rows without an MPC
        driver (absent vehicles, profiles, baseline models): before, it fed them a made-up
        cruise, the kernel planned it and the result was thrown away."""
        idle = np.asarray(idle)
        if idle.shape != (self.n,) or idle.dtype != bool:
            raise ValueError(f"idle must be booleans of shape ({self.n},), got {idle.dtype} {idle.shape}")
        self._state["idle"] = idle

    def set_params(self, index, params: MPCDriverParams) -> None:
        """Give drivers ``index`` (an int or a sequence) new ``params`` and restart them.

        Only those drivers' rows of the kernel arrays are rebuilt (their condensed QPs come
        from :func:`~acc_gym.drivers.qp.condensed_qp`'s cache when a configuration repeats)
        and their solver workspaces dropped, so a batch of drivers can host a new human in
        one slot while the others drive on -- what a vector environment's autoreset needs.

        Decided: the cruise QP is installed here, the follow QP at the driver's
        first step with a real target (a vehicle ahead or a stop position; the kernel reads
        the follow law only then). Most surrounding drivers of a single-lane scene never have
        one (the front vehicle of every scene), so a reset condenses about half as much. The
        QP is the same whenever it is condensed (:func:`~acc_gym.drivers.qp.condensed_qp` of
        the same configuration), so the numbers are too (``tests/drivers/test_lazy_follow.py``).
        """
        idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
        if idx.size and (idx.min() < 0 or idx.max() >= self.n):
            raise ValueError(f"driver index out of range [0, {self.n}): {idx}")
        cur = self.params
        if cur.v_max is None and params.v_max is not None:
            object.__setattr__(cur, "v_max", np.array(cur.speed_limit, dtype=float))
        values = params.__dict__
        rows = idx
        if all(values[name] is None or type(values[name]) is float or np.ndim(values[name]) == 0
               for name in _FIELD_NAMES):
            if idx.size == 1:
                rows = int(idx[0])  # one driver, plain numbers (a reset's): written in place, no index arrays
        else:
            values = params.broadcast(idx.size).__dict__  # one value per driver (checks the sizes)
        limit = values["v_desired"] if values["v_max"] is None else values["v_max"]
        for name in _FIELD_NAMES:
            target = getattr(cur, name)
            if target is not None:
                value = values[name]
                target[rows] = limit if value is None else value
        limit_col = cur.v_desired if cur.v_max is None else cur.v_max  # speed_limit, without its array copy
        d = self._drivers
        for c in K.DRIVER_PARAMS:
            d[c][rows] = (limit_col if c == "v_max" else getattr(cur, c))[rows]
        self._alpha[rows], self._beta[rows] = terminal_chords(cur.a_min[rows], cur.jerk_max[rows], limit_col[rows])
        for i in idx.tolist():
            self._install_qps(i)
        self._restart(rows)

    def _restart(self, idx) -> None:
        """Drivers ``idx`` (an int or an index array) from the start: no mode, working set,
        statistics, plan or step; their follow QPs pending; not idle."""
        self._state[idx] = 0
        self._state["follow_pending"][idx] = 1
        self._active[idx] = 0
        self._stats[idx] = 0
        self._plan[idx] = 0.0
        self._aseq[idx] = 0.0
        self._out[idx] = 0
        self._out["path"][idx] = -1

    def _condensed(self, q1: float, q2: float, r1: float, c_tg: float, r_jerk: float):
        """The follow and cruise QPs of one driver configuration, from
        :func:`~acc_gym.drivers.qp.condensed_qp`'s cache when it repeats.

        Both are condensed with the weights divided by ``max(1, q1)`` (the same minimiser and
        the same laws): the slack's exact penalty (``MPCSettings.slack_linear``) must stay above
        every constraint multiplier, which grow with ``q1`` times the distance error. Unscaled,
        a slow driver's speed-scaled ``q1`` (5,200 at 3 m/s) makes the slack cheaper than the
        speed bound 300 m before a stopped vehicle: its QP takes slack and the driver brakes at
        the vehicle's limit in EMERGENCY."""
        return self._follow_qp(q1, q2, r1, c_tg, r_jerk), self._cruise_qp(q1, q2, r1, c_tg, r_jerk)

    def _follow_qp(self, q1: float, q2: float, r1: float, c_tg: float, r_jerk: float):
        """The follow QP of :meth:`_condensed` (with the lead-acceleration gains when used)."""
        s = self.settings
        k = 1.0 / max(1.0, q1)
        qf = condensed_qp(q1 * k, q2 * k, r1 * k, c_tg, self.horizon, s.slack_linear, s.slack_quadratic, r_jerk * k)
        if s.use_lead_accel:
            qf.gain_lead_sums  # noqa: B018  (made once, kept by the shared QP)
        return qf

    def _cruise_qp(self, q1: float, q2: float, r1: float, c_tg: float, r_jerk: float):
        """The cruise QP of :meth:`_condensed`."""
        s = self.settings
        k = 1.0 / max(1.0, q1)
        return condensed_qp(0.0, q2 * k, r1 * k, c_tg, self.horizon, s.slack_linear, s.slack_quadratic, r_jerk * k)

    def prepare(self, params: MPCDriverParams) -> bool:
        """Condense the QP of one driver's ``params`` (plain numbers) that :meth:`set_params`
        installs (the cruise QP; the follow QP waits for a real target) now, ahead of the
        :meth:`set_params` that will install it, which then finds it in
        :func:`~acc_gym.drivers.qp.condensed_qp`'s cache: the same objects, so the same
        numbers. A vector environment's worker does this for its next episodes while it
        would otherwise wait (:meth:`ACCVectorEnv.prepare_resets
        <acc_gym.envs.vector.ACCVectorEnv.prepare_resets>`). Returns whether it did; a
        configuration the QP cannot take is left for :meth:`set_params` to report."""
        values = [getattr(params, name) for name in ("q1", "q2", "r1", "c_tg", "r_jerk")]
        if not all(type(v) is float or (v is not None and np.ndim(v) == 0) for v in values):
            return False
        try:
            self._cruise_qp(*(float(v) for v in values))
        except (ValueError, np.linalg.LinAlgError):
            return False
        return True

    def _config(self, i: int) -> tuple[float, float, float, float, float]:
        p = self.params
        return float(p.q1[i]), float(p.q2[i]), float(p.r1[i]), float(p.c_tg[i]), float(p.r_jerk[i])

    def _install_qps(self, i: int) -> None:
        """Driver ``i``'s cruise QP (from the cache when a configuration repeats) and the
        kernel's rows made from it; its follow QP is left to :meth:`_install_follow` (the
        caller flags the row pending); its solver workspaces are dropped."""
        qc = self._cruise_qp(*self._config(i))
        self._qp_follow[i], self._qp_cruise[i] = None, qc
        self._gain_c[i] = qc.gain[:, 1:]
        self._hinv_c[i] = qc.hinv_columns
        if self._backends:
            for key in [k for k in self._backends if k[0] == i]:
                del self._backends[key]
                self._last_used.pop(key, None)

    def _install_follow(self, i: int) -> None:
        """Driver ``i``'s follow QP and the kernel's rows made from it (at its first step with
        a real target, see :meth:`set_params`)."""
        qf = self._follow_qp(*self._config(i))
        self._qp_follow[i] = qf
        self._gain_f[i] = qf.gain
        self._hinv_f[i] = qf.hinv_columns
        if self.settings.use_lead_accel:
            self._gain_lead[i] = qf.gain_lead_sums
        self._state[i]["follow_pending"] = 0

    def __getstate__(self):
        state = self.__dict__.copy()
        for view in ("mode", "_act_count", "_record", "_last_arrays", "_u_prev"):
            state.pop(view, None)  # views into the kernel's arrays and its record, re-made in __setstate__
        state["_backends"] = {}  # solver workspaces are rebuilt after unpickling ...
        state["_last_used"] = {}  # ... and start from the kernel's working set
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._views()

    def _views(self) -> None:
        """Views into the kernel's arrays by name, and the kernel's record of them."""
        self.mode = self._state["mode"]
        self._act_count = self._state["n_active"]
        self._record = K.record(self._settings, {
            "drivers": self._drivers, "alpha": self._alpha, "beta": self._beta, "gain_f": self._gain_f, "gain_c": self._gain_c, "gain_lead": self._gain_lead,
            "hinv_f": self._hinv_f, "hinv_c": self._hinv_c, "lower": self._lower, "upper": self._upper,
            "plan": self._plan, "aseq": self._aseq, "state": self._state, "active": self._active, "stats": self._stats, "out": self._out, "hard": self._hard,
            "sf": self._SF, "sc": self._SC})

    @property
    def stats(self) -> dict[str, np.ndarray]:
        """Running counts per driver: steps, each solve path, slack steps, emergency steps."""
        return {name: self._stats[:, j].copy() for j, name in enumerate(_STAT_NAMES)}

    def stats_column(self, name: str) -> np.ndarray:
        """One running count per driver (a view, no copy): ``"steps"``, ``"fallback"``, ..."""
        return self._stats[:, _STAT_NAMES.index(name)]

    @property
    def info(self) -> dict[str, np.ndarray]:
        """Diagnostics of the last :meth:`act` call, arrays of shape ``(n,)``."""
        out = self._out
        return {
            "mode": self.mode.copy(),
            "target": out["target"].copy(),
            "a_req": out["a_req"].copy(),
            "path": out["path"].copy(),
            "slack": out["slack"].copy(),
            "iterations": out["iterations"].copy(),
            "lower0": out["lower0"].copy(),
            "upper0": out["upper0"].copy(),
            "fallbacks": self._stats[:, K.ST_FALLBACK].copy(),
        }

    def qp_data(self, i: int) -> dict:
        """The QP driver ``i`` solved in the last step (after any escalation), for inspection
        and cross-checks: ``hessian`` (N+1, N+1), ``q`` (N+1,), ``G`` (rows, N+1) and the
        bounds ``lower``/``upper`` on ``(z, G z)`` (layout in :mod:`acc_gym.drivers.qp`)."""
        w = self._out[i]
        if int(w["path"]) in (K.FAST, K.HOLD):  # the fast paths never write the bounds: do it now
            v, u_prev, gap, v_lead, _, stop_gap = (float(arr[i]) for arr in self._last_arrays)
            K.fill_bounds(self._record, i, int(w["mode_pre"]), v, u_prev, float(w["a_need"]), float(w["floor0"]))
            K.fill_target_rows(self._record, i, v, gap, v_lead, stop_gap)
        target = int(w["target"])
        qp = (self._qp_cruise if target == K.CRUISE else self._qp_follow)[i]
        theta = np.array([w["th0"], w["th1"], self._u_prev[i]])
        aseq = self._aseq[i] if (target == K.LEAD and self.settings.use_lead_accel) else None
        return {"hessian": np.array(qp.hessian), "q": qp.linear_term(theta, aseq),
                "G": self.horizon.constraint_matrix(self._beta[i]), "lower": self._lower[i].copy(),
                "upper": self._upper[i].copy(), "path": int(w["path"])}

    @property
    def plan(self) -> np.ndarray:
        """The planned accelerations ``(n, N)`` of the last step [m/s^2]."""
        return self._plan.copy()

    # ------------------------------------------------------------------ step
    def act(self, obs: Observation) -> np.ndarray:
        """Desired accelerations ``(n,)`` [m/s^2] for the observed snapshot.

        Raises ``ValueError`` naming the field for a wrong shape, NaN, a negative speed,
        or an infinite speed or acceleration; never raises once the inputs are valid.
        """
        n = self.n
        arrays = []
        shape = (n,)
        for name in _FIELDS:
            value = getattr(obs, name)
            if value is None:
                value = self._inf
            elif not (value.__class__ is np.ndarray and value.dtype is _F64 and value.shape == shape):
                value = np.asarray(value, dtype=float)
                if value.shape != shape:
                    raise ValueError(f"observation field {name!r} must have shape ({n},), got {value.shape}")
            arrays.append(value)
        return self._act(arrays)

    def act_rows(self, rows: np.ndarray) -> np.ndarray:
        """:meth:`act` for an observation given as the rows of one float64 array ``(>= 5, n)``
        in :class:`~acc_gym.drivers.base.Observation`'s field order (``v, a, gap, v_lead,
        a_lead, ...``; what :meth:`SingleLaneWorld.observation_array
        <acc_gym.simulation.single_lane.SingleLaneWorld.observation_array>` gives), with no
        stop position: the same numbers as ``act(Observation(*rows))``, without building
        the observation and checking each field's type and shape (a row of such an array
        has them). The kernel still rejects invalid values, naming the field."""
        if not (rows.__class__ is np.ndarray and rows.dtype is _F64 and rows.ndim == 2 and rows.shape[0] >= 5
                and rows.shape[1] == self.n):
            return self.act(Observation(*rows))
        return self._act([rows[0], rows[1], rows[2], rows[3], rows[4], self._inf])

    def _act(self, arrays: list) -> np.ndarray:
        if self.perception is not None:
            # what the drivers see; one whose true scene is an emergency (braking at its a_min
            # cannot keep x_min) sees it as it is: the reflex that the reaction time does not delay
            seen = self.perception.perceive_fields(*arrays[:5])
            alarm = K.alarmed(self._record, arrays[0], arrays[2], arrays[3], arrays[4], self._alarm)
            if alarm.any():
                for f in range(5):
                    seen[f, alarm] = arrays[f][alarm]
            arrays = [seen[0], seen[1], seen[2], seen[3], seen[4], arrays[5]]
        obs = tuple(arrays)
        status, n_hard = self._prepare(self._record, obs)
        if status == K.NEED_FOLLOW:  # drivers meeting their first real target: their follow QPs, then the step
            for i in self._hard[:n_hard].tolist():
                self._install_follow(i)
            status, n_hard = self._prepare(self._record, obs)
        if status == K.BAD_INPUT:
            name = _FIELDS[n_hard - 1]
            raise ValueError(f"observation.{name} is invalid for an MPC driver: {arrays[n_hard - 1]!r} "
                             f"(speeds must be finite and >= 0, accelerations finite, gaps not NaN or -inf)")
        self._u_prev = arrays[1]
        self._last_arrays = arrays
        for j in range(n_hard):
            self._solve_one(int(self._hard[j]), arrays)
        self._step += 1
        return self._out["u0"].copy()

    def _backend(self, i: int, cruise: bool, emergency: bool = False):
        # one workspace per driver, law and bound regime (emergency bounds differ a lot)
        key = (i, cruise, emergency)
        b = self._backends.get(key)
        if b is None:
            qp = (self._qp_cruise if cruise else self._qp_follow)[i]
            g = self.horizon.constraint_matrix(self._beta[i])
            b = self._backends[key] = make_backend(self.settings.backend, qp, g, self.settings.max_iter)
        return b

    def _solve_backend(self, i: int, key_cruise: bool, emergency: bool, q: np.ndarray):
        """Solve with the backend: warm from its own last solve if that was the previous
        step, else from the kernel's working set."""
        key = (i, key_cruise, emergency)
        backend = self._backend(*key)
        fresh = self._last_used.get(key, -2) == self._step - 1
        start = None if fresh else self._active[i, : self._act_count[i]]
        self._last_used[key] = self._step
        return backend, backend.solve(q, self._lower[i], self._upper[i], start)

    def _only_chords_short(self, i: int, u: np.ndarray, arrays) -> bool:
        """Whether the plan ``u`` (no slack) keeps every row of driver ``i``'s current bounds
        but the terminal chords, and the exact terminal condition they approximate, within
        ``MPCSettings.brake_slack_tol``: from the plan's end, braking at ``a_min`` (reached at
        ``jerk_max``) stops clear of every real target, ``room_N >= w_N^2 / (2 b) + w_N b /
        (2 jerk_max)`` (``b = -a_min``, ``w_N`` the closing speed at the end, ``room_N`` the
        gap beyond ``x_min`` or to the stop).

        The chords lie above that curve by up to ``v_max^2 / (8 K_TERM^2 b)`` (metres at
        highway speeds), so a driver braking at its own ``a_min`` can lose their recursive
        feasibility while the stop itself is in reach. And a plan braking at ``a_min`` to
        a stop at ``x_min`` must release the brake at the jerk bound before the standstill,
        which rolls ``b^3 / (24 jerk_max^2)`` further than the constant braking the stop
        needs (0.10 m for ``a_min = -2.5``, ``jerk_max = 2.5``): a real car's deceleration
        drops to 0 as it stops (the driver's own final stop does so, see the HOLD path), so
        this release distance is added to the tolerance. Neither is an emergency. (Compiled:
        :func:`acc_gym.drivers._mpc_kernel.only_chords_short`.)"""
        return K.only_chords_short(self._record, i, u, self.horizon.general_rows, self.horizon.terminal_rows,
                                   float(arrays[0][i]),
                                   float(arrays[2][i]), float(arrays[3][i]), float(arrays[5][i]))

    def _solve_one(self, i: int, arrays) -> None:
        """Backend solve for driver ``i``, with mode escalation on slack and a counted fallback."""
        W = self._out[i]  # this driver's STEP record (a view)
        s = self.settings
        N = self.horizon.n_steps
        v, u_prev = float(arrays[0][i]), float(arrays[1][i])
        target = int(W["target"])
        cruise = target == K.CRUISE
        qp = (self._qp_cruise if cruise else self._qp_follow)[i]
        theta = np.array([W["th0"], W["th1"], u_prev])
        aseq = self._aseq[i] if (target == K.LEAD and s.use_lead_accel) else None
        q = qp.linear_term(theta, aseq)
        m = int(W["mode_pre"])
        backend, res = self._solve_backend(i, cruise, m == K.EMERGENCY, q)
        total_iter = res.iterations
        # escalation while the QP needs slack: decelerating, then an emergency braking as hard
        # as needed (a_need), then the vehicle's whole braking range (a_need = -inf)
        a_need = W["a_need"]
        escalate = {K.ACCELERATE: [(K.BRAKE, a_need), (K.EMERGENCY, a_need), (K.EMERGENCY, -np.inf)],
                    K.EMERGENCY: [(K.EMERGENCY, -np.inf)]}.get(m, [(K.EMERGENCY, a_need), (K.EMERGENCY, -np.inf)])
        while res.ok and res.z[N] > s.slack_tol and escalate:
            # decelerating, a plan that needs slack only on the terminal chords (conservative by
            # up to v_max^2 / (8 K_TERM^2 |a_min|) metres) while it keeps every other row and the
            # exact terminal condition is within the driver's own limits: it brakes, no emergency
            if (m == K.SAIL or m == K.BRAKE) and self._only_chords_short(i, res.z[:N], arrays):
                break
            m, a_need = escalate.pop(0)
            lower0, upper0 = K.fill_bounds(self._record, i, m, v, u_prev, a_need, float(W["floor0"]))
            W["lower0"], W["upper0"], W["mode_pre"] = lower0, upper0, m
            if v + s.dt * upper0 <= 0.0:  # stopping inside the step anyway
                res = None
                break
            if res.duals is not None:
                K.store_active(self._record, i, res.duals, 1e-10)
            backend, res = self._solve_backend(i, cruise, m == K.EMERGENCY, q)
            total_iter += res.iterations
        upper0 = W["upper0"]
        W["iterations"] = total_iter
        st = self._stats[i]
        if res is None:
            W["u0"] = upper0
            W["path"] = K.HOLD
            st[K.ST_HOLD] += 1
            self.mode[i] = m if m == K.EMERGENCY else K.BRAKE  # stopping inside the step: the brake holds it
            st[K.ST_EMERGENCY] += m == K.EMERGENCY
            self._act_count[i] = 0
            return
        if res.ok:
            z = res.z
            u0 = min(max(z[0], W["lower0"]), upper0)  # solver tolerance never leaves the box
            self._plan[i] = z[:N]
            W["slack"] = z[N]
            W["u0"] = u0
            st[K.ST_QP] += 1
            st[K.ST_SLACK] += z[N] > s.slack_tol
            if res.duals is not None:
                K.store_active(self._record, i, res.duals, 1e-10)
            else:
                self._act_count[i] = 0
            if m == K.EMERGENCY or m == K.ACCELERATE:
                self.mode[i] = m
                st[K.ST_EMERGENCY] += m == K.EMERGENCY
            else:
                # SAIL: the pedals released (the coasting deceleration); harder: BRAKE; above it: still ACCELERATE
                self.mode[i] = K.decel_label(u0, K.coast_decel(self._record, i, v), 1e-6)
            return
        # --- fallback: stop behind the most demanding real target at x_min, or keep the plan
        W["path"] = K.FALLBACK
        st[K.ST_FALLBACK] += 1
        self._act_count[i] = 0
        x_min = float(self._drivers[i]["x_min"])
        a_need = np.inf
        gap, v_lead, stop_gap = arrays[2][i], arrays[3][i], arrays[5][i]
        for R, vt in ((gap, v_lead), (stop_gap + x_min, 0.0)):
            if np.isfinite(R) and v > vt:
                a_need = min(a_need, -(v - vt) ** 2 / (2.0 * max(R - x_min, 0.05)))
        planned = self._plan[i, 1]
        a_lo = float(accel_lower(v, self.vehicle.take(i)))
        u0 = float(np.clip(min(planned, a_need), a_lo, max(upper0, a_lo)))
        W["u0"] = u0
        self._plan[i, :-1] = self._plan[i, 1:]
        self.mode[i] = K.EMERGENCY if u0 < self._drivers[i]["a_min"] else (K.BRAKE if u0 < 0 else K.ACCELERATE)
        st[K.ST_EMERGENCY] += self.mode[i] == K.EMERGENCY


@dataclass(frozen=True)
class DriverModel:
    """A version of the human-like driver's behaviour: the MPC's settings and its perception
    (``None``: it sees the scene exactly and at once)."""

    version: int
    settings: MPCSettings
    perception: object = None  # acc_gym.drivers.perception.HumanPerception or None


def _driver_models() -> dict:
    from acc_gym.drivers.perception import HumanPerception

    return {5: DriverModel(5, MPCSettings()),
            6: DriverModel(6, MPCSettings(follow_in_range=True), HumanPerception())}


DRIVER_MODELS = _driver_models()  # version -> DriverModel; the versions a user can select


def driver_model(version) -> DriverModel:
    """The :class:`DriverModel` of ``version`` (an int in :data:`DRIVER_MODELS`)."""
    if isinstance(version, bool) or not isinstance(version, (int, np.integer)) or int(version) not in DRIVER_MODELS:
        raise ValueError(f"unknown driver model {version!r}; known: {sorted(DRIVER_MODELS)}")
    return DRIVER_MODELS[int(version)]


def human_drivers(params: MPCDriverParams, model: int = MODEL_VERSION, *, groups=None,
                  vehicle: VehicleParams | None = None, settings: MPCSettings | None = None) -> MPCDriver:
    """One :class:`MPCDriver` over ``params`` behaving as driver model ``model``.

    ``groups``: the perception's generators, ``[(numpy.random.Generator, rows), ...]`` over
    consecutive rows (one per ring or episode, so that each draws its own errors); needed
    only by a perception with estimation errors. ``settings``: overrides the model's settings except the
    behavioural switch that defines the model (``follow_in_range``)."""
    from acc_gym.drivers.perception import Perception

    dm = driver_model(model)
    s = dm.settings if settings is None else replace(settings, follow_in_range=dm.settings.follow_in_range)
    perception = None if dm.perception is None else Perception(dm.perception, params.size, s.dt, groups)
    return MPCDriver(params, vehicle=vehicle, settings=s, perception=perception)
