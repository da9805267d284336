"""Classical car-following models and ACC laws as array functions over vehicles.

Paper 001 Table 1 (Pipes, Gazis/GM, Newell, Tyler, Gipps), paper 003 Section 4.1 (GM,
Gipps with the extra reaction time theta, fuzzy reasoning), paper 004 Section II (ACC,
CACC, multi-predecessor CACC) and IDM (Treiber et al. 2000, the usual choice in traffic
simulators). Each model is

* a **pure function** of arrays (``gipps_speed``, ``idm_accel``, ...), usable on its own,
  and
* a **driver class** controlling ``n`` vehicles (``act(obs) -> a_des``, ``reset()``,
  ``info``), with a reaction-delay buffer where the model has a reaction time. Its law
  runs compiled (:mod:`acc_gym.drivers._baseline_kernels`: the array function's
  operations entry by entry, one call for all rows of a batch, ``act_into``), so a
  vector environment's baseline drivers cost one call per model and step; the array
  functions are the definitions (``tests/drivers/test_baselines.py``: equal to 1e-12).

Conventions: ``gap`` is bumper to bumper [m] (``inf``: nothing ahead); relative speed
``dv = v_lead - v`` (positive when the gap opens); decelerations ``b`` are negative, as in
Gipps's paper. A model's reaction time ``tau`` [s] delays what it *perceives* of the
scene by ``round(tau / dt)`` steps (its own speed is always current, as in the GM form
``a(t + T) = c v(t + T)^m dv(t) / dx(t)^l``). Models without a free-road term (GM,
Pipes, Tyler, fuzzy) are combined with a simple speed controller ``k_free (v_desired -
v)`` by taking the minimum (as ACC does), so that they cruise when nothing is ahead.
Speed-based models (Gipps, Newell) compute their speed for ``t + tau`` from the scene
seen at ``t``: they perceive the scene ``round(tau / dt) - 1`` steps late and ask for the
acceleration ``(v_target - v) / dt`` that reaches that speed at the end of the current
step, which is exactly their update rule when ``tau`` is a multiple of ``dt``. Every output is finite; the vehicle model
(:mod:`acc_gym.vehicle`) then limits it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from acc_gym._validation import check_finite
from acc_gym.drivers import _baseline_kernels as _k
from acc_gym.drivers.base import DelayBuffer, Observation, delay_steps

A_FLOOR = -20.0  # [m/s^2] outputs are clipped to [A_FLOOR, A_CEIL] (the vehicle limits further)
A_CEIL = 10.0


_PLAIN = (float, int)  # plain numbers: checked without building arrays (resets validate every new driver)


_FIELD_NAMES: dict = {}  # parameter dataclass -> its fields' names (resets validate every new driver)


def _validate(params, positive=(), negative=(), nonnegative=()):
    names = _FIELD_NAMES.get(type(params))
    if names is None:
        names = _FIELD_NAMES[type(params)] = tuple(f.name for f in fields(params))
    for name in names:
        value = getattr(params, name)
        if value is None:
            continue
        if type(value) in _PLAIN and math.isfinite(value) and not (
                (name in positive and value <= 0) or (name in negative and value >= 0)
                or (name in nonnegative and value < 0)):
            continue  # a valid plain number, checked without numpy (an invalid one gets the messages below)
        check_finite(f"{type(params).__name__}.{name}", value)
        arr = np.asarray(value, dtype=float)
        if name in positive and np.any(arr <= 0):
            raise ValueError(f"{type(params).__name__}.{name} must be > 0, got {value!r}")
        if name in negative and np.any(arr >= 0):
            raise ValueError(f"{type(params).__name__}.{name} must be < 0, got {value!r}")
        if name in nonnegative and np.any(arr < 0):
            raise ValueError(f"{type(params).__name__}.{name} must be >= 0, got {value!r}")


def _has(gap) -> np.ndarray:
    return np.isfinite(gap)


def free_accel(v, v_desired, k_free, a_max):
    """Free-road speed controller ``clip(k_free (v_desired - v), -a_max, a_max)`` [m/s^2]."""
    return np.clip(k_free * (v_desired - v), -a_max, a_max)


# ---------------------------------------------------------------------------------------
# Pure laws
# ---------------------------------------------------------------------------------------

def gipps_speed(v, gap, v_lead, a, b, b_hat, tau, v_desired, s0, theta=None):
    """Gipps (1981) speed after the reaction time ``tau`` [m/s].

    ``min(v + 2.5 a tau (1 - v/V) sqrt(0.025 + v/V),
          b (tau/2 + theta) + sqrt(b^2 (tau/2 + theta)^2 - b (2 (gap - s0) - v tau - v_lead^2 / b_hat)))``

    with ``b, b_hat < 0``; ``theta = tau / 2`` (default) is the 1981 form
    ``b tau + sqrt(b^2 tau^2 - ...)``, another ``theta`` paper 003's form. ``gap - s0``
    is ``x_lead - s_lead - x`` with ``s_lead`` the leader's length plus the standstill
    margin ``s0``. No vehicle ahead (``gap = inf``): only the free term. Where the root's
    argument is negative the safe speed is 0.
    """
    v = np.asarray(v, dtype=float)
    theta = 0.5 * np.asarray(tau, float) if theta is None else theta
    ratio = v / v_desired
    free = v + 2.5 * a * tau * (1.0 - ratio) * np.sqrt(np.maximum(0.025 + ratio, 0.0))
    h = 0.5 * tau + theta
    has = _has(gap)
    g = np.where(has, gap, 0.0)
    arg = b * b * h * h - b * (2.0 * (g - s0) - v * tau - np.asarray(v_lead, float) ** 2 / b_hat)
    safe = np.where(arg >= 0.0, b * h + np.sqrt(np.maximum(arg, 0.0)), 0.0)
    safe = np.where(has, np.maximum(safe, 0.0), np.inf)
    return np.maximum(np.minimum(free, safe), 0.0)


def gm_accel(v, gap, dv, c, m, l):
    """Gazis-Herman-Rothery (GM): ``c v^m dv / gap^l`` [m/s^2] (0 with nothing ahead)."""
    has = _has(gap)
    g = np.where(has, np.maximum(gap, 1e-3), 1.0)
    out = c * np.power(np.maximum(v, 0.0), m) * dv / np.power(g, l)
    return np.where(has, out, 0.0)


def fuzzy_accel(v, gap, dv, a_lead, T, gamma, s0, h, level_width, max_level, step):
    """Fuzzy-reasoning model (paper 003): ``(dv + a_lead T) / gamma + step * level``.

    The gap is "appropriate" within half a level of ``s0 + h v``; each ``level_width``
    [m] further (closer) adds (removes) ``step`` [m/s^2], up to ``max_level`` levels.
    """
    has = _has(gap)
    g = np.where(has, gap, 0.0)
    level = np.clip(np.round((g - (s0 + h * v)) / level_width), -max_level, max_level)
    out = (dv + a_lead * T) / gamma + step * level
    return np.where(has, out, 0.0)


def pipes_accel(dv, gap, c):
    """Pipes (1953): ``C dR`` [m/s^2] (0 with nothing ahead)."""
    return np.where(_has(gap), c * dv, 0.0)


def newell_speed(gap, v_desired, c, r_min):
    """Newell (1961): ``V_d (1 - exp(-C (R - R_min) / V_d))`` [m/s], ``V_d`` with nothing ahead."""
    has = _has(gap)
    g = np.where(has, gap, 0.0)
    v = v_desired * (1.0 - np.exp(-c * (g - r_min) / v_desired))
    return np.where(has, np.maximum(v, 0.0), v_desired)


def tyler_accel(v, gap, dv, c_v, c_s, c_t, s0):
    """Tyler (1964): ``C_V dR + C_S (R - s0 - C_t v)`` [m/s^2]; ``s0 = 0`` is Table 1's form."""
    has = _has(gap)
    g = np.where(has, gap, 0.0)
    return np.where(has, c_v * dv + c_s * (g - s0 - c_t * v), 0.0)


def idm_accel(v, gap, dv, a, b, time_gap, s0, v_desired, delta=4.0):
    """Intelligent Driver Model: ``a (1 - (v/v0)^delta - (s*/s)^2)``,
    ``s* = s0 + max(0, v T - v dv / (2 sqrt(a b)))`` with ``dv = v_lead - v`` and ``b > 0``."""
    v = np.asarray(v, dtype=float)
    free = 1.0 - np.power(np.maximum(v, 0.0) / v_desired, delta)
    has = _has(gap)
    g = np.where(has, np.maximum(gap, 1e-3), 1.0)
    s_star = s0 + np.maximum(0.0, v * time_gap - v * dv / (2.0 * np.sqrt(a * b)))
    inter = np.where(has, (s_star / g) ** 2, 0.0)
    return a * (free - inter)


def acc_accel(v, gap, dv, k1, k2, time_gap, s0, a_lead=0.0, k3=0.0):
    """Paper 004 Eqs. (1)/(2): ``k3 a_lead + k2 e_v + k1 e_x`` with ``e_x = gap - (s0 + h v)``."""
    has = _has(gap)
    g = np.where(has, gap, 0.0)
    return np.where(has, k3 * a_lead + k2 * dv + k1 * (g - (s0 + time_gap * v)), np.inf)


# ---------------------------------------------------------------------------------------
# Driver classes
# ---------------------------------------------------------------------------------------

class _Model:
    """Shared plumbing: batch size, optional perception delay, reset, info."""

    params_type: type
    name = "model"

    def __init__(self, params=None, n: int | None = None, dt: float = 0.2):
        self.params = params if params is not None else self.params_type()
        sizes = {f.name: 1 if type(v) in _PLAIN or v is None else np.size(v)
                 for f in fields(self.params) for v in (getattr(self.params, f.name),)}
        self.n = int(n) if n is not None else max(sizes.values())
        if self.n < 1:
            raise ValueError(f"n must be >= 1, got {self.n}")
        for f in fields(self.params):
            size = sizes[f.name]
            if size not in (1, self.n):
                raise ValueError(f"{type(self.params).__name__}.{f.name} has {size} values for n={self.n} vehicles")
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be > 0, got {dt!r}")
        self.dt = float(dt)
        self._delay = DelayBuffer(delay_steps(self._delay_time(), self.dt))
        self.info: dict[str, np.ndarray] = {}

    def _delay_time(self) -> float:
        tau = getattr(self.params, "tau", 0.0)
        return float(np.max(tau)) if tau is not None else 0.0

    def reset(self) -> None:
        self._delay.reset()

    def act(self, obs: Observation) -> np.ndarray:
        obs.validate(self.n)
        return self.act_checked(obs)

    def act_checked(self, obs: Observation) -> np.ndarray:
        """:meth:`act` for an observation whose shapes and values the caller has already checked
        (as :meth:`Observation.validate <acc_gym.drivers.base.Observation.validate>` would): the
        column simulation builds every observation itself and checks its values in one compiled
        pass per step, so the models need not check them again (:mod:`acc_gym.drivers.base`)."""
        return self._law(obs, self._delay.push(obs))  # finite and clipped by the compiled law

    def compiled_law(self) -> "CompiledLaw | None":
        """What a compiled loop needs to run this model's law itself, without calling :meth:`act`
        (the column simulation, :mod:`acc_gym.simulation._column_kernel`), or None for a subclass
        (which may change the law: it runs through :meth:`act`). The loop must give the law the
        scene :attr:`CompiledLaw.delay_steps` steps ago (the first one until then), exactly what
        this model's delay buffer would hand it after a :meth:`reset`."""
        if MODELS.get(self.name) is not type(self):
            return None
        params = np.full((self.n, _k.MAX_PARAMS), np.nan)
        for i, values in enumerate(self._param_arrays()):
            params[:, i] = values  # one value for all vehicles, or one each
        return CompiledLaw(_k.KINDS[self.name], params, self._delay.delay_steps, self.dt,
                           getattr(self.params, "predecessors", 1) == 2)

    # the parameters the model's compiled law (acc_gym.drivers._baseline_kernels) takes, in its order
    _kernel_fields: tuple[str, ...] = ()
    _kind = -1  # that law's code (_baseline_kernels.KINDS): the nearest package model's, set per class

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls._kind = _k.KINDS.get(cls.__dict__.get("name"), cls._kind)  # a subclass keeps its model's law

    def _param_arrays(self) -> tuple:
        """The parameters of :attr:`_kernel_fields` as float arrays (one value per row, or one for
        all; ``None`` as NaN), made once per parameter object: a
        :class:`~acc_gym.drivers.slots.BaselineRows` group writes new rows into these very arrays."""
        p = self.params
        cached = self.__dict__.get("_arrays")
        if cached is None or cached[0] is not p:
            cached = self._arrays = (p, tuple(np.ascontiguousarray(np.atleast_1d(np.asarray(getattr(p, name),
                                                                                             dtype=float)))
                                              for name in self._kernel_fields))
        return cached[1]

    def act_into(self, now: Observation, seen: Observation, rows: np.ndarray, out: np.ndarray) -> None:
        """The finite, clipped output of rows ``rows`` (as :meth:`act` gives it) into ``out``, by
        the model's compiled law (:func:`acc_gym.drivers._baseline_kernels.law_rows`): one call
        for a batch's rows; ``now`` is the scene now, ``seen`` what the rows perceive."""
        a_lead = seen.a_lead if seen.a_lead is not None else now.v  # (read by the laws that use it only)
        _k.law_rows(self._kind, self._param_arrays(), self.dt, False,
                    (now.v, seen.v, seen.gap, seen.v_lead, a_lead, now.v, now.v, now.v), rows, out)

    def _law(self, now: Observation, seen: Observation) -> np.ndarray:
        """Every row's output, finite and clipped to ``[A_FLOOR, A_CEIL]`` (:meth:`act_into`)."""
        out = np.empty(np.shape(now.v)[-1])
        self.act_into(now, seen, np.arange(out.size), out)
        return out


class CompiledLaw(NamedTuple):
    """A baseline model's law as a compiled loop runs it (:meth:`_Model.compiled_law`):
    :func:`acc_gym.drivers._baseline_kernels.law` with these arguments."""

    kind: int  # the law's code (acc_gym.drivers._baseline_kernels.KINDS)
    params: np.ndarray  # (n, MAX_PARAMS) each vehicle's parameters in the model's _kernel_fields order (NaN after)
    delay_steps: int  # perception delay [steps]: the law sees the scene this many steps ago
    dt: float  # [s] the model's step (Gipps and Newell ask for the speed at its end)
    two_ahead: bool  # ACC's Eq. (3): the second vehicle ahead too, where there is one


@dataclass(frozen=True)
class GippsParams:
    a: float | np.ndarray = 1.7  # [m/s^2] maximum acceleration the driver wishes
    b: float | np.ndarray = -3.0  # [m/s^2] most severe braking the driver wishes (< 0)
    b_hat: float | np.ndarray = -3.5  # [m/s^2] its estimate of the leader's braking (< 0)
    tau: float | np.ndarray = 0.6  # [s] reaction time (also the perception delay)
    theta: float | np.ndarray | None = None  # [s] extra reaction time (paper 003); None: tau/2
    v_desired: float | np.ndarray = 25.0  # [m/s]
    s0: float | np.ndarray = 2.0  # [m] standstill margin (s_lead minus the leader's length)

    def __post_init__(self):
        _validate(self, positive=("a", "tau", "v_desired"), negative=("b", "b_hat"), nonnegative=("theta", "s0"))


class _SpeedModel(_Model):
    """A model whose law gives the speed ``tau`` after the scene it sees."""

    def __init__(self, params=None, n=None, dt=0.2):
        super().__init__(params, n, dt)
        self._delay = DelayBuffer(max(delay_steps(float(np.max(self.params.tau)), self.dt) - 1, 0))


class Gipps(_SpeedModel):
    """Gipps (1981), or paper 003's form with ``theta``."""

    params_type = GippsParams
    name = "gipps"
    _kernel_fields = ("a", "b", "b_hat", "tau", "theta", "v_desired", "s0")



@dataclass(frozen=True)
class GMParams:
    c: float | np.ndarray = 12.0  # sensitivity [m^(l-m) s^(m-1)]; with m=0, l=1: 12 m/s
    m: float | np.ndarray = 0.0  # speed exponent
    l: float | np.ndarray = 1.0  # gap exponent
    tau: float | np.ndarray = 1.0  # [s] reaction time T
    v_desired: float | np.ndarray = 25.0  # [m/s] free-road speed
    k_free: float | np.ndarray = 0.4  # [1/s] free-road speed gain
    a_max: float | np.ndarray = 2.0  # [m/s^2] free-road acceleration bound
    # [m] the vehicle ahead's length: paper 003's GM divides by the distance between the two
    # vehicles' heads (bumper gap + this), not the bumper gap (the package's car length)
    length_ahead: float | np.ndarray = 4.7

    def __post_init__(self):
        _validate(self, positive=("c", "v_desired", "k_free", "a_max"), nonnegative=("m", "l", "tau", "length_ahead"))


class GM(_Model):
    """GM / Gazis-Herman-Rothery: own speed now, stimulus ``tau`` ago; min with the free-road law.

    The distance is head to head, as paper 003 states it ("inversely proportional to the
    distance between the heads of the two vehicles"): the bumper gap plus
    ``length_ahead``. (With the bumper gap the sensitivity ``c / gap`` would blow up at short
    gaps: full-brake steps of 40 m/s^3 at 60 and 90 km/h; head to head, its largest jerk
    there is about 2 m/s^3 and only the final emergency stop at 120 km/h saturates.)"""

    params_type = GMParams
    name = "gm"
    _kernel_fields = ("c", "m", "l", "v_desired", "k_free", "a_max", "length_ahead")



@dataclass(frozen=True)
class FuzzyParams:
    T: float | np.ndarray = 1.0  # [s] reaction time in the anticipation term (paper: 1 s)
    gamma: float | np.ndarray = 2.5  # [s] catch-up time (paper: 2.5 s)
    s0: float | np.ndarray = 2.0  # [m] standstill gap of the appropriate-gap policy
    h: float | np.ndarray = 1.5  # [s] time gap of the appropriate-gap policy
    level_width: float | np.ndarray = 5.0  # [m] width of one gap level
    max_level: float | np.ndarray = 3.0  # levels counted each way
    step: float | np.ndarray = 0.3  # [m/s^2] per level (paper: 0.3)
    tau: float | np.ndarray = 0.0  # [s] perception delay (the paper's T enters the law)
    v_desired: float | np.ndarray = 25.0
    k_free: float | np.ndarray = 0.4
    a_max: float | np.ndarray = 2.0

    def __post_init__(self):
        _validate(self, positive=("T", "gamma", "level_width", "v_desired", "k_free", "a_max"),
                  nonnegative=("s0", "h", "max_level", "step", "tau"))


class Fuzzy(_Model):
    """Fuzzy-reasoning car following (paper 003), min with the free-road law."""

    params_type = FuzzyParams
    name = "fuzzy"
    _kernel_fields = ("T", "gamma", "s0", "h", "level_width", "max_level", "step", "v_desired", "k_free", "a_max")



@dataclass(frozen=True)
class PipesParams:
    c: float | np.ndarray = 0.5  # [1/s]
    tau: float | np.ndarray = 1.0  # [s]
    v_desired: float | np.ndarray = 25.0
    k_free: float | np.ndarray = 0.4
    a_max: float | np.ndarray = 2.0

    def __post_init__(self):
        _validate(self, positive=("c", "v_desired", "k_free", "a_max"), nonnegative=("tau",))


class Pipes(_Model):
    """Pipes (1953) ``a(t + tau) = C dR(t)``, min with the free-road law."""

    params_type = PipesParams
    name = "pipes"
    _kernel_fields = ("c", "v_desired", "k_free", "a_max")



@dataclass(frozen=True)
class NewellParams:
    c: float | np.ndarray = 0.6  # [1/s] slope of speed over spacing at small spacings
    r_min: float | np.ndarray = 2.0  # [m] jam spacing (bumper to bumper)
    tau: float | np.ndarray = 0.6  # [s]
    v_desired: float | np.ndarray = 25.0

    def __post_init__(self):
        _validate(self, positive=("c", "tau", "v_desired"), nonnegative=("r_min",))


class Newell(_SpeedModel):
    """Newell (1961): the speed ``tau`` after seeing the spacing (collision-free if ``C tau < 1``)."""

    params_type = NewellParams
    name = "newell"
    _kernel_fields = ("c", "r_min", "v_desired")



@dataclass(frozen=True)
class TylerParams:
    c_v: float | np.ndarray = 0.8  # [1/s]
    c_s: float | np.ndarray = 0.2  # [1/s^2]
    c_t: float | np.ndarray = 1.5  # [s] time gap
    s0: float | np.ndarray = 2.0  # [m] standstill distance (0: Table 1's form)
    tau: float | np.ndarray = 0.6  # [s]
    v_desired: float | np.ndarray = 25.0
    k_free: float | np.ndarray = 0.4
    a_max: float | np.ndarray = 2.0

    def __post_init__(self):
        _validate(self, positive=("c_v", "c_s", "v_desired", "k_free", "a_max"), nonnegative=("c_t", "s0", "tau"))


class Tyler(_Model):
    """Tyler (1964) ``C_V dR + C_S (R - s0 - C_t v)``, min with the free-road law."""

    params_type = TylerParams
    name = "tyler"
    _kernel_fields = ("c_v", "c_s", "c_t", "s0", "v_desired", "k_free", "a_max")



@dataclass(frozen=True)
class IDMParams:
    """IDM's parameters. **The time headway is** ``time_gap`` (IDM's T; SUMO calls it
    ``tau``); ``tau`` here is a *reaction delay* (IDM has none), as for every model of this
    module. Passing ``tau=1.5`` meaning the headway gives a follower that perceives 1.5 s
    late and keeps the default 1.5 s headway -- it crashes -- so a ``tau`` of 0.5 s or more
    with ``time_gap`` left at its default warns."""

    a: float | np.ndarray = 1.5  # [m/s^2] maximum acceleration
    b: float | np.ndarray = 2.0  # [m/s^2] comfortable deceleration (> 0, IDM's convention)
    time_gap: float | np.ndarray = 1.5  # [s] T, the time headway (SUMO's tau)
    s0: float | np.ndarray = 2.0  # [m] standstill gap
    v_desired: float | np.ndarray = 25.0  # [m/s] v0
    delta: float | np.ndarray = 4.0  # acceleration exponent
    tau: float | np.ndarray = 0.0  # [s] perception DELAY, not the headway (IDM has none; for experiments)

    def __post_init__(self):
        _validate(self, positive=("a", "b", "v_desired", "delta"), nonnegative=("time_gap", "s0", "tau"))
        tau, time_gap = self.tau, self.time_gap
        if (tau >= 0.5 and time_gap == 1.5) if type(tau) in _PLAIN and type(time_gap) in _PLAIN else (
                np.any(np.asarray(tau) >= 0.5) and np.all(np.asarray(time_gap) == 1.5)):
            warnings.warn(f"IDMParams(tau={self.tau!r}) is a reaction delay, not IDM's time headway (that is "
                          f"time_gap, left at 1.5 s): did you mean time_gap={self.tau!r}? (SUMO's tau is the "
                          f"headway)", UserWarning, stacklevel=3)


class IDM(_Model):
    """Intelligent Driver Model (Treiber, Hennecke, Helbing 2000)."""

    params_type = IDMParams
    name = "idm"
    _kernel_fields = ("a", "b", "time_gap", "s0", "v_desired", "delta")



@dataclass(frozen=True)
class ACCParams:
    k1: float | np.ndarray = 0.2  # [1/s^2] gap-error gain
    k2: float | np.ndarray = 0.6  # [1/s] speed-error gain
    k3: float | np.ndarray = 0.0  # [-] lead-acceleration gain (CACC, Eq. 2)
    time_gap: float | np.ndarray = 1.5  # [s] h in x_d = s0 + h v
    s0: float | np.ndarray = 2.0  # [m]
    v_set: float | np.ndarray = 25.0  # [m/s] set speed
    k_cruise: float | np.ndarray = 0.4  # [1/s] speed-control gain
    a_max: float | np.ndarray = 2.0  # [m/s^2] bound of the speed controller
    predecessors: int = 1  # n in Eq. (3) (multi-predecessor CACC uses 2)
    vehicle_length: float | np.ndarray = 4.7  # [m] l_v in the spacing n x_d + (n-1) l_v

    def __post_init__(self):
        _validate(self, positive=("time_gap", "v_set", "k_cruise", "a_max"),
                  nonnegative=("k1", "k2", "k3", "s0", "vehicle_length"))
        if self.predecessors not in (1, 2):
            raise ValueError(f"ACCParams.predecessors must be 1 or 2, got {self.predecessors!r}")


class ACC(_Model):
    """Paper 004's ACC (Eq. 1), CACC (Eq. 2, ``k3 > 0``) and multi-predecessor CACC (Eq. 3,
    ``predecessors=2``: one law per preceding vehicle ``n`` with spacing ``n x_d + (n-1) l_v``,
    the minimum taken), each limited by the set-speed controller."""

    params_type = ACCParams
    name = "acc"
    _kernel_fields = ("k1", "k2", "k3", "time_gap", "s0", "v_set", "k_cruise", "a_max", "vehicle_length")

    def act_into(self, now, seen, rows, out):  # acc_accel (and Eq. 3's second vehicle), min free_accel, compiled
        # the law reads the current scene (ACC has no reaction delay); for the second vehicle ahead
        # x_d is 2 x_d + l_v, i.e. s0 and h doubled plus one length
        two = self.params.predecessors == 2 and now.gap2 is not None
        g2, vl2, al2 = (now.gap2, now.v_lead2, now.a_lead2) if two else (now.v, now.v, now.v)
        _k.law_rows(_k.ACC, self._param_arrays(), self.dt, two, (now.v, now.v, now.gap, now.v_lead, now.a_lead, g2, vl2,
                                                                 al2), rows, out)


def cacc_params(**kw) -> ACCParams:
    """CACC defaults: a shorter time gap (0.6 s) and lead-acceleration feed-forward (k3 = 1)."""
    return ACCParams(**{"k3": 1.0, "time_gap": 0.6, **kw})


def mp_cacc_params(**kw) -> ACCParams:
    """Multi-predecessor CACC defaults (Eq. 3 over the two vehicles ahead)."""
    return ACCParams(**{"k3": 1.0, "time_gap": 0.6, "predecessors": 2, **kw})


MODELS = {"gipps": Gipps, "gm": GM, "fuzzy": Fuzzy, "pipes": Pipes, "newell": Newell, "tyler": Tyler,
          "idm": IDM, "acc": ACC}
