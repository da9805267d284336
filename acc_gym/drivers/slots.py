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
* baseline models (on request: IDM, Gipps, ACC, ...) are one law call per model and step
  over all their rows (:class:`BaselineRows`): each row keeps its own parameters and its
  own reaction-delay history, so a delay never mixes scenes.

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

from dataclasses import fields

import numpy as np

from acc_gym.drivers import _baseline_kernels as _bk
from acc_gym.drivers.base import Observation
from acc_gym.drivers.baselines import _PLAIN, MODELS
from acc_gym.drivers.mpc import MPCDriver, MPCSettings
from acc_gym.simulation import _world_kernel as _WK


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
        self._baseline = BaselineRows(self.n, self.dt)
        self.info: dict[str, np.ndarray] = {}
        self.fallbacks = np.zeros(self.n, dtype=np.int64)  # solver fallbacks in the current episode
        self._no_modes = np.full(self.n, -1, dtype=np.int64)  # info["mode"] of a step without MPC drivers
        self._no_modes.setflags(write=False)  # one array for every such step: read-only
        self._stale = True  # the rows changed since _refresh (assign sets it)

    # ------------------------------------------------------------------ episodes
    def assign(self, row: int, spec) -> None:
        """Give scene ``row`` the driver ``spec`` (a :class:`~acc_gym.scenarios.spec.DriverSpec`
        or None for an absent vehicle) and restart it."""
        row = int(row)
        self._stale = True
        self._baseline.remove(row)
        self._clock[row] = 0
        self.fallbacks[row] = 0
        self.kind[row] = 0  # absent until the new driver is in place (an assignment that raises leaves it so)
        if spec is None:
            return
        if spec.model == "mpc":
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
            self._baseline.assign(row, MODELS[spec.model], spec.params_object())
            self.kind[row] = 3

    def prepare(self, spec) -> bool:
        """Do ahead of :meth:`assign` what needs only the driver ``spec`` itself: an MPC
        driver's condensed cruise QP (:meth:`MPCDriver.prepare <acc_gym.drivers.mpc.MPCDriver.prepare>`).
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
        # baseline rows restart with the clocks: a row's delay history is read by its clock

    def _refresh(self) -> None:
        """The rows' kinds as a step reads them (which rows hold an MPC driver, profiles, baseline
        models; whether :meth:`act_world` is one compiled call, and then its laws), worked out
        again only after :meth:`assign` (the one place the rows change: their kinds, the baseline
        rows' reaction delays and laws, the profiles). The MPC batch is told which rows to skip
        (:meth:`MPCDriver.set_idle <acc_gym.drivers.mpc.MPCDriver.set_idle>`): their output is
        not used."""
        if not self._stale:
            return
        self._stale = False
        b = self._baseline
        counts = np.bincount(self.kind, minlength=4)  # rows per kind (none, mpc, profile, baseline)
        self._is_mpc = self.kind == 1
        self._n_mpc = int(counts[1])
        if self._mpc is not None:
            self._mpc.set_idle(~self._is_mpc)
        self._profile_rows = np.flatnonzero(self.kind == 2) if counts[2] else np.zeros(0, dtype=np.int64)
        self._has_profiles = bool(counts[2])
        self._has_baselines = bool(counts[3])
        # baseline models without a reaction delay (every law a MODELS class's), profiles and absent
        # vehicles only: act_world is one compiled call (_baseline_kernels.slot_laws) over these arrays
        compiled = not counts[1] and not b.delayed() and b.all_compiled()
        self._laws = (self.kind, b.law_kind, b.law_params, b.law_two, self.dt, self._profile,
                      self._clock) if compiled else None

    # ------------------------------------------------------------------ step
    def act(self, obs: Observation) -> np.ndarray:
        """Every row's desired acceleration [m/s^2] for the observation ``obs`` (0 where no
        vehicle is)."""
        return self._act(obs, lambda: self._mpc.act(obs))

    def act_rows(self, rows: np.ndarray) -> np.ndarray:
        """:meth:`act` for an observation given as rows of one float64 array ``(>= 5, n)`` in
        :class:`~acc_gym.drivers.base.Observation`'s field order (what the world observes; see
        :meth:`MPCDriver.act_rows <acc_gym.drivers.mpc.MPCDriver.act_rows>`): the same numbers,
        without building the observation."""
        rows = np.asarray(rows, dtype=float)
        return self._act(_RowFields(rows), lambda: self._mpc.act_rows(rows))

    def _act(self, obs, mpc_act) -> np.ndarray:
        """The step of :meth:`act` and :meth:`act_rows`: ``obs`` has Observation's fields,
        ``mpc_act()`` steps the MPC batch on it (its rows without an MPC driver are skipped and
        give 0); then the profiles are played and the baseline models' laws run on their rows."""
        self._refresh()
        mpc = self._mpc
        if self._n_mpc:
            out = mpc_act()
            if self._n_mpc == self.n:
                mode = mpc.mode.copy()
                self.fallbacks[:] = mpc.stats_column("fallback")
            else:
                is_mpc = self._is_mpc
                mode = np.full(self.n, -1, dtype=np.int64)
                mode[is_mpc] = mpc.mode[is_mpc]
                self.fallbacks[is_mpc] = mpc.stats_column("fallback")[is_mpc]
        else:
            out = np.zeros(self.n)
            mode = self._no_modes
        if self._has_profiles:
            self._play_profiles(np.asarray(obs.v), out)
        if self._has_baselines:
            self._baseline.act(obs, self._clock, out)
        self._clock += 1
        self.info = {"mode": mode}
        return out

    def act_world(self, obs: np.ndarray, a_des: np.ndarray) -> None:
        """:meth:`act_rows` for the surrounding slots of a world holding every one of them in
        this object (slot ``s`` of scene ``b`` is row ``(s - 1) B + b``): reads the world's
        observation array ``obs`` (``(S, 8, B)``) and writes the accelerations into
        ``a_des[:, 1:]`` (``(B, S)``). When the rows hold baseline models without a reaction
        delay, profiles and absent vehicles only (``drivers="idm"`` and the like) that is one
        compiled call (:func:`acc_gym.drivers._baseline_kernels.slot_laws`: each row's law on
        the observation as it is); otherwise the rows are gathered, :meth:`act_rows` run and
        its outputs put back (:func:`acc_gym.simulation._world_kernel.slot_rows`,
        :func:`~acc_gym.simulation._world_kernel.put_slots`). The same numbers either way
        (``tests/drivers/test_slots.py``)."""
        if self._stale:
            self._refresh()
        laws = self._laws
        if laws is not None:  # compiled_laws(), inline: this is every step of such a world
            self.info = {"mode": self._no_modes}
            _bk.slot_laws(obs, laws, a_des)  # (it advances the clocks)
            return
        rows = np.empty((obs.shape[1], self.n))
        _WK.slot_rows(obs, rows)
        _WK.put_slots(self.act_rows(rows), a_des)

    def compiled_laws(self) -> tuple | None:
        """When :meth:`act_world` is one compiled call (baseline models without a reaction delay,
        profiles and absent vehicles, every law a :data:`~acc_gym.drivers.baselines.MODELS`
        class's): :func:`~acc_gym.drivers._baseline_kernels.slot_laws`' ``laws`` (the rows' kinds,
        laws, parameters, switches, the step, the profiles and the clocks, which it advances by
        one a step), and ``info`` is then
        every row's mode -1, as after such a call; else None. A caller that runs the laws
        itself over several steps (:meth:`SingleLaneWorld.coast
        <acc_gym.simulation.single_lane.SingleLaneWorld.coast>`) takes them from here."""
        self._refresh()
        if self._laws is not None:
            self.info = {"mode": self._no_modes}
        return self._laws

    @property
    def stats(self) -> dict[str, np.ndarray]:
        """Per-row running counts of the MPC drivers' solver (steps, solve paths, slack and
        emergency steps; 0 on rows that never held one); empty without MPC drivers."""
        return {} if self._mpc is None else self._mpc.stats

    def _play_profiles(self, v: np.ndarray, out: np.ndarray) -> None:
        """The profile rows' accelerations to their next speed sample (speeds ``v``) into ``out``
        (rows from :meth:`_refresh`, which runs first in every step)."""
        rows = self._profile_rows
        k = np.minimum(self._clock[rows] + 1, self._profile.shape[1] - 1)
        out[rows] = (self._profile[rows, k] - v[rows]) / self.dt


class BaselineRows:
    """Baseline drivers (:data:`~acc_gym.drivers.baselines.MODELS`) of some of ``n`` rows,
    stepped as one law call per model and parameter structure (e.g. every IDM row at once).

    Each row keeps its own parameters and its own reaction delay (whole steps, as the
    model's :class:`~acc_gym.drivers.base.DelayBuffer` would hold for that row alone): the
    observations of the rows are kept in a ring of the last ``D + 1`` steps (``D`` the
    longest delay), and a row ``k`` steps after its start sees step ``max(k - d, 0)``
    (until ``d`` steps have passed, its first one), exactly what a model of that row alone
    sees. The laws are element-wise over rows, so a row's output is the same number as
    that row's own model gives (tests/drivers/test_slots.py). Parameters are validated when
    a row is assigned (by the model's parameter class); the observation comes from the
    simulation, so it is not re-validated each step (the output is made finite and clipped
    to the models' range, as each model does).

    Each group (a model class and the row-invariant fields that split it: ACC's
    ``predecessors``, Gipps's ``theta=None``) holds one model over all ``n`` rows for the
    life of the holder; assigning a row writes its parameters into that model's arrays in
    place (no rebuild when scenes restart, which in a vector env is every step), and its
    compiled law (``act_into``, :mod:`acc_gym.drivers._baseline_kernels`) runs over the
    group's rows only, in one call per step."""

    _FIELDS = tuple(f.name for f in fields(Observation))

    def __init__(self, n: int, dt: float):
        self.n = int(n)
        self.dt = float(dt)
        self._delay = np.zeros(self.n, dtype=np.int64)  # row -> delay [steps]
        self._ring = np.zeros((len(self._FIELDS), self.n, 1))
        self._keys: dict[tuple, int] = {}  # (model class, fixed fields) -> group index
        self._models: list = []  # group index -> its model over all n rows
        self._group = np.full(self.n, -1, dtype=np.int64)  # row -> its group (-1: no baseline driver)
        self._active: list[tuple[object, np.ndarray, bool]] | None = []  # (model, rows, delayed); None: recompute
        self._delayed = False
        self.rows = np.zeros(0, dtype=np.int64)
        self._layouts: dict[type, tuple] = {}  # model class -> its parameters' (name, array-typed) fields
        self._delays: dict[tuple, int] = {}  # (model class, tau) -> reaction delay [steps] (MODELS' classes)
        # each row's law as one compiled loop runs it (SlotDrivers.act_world): its model's code
        # (_baseline_kernels.KINDS; -1 none), parameters (the model's _kernel_fields order, NaN after and
        # for None) and ACC's Eq. (3) switch -- the numbers its group's arrays hold for that row
        self.law_kind = np.full(self.n, -1, dtype=np.int64)
        self.law_params = np.full((self.n, _bk.MAX_PARAMS), np.nan)
        self.law_two = np.zeros(self.n, dtype=np.bool_)
        # rows with a driver that has a reaction delay, and with a law outside the compiled loop (law_kind -1):
        # counted as rows are assigned and removed, so that delayed() and all_compiled() read no arrays
        self._n_delayed = 0
        self._n_uncompiled = 0

    def assign(self, row: int, cls, params) -> None:
        """Row ``row`` is driven by model ``cls`` with ``params`` (one vehicle's) from now.

        Parameters of plain numbers (or None) for a model of
        :data:`~acc_gym.drivers.baselines.MODELS` (a scenario's driver, at every reset) take a
        shorter path: the row's reaction delay comes from a cache by (model, ``tau``) -- these
        models' delay depends on ``tau`` and the step alone -- instead of building the model
        (parameters are validated when their object is made); anything else builds the model
        for one vehicle, which checks the sizes and gives the delay."""
        layout = self._layouts.get(cls)
        if layout is None:  # (field, declared with an array type) in the parameters' order
            layout = self._layouts[cls] = tuple((f.name, "ndarray" in str(f.type)) for f in fields(cls.params_type))
        p = params
        compiled = MODELS.get(cls.name) is cls  # a package model (not a subclass): its law is compiled by code
        raw = [(name, typed, getattr(p, name)) for name, typed in layout] if type(p) is cls.params_type else None
        if raw is not None and compiled and all(type(v) in _PLAIN or v is None for *_, v in raw):
            tau = getattr(p, "tau", None)
            delay = self._delays.get((cls, tau))
            if delay is None:
                delay = self._delays[(cls, tau)] = cls(p, n=1, dt=self.dt)._delay.delay_steps
            # fields that cannot hold one number per row (declared without an array type: ACC's
            # predecessors; or None: Gipps's theta=None) split the groups
            fixed = tuple((name, v) for name, typed, v in raw if not (typed and v is not None))
            values = {name: float(v) for name, typed, v in raw if typed and v is not None}
        else:
            model = cls(params, n=1, dt=self.dt)  # validates, and gives this row's delay
            p = model.params
            delay = model._delay.delay_steps
            per_row = {f.name: getattr(p, f.name) is not None and "ndarray" in str(f.type) for f in fields(p)}
            fixed = tuple((name, getattr(p, name)) for name, yes in per_row.items() if not yes)
            values = {name: float(np.asarray(getattr(p, name)).ravel()[0]) for name, yes in per_row.items() if yes}
        key = (cls, fixed)
        g = self._keys.get(key)
        if g is not None:
            group_params = self._models[g].params
            for name, value in values.items():
                getattr(group_params, name)[row] = value
        else:
            g = len(self._keys)
            full = {name: np.full(self.n, value) for name, value in values.items()}
            self._keys[key] = g
            self._models.append(cls(type(p)(**full, **dict(fixed)), n=self.n, dt=self.dt))
        if self._group[row] >= 0:  # a row assigned again: its former driver no longer counts
            self._uncount(row)
        self._group[row] = g
        self._delay[row] = delay
        self.law_kind[row] = _bk.KINDS[cls.name] if compiled else -1  # -1: act_world not used
        self._n_delayed += int(self._delay[row] > 0)
        self._n_uncompiled += int(self.law_kind[row] < 0)
        law = [np.nan if v is None else float(v) if type(v) in _PLAIN else float(np.asarray(v, dtype=float).ravel()[0])
               for v in (getattr(p, name) for name in cls._kernel_fields)]
        self.law_params[row, :len(law)] = law
        self.law_params[row, len(law):] = np.nan
        self.law_two[row] = getattr(p, "predecessors", 1) == 2
        if self._delay[row] + 1 > self._ring.shape[2]:
            self._ring = np.concatenate(
                [self._ring, np.zeros(self._ring.shape[:2] + (int(self._delay[row]) + 1 - self._ring.shape[2],))], axis=2)
        self._active = None

    def remove(self, row: int) -> None:
        if self._group[row] >= 0:
            self._uncount(row)
            self._group[row] = -1
            self._delay[row] = 0
            self.law_kind[row] = -1
            self._active = None

    def _uncount(self, row: int) -> None:
        """Take assigned row ``row``'s driver out of the counts behind :meth:`delayed` and :meth:`all_compiled`."""
        self._n_delayed -= int(self._delay[row] > 0)
        self._n_uncompiled -= int(self.law_kind[row] < 0)

    def delayed(self) -> bool:
        """Does some row's driver have a reaction delay (then :meth:`act` keeps a ring of past
        observations)? A row without a baseline driver has no delay (:meth:`remove`).
        Counted as rows are assigned and removed: ``np.any(self._delay > 0)``, without reading it."""
        return self._n_delayed > 0

    def all_compiled(self) -> bool:
        """Is every assigned row's law one the compiled loop runs (a :data:`~acc_gym.drivers.baselines.MODELS`
        class's, ``law_kind >= 0``)? Counted like :meth:`delayed`."""
        return self._n_uncompiled == 0

    def _groups(self) -> list:
        if self._active is None:
            self.rows = np.flatnonzero(self._group >= 0)
            self._delayed = bool(np.any(self._delay[self.rows] > 0))
            self._active = []
            for g, model in enumerate(self._models):
                grp = np.flatnonzero(self._group == g)
                if grp.size:
                    self._active.append((model, grp, bool(np.any(self._delay[grp] > 0))))
        return self._active

    def act(self, obs: Observation, clock: np.ndarray, out: np.ndarray) -> None:
        """Write the baseline rows' desired accelerations into ``out``; ``clock[row]`` is the
        number of steps the row's driver has taken."""
        groups = self._groups()
        seen = obs
        if self._delayed:  # the ring is kept only while some row has a reaction delay
            size = self._ring.shape[2]
            present = [i for i, name in enumerate(self._FIELDS) if getattr(obs, name) is not None]
            rows = self.rows
            k = clock[rows] % size
            for i in present:
                self._ring[i, rows, k] = getattr(obs, self._FIELDS[i])[rows]
            every = np.arange(self.n)
            back = np.maximum(clock - self._delay, 0) % size
            seen = Observation(**{name: (self._ring[i, every, back] if i in present else None)
                                  for i, name in enumerate(self._FIELDS)})
        for model, grp, delayed in groups:  # each model's compiled law: the group's rows only, finite and clipped
            model.act_into(obs, seen if delayed else obs, grp, out)


_OBS_NAMES = tuple(f.name for f in fields(Observation))  # Observation's field order (observation rows)


class _RowFields:
    """:class:`~acc_gym.drivers.base.Observation`'s fields read from observation rows (``(>= 5,
    n)``, Observation's field order) when a law asks for them: the same arrays as
    ``Observation(*rows)``'s, a view made per field read instead of one per row up front
    (a field the rows lack, such as ``stop_gap`` of the world's eight rows, is None, as there)."""

    __slots__ = ("rows",)

    def __init__(self, rows: np.ndarray):
        self.rows = rows


def _row_field(i: int) -> property:
    return property(lambda self: self.rows[i] if i < self.rows.shape[0] else None)


for _i, _name in enumerate(_OBS_NAMES):
    setattr(_RowFields, _name, _row_field(_i))


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
