"""What every longitudinal driver model sees and how it is called.

A driver model controls a batch of ``n`` vehicles. Each simulation step has two phases
(HighwayEnv's ``act`` then ``step``): every model computes its desired accelerations from
the same :class:`Observation` snapshot, then all vehicles move. So the order in which the
models are called never matters.

Models are objects with::

    n: int                               # number of vehicles controlled
    reset() -> None                      # forget all internal state (delay buffers, modes)
    act(obs: Observation) -> ndarray     # desired accelerations, shape (n,) [m/s^2]
    info: dict[str, ndarray]             # per-vehicle diagnostics of the last act()

A model may also offer ``act_checked(obs)``: ``act`` for an observation whose shapes and
values the caller has already checked. ``act`` must check its input (a user hands it
anything); a simulation that builds every observation itself knows the shapes (every field a
float64 array ``(n,)``, fixed while its vehicles and models stay the same) and checks the
values that can go wrong at run time (a NaN, an infinite speed, a gap of ``-inf``) in one
compiled pass per step (:mod:`acc_gym.simulation._column_kernel`, with the rules of
:meth:`Observation.validate`), so re-checking each field in each model's ``act`` would only
cost time (it was 71 % of a column of IDM drivers). The baseline models
(:mod:`acc_gym.drivers.baselines`) offer it; other models are called through ``act``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields, replace

import numpy as np

from acc_gym._validation import check_finite, check_not_nan

NO_VEHICLE = np.inf  # gap value meaning "nothing ahead within range"


@dataclass
class Observation:
    """What the drivers of ``n`` vehicles perceive at one instant (arrays of shape ``(n,)``).

    ``gap`` is bumper to bumper, from the vehicle's front to the rear of the vehicle
    ahead [m]; ``inf`` means nothing within range (then ``v_lead``/``a_lead`` are
    ignored). ``gap2``/``v_lead2``/``a_lead2`` describe the second vehicle ahead (for
    multi-predecessor CACC). ``stop_gap`` is the distance from the front bumper to a
    position where the driver must stop [m] (``inf``: none).
    """

    v: np.ndarray  # [m/s] own speed
    a: np.ndarray  # [m/s^2] own acceleration over the last step
    gap: np.ndarray  # [m] to the vehicle ahead (inf: none)
    v_lead: np.ndarray  # [m/s]
    a_lead: np.ndarray  # [m/s^2]
    gap2: np.ndarray | None = None  # [m] to the second vehicle ahead (inf: none)
    v_lead2: np.ndarray | None = None  # [m/s]
    a_lead2: np.ndarray | None = None  # [m/s^2]
    stop_gap: np.ndarray | None = None  # [m] to a stop position (inf: none)

    @classmethod
    def build(cls, v, a=0.0, gap=np.inf, v_lead=0.0, a_lead=0.0, gap2=None, v_lead2=None,
              a_lead2=None, stop_gap=None) -> "Observation":
        """Broadcast scalars and arrays to a common ``(n,)`` shape."""
        parts = [v, a, gap, v_lead, a_lead]
        extra = [gap2, v_lead2, a_lead2, stop_gap]
        shape = np.broadcast_shapes(*(np.shape(p) for p in parts + [e for e in extra if e is not None]))
        shape = shape if shape else (1,)

        def arr(x):
            return None if x is None else np.broadcast_to(np.asarray(x, dtype=float), shape).copy()

        return cls(*(arr(p) for p in parts), *(arr(e) for e in extra))

    @property
    def n(self) -> int:
        return self.v.shape[-1]

    def validate(self, n: int | None = None) -> "Observation":
        """Raise ``ValueError`` naming the field if a value is NaN, infinite where it must
        be finite, negative where it must not be, or of the wrong shape."""
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            if n is not None and np.shape(value) != (n,):
                raise ValueError(f"observation field {f.name!r} must have shape ({n},), got {np.shape(value)}")
            if f.name in ("gap", "gap2", "stop_gap"):
                check_not_nan(f"observation.{f.name}", value)
                if np.any(np.asarray(value) == -np.inf):
                    raise ValueError(f"observation.{f.name} must not be -inf")
            else:
                check_finite(f"observation.{f.name}", value)
        if np.any(self.v < 0):
            raise ValueError(f"observation.v must be >= 0, got {self.v[self.v < 0]!r}")
        return self

    def take(self, index) -> "Observation":
        """The observations of the vehicles selected by ``index``."""
        return replace(self, **{f.name: (None if getattr(self, f.name) is None else getattr(self, f.name)[index])
                                for f in fields(self)})


class DelayBuffer:
    """Fixed reaction delay over whole steps: ``push(x)`` returns the value from ``d`` steps ago.

    Until ``d`` values have been seen, the oldest one is returned (the driver has watched
    the scene since the start). ``d = 0`` passes values through.
    """

    def __init__(self, delay_steps: int):
        if int(delay_steps) != delay_steps or delay_steps < 0:
            raise ValueError(f"delay_steps must be a non-negative integer, got {delay_steps!r}")
        self.delay_steps = int(delay_steps)
        self._buf: deque = deque(maxlen=self.delay_steps + 1)

    def reset(self) -> None:
        self._buf.clear()

    def push(self, value):
        if not self._buf:
            for _ in range(self.delay_steps):
                self._buf.append(value)
        self._buf.append(value)
        return self._buf[0]


def delay_steps(delay: float, dt: float) -> int:
    """A reaction time [s] as a whole number of steps of ``dt`` [s] (rounded, >= 0)."""
    if not (np.isfinite(delay) and delay >= 0):
        raise ValueError(f"reaction delay must be >= 0 s, got {delay!r}")
    return int(round(delay / dt))
