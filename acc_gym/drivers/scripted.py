"""Scripted drivers and a grouping of heterogeneous driver models behind one batch.

:class:`ProfileDriver` makes a vehicle follow a :class:`~acc_gym.simulation.profiles.SpeedProfile`
(scripted or recorded; one profile, or one per vehicle) with the driver-model call shape,
so a scripted lead and a human-like MPC lead are interchangeable in any simulation.
It keeps its own clock (``dt`` per ``act``), restarted by ``reset()``; each step it asks
for the acceleration that reaches the profile's speed at the end of the step, which the
vehicle model then limits (so a profile that brakes harder than the tyres allow is
followed as closely as physics permits).

:class:`DriverGroup` presents several models, each controlling a subset of a batch of
``n`` vehicles, as one model over the whole batch (vehicles no model controls ask for 0).
A batch of scenarios whose lead is an MPC driver in some and a scripted profile in others
thus steps as one array.
"""

from __future__ import annotations

import numpy as np

from acc_gym._validation import check_positive
from acc_gym.drivers.base import Observation

_INFO_FILL = {"mode": -1, "path": -1, "a_req": np.nan, "slack": np.nan}


class ProfileDriver:
    """Follow a speed profile: ``profile.speeds`` ``(K,)`` for all ``n`` vehicles or ``(n, K)``."""

    name = "profile"

    def __init__(self, profile, n: int | None = None, dt: float = 0.2):
        check_positive("dt", dt)
        speeds = np.asarray(profile.speeds)
        rows = speeds.shape[0] if speeds.ndim == 2 else None
        self.n = int(n) if n is not None else (rows or 1)
        if rows is not None and rows != self.n:
            raise ValueError(f"profile has {rows} rows for n={self.n} vehicles")
        self.profile = profile
        self.dt = float(dt)
        self.info: dict[str, np.ndarray] = {}
        self.reset()

    def reset(self) -> None:
        self._k = 0

    def act(self, obs: Observation) -> np.ndarray:
        obs.validate(self.n)
        self._k += 1
        target = np.broadcast_to(self.profile.speed(self._k * self.dt + self.profile.times[0]), (self.n,))
        return (target - obs.v) / self.dt


class DriverGroup:
    """Several models, each owning the vehicles ``index`` of a batch of ``n``, as one model."""

    name = "group"

    def __init__(self, parts, n: int):
        self.n = int(n)
        self.parts = [(model, np.asarray(index, dtype=np.int64)) for model, index in parts]
        seen = np.zeros(self.n, dtype=int)
        for model, index in self.parts:
            if getattr(model, "n", None) != index.size:
                raise ValueError(f"model {getattr(model, 'name', model)!r} controls n={getattr(model, 'n', None)} "
                                 f"vehicles but was given {index.size}")
            if index.size and (index.min() < 0 or index.max() >= self.n):
                raise ValueError(f"vehicle indices must lie in [0, {self.n}), got {index}")
            np.add.at(seen, index, 1)
        if np.any(seen > 1):
            raise ValueError(f"vehicles {np.flatnonzero(seen > 1)} are controlled by more than one model")
        self.controlled = seen == 1
        self.info: dict[str, np.ndarray] = {}

    def reset(self) -> None:
        for model, _ in self.parts:
            if hasattr(model, "reset"):
                model.reset()

    def act(self, obs: Observation) -> np.ndarray:
        if obs.v.shape != (self.n,):  # the models validate the values of their own parts
            raise ValueError(f"observation field 'v' must have shape ({self.n},), got {obs.v.shape}")
        out = np.zeros(self.n)
        info = {k: np.full(self.n, fill, dtype=float if isinstance(fill, float) else np.int64)
                for k, fill in _INFO_FILL.items()}
        for model, index in self.parts:
            out[index] = model.act(obs.take(index))
            for key, value in (getattr(model, "info", None) or {}).items():
                if key in info:
                    info[key][index] = value
        self.info = info
        return out

    @property
    def stats(self) -> dict[str, np.ndarray]:
        """Per-vehicle solver counters of the models that keep them (MPC), zero elsewhere."""
        merged: dict[str, np.ndarray] = {}
        for model, index in self.parts:
            for key, value in (getattr(model, "stats", None) or {}).items():
                merged.setdefault(key, np.zeros(self.n, dtype=np.asarray(value).dtype))[index] = value
        return merged
