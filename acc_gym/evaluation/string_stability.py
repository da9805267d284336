"""String stability: does a speed disturbance shrink or grow down a column of vehicles?

``string_stability(controller)`` puts ``N`` copies of a controller (default 8, up to 100)
in one column behind a lead and measures, on this package's vehicle model and at the
environments' step (0.2 s), how the lead's speed fluctuations pass from vehicle to
vehicle:

* **frequency response**: the lead oscillates, ``v_0(t) = V + A(f) sin(2 pi f t)``, at
  each frequency of a grid (default 25 frequencies from 0.005 to 1 Hz, log-spaced), faded
  in over the first half of the settling time (``settle``, 200 s); from then on each
  vehicle's speed is fitted with ``c + Y sin + Y' cos`` by least squares and the gain of
  each pair is ``|Gamma_i(j w)| = |Y_i| / |Y_(i-1)|`` (Ploeg, van de Wouw and Nijmeijer
  2014). The amplitude ``A(f) = min(0.5 m/s, 0.25 m/s^2 / w)`` keeps the lead's
  acceleration small, so the controllers stay in their linear range;
* **a disturbance like Gunter et al.'s (2020)**: the lead slows by 6 mph (2.68 m/s) at
  1 m/s^2, holds 5 s, and recovers at 0.5 m/s^2; each vehicle's largest speed drop, and the
  L2 and L-infinity gains of the speed error ``v_i - V`` and of the acceleration from
  vehicle to vehicle;
* optionally **a lead trace**: a recorded speed profile, or a human-like stop-and-go
  wave (:func:`acc_gym.scenarios.stopandgo.wave_profile`).

All frequencies and the disturbance are the rows of one batched simulation: every
controlled position's copy answers its rows in one ``predict`` call per step (a
controller whose ``vectorised`` attribute is false gets one copy per row instead).

**Verdict.** String stable when the largest pair gain over the grid is at most
``1 + tolerance`` (:data:`TOLERANCE`, 0.005: the measurement's error on a controller
whose true gain is 1, which is 1e-5 here, with a margin for slow transients); the report
lists the frequency bands where it is not. A pair is measured where its predecessor
oscillates with at least :data:`RESOLUTION` (1e-4 m/s: the observation is float32, about
2e-6 m/s at 20 m/s, and far down a strongly damping column the oscillation falls below
what the copies can see) and both speeds are sinusoids to within :data:`MAX_RESIDUAL`
(5 % rms residual; ``report.steady``). Where the predecessor's speed is such a sinusoid but
the vehicle's is not -- it grows (a loop unstable on its own), or it is far from linear --
the pair's gain is the ratio of their largest deviations when that exceeds
``1 + tolerance`` (amplification in the L-infinity sense). Other pairs are NaN and take no
part in the verdict.

**Decisions** (documented here, tested in ``tests/evaluation/test_string_stability.py``):

* The column starts at equilibrium: each kind of vehicle (the controller, each human
  driver) first follows a lead at constant speed for 150 s, two copies deep; the
  column is then placed at the gaps they settled at. A controller that does not settle
  (its speed more than 0.05 m/s off the lead's, or its gap still moving more than 0.05 m
  over the last 10 s) has no steady state to disturb: :class:`StringStabilityError` says
  what it did.
* The observation is the environments' ``-v0`` one (``-v1``'s with ``version=1``), built by
  the same compiled function, float32; the set speed is the operating speed plus 5 m/s
  (``set_speed``), so the cruise law does not bind; the time gap is the controller's
  declared one (its ``time_gap`` attribute) or 1.5 s.
* Mixed traffic: with ``penetration`` p < 1 the controller drives ``k = round(p N)`` of the
  ``N`` positions, spread evenly (``ceil((i + 1) N / k)`` for i = 0..k-1, so the last
  vehicle is always one of them), and human-like MPC drivers of the population
  ``drivers`` drive the others (one driver per position, drawn from
  ``default_rng([seed, 34])``, desired speed the set speed), behaving as driver model
  ``driver_model`` (:data:`acc_gym.drivers.mpc.DRIVER_MODELS`; by default the
  environments' model, :data:`~acc_gym.drivers.mpc.ENV_DRIVER_MODEL`). A model whose
  perception draws estimation errors draws them, in each row of a batch (a frequency, the
  disturbance, the trace, an equilibrium run), from its own generator,
  ``default_rng(SeedSequence([seed, 34, 2, crc32(row name)]))``: a row's draws do not
  depend on the other rows of its batch (model 6's perception has no errors and draws
  nothing). ``p = 0`` (the controller ``"human"``) measures the human column alone.
* A column whose vehicle collides, or whose controller answers NaN, infinity or the wrong
  shape, or raises, is a failed row: the report names the frequency (or input), the
  vehicle and the time, and gives the other rows' results. (A controller that raises in
  a batched call is run again one row at a time, so the failure is named per row.)

**Analytic reference** (:func:`linear_transfer`). The vehicle model realises the desired
acceleration over the next step (zero-order hold, exact integration), so with
``z = exp(j w dt)`` a vehicle's speed and position are ``V = dt/(z-1) A`` and ``X = I V``,
``I = dt (z+1) / (2 (z-1))`` (the trapezoidal integrator). The linear ACC law
``a = k2 (v_(i-1) - v_i) + k1 (gap - s0 - h v_i)`` (plus ``k3 a_(i-1)`` for CACC, where the
observation holds the vehicle ahead's acceleration over the last step, ``z^-1 A_(i-1)``)
gives::

    (z-1)/dt V_i = (k2 + k1 I)(V_(i-1) - V_i) - k1 h V_i + k3 z^-1 (z-1)/dt V_(i-1)

    Gamma(z) = (k2 + k1 I + k3 (z-1)/(dt z)) / ((z-1)/dt + k2 + k1 I + k1 h)

which tends to the continuous ``(k3 s^2 + k2 s + k1) / (s^2 + (k2 + k1 h) s + k1)`` as
``dt -> 0``; there the ACC (k3 = 0) is string stable iff ``k1 h^2 + 2 k2 h - 2 >= 0``.
:func:`time_gap_threshold` finds the sampled system's threshold: 0.761 s for the built-in
``acc`` (k1 = 0.3, k2 = 1.2; the 0.2 s sampling moves it by less than 1e-5 s from the
continuous 0.761 s), 0.320 s for ``cacc`` (k3 = 0.6).
"""

from __future__ import annotations

import copy
import math
import zlib
from dataclasses import dataclass, field

import numpy as np

from acc_gym._validation import check_finite
from acc_gym.drivers.base import Observation
from acc_gym.drivers.mpc import DRIVER_MODELS, ENV_DRIVER_MODEL, driver_model, human_drivers
from acc_gym.drivers.population import KINDS, sample_drivers
from acc_gym.envs import _kernel as K
from acc_gym.envs.core import DT
from acc_gym.onboard import ActuatorConfig, Actuators, actuator_config
from acc_gym.onboard.actuators import transfer as actuator_transfer
from acc_gym.simulation._world_kernel import advance
from acc_gym.vehicle import VehicleParams

TOLERANCE = 0.005  # gains up to 1 + TOLERANCE count as string stable
MAX_RESIDUAL = 0.05  # a pair is measured only where both speeds are sinusoids to within this (rms residual / rms)
RESOLUTION = 1e-4  # [m/s] a pair is measured only where its predecessor's oscillation is at least this
FREQUENCIES = tuple(np.geomspace(0.005, 1.0, 25).round(6))  # [Hz] the default grid
SPEED_AMPLITUDE = 0.5  # [m/s] the lead's speed amplitude at low frequency
ACCEL_AMPLITUDE = 0.25  # [m/s^2] ... capped so that its acceleration amplitude is at most this
GUNTER_DROP = 6 * 0.44704  # [m/s] Gunter et al.'s 6 mph disturbance
MAX_VEHICLES = 100
EQUILIBRIUM_TIME = 150.0  # [s] each kind of vehicle follows a constant-speed lead this long first
SPEED_SETTLED = 0.05  # [m/s]
GAP_SETTLED = 0.05  # [m] over the last 10 s
RAMP_SHARE = 0.5  # the sweep's oscillation fades in over this share of the settling time
SET_SPEED_MARGIN = 5.0  # [m/s] the set speed above the operating speed, by default
LENGTH = VehicleParams().length  # [m] every vehicle's


class StringStabilityError(ValueError):
    """The column cannot be measured at all (e.g. the controller has no steady state)."""


@dataclass(frozen=True)
class PlatoonConfig:
    """The column and its operating point; validated on construction.

    ``vehicles`` followers (1-100) behind the lead at ``speed`` [m/s]; ``set_speed`` and
    ``time_gap`` are what the observation says (None: speed + 5 m/s; the controller's
    declared time gap, else 1.5 s); ``penetration`` the share of the positions the
    controller drives, ``drivers`` the human population of the others and ``seed`` their
    draw, ``driver_model`` their behaviour (a version in
    :data:`~acc_gym.drivers.mpc.DRIVER_MODELS`; default the environments' model 5; an
    unknown one is a ValueError naming it); ``settle`` [s] the time from the start of the
    oscillation to the start of the fit; ``v2v``, ``version``, ``accel_max``, ``decel_max`` and ``sensor_range`` as in
    :class:`~acc_gym.envs.config.EnvConfig`; ``actuators`` the lag and dead time between the
    controller's command and its vehicle's acceleration (:mod:`acc_gym.onboard.actuators`;
    the human drivers' vehicles have none: their reaction is their driver model's).
    """

    vehicles: int = 8
    speed: float = 20.0  # [m/s]
    set_speed: float | None = None  # [m/s]
    time_gap: float | None = None  # [s]
    penetration: float = 1.0  # [-]
    drivers: str = "typical"
    seed: int = 0
    settle: float = 200.0  # [s]
    v2v: bool = False
    version: int = 0
    accel_max: float = 3.0  # [m/s^2]
    decel_max: float = 8.0  # [m/s^2]
    sensor_range: float = 200.0  # [m]
    driver_model: int = ENV_DRIVER_MODEL  # the human drivers' model (acc_gym.drivers.mpc.DRIVER_MODELS)
    # the controller's vehicles' actuators (acc_gym.onboard.actuators; a preset's name, a mapping or the config)
    actuators: ActuatorConfig = field(default_factory=ActuatorConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "actuators", actuator_config(self.actuators))
        n = self.vehicles
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_VEHICLES:
            raise ValueError(f"PlatoonConfig.vehicles must be an integer from 1 to {MAX_VEHICLES}, got {n!r}")
        for name, low, high in (("speed", 0.0, 60.0), ("set_speed", 0.0, 70.0), ("time_gap", 0.0, 10.0),
                                ("settle", 0.0, 3600.0), ("accel_max", 0.0, 50.0), ("decel_max", 0.0, 50.0),
                                ("sensor_range", 0.0, 1e4)):
            value = getattr(self, name)
            if value is None and name in ("set_speed", "time_gap"):
                continue
            number = isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool)
            if not number or not math.isfinite(value) or not low < value <= high:
                raise ValueError(f"PlatoonConfig.{name} must be a number in ({low:g}, {high:g}], got {value!r}")
        p = self.penetration
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not (math.isfinite(p) and 0.0 <= p <= 1.0):
            raise ValueError(f"PlatoonConfig.penetration must be a share in [0, 1], got {p!r}")
        if self.drivers not in KINDS:
            raise ValueError(f"PlatoonConfig.drivers must be one of {list(KINDS)}, got {self.drivers!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"PlatoonConfig.seed must be an integer >= 0, got {self.seed!r}")
        if self.version not in (0, 1) or isinstance(self.version, bool):
            raise ValueError(f"PlatoonConfig.version must be 0 or 1, got {self.version!r}")
        if not isinstance(self.v2v, bool):
            raise ValueError(f"PlatoonConfig.v2v must be True or False, got {self.v2v!r}")
        try:
            driver_model(self.driver_model)
        except ValueError:
            raise ValueError(f"PlatoonConfig.driver_model must be one of {sorted(DRIVER_MODELS)}, got "
                             f"{self.driver_model!r}") from None

    @property
    def cruise_speed(self) -> float:
        """The set speed in the observation [m/s] (and the human drivers' desired speed)."""
        return float(self.set_speed) if self.set_speed is not None else float(self.speed) + SET_SPEED_MARGIN

    @property
    def controlled(self) -> tuple[int, ...]:
        """The positions (1 = behind the lead) the controller drives."""
        n = self.vehicles
        k = int(round(self.penetration * n))
        return tuple(int(math.ceil((i + 1) * n / k)) for i in range(k))


# -- analytic reference -----------------------------------------------------------------------------
def linear_transfer(freq_hz, k1: float, k2: float, h: float, k3: float = 0.0, dt: float = DT,
                    actuators: ActuatorConfig | None = None) -> np.ndarray:
    """``Gamma(exp(j w dt))`` of the linear ACC / CACC law on the sampled vehicle model
    (module docstring); ``dt = 0`` gives the continuous-time ``Gamma(j w)``.

    With ``actuators`` (:mod:`acc_gym.onboard.actuators`) the vehicle realises
    ``A = G U`` of the law's command ``U`` (``G`` :func:`acc_gym.onboard.actuators.transfer`:
    the lag ``alpha z / (z - 1 + alpha)`` and the dead time), so ``(z-1)/dt V_i = G (N V_(i-1) -
    D V_i)`` with ``N`` the numerator and ``D = k2 + k1 I + k1 h`` of the law::

        Gamma(z) = G N / ((z-1)/dt + G D)

    (continuous: ``(k3 s^2 + k2 s + k1) e^(-s D) / ((T s + 1) s^2 + ((k2 + k1 h) s + k1) e^(-s D))``).
    The feed-forward ``k3`` term acts on the vehicle ahead's realised acceleration, which its
    V2V message carries, so ``N`` is unchanged."""
    w = 2.0 * np.pi * np.asarray(freq_hz, dtype=float)
    g = 1.0 if actuators is None else actuator_transfer(actuators, freq_hz, dt)
    if dt == 0:
        s = 1j * w
        return g * (k3 * s * s + k2 * s + k1) / (s * s + g * ((k2 + k1 * h) * s + k1))
    z = np.exp(1j * w * dt)
    integ = dt * (z + 1.0) / (2.0 * (z - 1.0))
    num = k2 + k1 * integ + k3 * (z - 1.0) / (dt * z)
    return g * num / ((z - 1.0) / dt + g * (k2 + k1 * integ + k1 * h))


def time_gap_threshold(k1: float, k2: float, k3: float = 0.0, dt: float = DT, h_max: float = 5.0,
                       actuators: ActuatorConfig | None = None) -> float:
    """The smallest time gap [s] at which the linear law's ``sup_w |Gamma|`` is at most 1: the
    first stable one on a 0.01 s grid up to ``h_max``, refined by bisection (the sup over 4,000
    frequencies up to the Nyquist frequency). ``inf`` when none is. (Not monotone in general:
    sampled CACC gains more than 1 near the Nyquist frequency again at large time gaps.)"""
    f_top = 0.5 / dt if dt > 0 else 50.0
    freqs = np.geomspace(1e-4, f_top * 0.999, 4000)

    def stable(h):
        return float(np.max(np.abs(linear_transfer(freqs, k1, k2, h, k3, dt, actuators)))) <= 1.0 + 1e-9

    grid = np.arange(0.0, h_max + 1e-9, 0.01)
    ok = [h for h in grid if stable(h)]
    if not ok:
        return math.inf
    hi = float(ok[0])
    if hi == 0.0:
        return 0.0
    lo = hi - 0.01
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if stable(mid) else (mid, hi)
    return hi


# -- results ------------------------------------------------------------------------------------------
@dataclass
class RowError:
    """What went wrong in one row (a frequency or an input) of the batch."""

    row: str  # "0.0123 Hz", "disturbance", "trace"
    vehicle: int  # position in the column (1 = behind the lead)
    time_s: float  # [s]
    message: str

    def __str__(self) -> str:
        return f"{self.row}: vehicle {self.vehicle} at t = {self.time_s:.1f} s: {self.message}"


@dataclass
class Disturbance:
    """The column's response to one lead input (:func:`disturbance_lead` or a trace)."""

    name: str
    lead_drop: float  # [m/s] the lead's largest drop below its starting speed
    drops: np.ndarray  # (N,) [m/s] each follower's largest drop below the starting speed
    l2_speed: np.ndarray  # (N,) ||e_i||_2 / ||e_(i-1)||_2, e = v - v(0)
    linf_speed: np.ndarray  # (N,)
    l2_accel: np.ndarray  # (N,)
    linf_accel: np.ndarray  # (N,)
    min_gap: np.ndarray  # (N,) [m]
    t: np.ndarray  # (T+1,) [s]
    x: np.ndarray  # (T+1, N+1) [m] lead first
    v: np.ndarray  # (T+1, N+1) [m/s]

    def to_dict(self) -> dict:
        def lst(a):
            return [None if not math.isfinite(float(x)) else round(float(x), 6) for x in a]
        return {"name": self.name, "lead_drop": round(float(self.lead_drop), 6), "drops": lst(self.drops),
                "l2_speed_gains": lst(self.l2_speed), "linf_speed_gains": lst(self.linf_speed),
                "l2_accel_gains": lst(self.l2_accel), "linf_accel_gains": lst(self.linf_accel),
                "min_gaps": lst(self.min_gap)}


@dataclass
class StringStabilityReport:
    """Everything measured; ``to_dict()`` is the ``--json`` object."""

    controller: str
    config: PlatoonConfig
    time_gap: float  # [s] the one in the observation
    positions: tuple  # the controlled positions
    frequencies: np.ndarray  # (F,) [Hz]
    amplitudes: np.ndarray  # (F,) [m/s] the lead's
    pair_gains: np.ndarray  # (F, N): |Gamma_i|, NaN where not measured
    pair_phases: np.ndarray  # (F, N) [rad]
    column_gain: np.ndarray  # (F,) |V_N / V_0|
    residuals: np.ndarray  # (F, N+1) each speed's rms residual of the sinusoid fit / its rms
    steady: np.ndarray  # (F, N) the pair's gain is |Y_i / Y_(i-1)| of two clean sinusoids (else a peak ratio)
    errors: list = field(default_factory=list)  # RowError
    disturbance: Disturbance | None = None
    trace: Disturbance | None = None
    tolerance: float = TOLERANCE

    @property
    def gains(self) -> np.ndarray:
        """(F,) the largest measured pair gain at each frequency (NaN: none measured)."""
        g = self.pair_gains
        out = np.full(g.shape[0], np.nan)
        ok = np.isfinite(g).any(axis=1)
        out[ok] = np.nanmax(g[ok], axis=1)
        return out

    @property
    def max_gain(self) -> float:
        g = self.gains
        return float(np.nanmax(g)) if np.isfinite(g).any() else math.nan

    @property
    def string_stable(self) -> bool | None:
        """True / False by the verdict rule; None when no frequency could be measured."""
        m = self.max_gain
        return None if not math.isfinite(m) else bool(m <= 1.0 + self.tolerance)

    @property
    def unstable_bands(self) -> list[tuple[float, float]]:
        """Runs of grid frequencies [Hz] whose gain exceeds ``1 + tolerance``: (first, last)."""
        bad = np.nan_to_num(self.gains, nan=0.0) > 1.0 + self.tolerance
        bands, start = [], None
        for i, b in enumerate(list(bad) + [False]):
            if b and start is None:
                start = i
            elif not b and start is not None:
                bands.append((float(self.frequencies[start]), float(self.frequencies[i - 1])))
                start = None
        return bands

    def to_dict(self) -> dict:
        c = self.config

        def num(x):
            return None if x is None or not math.isfinite(float(x)) else round(float(x), 6)
        return {
            "controller": self.controller, "vehicles": c.vehicles, "speed": c.speed, "set_speed": c.cruise_speed,
            "time_gap": self.time_gap, "penetration": c.penetration, "positions": list(self.positions),
            "drivers": c.drivers if len(self.positions) < c.vehicles else None,
            "driver_model": c.driver_model if len(self.positions) < c.vehicles else None, "v2v": c.v2v,
            "max_gain": num(self.max_gain), "string_stable": self.string_stable, "tolerance": self.tolerance,
            "unstable_bands_hz": [list(b) for b in self.unstable_bands],
            "frequencies": [{"freq_hz": float(f), "gain": num(g), "lead_amplitude": num(a), "column_gain": num(cg),
                             "pair_gains": [num(x) for x in row]}
                            for f, g, a, cg, row in zip(self.frequencies, self.gains, self.amplitudes,
                                                        self.column_gain, self.pair_gains)],
            "disturbance": None if self.disturbance is None else self.disturbance.to_dict(),
            "trace": None if self.trace is None else self.trace.to_dict(),
            "errors": [{"row": e.row, "vehicle": e.vehicle, "time_s": round(e.time_s, 3), "message": e.message}
                       for e in self.errors],
        }

    def summary(self) -> str:
        c = self.config
        verdict = {True: "string stable", False: "NOT string stable", None: "no verdict"}[self.string_stable]
        lines = [f"{self.controller}: {c.vehicles} vehicles at {c.speed:g} m/s, time gap {self.time_gap:g} s"
                 + (f", controller in positions {list(self.positions)} ({c.drivers} human drivers, driver model "
                    f"{c.driver_model}, elsewhere)"
                    if len(self.positions) < c.vehicles else ""),
                 f"  largest gain {self.max_gain:.4f} -> {verdict} (rule: <= 1 + {self.tolerance:g})"]
        if self.unstable_bands:
            lines.append("  gain > 1 in " + ", ".join(f"{a:.4g}-{b:.4g} Hz" for a, b in self.unstable_bands))
        lines.append("  freq [Hz]   gain    column |V_N/V_0|")
        for f, g, cg in zip(self.frequencies, self.gains, self.column_gain):
            lines.append(f"  {f:9.4f}  {g:7.4f}  {cg:9.4f}")
        d = self.disturbance
        if d is not None:
            lines.append(f"  disturbance: lead drops {d.lead_drop:.2f} m/s; followers "
                         + " ".join(f"{x:.2f}" for x in d.drops) + " m/s")
        for e in self.errors:
            lines.append(f"  FAILED {e}")
        return "\n".join(lines)


# -- the simulation -----------------------------------------------------------------------------------
class _Raised(Exception):
    def __init__(self, vehicle: int, k: int, exc: BaseException):
        super().__init__(str(exc))
        self.vehicle, self.k, self.exc = vehicle, k, exc


def _describe_exc(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {text}"


class _Copies:
    """The controller's copies for the controlled cells of a ``(B, N)`` layout: one per column
    position when it is vectorised (its cells in one ``predict``), else one per cell; each
    made from the pristine controller and ``reset()`` before its first call."""

    def __init__(self, controller, cells: np.ndarray):
        self.vectorised = bool(getattr(controller, "vectorised", False))
        self.cells = cells  # (M, 2) rows of (b, j) with j 0-based, in row-major order
        if self.vectorised:
            self.groups = [(int(j), np.flatnonzero(cells[:, 1] == j)) for j in np.unique(cells[:, 1])]
            self.copies = [copy.deepcopy(controller) for _ in self.groups]
        else:
            self.copies = [copy.deepcopy(controller) for _ in range(len(cells))]
        for c in self.copies:
            if hasattr(c, "reset"):
                c.reset()

    def __call__(self, obs: np.ndarray, k: int, failed: np.ndarray, errors: dict, row_names, t: float) -> np.ndarray:
        from acc_gym.evaluation.runner import _action, as_action

        out = np.zeros(len(self.cells))
        if self.vectorised:
            for (j, idx), c in zip(self.groups, self.copies):
                try:
                    raw = np.asarray(_action(c, obs[idx]), dtype=float).reshape(-1)
                except Exception as exc:  # noqa: BLE001  (the controller's fault: attributed by the caller)
                    raise _Raised(j + 1, k, exc) from None
                if raw.shape != (idx.size,):
                    raise _Raised(j + 1, k, ValueError(f"answered {idx.size} observations with {raw.size} values"))
                for r in idx[~np.isfinite(raw)]:
                    self._fail(int(r), raw[np.searchsorted(idx, r)], failed, errors, row_names, t)
                # float32, as the env's action space and the sandbox's answers are
                out[idx] = np.where(np.isfinite(raw), np.clip(raw, -1.0, 1.0), 0.0).astype(np.float32)
            return out
        for r, c in enumerate(self.copies):
            b = int(self.cells[r, 0])
            if failed[b]:
                continue
            try:
                out[r] = as_action(_action(c, obs[r]), c)[0]
            except Exception as exc:  # noqa: BLE001
                failed[b] = True
                errors[b] = RowError(row_names[b], int(self.cells[r, 1]) + 1, t, _describe_exc(exc))
        return out

    def _fail(self, r: int, value: float, failed, errors, row_names, t) -> None:
        b = int(self.cells[r, 0])
        if not failed[b]:
            failed[b] = True
            what = "NaN" if math.isnan(value) else "infinite"
            errors[b] = RowError(row_names[b], int(self.cells[r, 1]) + 1, t, f"returned an action that is {what}")


class Remote:
    """The controller's side when its copies live in another process (the leaderboard's
    sandbox): each controlled cell is a slot there -- a fresh copy of the controller,
    ``reset()`` at its first call -- and ``exchange(obs, starts, slots)`` sends one step's
    rows and returns one action per row. What the controller does wrong (it raises, answers
    NaN, overruns its budget) is raised by ``exchange``: the measurement ends there."""

    def __init__(self, exchange, cells: np.ndarray, first_slot: int):
        self.exchange, self.cells = exchange, cells
        # one slot per column position: its rows (one per frequency) go to one copy there when
        # the controller is vectorised, as _Copies does here (the sandbox decides)
        _, position = np.unique(cells[:, 1], return_inverse=True)
        self.slots = first_slot + position.reshape(-1)
        self.first = True

    def __call__(self, obs: np.ndarray, k: int, failed: np.ndarray, errors: dict, row_names, t: float) -> np.ndarray:
        starts = np.full(len(self.cells), self.first)
        self.first = False
        acts = np.asarray(self.exchange(obs.astype(float), starts, self.slots), dtype=float).reshape(-1)
        if acts.shape != (len(self.cells),) or not np.all(np.isfinite(acts)):
            raise ValueError(f"the controller answered {len(self.cells)} observations with {acts.size} values, "
                             f"not all finite")
        return np.clip(acts, -1.0, 1.0)


def remote_actors(exchange, first_slot: int = 0):
    """``actors`` for :func:`measure` whose copies are reached through ``exchange`` (:class:`Remote`);
    every batch gets new slots (``first_slot`` on), so every simulation starts from fresh copies."""
    counter = [int(first_slot)]

    def make(cells):
        first = counter[0]
        counter[0] += len(np.unique(cells[:, 1]))
        return Remote(exchange, cells, first)

    return make


LEADERBOARD_CONFIG = PlatoonConfig()  # 8 copies at 20 m/s, the observation's time gap the controller's (or 1.5 s)
LEADERBOARD_FREQUENCIES = tuple(np.geomspace(0.005, 1.0, 13).round(6))  # [Hz] every other one of the full grid


def leaderboard_verdict(actors, declared: float | None) -> dict:
    """The leaderboard's string-stability cell (JSON-safe): the sweep of :data:`LEADERBOARD_CONFIG`
    over :data:`LEADERBOARD_FREQUENCIES` (every other frequency of the default grid) and the
    Gunter-like disturbance; ``{"failed": reason}`` when the column has no steady state."""
    try:
        r = measure(actors, "the controller", declared, LEADERBOARD_CONFIG, frequencies=LEADERBOARD_FREQUENCIES)
    except StringStabilityError as exc:
        return {"failed": str(exc)}
    d = r.disturbance
    out = {"max_gain": None if not math.isfinite(r.max_gain) else round(r.max_gain, 6),
           "string_stable": r.string_stable, "tolerance": r.tolerance,
           "unstable_bands_hz": [list(b) for b in r.unstable_bands], "vehicles": r.config.vehicles,
           "speed": r.config.speed, "time_gap": r.time_gap, "frequencies": len(r.frequencies),
           "disturbance_growth": None if d is None else round(float(d.drops[-1] / d.lead_drop), 6),
           "errors": [str(e) for e in r.errors]}
    return out


def format_verdict(cell: dict | None) -> str:
    """A table cell: ``stable (0.996)``, ``UNSTABLE (1.016)``, ``no verdict`` or ``failed``."""
    if not cell:
        return "-"
    if "failed" in cell:
        return "failed"
    if cell.get("string_stable") is None:
        return "no verdict"
    word = "stable" if cell["string_stable"] else "UNSTABLE"
    return f"{word} ({cell['max_gain']:.3f})"


@dataclass
class _Run:
    t: np.ndarray
    x: np.ndarray  # (T+1, B, N+1)
    v: np.ndarray
    a: np.ndarray
    errors: dict  # row index -> RowError


def _simulate(actors, layout: np.ndarray, humans, lead: np.ndarray, gap0: np.ndarray, v0: np.ndarray,
              cfg: PlatoonConfig, time_gap: float, row_names: list[str]) -> _Run:
    """One batch: ``actors(cells)`` makes the controller's side for the controlled ``cells``
    (:class:`_Copies` here, :class:`Remote` in a sandbox); ``layout`` ``(B, N)`` of -1 (the
    controller) or a human driver's index into
    ``humans``; ``lead`` ``(B, T+1)`` the lead's speed at each step; ``gap0`` ``(B, N)`` and
    ``v0`` ``(B,)`` the start. Raises :class:`_Raised` when a vectorised controller raises."""
    from acc_gym.envs.acc_env import observation_space
    from acc_gym.envs.config import EnvConfig
    from acc_gym.envs.observation import margin_features

    B, N = layout.shape
    T = lead.shape[1] - 1
    env_cfg = EnvConfig(v2v=cfg.v2v, sensor_range=float(cfg.sensor_range))
    space = observation_space(env_cfg)
    low, high = space.low.astype(float), space.high.astype(float)
    m = low.shape[0]
    mine = layout < 0
    cells = np.argwhere(mine)  # row-major (b, j)
    ctl = actors(cells) if cells.size else None
    # the controlled vehicles' actuators (none when ideal): at rest on the start's zero acceleration
    actuators = Actuators(cfg.actuators, len(cells), DT) if cells.size and not cfg.actuators.ideal else None
    human_cells = np.argwhere(~mine)
    driver = None
    if human_cells.size:
        params = humans.take(layout[~mine])
        counts = np.bincount(human_cells[:, 0], minlength=B)  # the rows' drivers are consecutive (row-major)
        driver = human_drivers(params, cfg.driver_model,
                               groups=[(_row_rng(cfg, row_names[b]), int(counts[b])) for b in range(B)])
    x = np.zeros((B, N + 1))
    x[:, 1:] = -np.cumsum(gap0 + LENGTH, axis=1)
    v = np.broadcast_to(np.asarray(v0, float)[:, None], (B, N + 1)).copy()
    a = np.zeros((B, N + 1))
    rec = {k: np.empty((T + 1, B, N + 1)) for k in ("x", "v", "a")}
    rec["x"][0], rec["v"][0], rec["a"][0] = x, v, a
    set_speed = np.full(B * N, cfg.cruise_speed)
    tg = np.full(B * N, float(time_gap))
    failed = np.zeros(B, dtype=bool)
    errors: dict[int, RowError] = {}
    vp = np.ascontiguousarray(np.broadcast_to(VehicleParams().as_matrix(N + 1), (B, N + 1, 10)))  # the move's
    present = np.ones((B, N + 1), dtype=np.bool_)
    o = np.empty((8, B, N))
    obs = np.empty((B * N, m), dtype=np.float32)
    a_des = np.zeros((B, N + 1))
    rng_ = cfg.sensor_range
    gap = x[:, :-1] - LENGTH - x[:, 1:]  # (B, N) [m] to the vehicle ahead, kept up to date after each move
    for k in range(T):
        t = k * DT
        o[0], o[1] = v[:, 1:], a[:, 1:]
        o[2] = np.where(gap <= rng_, gap, np.inf)
        o[3], o[4] = v[:, :-1], a[:, :-1]
        o[5, :, 0] = np.inf
        o[6, :, 0] = 0.0
        o[7, :, 0] = 0.0
        if N > 1:
            gap2 = x[:, :-2] - LENGTH - x[:, 2:]
            o[5, :, 1:] = np.where((gap2 <= rng_) & (gap[:, 1:] <= rng_), gap2, np.inf)
            o[6, :, 1:], o[7, :, 1:] = v[:, :-2], a[:, :-2]
        if ctl is not None:
            K.observe(o.reshape(8, B * N), set_speed, tg, float(rng_), cfg.v2v, low, high, obs)
            rows = obs[cells[:, 0] * N + cells[:, 1]]
            if cfg.version >= 1:
                rows = margin_features(rows.astype(float), float(rng_)).astype(np.float32)
            act = ctl(rows, k, failed, errors, row_names, t)
            acc = np.empty_like(act)
            K.action_to_accel(act, float(cfg.accel_max), float(cfg.decel_max), acc)
            if actuators is not None:
                acc = actuators.command(acc, a[cells[:, 0], cells[:, 1] + 1])
            a_des[cells[:, 0], cells[:, 1] + 1] = acc
        if driver is not None:
            hb, hj = human_cells[:, 0], human_cells[:, 1]
            two = hj >= 1
            seen = np.isfinite(o[2, hb, hj])
            ob = Observation(v=o[0, hb, hj].copy(), a=o[1, hb, hj].copy(), gap=o[2, hb, hj].copy(),
                             v_lead=o[3, hb, hj].copy(), a_lead=np.where(seen, o[4, hb, hj], 0.0),
                             gap2=np.where(two, o[5, hb, hj], np.inf), v_lead2=o[6, hb, hj].copy(),
                             a_lead2=o[7, hb, hj].copy())
            a_des[hb, hj + 1] = driver.act(ob)
        a_des[:, 0] = (lead[:, k + 1] - v[:, 0]) / DT
        a_des[failed, 1:] = 0.0
        # (every vehicle present: advance copies each request onto itself)
        advance(a_des, present, x, v, vp, DT, rec["x"][k + 1], rec["v"][k + 1], rec["a"][k + 1], a_des)
        x, v, a = rec["x"][k + 1], rec["v"][k + 1], rec["a"][k + 1]  # Eq. (3), the exact integration
        gap = x[:, :-1] - LENGTH - x[:, 1:]
        hit = (gap <= 0.0) & ~failed[:, None]
        for b in np.flatnonzero(hit.any(axis=1)):
            j = int(np.argmax(hit[b]))
            failed[b] = True
            errors[int(b)] = RowError(row_names[b], j + 1, (k + 1) * DT, f"collided with vehicle {j} "
                                      f"(gap {gap[b, j]:.2f} m)")
        rec["x"][k + 1], rec["v"][k + 1], rec["a"][k + 1] = x, v, a
        if failed.all():  # every row has failed: nothing left to measure (the rest is NaN)
            for arr in rec.values():
                arr[k + 2:] = np.nan
            break
    return _Run(np.arange(T + 1) * DT, rec["x"], rec["v"], rec["a"], errors)


def _simulate_rows(actors, layout, humans, lead, gap0, v0, cfg, time_gap, row_names) -> _Run:
    """:func:`_simulate`, and when a vectorised controller raises, each row again on its own so
    the failure is named per row (the other rows' results stand)."""
    try:
        return _simulate(actors, layout, humans, lead, gap0, v0, cfg, time_gap, row_names)
    except _Raised as first:
        B = layout.shape[0]
        if B == 1:
            T = lead.shape[1] - 1
            nan = np.full((T + 1, 1, layout.shape[1] + 1), np.nan)
            err = RowError(row_names[0], first.vehicle, first.k * DT, _describe_exc(first.exc))
            return _Run(np.arange(T + 1) * DT, nan, nan.copy(), nan.copy(), {0: err})
    parts = [_simulate_rows(actors, layout[b:b + 1], humans, lead[b:b + 1], gap0[b:b + 1], v0[b:b + 1], cfg,
                            time_gap, [row_names[b]]) for b in range(layout.shape[0])]
    errors = {b: p.errors[0] for b, p in enumerate(parts) if 0 in p.errors}
    return _Run(parts[0].t, *(np.concatenate([getattr(p, k) for p in parts], axis=1) for k in ("x", "v", "a")),
                errors)


def _row_rng(cfg: PlatoonConfig, row: str) -> np.random.Generator:
    """The generator of the human drivers' perception in the row named ``row`` (module docstring)."""
    return np.random.default_rng(np.random.SeedSequence([int(cfg.seed), 34, 2, zlib.crc32(row.encode())]))


def _layout(cfg: PlatoonConfig) -> np.ndarray:
    """(N,) -1 where the controller drives, else the human driver's index."""
    kinds = np.full(cfg.vehicles, -1, dtype=np.int64)
    humans = [j for j in range(cfg.vehicles) if j + 1 not in cfg.controlled]
    kinds[humans] = np.arange(len(humans))
    return kinds


def _humans(cfg: PlatoonConfig):
    n = int(np.sum(_layout(cfg) >= 0))
    if n == 0:
        return None
    return sample_drivers(np.random.default_rng([cfg.seed, 34]), n, cfg.cruise_speed, cfg.drivers)


def _equilibrium(actors, name: str, cfg: PlatoonConfig, humans, time_gap: float, speed: float) -> np.ndarray:
    """(N,) the gap [m] each position settles at behind its predecessor at ``speed``: each kind of
    vehicle follows a constant-speed lead two copies deep (the first's gap for position 1, the
    second's -- which has a second vehicle ahead -- for the others)."""
    kinds = _layout(cfg)
    distinct = list(dict.fromkeys(kinds.tolist()))
    layout = np.array([[k, k] for k in distinct], dtype=np.int64)
    T = int(round(EQUILIBRIUM_TIME / DT))
    B = len(distinct)
    lead = np.full((B, T + 1), float(speed))
    guess = min(2.5 + time_gap * speed, 0.8 * cfg.sensor_range)
    gap0 = np.full((B, 2), guess)
    names = [f"equilibrium {b}" for b in range(len(distinct))]
    run = _simulate_rows(actors, layout, humans, lead, gap0, np.full(B, float(speed)), cfg, time_gap, names)
    gaps = run.x[:, :, :-1] - LENGTH - run.x[:, :, 1:]
    last = int(round(10.0 / DT))
    out = {}
    for b, kind in enumerate(distinct):
        who = name if kind < 0 else f"human driver {kind} ({cfg.drivers}, driver model {cfg.driver_model})"
        if b in run.errors:
            e = run.errors[b]
            raise StringStabilityError(f"{who} does not follow a lead at a constant {speed:g} m/s: copy {e.vehicle} "
                                       f"at t = {e.time_s:.1f} s: {e.message}")
        v_end = run.v[-1, b, 1:]
        drift = np.abs(gaps[-1, b] - gaps[-1 - last, b])
        if np.any(np.abs(v_end - speed) > SPEED_SETTLED) or np.any(drift > GAP_SETTLED):
            raise StringStabilityError(
                f"{who} has no steady state behind a lead at a constant {speed:g} m/s: after {EQUILIBRIUM_TIME:g} s "
                f"its two copies drive at {v_end[0]:.2f} and {v_end[1]:.2f} m/s with gaps {gaps[-1, b, 0]:.1f} and "
                f"{gaps[-1, b, 1]:.1f} m (still changing by {drift.max():.2f} m over 10 s)")
        out[kind] = gaps[-1, b]
    return np.array([out[k][0 if j == 0 else 1] for j, k in enumerate(kinds)])


def sweep_lead(frequencies, speed: float, duration: float, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """The lead's speed at each step ``(F, T+1)`` for the sweep, and each frequency's amplitude
    [m/s]. The oscillation fades in over ``ramp`` seconds (a raised cosine): switched on at
    once, it would also shift the lead by ``A / w`` for good, a step that excites the column's
    slowest modes, which then swamp the small steady oscillation far down a damping column."""
    f = np.asarray(frequencies, dtype=float)
    amp = np.minimum(SPEED_AMPLITUDE, ACCEL_AMPLITUDE / (2.0 * np.pi * f))
    t = np.arange(int(round(duration / DT)) + 1) * DT
    fade = np.where(t < ramp, 0.5 * (1.0 - np.cos(np.pi * t / max(ramp, 1e-9))), 1.0)
    return speed + amp[:, None] * fade[None, :] * np.sin(2.0 * np.pi * f[:, None] * t[None, :]), amp


def disturbance_lead(speed: float, duration: float, drop: float = GUNTER_DROP, decel: float = 1.0,
                     hold: float = 5.0, accel: float = 0.5, start: float = 5.0) -> np.ndarray:
    """The lead's speed at each step ``(T+1,)``: ``speed`` for ``start`` s, down by ``drop`` at
    ``decel``, ``hold`` s, back up at ``accel``, then constant (Gunter et al.'s disturbance)."""
    from acc_gym.simulation.profiles import SpeedProfile

    drop = min(float(drop), float(speed))
    prof = SpeedProfile.from_segments(speed, [(0.0, start), (-decel, drop / decel), (0.0, hold),
                                              (accel, drop / accel), (0.0, max(duration, 1.0))])
    return prof.speed(np.arange(int(round(duration / DT)) + 1) * DT)


def _response(name: str, run: _Run, b: int) -> Disturbance:
    v, a, x = run.v[:, b], run.a[:, b], run.x[:, b]
    e = v - v[0]
    drops = v[0] - v.min(axis=0)

    def gains(series, order):
        norm = np.linalg.norm(series, ord=order, axis=0) if order == 2 else np.max(np.abs(series), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(norm[:-1] > 0, norm[1:] / norm[:-1], np.nan)
    gap = x[:, :-1] - LENGTH - x[:, 1:]
    return Disturbance(name, float(drops[0]), drops[1:], gains(e, 2), gains(e, np.inf), gains(a[1:], 2),
                       gains(a[1:], np.inf), gap.min(axis=0), run.t, x, v)


def _fit(t: np.ndarray, v: np.ndarray, freq: float) -> tuple[np.ndarray, np.ndarray]:
    """Complex amplitudes ``Y`` (``v ~ c + Im(Y exp(j w t))``) of ``v`` ``(T, N+1)`` at ``freq``,
    and each column's residual relative to its oscillation (rms residual / rms of the fit)."""
    w = 2.0 * np.pi * freq
    basis = np.stack([np.ones_like(t), np.sin(w * t), np.cos(w * t)], axis=1)
    coef, *_ = np.linalg.lstsq(basis, v, rcond=None)
    y = coef[1] + 1j * coef[2]
    resid = np.sqrt(np.mean((v - basis @ coef) ** 2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = resid / (np.abs(y) / np.sqrt(2.0))
    return y, np.nan_to_num(rel, nan=np.inf)


def _name(controller) -> str:
    if isinstance(controller, str):
        return controller
    return getattr(controller, "name", None) if isinstance(getattr(controller, "name", None), str) \
        else type(controller).__name__


def string_stability(controller, config: PlatoonConfig | None = None, *, frequencies=None,
                     disturbance: bool = True, trace=None, name: str | None = None) -> StringStabilityReport:
    """Measure ``controller`` (a registered name, ``module:attribute``, a saved model's path, an
    object with ``predict``, or ``"human"``: the human drivers alone) in a column; see the module
    docstring. ``trace``: a :class:`~acc_gym.simulation.profiles.SpeedProfile` for the lead
    (a recorded or human-like trace), run as its own batch from an equilibrium at its first
    speed. Raises :class:`StringStabilityError` when the column has no steady state."""
    from acc_gym.evaluation.runner import declared_time_gap, load_controller

    cfg = config if config is not None else PlatoonConfig()
    human_only = isinstance(controller, str) and controller == "human"
    if human_only:
        cfg = PlatoonConfig(**{**cfg.__dict__, "penetration": 0.0})
        ctl = None
    else:
        ctl = load_controller(controller)
        if cfg.penetration == 0.0:
            raise ValueError("penetration 0 leaves the controller no position; use the controller 'human' to "
                             "measure the human drivers alone")
    label = name or ("human" if human_only else _name(controller))
    declared = None if ctl is None else declared_time_gap(ctl)
    actors = None if ctl is None else (lambda cells: _Copies(ctl, cells))
    return measure(actors, label, declared, cfg, frequencies=frequencies, disturbance=disturbance, trace=trace)


def measure(actors, label: str, declared: float | None, cfg: PlatoonConfig, *, frequencies=None,
            disturbance: bool = True, trace=None) -> StringStabilityReport:
    """:func:`string_stability` for a controller reached through ``actors(cells)`` (an object
    answering the controlled cells' observations each step; None: humans only), whose declared
    time gap is ``declared``: the leaderboard's path, where the copies live in a sandbox."""
    time_gap = float(cfg.time_gap if cfg.time_gap is not None else (declared if declared is not None else 1.5))
    freqs = np.asarray(FREQUENCIES if frequencies is None else frequencies, dtype=float)
    check_finite("frequencies", freqs)
    if freqs.ndim != 1 or freqs.size == 0 or np.any(freqs <= 0) or np.any(freqs >= 0.5 / DT):
        raise ValueError(f"frequencies must be a non-empty list of numbers in (0, {0.5 / DT:g}) Hz (below the "
                         f"Nyquist frequency of the {DT:g} s step), got {np.asarray(frequencies).tolist()!r}")
    humans = _humans(cfg)
    speed = float(cfg.speed)
    gaps = _equilibrium(actors, label, cfg, humans, time_gap, speed)
    duration = cfg.settle + max(float(np.max(1.0 / freqs)), 40.0)
    lead, amp = sweep_lead(freqs, speed, duration, RAMP_SHARE * cfg.settle)
    rows = [f"{f:.4g} Hz" for f in freqs]
    if disturbance:
        lead = np.vstack([lead, disturbance_lead(speed, duration)])
        rows.append("disturbance")
    B, N = lead.shape[0], cfg.vehicles
    layout = np.broadcast_to(_layout(cfg), (B, N)).copy()
    run = _simulate_rows(actors, layout, humans, lead, np.broadcast_to(gaps, (B, N)).copy(), np.full(B, speed), cfg,
                         time_gap, rows)
    F = freqs.size
    pair = np.full((F, N), np.nan)
    phase = np.full((F, N), np.nan)
    column = np.full(F, np.nan)
    residual = np.full((F, N + 1), np.nan)
    steady = np.zeros((F, N), dtype=bool)
    window = run.t >= cfg.settle
    for i, f in enumerate(freqs):
        if i in run.errors:
            continue
        vw = run.v[window, i]
        y, rel = _fit(run.t[window], vw, f)
        mag = np.abs(y)
        residual[i] = rel
        clean = rel <= MAX_RESIDUAL
        ok = (mag[:-1] >= RESOLUTION) & clean[:-1] & clean[1:]
        ratio = y[1:] / np.where(ok, y[:-1], 1.0)
        pair[i] = np.where(ok, np.abs(ratio), np.nan)
        phase[i] = np.where(ok, np.angle(ratio), np.nan)
        # a vehicle that answers a clean oscillation with no steady one (it grows, or it is not a
        # sinusoid) amplifies when its largest deviation exceeds its predecessor's
        peak = np.max(np.abs(vw - vw.mean(axis=0)), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            peak_ratio = peak[1:] / peak[:-1]
        unsteady = (mag[:-1] >= RESOLUTION) & clean[:-1] & ~clean[1:] & (peak_ratio > 1.0 + TOLERANCE)
        pair[i] = np.where(unsteady, peak_ratio, pair[i])
        steady[i] = ok
        column[i] = mag[-1] / mag[0]
    report = StringStabilityReport(label, cfg, time_gap, cfg.controlled, freqs, amp, pair, phase, column, residual, steady,
                                   errors=[run.errors[b] for b in sorted(run.errors)])
    if disturbance and F not in run.errors:
        report.disturbance = _response("disturbance", run, F)
    if trace is not None:
        report.trace = _trace(actors, label, cfg, humans, time_gap, trace, report)
    return report


def _trace(actors, label, cfg, humans, time_gap, profile, report) -> Disturbance | None:
    T = int(round(profile.duration / DT))
    lead = np.asarray(profile.speed(float(profile.times[0]) + np.arange(T + 1) * DT), dtype=float)
    if lead.ndim != 1:
        raise ValueError("trace must be a single speed profile, not a batch")
    v0 = float(lead[0])
    gaps = _equilibrium(actors, label, cfg, humans, time_gap, v0)
    run = _simulate_rows(actors, _layout(cfg)[None, :], humans, lead[None, :], gaps[None, :], np.array([v0]), cfg,
                         time_gap, ["trace"])
    if 0 in run.errors:
        report.errors.append(run.errors[0])
        return None
    return _response("trace", run, 0)


def lead_trace(spec: str, seed: int = 0):
    """A lead trace from the command line: ``"stopandgo"`` (a human-like stop-and-go wave of
    :mod:`acc_gym.scenarios.stopandgo`, 120 s, peaks around 8 m/s, drawn from
    ``default_rng([seed, 34, 1])``) or a CSV file with a header and columns ``t`` [s] and
    ``v`` [m/s] (a recorded drive)."""
    import csv

    from acc_gym.simulation.profiles import SpeedProfile

    if spec == "stopandgo":
        from acc_gym.scenarios.stopandgo import wave_profile

        return wave_profile(np.random.default_rng([seed, 34, 1]), 8.0, 120.0)
    try:
        with open(spec, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise ValueError(f"lead trace {spec!r}: {exc.strerror or exc}") from None
    except (csv.Error, UnicodeDecodeError) as exc:
        raise ValueError(f"lead trace {spec!r} is not a CSV file: {exc}") from None
    if not rows:
        raise ValueError(f"lead trace {spec!r} is empty")
    header = [h.strip() for h in rows[0]]
    if "t" not in header or "v" not in header:
        raise ValueError(f"lead trace {spec!r}: the header must name columns 't' and 'v', got {header!r}")
    it, iv = header.index("t"), header.index("v")
    t, v = [], []
    for number, row in enumerate(rows[1:], start=2):
        try:
            t.append(float(row[it]))
            v.append(float(row[iv]))
        except (ValueError, IndexError):
            raise ValueError(f"lead trace {spec!r}, line {number}: expected numbers in columns t and v, got "
                             f"{row!r}") from None
    if len(t) < 2:
        raise ValueError(f"lead trace {spec!r} needs at least two samples, got {len(t)}")
    try:
        return SpeedProfile.recorded(t, v)
    except ValueError as exc:
        raise ValueError(f"lead trace {spec!r}: {exc}") from None
