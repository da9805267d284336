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

One :class:`SlotDrivers` can also hold several slots at once (``n = slots x scenes``,
row ``j * scenes + b`` for slot ``j`` of scene ``b``), so that the MPC drivers of every
surrounding vehicle are one kernel call per step; :class:`SlotView` then presents slot
``j`` with the interface of a one-slot :class:`SlotDrivers` (``assign``, ``info``,
``fallbacks``) and :class:`~acc_gym.simulation.single_lane.SingleLaneWorld` (its
``joint`` argument) asks the holder for all slots' accelerations at once.
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

    def prepare(self, spec) -> bool:
        """Do ahead of :meth:`assign` what needs only the driver ``spec`` itself: an MPC
        driver's condensed QPs (:meth:`MPCDriver.prepare <acc_gym.drivers.mpc.MPCDriver.prepare>`).
        Returns whether there was anything to do."""
        if spec is None or spec.model != "mpc" or self._mpc is None:
            return False
        return self._mpc.prepare(spec.params_object())

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
    def _idle_rows_cruising(self, obs: Observation, idle: np.ndarray) -> Observation:
        """The observation the batched MPC driver gets: rows without an MPC driver (an absent
        vehicle, a scripted profile, a baseline model) see a steady cruise at their row's
        desired speed with nothing ahead -- a state whose plan is the unconstrained law,
        solved in the kernel without a QP -- instead of the parked vehicle an absent slot
        holds (a standing start with an open road: a backend QP solve every step). Their
        output is discarded, and a row that gets an MPC driver is restarted by
        :meth:`MPCDriver.set_params <acc_gym.drivers.mpc.MPCDriver.set_params>`, so no
        present vehicle's numbers change (rows of the batch do not interact)."""
        if not np.any(idle):
            return obs
        return _cruise_state(obs, idle, self._mpc.params.v_desired)

    def act_rows(self, rows: np.ndarray) -> np.ndarray:
        """:meth:`act` for an observation given as rows of one float64 array (see
        :meth:`MPCDriver.act_rows <acc_gym.drivers.mpc.MPCDriver.act_rows>`): when every
        scene's driver is an MPC driver, the batch takes that cheaper path; otherwise
        :meth:`act` on the :class:`~acc_gym.drivers.base.Observation` of the rows."""
        if not self._all_mpc():
            return self.act(Observation(*rows))
        mpc = self._mpc
        out = mpc.act_rows(rows)
        self.fallbacks[:] = mpc.stats_column("fallback")
        # no clock tick: only profile rows read their clock, and a row becomes one only through
        # assign(), which restarts its clock (the tick costs as much as the rest of this bookkeeping)
        self.info = {"mode": mpc.mode.copy()}
        return out

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
            is_mpc = self.kind == 1
            a = self._mpc.act(self._idle_rows_cruising(obs, ~is_mpc))
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


def _cruise_state(obs: Observation, idle: np.ndarray, v_desired: np.ndarray) -> Observation:
    """``obs`` with the ``idle`` rows replaced by a steady cruise at ``v_desired`` with
    nothing ahead."""
    cruise = {"v": v_desired, "a": 0.0, "gap": np.inf, "v_lead": 0.0, "a_lead": 0.0, "gap2": np.inf, "v_lead2": 0.0,
              "a_lead2": 0.0, "stop_gap": np.inf}
    fields = {}
    for name, value in cruise.items():
        given = getattr(obs, name)
        if given is None:
            fields[name] = None
            continue
        arr = np.array(given, dtype=float, copy=True)
        arr[idle] = value[idle] if isinstance(value, np.ndarray) else value
        fields[name] = arr
    return Observation(**fields)


class SlotView:
    """Slot ``index`` of a :class:`SlotDrivers` ``joint`` holding several slots of ``n`` scenes
    each (rows ``index * n .. index * n + n - 1``): what an environment reads and writes of
    one slot. It does not act on its own -- a world with ``joint=`` asks the holder for
    every slot at once (acting for one slot would step the other slots' drivers too)."""

    name = "slot"

    def __init__(self, joint: SlotDrivers, index: int, n: int):
        if not 0 <= index * n < (index + 1) * n <= joint.n:
            raise ValueError(f"slot {index} of {n} scenes does not fit {joint.n} driver rows")
        self.joint = joint
        self.index = int(index)
        self.n = int(n)
        self._rows = slice(self.index * self.n, (self.index + 1) * self.n)

    @property
    def fallbacks(self) -> np.ndarray:
        """Solver fallbacks of each scene's driver in the current episode (a view)."""
        return self.joint.fallbacks[self._rows]

    @property
    def info(self) -> dict[str, np.ndarray]:
        """The slot's rows of the holder's last diagnostics (e.g. ``"mode"``)."""
        return {key: value[self._rows] for key, value in self.joint.info.items()}

    @property
    def _mpc(self):
        """The holder's batched MPC driver (every slot's rows: index with :attr:`rows`)."""
        return self.joint._mpc

    @property
    def rows(self) -> slice:
        """This slot's rows of the holder."""
        return self._rows

    def assign(self, row: int, spec) -> None:
        """Give scene ``row`` of this slot the driver ``spec`` (see :meth:`SlotDrivers.assign`)."""
        row = int(row)
        if not 0 <= row < self.n:
            raise ValueError(f"scene {row} out of range [0, {self.n})")
        self.joint.assign(self.index * self.n + row, spec)

    def reset(self) -> None:
        """Restart the holder's drivers (every slot's: idempotent, as each slot's world reset calls it)."""
        self.joint.reset()

    def act(self, obs):
        raise RuntimeError("a SlotView does not act alone: step it through a SingleLaneWorld given joint=")
