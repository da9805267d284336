"""The powertrain and brakes between a controller's command and the vehicle's acceleration.

Without an actuator model (``ActuatorConfig()``, the ``ideal`` preset) the vehicle realises
the commanded acceleration over the next step, within its envelope
(:func:`acc_gym.vehicle.applied_acceleration`). With one, the command first passes a dead
time ``D`` and a first-order lag ``T``, the actuator model of the string-stability
literature (``T a' + a = u(t - D)``; Rajamani, *Vehicle Dynamics and Control*, ch. 5;
Ploeg et al. 2014)::

    u_D[k] = (1 - f) u[k - m] + f u[k - m - 1],   D = (m + f) dt, 0 <= f < 1     (dead time)
    a[k]   = a[k - 1] + alpha (u_D[k] - a[k - 1]),  alpha = 1 - exp(-dt / T)      (lag)

``u[k]`` is the controller's command at step ``k``, ``a[k]`` the acceleration the vehicle
holds over step ``k`` (after the envelope's clip, so a saturated powertrain does not wind
up: the lag starts from what was realised). A dead time between two steps interpolates
the two commands around it (a 0.3 s dead time at the 0.2 s step is half the command of one
step ago and half of two steps ago). ``T = 0`` is no lag (``alpha = 1``), ``D = 0`` no dead
time; both 0 is the ideal actuator, which the environments then do not model at all (their
trajectories are those without this module).

**Decided: the lag's discrete form.** ``a[k]`` is the lag's value at the end of step
``k``: with ``T -> 0`` it tends to ``u[k]`` (no hidden extra step of delay), and its step
response at the sampling instants is the continuous lag's exactly. In ``z``, with ``z^-1``
one step::

    A(z) = G(z) U(z),  G(z) = alpha z / (z - (1 - alpha)) * ((1 - f) z^-m + f z^-(m+1))

:func:`transfer` returns ``G(exp(j w dt))``; :func:`acc_gym.evaluation.string_stability.linear_transfer`
uses it for the linear ACC's analytic string-stability gain with an actuator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acc_gym.onboard import _actuator_kernel as K

MAX_LAG = 5.0  # [s]
MAX_DEAD_TIME = 5.0  # [s]


@dataclass(frozen=True)
class ActuatorConfig:
    """A first-order lag and a dead time on the realised acceleration; validated on
    construction (a negative, non-finite or too large value is a ``ValueError`` naming it).

    ``lag``: the time constant ``T`` [s] (0: none, up to 5 s); ``dead_time``: ``D`` [s]
    (0: none, up to 5 s; need not be a multiple of the step)."""

    lag: float = 0.0  # [s] first-order time constant of the realised acceleration
    dead_time: float = 0.0  # [s] pure delay before the lag

    def __post_init__(self) -> None:
        for name, top in (("lag", MAX_LAG), ("dead_time", MAX_DEAD_TIME)):
            value = getattr(self, name)
            number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
            if not number or not math.isfinite(value) or not 0.0 <= value <= top:
                raise ValueError(f"ActuatorConfig.{name} must be a number of seconds in [0, {top:g}], got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def ideal(self) -> bool:
        """No lag and no dead time: the command is realised at once."""
        return self.lag == 0.0 and self.dead_time == 0.0

    def delay_steps(self, dt: float) -> tuple[int, float]:
        """``(m, f)``: the dead time as ``(m + f) dt`` with ``0 <= f < 1`` (a dead time within
        1e-9 of a whole number of steps is that number)."""
        steps = self.dead_time / dt
        m = int(math.floor(steps + 1e-9))
        f = steps - m
        return m, (0.0 if f < 1e-9 else f)

    def alpha(self, dt: float) -> float:
        """The lag's share of the remaining difference closed in one step."""
        return 1.0 if self.lag == 0.0 else 1.0 - math.exp(-dt / self.lag)


def transfer(config: ActuatorConfig, freq_hz, dt: float) -> np.ndarray:
    """``G(exp(j w dt))``: realised over commanded acceleration at each frequency [Hz]
    (module docstring); ``dt = 0`` gives the continuous ``exp(-s D) / (T s + 1)``."""
    w = 2.0 * np.pi * np.asarray(freq_hz, dtype=float)
    if dt == 0:
        s = 1j * w
        return np.exp(-s * config.dead_time) / (config.lag * s + 1.0)
    z = np.exp(1j * w * dt)
    alpha = config.alpha(dt)
    m, f = config.delay_steps(dt)
    return alpha * z / (z - (1.0 - alpha)) * ((1.0 - f) * z ** (-m) + f * z ** (-(m + 1)))


class Actuators:
    """The actuators of ``n`` vehicles (arrays ``(n,)``): :meth:`command` turns this step's
    commands into what the vehicles are asked to realise, from what they realised last step.

    Each vehicle has its own lag and dead time (``config``'s until :meth:`reset` gives others,
    up to ``max_dead_time``). State: each vehicle's last commands (a ring buffer as long as the
    longest dead time needs). :meth:`reset` starts vehicles at rest on their actuator: their
    past commands are the acceleration they start with (0 in every built-in scenario)."""

    def __init__(self, config: ActuatorConfig, n: int, dt: float, max_dead_time: float | None = None):
        self.config = config
        self.dt = float(dt)
        n = int(n)
        longest = ActuatorConfig(dead_time=max(config.dead_time, max_dead_time or 0.0)).delay_steps(self.dt)[0]
        m, f = config.delay_steps(self.dt)
        self.vehicles = np.zeros(n, dtype=K.VEHICLE)  # one record per vehicle
        self.vehicles["m"], self.vehicles["f"], self.vehicles["alpha"] = m, f, config.alpha(self.dt)
        self.hist = np.zeros((longest + 2, n))  # [m/s^2] the last commands, newest at head[0]
        self.head = np.zeros(1, dtype=np.int64)

    @property
    def m(self) -> np.ndarray:
        """Each vehicle's whole steps of dead time."""
        return self.vehicles["m"]

    @property
    def f(self) -> np.ndarray:
        """Each vehicle's fraction of a step of dead time beyond them."""
        return self.vehicles["f"]

    @property
    def alpha(self) -> np.ndarray:
        """Each vehicle's lag's share of the difference closed in one step."""
        return self.vehicles["alpha"]

    def reset(self, rows, a0=0.0, configs=None) -> None:
        """Vehicles ``rows`` start with acceleration ``a0`` [m/s^2] held as if commanded for ever,
        with ``configs`` (one :class:`ActuatorConfig` per row; None: the actuators' own)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        self.hist[:, rows] = a0
        for j, r in enumerate(rows.tolist()):
            cfg = self.config if configs is None else configs[j]
            m, f = cfg.delay_steps(self.dt)
            if m + 1 >= self.hist.shape[0]:
                raise ValueError(f"a dead time of {cfg.dead_time:g} s is longer than these actuators hold "
                                 f"({(self.hist.shape[0] - 2) * self.dt:g} s)")
            self.vehicles[r] = (m, f, cfg.alpha(self.dt))  # the record's fields in VEHICLE's order

    def command(self, u: np.ndarray, a_prev: np.ndarray) -> np.ndarray:
        """What the vehicles are asked to realise this step [m/s^2], ``(n,)``, for commands
        ``u`` [m/s^2] and the accelerations ``a_prev`` they realised over the last step
        (:func:`acc_gym.onboard._actuator_kernel.command`)."""
        out = np.empty(self.vehicles.shape[0])
        K.command(self.vehicles, self.hist, self.head, np.asarray(u, dtype=np.float64),
                  np.asarray(a_prev, dtype=np.float64), out)
        return out
