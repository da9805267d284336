"""Scripted and recorded speed profiles for a lead vehicle.

A :class:`SpeedProfile` is a piecewise-linear speed over time (breakpoints ``times``,
``speeds``), optionally batched (``speeds`` shaped ``(B, K)``). It is built from
segments of constant acceleration (scripted) or from a recorded trace (any sampling).
The lead vehicle follows it through the vehicle model: each step it asks for the
acceleration that reaches the profile's next speed, which the model then limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acc_gym._validation import check_finite


_F64 = np.dtype(np.float64)
_SHORT = 64  # [breakpoints] profiles up to this long are checked as Python floats (scripted ones have a few)


def _short_valid(times: list, speeds: list) -> bool:
    """:class:`SpeedProfile`'s checks on plain floats: every time and speed finite, the
    times strictly increasing, the speeds >= 0 (False: the numpy checks then raise)."""
    prev = -math.inf
    for t, v in zip(times, speeds):
        if not (t - t == 0.0 and t > prev and v - v == 0.0 and v >= 0.0):
            return False
        prev = t
    return True


@dataclass(frozen=True)
class SpeedProfile:
    """Speed [m/s] as a piecewise-linear function of time [s]; held constant after the end."""

    times: np.ndarray  # (K,) strictly increasing [s]
    speeds: np.ndarray  # (K,) or (B, K) [m/s], >= 0

    def __post_init__(self) -> None:
        t, v = self.times, self.speeds
        if (type(t) is np.ndarray and type(v) is np.ndarray and t.dtype == _F64 and v.dtype == _F64 and t.ndim == 1
                and t.shape == v.shape and 0 < t.shape[0] <= _SHORT and _short_valid(t.tolist(), v.tolist())):
            return  # a short 1-D float64 profile that passes (a scenario's, at every reset): kept as given, as below
        t = np.asarray(self.times, dtype=float)
        v = np.asarray(self.speeds, dtype=float)
        check_finite("SpeedProfile.times", t)
        check_finite("SpeedProfile.speeds", v)
        if t.ndim != 1 or t.size < 1:
            raise ValueError(f"SpeedProfile.times must be a non-empty 1-D array, got shape {t.shape}")
        if v.shape[-1] != t.size or v.ndim > 2:
            raise ValueError(f"SpeedProfile.speeds must have shape (K,) or (B, K) with K = {t.size}, got {v.shape}")
        if np.any(np.diff(t) <= 0):
            raise ValueError("SpeedProfile.times must be strictly increasing")
        if np.any(v < 0):
            raise ValueError(f"SpeedProfile.speeds must be >= 0, got minimum {v.min()!r}")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "speeds", v)

    @classmethod
    def from_segments(cls, v0: float, segments, t0: float = 0.0) -> "SpeedProfile":
        """Scripted profile: start at ``v0`` [m/s], then ``(acceleration [m/s^2], duration [s])``
        segments. A deceleration that would reverse stops at 0 and holds there."""
        check_finite("v0", v0)
        if v0 < 0:
            raise ValueError(f"v0 must be >= 0, got {v0!r}")
        times, speeds = [t0], [float(v0)]
        for acc, dur in segments:
            check_finite("segment acceleration", acc)
            if not (np.isfinite(dur) and dur > 0):
                raise ValueError(f"segment duration must be > 0, got {dur!r}")
            v = speeds[-1]
            v_end = v + acc * dur
            if v_end < 0:
                t_stop = v / -acc
                times.append(times[-1] + t_stop)
                speeds.append(0.0)
                times.append(times[-2] + dur)
                speeds.append(0.0)
                if times[-1] <= times[-2]:
                    times.pop()
                    speeds.pop()
            else:
                times.append(times[-1] + dur)
                speeds.append(v_end)
        return cls(np.array(times), np.array(speeds))

    @classmethod
    def recorded(cls, t, v) -> "SpeedProfile":
        """A recorded speed trace (linear interpolation between samples)."""
        return cls(np.asarray(t, dtype=float), np.asarray(v, dtype=float))

    @property
    def duration(self) -> float:
        return float(self.times[-1] - self.times[0])

    def speed(self, t) -> np.ndarray:
        """Speed at time(s) ``t``: ``(…)`` for a single profile, ``(B, …)`` for a batch."""
        if self.speeds.ndim == 1:
            return np.interp(t, self.times, self.speeds)
        return np.stack([np.interp(t, self.times, row) for row in self.speeds])

    def distance(self, t_end: float, dt: float = 0.01) -> float | np.ndarray:
        """Distance covered from the start to ``t_end`` [m] (trapezoidal, for scenario layout)."""
        t = np.arange(self.times[0], t_end + 0.5 * dt, dt)
        return np.trapezoid(self.speed(t), t, axis=-1)
