"""The surrounding drivers of one vehicle slot over ``n`` scenes, replaceable scene by scene.

An environment (or a vector of them) keeps one :class:`SlotDrivers` per surrounding slot
(POV, POV2) for its whole life; each reset hands one scene a new driver
(:meth:`SlotDrivers.assign`) while the other scenes drive on. The drivers of a slot are
one model call per kind and step:

* MPC human-like drivers of every scene share one batched
  :class:`~acc_gym.drivers.mpc.MPCDriver` (rows re-parameterised in place with
  :meth:`~acc_gym.drivers.mpc.MPCDriver.set_params`, cached condensed QPs);
* scripted or recorded speed profiles are resampled on the step grid once per episode
  and played back as one array;
* baseline models (on request) get one small model per scene, so that a reaction-delay
  buffer never mixes scenes.

Each scene's driver depends only on that scene: a scene stepped among ``n`` gives the
same numbers as the scene stepped alone (what makes a vector environment equal to
``n`` single ones).
"""

from __future__ import annotations

import numpy as np

from acc_gym.drivers.base import Observation
from acc_gym.drivers.baselines import MODELS
from acc_gym.drivers.mpc import MPCDriver, MPCSettings


class SlotDrivers:
    """Drivers of one slot in ``n`` scenes; rows without a driver ask for 0."""

    name = "slot"

    def __init__(self, n: int, dt: float, mpc_settings: MPCSettings | None = None):
        self.n = int(n)
        self.dt = float(dt)
        self.mpc_settings = mpc_settings if mpc_settings is not None else MPCSettings(dt=self.dt)
        if self.mpc_settings.dt != self.dt:
            raise ValueError(f"MPC settings dt={self.mpc_settings.dt} differs from the step dt={self.dt}")
        self.kind = np.zeros(self.n, dtype=np.int8)  # 0 none, 1 mpc, 2 profile, 3 baseline
        self._mpc: MPCDriver | None = None
        self._profile = np.zeros((self.n, 1))  # speeds at steps 0, 1, ... (held after the end)
        self._clock = np.zeros(self.n, dtype=np.int64)
        self._baseline: dict[int, object] = {}
        self.info: dict[str, np.ndarray] = {}
        self.fallbacks = np.zeros(self.n, dtype=np.int64)  # solver fallbacks in the current episode

    # ------------------------------------------------------------------ episodes
    def assign(self, row: int, spec) -> None:
        """Give scene ``row`` the driver ``spec`` (a :class:`~acc_gym.scenarios.spec.DriverSpec`
        or None for an absent vehicle) and restart it."""
        row = int(row)
        self._baseline.pop(row, None)
        self._clock[row] = 0
        self.fallbacks[row] = 0
        if spec is None:
            self.kind[row] = 0
        elif spec.model == "mpc":
            params = spec.params_object()
            if self._mpc is None:
                self._mpc = MPCDriver(params.broadcast(self.n), settings=self.mpc_settings)
            self._mpc.set_params(row, params)
            self.kind[row] = 1
        elif spec.model == "profile":
            profile = spec.profile()
            k = np.arange(int(np.ceil(profile.duration / self.dt)) + 2)
            speeds = profile.speed(profile.times[0] + k * self.dt)
            if speeds.size > self._profile.shape[1]:
                pad = np.repeat(self._profile[:, -1:], speeds.size - self._profile.shape[1], axis=1)
                self._profile = np.concatenate([self._profile, pad], axis=1)
            self._profile[row, :speeds.size] = speeds
            self._profile[row, speeds.size:] = speeds[-1]
            self.kind[row] = 2
        else:
            cls = MODELS[spec.model]
            self._baseline[row] = cls(spec.params_object(), n=1, dt=self.dt)
            self.kind[row] = 3

    def reset(self) -> None:
        """Restart every scene's driver with its current parameters."""
        self._clock[:] = 0
        self.fallbacks[:] = 0
        if self._mpc is not None:
            rows = np.flatnonzero(self.kind == 1)
            if rows.size:
                self._mpc.set_params(rows, self._mpc.params.take(rows))
        for model in self._baseline.values():
            model.reset()

    def _all_mpc(self) -> bool:
        kinds = self.kind.tobytes()
        if kinds != getattr(self, "_kinds_seen", None):
            self._kinds_seen = kinds
            self._all_mpc_cached = bool(self._mpc is not None and np.all(self.kind == 1))
        return self._all_mpc_cached

    # ------------------------------------------------------------------ step
    def act(self, obs: Observation) -> np.ndarray:
        if self._all_mpc():  # the common case (every scene's slot has an MPC driver): no masks
            out = self._mpc.act(obs)
            self.fallbacks[:] = self._mpc.stats_column("fallback")
            self._clock += 1
            self.info = {"mode": self._mpc.mode.copy()}
            return out
        out = np.zeros(self.n)
        mode = np.full(self.n, -1, dtype=np.int64)
        if self._mpc is not None and np.any(self.kind == 1):
            a = self._mpc.act(obs)
            is_mpc = self.kind == 1
            out[is_mpc] = a[is_mpc]
            mode[is_mpc] = self._mpc.mode[is_mpc]
            self.fallbacks[is_mpc] = self._mpc.stats_column("fallback")[is_mpc]
        is_prof = self.kind == 2
        if np.any(is_prof):
            rows = np.flatnonzero(is_prof)
            k = np.minimum(self._clock[rows] + 1, self._profile.shape[1] - 1)
            out[rows] = (self._profile[rows, k] - obs.v[rows]) / self.dt
        for row, model in self._baseline.items():
            out[row] = model.act(obs.take([row]))[0]
        self._clock += 1
        self.info = {"mode": mode}
        return out
