"""Traffic-wave measures of a ring road (:mod:`acc_gym.simulation.ring`) or any batch of
trajectories ``(T+1, R, N)`` sampled every ``dt``.

Definitions (each a documented choice; ``tests/evaluation/test_waves.py`` checks them on
hand-made cases):

* **Speed standard deviation** (Stern et al. 2018's measure): the standard deviation of all
  vehicles' speeds pooled over the window after the warm-up (default :data:`WARMUP`, 120 s),
  one number per ring.
* **Stops**: a vehicle stops when its speed falls below :data:`STOP_SPEED` (0.5 m/s) after it
  has been above :data:`MOVING_SPEED` (1 m/s) since its last stop (hysteresis: creeping near
  0.5 m/s is one stop); counted after the warm-up, summed over the ring's vehicles.
* **Jam**: at some time a vehicle is below :data:`JAM_SPEED`
  (1 m/s) and the speed standard deviation over all the ring's vehicles at that instant is at
  least :data:`JAM_SD` (1 m/s), both holding without a break for :data:`JAM_HOLD` (60 s);
  the onset is the start of the first such stretch [s] (from t = 0: no warm-up, so the
  onset is the time since the start).
* **Braking events**: a vehicle's applied acceleration falls below :data:`BRAKE_DECEL`
  (-1 m/s^2) after having been above :data:`BRAKE_RELEASE` (-0.5 m/s^2) (hysteresis); counted
  after the warm-up, summed over the ring. (Stern et al. count braking events from the
  vehicles' accelerations too; their threshold is not reproduced here.)
* **Wave speed** [km/h] (:func:`wave_speed`): the phase velocity of the dominant spatial mode
  of the speed field along the ring, negative when the wave travels against the traffic.
  At each time the vehicles sample the speed field ``v(x)``; its Fourier coefficient of mode
  ``m`` (``m`` waves on the ring) is estimated as a Riemann sum weighted by each vehicle's
  share of the ring (half the space to its leader plus half to its follower), ``c_m(t) =
  sum_i w_i (v_i - mean) exp(-2 pi i m x_i / L)``. A wave ``v = V + A cos(2 pi m (x - c t) /
  L)`` has ``arg c_m = -2 pi m c t / L + const``, so ``c = -L / (2 pi m) d(arg c_m)/dt``: the
  slope of the unwrapped phase, fitted by least squares after the warm-up. ``m`` is the mode
  with the largest mean amplitude among ``1 .. max(1, N // 4)`` (``N`` vehicles sample the
  field at ``N`` points; higher modes of a sharp jam front are aliased by that sampling:
  ``docs/design/ring-wave-speed.md``). The phase only needs the wave's
  position, not its shape, and it does not jump between equally slow vehicles as the
  slowest vehicle's position would. NaN when the speed field has no wave (speed sd below
  :data:`WAVE_MIN_SD`).
* **Energy** [kWh/100 km] (:func:`tractive_energy`): the positive tractive work at the wheels
  of the package's vehicle model, ``F = m a + F_r(v) + F_a(v)`` (mass, rolling resistance
  ``N (C_r0 + C_r1 v + C_r2 v^2)``, drag ``0.5 C_d rho A v^2``: :class:`~acc_gym.vehicle.VehicleParams`),
  power ``max(F v, 0)`` with the step's applied acceleration and the step's mean speed,
  integrated over the run after the warm-up and divided by the distance driven. Braking
  energy is lost (no recuperation), no drivetrain or engine efficiency: it is the demand at
  the wheels, a relative measure between runs (as Stern et al. report fuel relative to the
  all-human ring), not a fuel figure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acc_gym.vehicle import VehicleParams, resistance_accel

WARMUP = 120.0  # [s] measures (but the jam onset) start after this
STOP_SPEED = 0.5  # [m/s]
MOVING_SPEED = 1.0  # [m/s]
JAM_SPEED = 1.0  # [m/s]
JAM_SD = 1.0  # [m/s]
JAM_HOLD = 60.0  # [s]
BRAKE_DECEL = -1.0  # [m/s^2]
BRAKE_RELEASE = -0.5  # [m/s^2]
WAVE_MIN_SD = 0.1  # [m/s] below this speed sd there is no wave to time


def _after(t: np.ndarray, warmup: float) -> np.ndarray:
    if warmup >= t[-1]:
        raise ValueError(f"the warm-up ({warmup:g} s) must be shorter than the run ({t[-1]:g} s)")
    return t >= warmup


def speed_sd(v: np.ndarray, t: np.ndarray, warmup: float = WARMUP) -> np.ndarray:
    """(R,) [m/s] the standard deviation of every vehicle's speed pooled over the run after ``warmup``."""
    w = _after(t, warmup)
    return v[w].std(axis=(0, 2))


def mean_speed(v: np.ndarray, t: np.ndarray, warmup: float = WARMUP) -> np.ndarray:
    """(R,) [m/s] the mean speed of all vehicles after ``warmup``."""
    return v[_after(t, warmup)].mean(axis=(0, 2))


def _events(x: np.ndarray, enter: float, leave: float) -> np.ndarray:
    """(R,) the number of times each series ``(T, R, N)`` falls below ``enter`` after having been at
    or above ``leave`` (> ``enter``) since the last time; a series that starts below does not count
    until it has been above."""
    T = x.shape[0]
    armed = x[0] >= leave
    count = np.zeros(x.shape[1:], dtype=np.int64)
    for k in range(1, T):
        fire = armed & (x[k] < enter)
        count += fire
        armed = (armed & ~fire) | (x[k] >= leave)
    return count.sum(axis=1)


def stops(v: np.ndarray, t: np.ndarray, warmup: float = WARMUP) -> np.ndarray:
    """(R,) stops after ``warmup`` (see the module docstring)."""
    return _events(v[_after(t, warmup)], STOP_SPEED, MOVING_SPEED)


def braking_events(a: np.ndarray, t: np.ndarray, warmup: float = WARMUP) -> np.ndarray:
    """(R,) braking events after ``warmup`` (see the module docstring)."""
    return _events(a[_after(t, warmup)], BRAKE_DECEL, BRAKE_RELEASE)


def jam_onset(v: np.ndarray, t: np.ndarray, *, speed: float = JAM_SPEED, sd: float = JAM_SD,
              hold: float = JAM_HOLD) -> np.ndarray:
    """(R,) [s] the start of the first stretch of at least ``hold`` seconds in which some vehicle
    is below ``speed`` and the instantaneous speed sd over the ring is at least ``sd``; NaN: no jam."""
    cond = (v.min(axis=2) < speed) & (v.std(axis=2) >= sd)  # (T+1, R)
    dt = float(t[1] - t[0])
    need = int(round(hold / dt))
    out = np.full(v.shape[1], np.nan)
    for r in range(v.shape[1]):
        run = 0
        for k in range(cond.shape[0]):
            run = run + 1 if cond[k, r] else 0
            if run > need:  # ``need`` steps after the first: hold seconds without a break
                out[r] = t[k - need]
                break
    return out


def _weights(x: np.ndarray, length: float) -> np.ndarray:
    """Each vehicle's share of the ring: half the distance to its leader plus half to its follower
    (positions along the ring ``x`` ``(..., N)`` in driving order, front to back)."""
    ahead = np.mod(np.roll(x, 1, axis=-1) - x, length)
    behind = np.roll(ahead, -1, axis=-1)
    return 0.5 * (ahead + behind) / length


def wave_speed(x: np.ndarray, v: np.ndarray, t: np.ndarray, length: float, warmup: float = WARMUP,
               mode: int | None = None) -> np.ndarray:
    """(R,) [km/h] the wave speed in the road's frame, negative against the traffic (which drives
    towards increasing ``x``); NaN where the speed field has no wave. ``x`` ``(T+1, R, N)`` positions
    along the ring in driving order; ``mode`` forces the number of waves (default: the strongest).
    See the module docstring."""
    w = _after(t, warmup)
    x, v, tt = x[w], v[w], t[w]
    N = x.shape[2]
    out = np.full(x.shape[1], np.nan)
    if N < 2:
        return out
    weights = _weights(x, length)
    dev = v - v.mean(axis=2, keepdims=True)
    modes = range(1, max(1, N // 4) + 1) if mode is None else (int(mode),)
    for r in range(x.shape[1]):
        if v[:, r].std() < WAVE_MIN_SD:
            continue
        best, phase_best = -1.0, None
        for m in modes:
            c = np.sum(weights[:, r] * dev[:, r] * np.exp(-2j * np.pi * m * x[:, r] / length), axis=1)
            amp = float(np.mean(np.abs(c)))
            if amp > best:
                best, phase_best, m_best = amp, np.unwrap(np.angle(c)), m
        slope = np.polyfit(tt, phase_best, 1)[0]  # [rad/s]
        out[r] = -length / (2.0 * np.pi * m_best) * slope * 3.6
    return out


def tractive_energy(v: np.ndarray, a: np.ndarray, t: np.ndarray, vehicle: VehicleParams | None = None,
                    warmup: float = WARMUP) -> tuple[np.ndarray, np.ndarray]:
    """(R,) ``(energy [kWh], distance [km])`` after ``warmup``: the positive tractive work at the
    wheels (module docstring). ``a[k]`` is the acceleration applied over step ``k - 1 -> k``."""
    p = vehicle if vehicle is not None else VehicleParams()
    w = _after(t, warmup)
    k = np.flatnonzero(w)
    k = k[k >= 1]
    dt = float(t[1] - t[0])
    v_mean = 0.5 * (v[k - 1] + v[k])  # (K, R, N) the step's mean speed
    mass = np.asarray(p.mass, dtype=float)
    force = mass * (a[k] + resistance_accel(v_mean, p))  # [N]
    work = np.sum(np.maximum(force * v_mean, 0.0), axis=(0, 2)) * dt  # [J]
    dist = np.sum(v_mean, axis=(0, 2)) * dt  # [m]
    return work / 3.6e6, dist / 1e3


def energy_per_100km(v, a, t, vehicle: VehicleParams | None = None, warmup: float = WARMUP) -> np.ndarray:
    """(R,) [kWh/100 km] :func:`tractive_energy` per distance driven (NaN if nobody moved)."""
    e, d = tractive_energy(v, a, t, vehicle, warmup)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(d > 0, 100.0 * e / d, np.nan)


@dataclass(frozen=True)
class WaveReport:
    """The wave measures of one ring (see the module docstring); JSON-safe via :meth:`to_dict`."""

    mean_speed: float  # [m/s]
    speed_sd: float  # [m/s]
    stops: int
    jam: bool
    jam_onset_s: float | None  # [s]
    wave_speed_kmh: float | None  # [km/h]
    braking_events: int
    energy_kwh_per_100km: float | None
    collisions: int  # vehicles whose gap reached 0
    warmup_s: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def _num(x) -> float | None:
    x = float(x)
    return None if not np.isfinite(x) else x


def ring_waves(trace, warmup: float = WARMUP) -> list[WaveReport]:
    """The measures of every ring of a :class:`~acc_gym.simulation.ring.RingTrace`."""
    t, v, a, x = trace.t, trace.v, trace.a, trace.x
    sd, mean = speed_sd(v, t, warmup), mean_speed(v, t, warmup)
    n_stops, n_brake = stops(v, t, warmup), braking_events(a, t, warmup)
    onset = jam_onset(v, t)
    c = wave_speed(x, v, t, trace.length, warmup)
    energy = energy_per_100km(v, a, t, trace.vehicle, warmup)
    hit = trace.collided.sum(axis=1)
    return [WaveReport(mean_speed=float(mean[r]), speed_sd=float(sd[r]), stops=int(n_stops[r]),
                       jam=bool(np.isfinite(onset[r])), jam_onset_s=_num(onset[r]), wave_speed_kmh=_num(c[r]),
                       braking_events=int(n_brake[r]), energy_kwh_per_100km=_num(energy[r]),
                       collisions=int(hit[r]), warmup_s=float(warmup)) for r in range(v.shape[1])]


def idm_linear_stability(params, length: float, vehicles: int, vehicle_length: float = 4.7) -> dict:
    """Linear stability of the uniform flow of ``vehicles`` IDM vehicles (``params``:
    :class:`~acc_gym.drivers.baselines.IDMParams`, scalars) on a ring of ``length`` [m].

    With ``a = f(s, v, dv)`` (``s`` the gap, ``dv = v_lead - v``), linearised at the equilibrium
    ``f(s_e, v_e, 0) = 0`` (``s_e = L / N - length``): ``du_n/dt = f_s y_n + f_v u_n + f_dv
    (u_(n-1) - u_n)``, ``dy_n/dt = u_(n-1) - u_n``. The ansatz ``u_n, y_n ~ exp(lambda t + i n
    theta)`` gives, with ``q = exp(-i theta) - 1``, ``lambda^2 - (f_v + f_dv q) lambda - f_s q =
    0``. On the long-wave branch ``lambda = c1 theta + c2 theta^2 + ...``: ``c1 = i f_s / f_v``
    and ``f_v c2 = f_s / 2 - f_s^2 / f_v^2 - f_dv f_s / f_v``, so (``f_v < 0 < f_s``) the flow is
    string stable iff ``f_v^2 / 2 - f_dv f_v - f_s >= 0`` (Wilson and Ward 2011's form; in
    Treiber and Kesting's convention ``dv = v - v_lead``, whose ``f_dv`` is minus ours, it reads
    ``f_v^2 / 2 + f_dv f_v - f_s >= 0``). On a ring only ``theta = 2 pi k / N`` exist: the
    ring's uniform flow is unstable iff some root of some ``k = 1 .. N-1`` has a positive real
    part (``growth`` below); for long rings the two verdicts agree.

    IDM: ``f = a (1 - (v / v0)^delta - (s* / s)^2)``, ``s* = s0 + v T - v dv / (2 sqrt(a b))``:
    ``f_s = 2 a s*^2 / s^3``, ``f_v = -a (delta v^(delta-1) / v0^delta + 2 s* T / s^2)``,
    ``f_dv = a s* v / (s^2 sqrt(a b))`` at ``dv = 0``.

    Returns ``{"v_e", "s_e", "f_s", "f_v", "f_dv", "criterion", "string_stable", "growth",
    "ring_stable"}`` (``criterion = f_v^2/2 - f_dv f_v - f_s``; ``growth`` [1/s] the largest real
    part over the ring's modes; continuous time: the 0.2 s step adds a little instability)."""
    a, b, T, s0, v0, delta = (float(getattr(params, k)) for k in ("a", "b", "time_gap", "s0", "v_desired", "delta"))
    s = length / vehicles - vehicle_length
    if s <= s0:
        raise ValueError(f"the ring leaves {s:.2f} m per vehicle, not more than s0 = {s0:g} m")
    lo, hi = 0.0, v0
    for _ in range(200):  # equilibrium speed: 1 - (v/v0)^delta - ((s0 + v T)/s)^2 = 0, decreasing in v
        mid = 0.5 * (lo + hi)
        if 1.0 - (mid / v0) ** delta - ((s0 + mid * T) / s) ** 2 > 0:
            lo = mid
        else:
            hi = mid
    v = 0.5 * (lo + hi)
    star = s0 + v * T
    f_s = 2.0 * a * star ** 2 / s ** 3
    f_v = -a * (delta * v ** (delta - 1.0) / v0 ** delta + 2.0 * star * T / s ** 2)
    f_dv = a * star * v / (s ** 2 * np.sqrt(a * b))
    crit = f_v ** 2 / 2.0 - f_dv * f_v - f_s
    growth = -np.inf
    for k in range(1, vehicles):
        q = np.exp(-2j * np.pi * k / vehicles) - 1.0
        roots = np.roots([1.0, -(f_v + f_dv * q), -f_s * q])
        growth = max(growth, float(np.max(roots.real)))
    return {"v_e": v, "s_e": s, "f_s": f_s, "f_v": f_v, "f_dv": f_dv, "criterion": crit,
            "string_stable": bool(crit >= 0), "growth": growth, "ring_stable": bool(growth < 0)}
