"""Human perception for the MPC drivers: a reaction time with temporal anticipation, and
estimation errors of the gap and of the approach rate (Treiber, Kesting and Helbing 2006,
"Delays, inaccuracies and anticipation in microscopic traffic models", Physica A 360:71-88:
the Human Driver Model's perception, HDM).

Paper 001's MPC driver sees the scene exactly and at once. Real drivers do neither, and the
two together are what make a column of otherwise stable drivers form stop-and-go waves
(HDM's finding; ``docs/design/human-driver-waves.md`` measures it on Sugiyama's ring). Driver
model 6 (:data:`acc_gym.drivers.mpc.DRIVER_MODELS`) puts this layer between the scene and the
MPC; each step it turns the true observation into the perceived one:

Reaction time ``T'`` (``reaction_time`` [s], rounded to whole steps of ``dt``)
    The driver sees the vehicle ahead as it was ``T'`` ago: gap ``s_d``, relative speed
    ``dv_d = v_lead,d - v_d`` and the lead's acceleration ``a_lead,d`` (its brake lights).
    Before the first ``T'`` of a run the scene is taken as it was at the start.
Temporal anticipation (HDM's, with the driver's own motion known)
    The driver knows its own speed and acceleration now and how far it has driven since,
    ``D`` (its odometer: each step's ``(v_prev + v) dt / 2``), and extrapolates the vehicle
    ahead from what it saw at constant speed: ``s' = s_d + T' v_lead,d - D``, the lead's speed
    ``v_lead,d``. For a driver at constant speed this is HDM's ``s_d + T' dv_d``; a stopped
    vehicle ahead is then seen where it is, and what the delay hides is only what the vehicle
    ahead did in the last ``T'`` (the source of the waves). Without anticipation a driver
    reacting 1 s late plans from a stale gap and collides (``docs/design/human-driver-waves.md``).
Estimation errors (HDM), two Wiener processes per driver
    ``s_est = s' exp(V_s w_s)`` (``gap_error`` ``V_s``: the relative sd of the gap estimate)
    and ``v_lead,est = v_lead,d - r_c s' w_l`` (``rate_error`` ``r_c`` [1/s]: the error of
    the approach rate, HDM's ``dv_est = dv - r_c s w_l``, grows with the distance, as the
    angular size's rate of change a human reads falls with it). ``w`` are Ornstein-Uhlenbeck processes of unit variance and correlation time
    ``correlation_time`` [s], started from their stationary distribution, advanced exactly:
    ``w <- exp(-dt / tau) w + sqrt(1 - exp(-2 dt / tau)) xi``.

The perceived observation: own ``v`` and ``a`` as they are; ``gap = max(s_est, 0)``;
``v_lead = max(v_lead,est, 0)``; ``a_lead = a_lead,d``. Where nothing is ahead (``gap = inf``
now or ``T'`` ago) the fields pass through as given. A stop position (``stop_gap``) is
static and passes through exactly.

Driver model 6's perception (the defaults): a reaction time of 1.0 s, the middle of measured
brake reaction times (about 0.7-0.75 s for a driver expecting the event, about 1.25-1.5 s
surprised; Green 2000, "How long does it take to stop?") and the value HDM's studies use, with
the anticipation above, and **no estimation errors**: with HDM's (``V_s = 0.1``,
``r_c = 0.01 1/s``, ``tau = 20 s``) paper 001's drivers, calibrated to brake at their own
limit ``a_min`` at the end of an approach, exceeded it or entered EMERGENCY in a benign
approach to a stopped car (89 of 400 naturalistic drivers; 64 with half the errors), against
the paper's 0. The errors stay available (``HumanPerception(gap_error=0.1, rate_error=0.01)``)
for studies that accept that. ``docs/design/driver-model-6.md`` lists what was tried.

Randomness (only with estimation errors): each group of rows (``groups``: e.g. one ring's
drivers) draws from its own ``numpy.random.Generator``, in blocks, so a group's errors do not
depend on which other groups share the batch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acc_gym.drivers._perception_kernel import perceive as _perceive
from acc_gym.drivers.base import delay_steps

_BLOCK = 256  # steps of standard normals drawn at once per group


@dataclass(frozen=True)
class HumanPerception:
    """Parameters of the perception layer (scalars shared by a batch of drivers)."""

    reaction_time: float = 1.0  # [s] T': the scene ahead is seen this late (whole steps of dt)
    gap_error: float = 0.0  # [-] V_s: relative sd of the gap estimate (log-normal; HDM: 0.1)
    rate_error: float = 0.0  # [1/s] r_c: sd of the approach-rate estimate per metre of gap (HDM: 0.01)
    correlation_time: float = 20.0  # [s] tau of the two error processes

    def __post_init__(self) -> None:
        for name in ("reaction_time", "gap_error", "rate_error"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value <= 10.0):
                raise ValueError(f"HumanPerception.{name} must be a number in [0, 10], got {value!r}")
        tau = self.correlation_time
        if not (isinstance(tau, (int, float)) and math.isfinite(tau) and tau > 0):
            raise ValueError(f"HumanPerception.correlation_time must be a number of seconds > 0, got {tau!r}")

    @property
    def noisy(self) -> bool:
        """Whether it has estimation errors (and so needs generators)."""
        return self.gap_error > 0.0 or self.rate_error > 0.0



class Perception:
    """The perception of ``n`` drivers (see the module docstring): ``perceive(rows)`` maps the
    true rows ``(>= 5, n)`` (``v, a, gap, v_lead, a_lead``) to the perceived ones (a new array).

    ``groups`` pairs each generator with how many consecutive rows it serves (their sum is
    ``n``); one generator for all rows: ``[(rng, n)]``.
    """

    def __init__(self, params: HumanPerception, n: int, dt: float, groups=None):
        self.params = params
        self.n = int(n)
        self.dt = float(dt)
        if groups is None and params.noisy:
            raise ValueError("a perception with estimation errors needs groups=[(numpy.random.Generator, rows), "
                             "...] covering every driver")
        self.groups = [(rng, int(count)) for rng, count in groups] if params.noisy else []
        if params.noisy and (sum(c for _, c in self.groups) != self.n or any(c < 0 for _, c in self.groups)):
            raise ValueError(f"Perception: the groups serve {[c for _, c in self.groups]} rows, not {self.n}")
        for rng, _ in self.groups:
            if not isinstance(rng, np.random.Generator):
                raise TypeError(f"Perception: each group needs a numpy.random.Generator, got {type(rng).__name__}")
        self.k = delay_steps(params.reaction_time, self.dt)
        # the kernel's parameters: delay [steps], dt [s], the errors' scales
        self._params = np.array([self.k, self.dt, float(params.gap_error), float(params.rate_error)])
        self._f = math.exp(-self.dt / params.correlation_time)
        self._g = math.sqrt(1.0 - self._f * self._f)
        self.reset()

    def reset(self) -> None:
        """Forget the scene's history; the error processes restart from their stationary draw."""
        self._push = 0  # scenes seen since the start (0: the next fills the delay's ring)
        self._hist = np.empty((self.k + 1, 4, self.n))  # the ring of the scenes ahead: gap, v_lead, a_lead, odometer
        self._motion = np.zeros((2, self.n))  # [m/s] the speed a step ago, [m] the distance driven
        self._noise = [np.empty((0, 2, c)) for _, c in self.groups]
        self._at = [0] * len(self.groups)
        self._w = (np.concatenate([self._draw(j) for j in range(len(self.groups))], axis=1) if self.groups
                   else np.zeros((2, self.n)))

    def _draw(self, j: int) -> np.ndarray:
        """Group ``j``'s next standard normals ``(2, count)``."""
        if self._at[j] >= self._noise[j].shape[0]:
            rng, count = self.groups[j]
            self._noise[j] = rng.standard_normal((_BLOCK, 2, count))
            self._at[j] = 0
        out = self._noise[j][self._at[j]]
        self._at[j] += 1
        return out

    def perceive(self, rows: np.ndarray) -> np.ndarray:
        """The perceived rows (a new array) of the true rows ``(>= 5, n)`` (``v, a, gap, v_lead,
        a_lead``, then any others, passed through)."""
        rows = np.asarray(rows, dtype=float)
        out = self.perceive_fields(rows[0], rows[1], rows[2], rows[3], rows[4])
        if rows.shape[0] > 5:
            out = np.concatenate([out, rows[5:]])
        return out

    def perceive_fields(self, v, a, gap, v_lead, a_lead) -> np.ndarray:
        """The perceived ``(v, a, gap, v_lead, a_lead)`` ``(5, n)`` (a new array) of the true
        fields, each a float64 array ``(n,)``: one step of the scene
        (:func:`acc_gym.drivers._perception_kernel.perceive`)."""
        if self.groups:
            xi = np.concatenate([self._draw(j) for j in range(len(self.groups))], axis=1)
            self._w = self._f * self._w + self._g * xi
        out = np.empty((5, self.n))
        _perceive(v, a, gap, v_lead, a_lead, self._hist, self._push, self._motion, self._w, self._params, out)
        self._push += 1
        return out
