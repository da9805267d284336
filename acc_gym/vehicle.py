"""Point-mass longitudinal vehicle model (paper 001, Section 2; SPEC section 2).

Flat road, longitudinal motion only::

    dv/dt = a_x                                                        (1)
    m a_x = F_x - F_r - F_a                                            (2)
    F_r = N (C_r0 + C_r1 v + C_r2 v^2),  F_a = 0.5 C_d rho A v^2
    a_x = clip(a_des, a_L(v), a_U(v))                                  (3)

The powertrain and brakes are assumed to realise any desired acceleration inside the
vehicle's envelope ``[a_L(v), a_U(v)]`` (the paper's Figure 1b simplification):

* ``a_U(v) = (min(F_trac, P_max / v) - F_r(v) - F_a(v)) / m``: flat at low speed (the
  traction/first-gear limit), falling with speed once the engine power limit binds,
  and reduced by the resistances, so it reaches 0 at the vehicle's top speed.
* ``a_L(v) = -(mu_brake m g + F_r(v) + F_a(v)) / m``: the tyre/road braking limit,
  helped slightly by the resistances (about -8.5 m/s^2 on dry asphalt).
* Coasting (pedals released, out of gear) decelerates at ``-(F_r + F_a) / m``
  (:func:`coast_acceleration`); the MPC drivers' ``a_sail`` parameter is their
  pedals-released deceleration including engine drag.

State arrays are shaped ``(n,)`` or ``(..., n)``; every function here is a pure,
broadcasting function of arrays, so one code path serves one vehicle, a column of
vehicles and a batch of environments.

Integration is exact for the acceleration held over a step (zero-order hold), and a
vehicle that would reach ``v = 0`` inside the step stops there: its position advances
by ``v^2 / (2 |a|)`` and it stays at rest (no reversing). A stopped vehicle asked to
decelerate applies ``a = 0`` (its brakes hold it).

Positions are those of the **front bumper**; a vehicle occupies ``[x - length, x]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from acc_gym._validation import check_finite, check_positive

G = 9.81  # [m/s^2]


@dataclass(frozen=True)
class VehicleParams:
    """Physical parameters of a mid-size passenger car (defaults) or of a batch of cars.

    Every field may be a Python float or a numpy array broadcastable to the batch
    shape ``(n,)``. Defaults describe a 1500 kg mid-size car with a 110 kW engine
    (0-100 km/h in about 9 s, top speed about 55 m/s).
    """

    mass: float | np.ndarray = 1500.0  # [kg]
    length: float | np.ndarray = 4.7  # [m]
    c_r0: float | np.ndarray = 0.010  # [-] constant rolling-resistance coefficient
    c_r1: float | np.ndarray = 0.0  # [s/m] linear rolling-resistance coefficient
    c_r2: float | np.ndarray = 6.5e-6  # [s^2/m^2] quadratic rolling-resistance coefficient
    c_d: float | np.ndarray = 0.30  # [-] aerodynamic drag coefficient
    area: float | np.ndarray = 2.2  # [m^2] frontal area
    rho: float | np.ndarray = 1.225  # [kg/m^3] air density
    traction_accel: float | np.ndarray = 3.5  # [m/s^2] F_trac / m, the low-speed traction limit
    power: float | np.ndarray = 110e3  # [W] maximum engine power at the wheels
    mu_brake: float | np.ndarray = 0.87  # [-] usable tyre/road friction when braking

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            check_finite(f"VehicleParams.{f.name}", value)
            if f.name in ("c_r0", "c_r1", "c_r2", "c_d"):
                if np.any(np.asarray(value) < 0):
                    raise ValueError(f"VehicleParams.{f.name} must be >= 0, got {value!r}")
            else:
                check_positive(f"VehicleParams.{f.name}", value)

    def take(self, index) -> "VehicleParams":
        """The parameters of the vehicles selected by ``index`` (scalars stay scalars)."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = np.asarray(value)[index] if np.ndim(value) else value
        return VehicleParams(**out)

    def as_matrix(self, n: int) -> np.ndarray:
        """The parameters of ``n`` vehicles as a ``(n, 10)`` array, columns :data:`VEHICLE_COLUMNS`."""
        return np.stack([np.broadcast_to(np.asarray(getattr(self, c), float), (n,)) for c in VEHICLE_COLUMNS], axis=1)

    def broadcast(self, n: int) -> "VehicleParams":
        """The same parameters as arrays of shape ``(n,)``."""
        return VehicleParams(**{f.name: np.broadcast_to(np.asarray(getattr(self, f.name), float), (n,)).copy()
                                for f in fields(self)})


# The physics is written once, as functions of plain numbers or arrays that use only
# arithmetic and np.minimum/np.maximum, so numpy runs them over arrays and numba compiles
# them for the driver kernels (acc_gym.drivers._mpc_kernel).

def resistance_accel_core(v, c_r0, c_r1, c_r2, c_d, area, rho, mass):
    """``(F_r + F_a) / m`` [m/s^2] from plain numbers or arrays."""
    return G * (c_r0 + c_r1 * v + c_r2 * v * v) + 0.5 * c_d * rho * area * v * v / mass


def accel_upper_core(v, c_r0, c_r1, c_r2, c_d, area, rho, mass, traction_accel, power):
    """``a_U(v)`` [m/s^2]; below 1 mm/s the power limit is irrelevant and is not divided by 0."""
    power_accel = power / (mass * np.maximum(v, 1e-3))
    resistance = G * (c_r0 + c_r1 * v + c_r2 * v * v) + 0.5 * c_d * rho * area * v * v / mass
    return np.minimum(traction_accel, power_accel) - resistance


def accel_lower_core(v, c_r0, c_r1, c_r2, c_d, area, rho, mass, mu_brake):
    """``a_L(v)`` [m/s^2] (negative)."""
    # (resistance written out: numba compiles these functions and cannot call plain Python ones)
    resistance = G * (c_r0 + c_r1 * v + c_r2 * v * v) + 0.5 * c_d * rho * area * v * v / mass
    return -(mu_brake * G) - resistance


def _res_args(p: VehicleParams):
    return (p.c_r0, p.c_r1, p.c_r2, p.c_d, p.area, p.rho, p.mass)


def resistance_accel(v, p: VehicleParams):
    """Deceleration magnitude from rolling and aerodynamic resistance, ``(F_r + F_a)/m`` [m/s^2]."""
    return resistance_accel_core(np.asarray(v, dtype=float), *_res_args(p))


def coast_acceleration(v, p: VehicleParams):
    """Acceleration with the pedals released and no engine drag, ``-(F_r + F_a)/m`` [m/s^2]."""
    return -resistance_accel(v, p)


def accel_upper(v, p: VehicleParams):
    """Speed-dependent upper acceleration bound ``a_U(v)`` [m/s^2] (traction, then power limit)."""
    return accel_upper_core(np.asarray(v, dtype=float), *_res_args(p), p.traction_accel, p.power)


def accel_lower(v, p: VehicleParams):
    """Braking limit ``a_L(v)`` [m/s^2] (negative): tyre/road friction plus resistance."""
    return accel_lower_core(np.asarray(v, dtype=float), *_res_args(p), p.mu_brake)


# Column order of VehicleParams.as_matrix(), used by compiled kernels.
VEHICLE_COLUMNS = ("c_r0", "c_r1", "c_r2", "c_d", "area", "rho", "mass", "traction_accel", "power", "mu_brake")


def top_speed(p: VehicleParams, tol: float = 1e-6) -> np.ndarray:
    """Speed where ``a_U(v) = 0`` [m/s], found by bisection (array over the batch)."""
    lo = np.zeros(np.broadcast(np.asarray(p.mass), np.asarray(p.power)).shape)
    hi = lo + 200.0
    while np.max(hi - lo) > tol:
        mid = 0.5 * (lo + hi)
        pos = accel_upper(mid, p) > 0
        lo = np.where(pos, mid, lo)
        hi = np.where(pos, hi, mid)
    return 0.5 * (lo + hi)


@dataclass
class VehicleState:
    """Longitudinal state of a batch of vehicles: arrays shaped ``(n,)`` (or ``(..., n)``).

    ``x`` is the front-bumper position [m], ``v`` the speed [m/s] (never negative),
    ``a`` the acceleration applied over the last step [m/s^2].
    """

    x: np.ndarray  # [m]
    v: np.ndarray  # [m/s]
    a: np.ndarray = field(default=None)  # [m/s^2]

    def __post_init__(self) -> None:
        self.x = np.array(self.x, dtype=float)
        self.v = np.array(self.v, dtype=float)
        self.a = np.zeros_like(self.v) if self.a is None else np.array(self.a, dtype=float)
        self.x, self.v, self.a = np.broadcast_arrays(self.x, self.v, self.a)
        self.x, self.v, self.a = self.x.copy(), self.v.copy(), self.a.copy()
        check_finite("VehicleState.x", self.x)
        check_finite("VehicleState.v", self.v)
        check_finite("VehicleState.a", self.a)
        if np.any(self.v < 0):
            raise ValueError(f"VehicleState.v must be >= 0 (no reversing), got {self.v[self.v < 0]!r}")

    def copy(self) -> "VehicleState":
        return VehicleState(self.x.copy(), self.v.copy(), self.a.copy())


def applied_acceleration(a_des, v, p: VehicleParams):
    """Eq. (3): the acceleration the vehicle realises for a desired one [m/s^2].

    ``clip(a_des, a_L(v), a_U(v))``, and 0 for a stopped vehicle asked to decelerate.
    """
    a = np.clip(a_des, accel_lower(v, p), accel_upper(v, p))
    return np.where((v <= 0.0) & (a < 0.0), 0.0, a)


def integrate(x, v, a, dt: float):
    """Exact motion over ``dt`` under constant acceleration ``a``, stopping at ``v = 0``.

    Returns ``(x_next, v_next)``. Pure array function.
    """
    v_end = v + a * dt
    stops = v_end < 0.0
    # Distance while moving: v dt + a dt^2 / 2, or v^2 / (2 |a|) if the vehicle stops inside the step.
    with np.errstate(divide="ignore", invalid="ignore"):
        d_stop = np.where(stops, v * v / np.where(stops, -2.0 * a, 1.0), 0.0)
    dx = np.where(stops, d_stop, v * dt + 0.5 * a * dt * dt)
    return x + dx, np.where(stops, 0.0, v_end)


def step(state: VehicleState, a_des, p: VehicleParams, dt: float) -> VehicleState:
    """Advance a batch of vehicles by ``dt`` [s] with desired accelerations ``a_des`` [m/s^2]."""
    a_des = np.asarray(a_des, dtype=float)
    check_finite("a_des", a_des)
    a = applied_acceleration(a_des, state.v, p)
    x, v = integrate(state.x, state.v, a, dt)
    return VehicleState(x, v, a)
