"""Domain randomisation of the car: each episode draws its actuators' lag and dead time and its
radar's error scale, so that a policy trained on it does not learn one car only.

``gym.make(id, sensors="typical", randomise={"lag": [0, 0.6], "dead_time": [0, 0.4], "noise": [0, 2]})``:
at every reset each scene draws, uniformly and independently, a lag [s], a dead time [s] and a
multiple of the ``sensors`` config's errors (its gap and relative-speed standard deviations and
biases and its dropout share; its beams, coasting and latency stay), from a generator spawned
from the scene's own (so the scenarios drawn are those without randomisation). The draws replace
the ``actuators`` config's lag and dead time. A range ``[a, a]`` is the constant ``a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acc_gym.onboard.actuators import MAX_DEAD_TIME, MAX_LAG, ActuatorConfig

MAX_NOISE = 10.0  # multiples of the sensors' errors


def _range(name: str, value, top: float) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"Randomisation.{name} must be a pair [low, high], got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo <= hi <= top):
        raise ValueError(f"Randomisation.{name} must be [low, high] with 0 <= low <= high <= {top:g}, got {value!r}")
    return lo, hi


@dataclass(frozen=True)
class Randomisation:
    """Per-episode uniform ranges (module docstring); validated on construction."""

    lag: tuple = (0.0, 0.0)  # [s] the actuators' first-order lag
    dead_time: tuple = (0.0, 0.0)  # [s] the actuators' dead time
    noise: tuple = (1.0, 1.0)  # multiples of the sensors' errors and dropout share

    def __post_init__(self) -> None:
        for name, top in (("lag", MAX_LAG), ("dead_time", MAX_DEAD_TIME), ("noise", MAX_NOISE)):
            object.__setattr__(self, name, _range(name, getattr(self, name), top))

    @property
    def actuated(self) -> bool:
        """Whether the draws give the car actuators other than ideal ones."""
        return self.lag[1] > 0 or self.dead_time[1] > 0

    def draw(self, rng: np.random.Generator) -> tuple[ActuatorConfig, float]:
        """One episode's actuators and error multiple (three uniform draws from ``rng``, in the order lag, dead
        time, noise)."""
        lag, dead, noise = (float(rng.uniform(lo, hi)) for lo, hi in (self.lag, self.dead_time, self.noise))
        return ActuatorConfig(lag=lag, dead_time=dead), noise


def randomisation(value) -> Randomisation | None:
    """``value`` as a :class:`Randomisation`: one itself, a mapping of its fields, or None (none)."""
    if value is None or isinstance(value, Randomisation):
        return value
    if isinstance(value, dict):
        from acc_gym._validation import from_mapping

        return from_mapping(Randomisation, dict(value), "Randomisation")
    raise TypeError(f"randomise must be a mapping of Randomisation's fields (lag, dead_time, noise), one, or None, "
                    f"got {type(value).__name__}")
