"""A ring road: a closed single lane of length ``L`` [m] with ``N`` vehicles (Sugiyama et al.'s
circuit, Stern et al.'s ring, Flow's ring benchmark).

Vehicles are numbered in driving order: vehicle ``i``'s leader is vehicle ``i - 1`` and the
first vehicle's (``i = 0``) leader is the last (``N - 1``): the gaps wrap around. Each
position is driven by one of

* ``"human"``: a human-like MPC driver (:class:`~acc_gym.drivers.mpc.MPCDriver`) sampled from
  a population kind (:func:`~acc_gym.drivers.population.sample_drivers`, ``drivers=``) with
  the desired speed ``v_desired``;
* a baseline model's name (``"idm"``, ``"gipps"``, ``"acc"``, ...:
  :data:`acc_gym.drivers.baselines.MODELS`), its parameters from ``models={name: params}``
  (default: the model's defaults);
* ``"controller"``: the controller under test (an object with SB3's ``predict(obs)``),
  called on the environments' observation through the string-stability measurement's
  adapter (:class:`acc_gym.evaluation.string_stability._Copies`: one copy per controlled
  position when the controller is ``vectorised``, answering that position in every ring of
  the batch at once; else one copy per vehicle), whose action is scaled to an acceleration
  as the environments do (``accel_max``, ``decel_max``).

**Batched.** ``seeds`` gives one seed per ring: ``R`` rings of ``N`` vehicles are simulated
together, every array shaped ``(R, N)``. All the MPC drivers of all rings are one
:class:`~acc_gym.drivers.mpc.MPCDriver` (one ``act`` per step), each baseline model one
model object, each controlled position one controller call. A ring's randomness (its human
drivers' parameters) comes only from its own ``SeedSequence(seed)``, and the driver rows do
not interact, so a ring is the same whatever the batch it is run in
(``tests/simulation/test_ring.py``).

**Step.** One implementation, :class:`RingWorld` (``reset``, then ``fields`` and ``step`` per
step), which :func:`simulate_ring` steps with the controller's answers and the ring
environment (:class:`acc_gym.envs.ring_env.RingEnv`) with the agent's. Two phases, as in every
simulation of the package: every driver decides from the same snapshot (gaps, speeds and
accelerations at the start of the step), then every vehicle moves by the package's vehicle
model (Eq. (3) and the exact integration, :func:`acc_gym.simulation._world_kernel.advance`,
the compiled form of :mod:`acc_gym.vehicle`). Positions are kept unwrapped internally (the distance each front
bumper has travelled; :attr:`RingTrace.s`), so a gap is ``s[i-1] - s[i] - length`` (plus ``L``
for the first vehicle); :attr:`RingTrace.x` is the position along the ring in ``[0, L)``.
A gap that reaches 0 is a collision: recorded (:attr:`RingTrace.collided`), not an error;
the run goes on.

**Start.** Uniform: the vehicles evenly spaced (vehicle ``i`` at ``(N - 1 - i) L / N``), all
at ``v0`` (default 0: standing, as Sugiyama's cars started), unless ``x0`` is given. Nothing
is perturbed unless the caller perturbs ``x0`` or ``v0``: the human drivers' heterogeneity
(each has its own parameters) is what can start a wave.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from acc_gym._validation import check_finite
from acc_gym.drivers.base import Observation
from acc_gym.drivers.mpc import MODEL_VERSION
from acc_gym.drivers.population import KINDS
from acc_gym.simulation._ring_kernel import gaps as _gaps
from acc_gym.simulation._ring_kernel import snapshot
from acc_gym.simulation._world_kernel import advance
from acc_gym.vehicle import VehicleParams

HUMAN = "human"
CONTROLLER = "controller"
SUGIYAMA_SPEED = 30.0 / 3.6  # [m/s] the speed Sugiyama et al.'s drivers were asked to cruise at
MAX_VEHICLES = 1000


def controlled_positions(vehicles: int, penetration: float | None) -> tuple[int, ...]:
    """The 0-based positions a controller drives: ``k = round(p N)`` spread evenly, ``ceil((i + 1) N
    / k) - 1`` for ``i = 0..k-1`` (the string-stability column's rule; the last vehicle is always
    one of them); ``penetration=None``: one vehicle, the last."""
    if penetration is None:
        return (vehicles - 1,)
    p = float(penetration)
    if not (math.isfinite(p) and 0.0 <= p <= 1.0):
        raise ValueError(f"penetration must be a share in [0, 1], got {penetration!r}")
    k = int(round(p * vehicles))
    return tuple(int(math.ceil((i + 1) * vehicles / k)) - 1 for i in range(k))


def ring_layout(vehicles: int, controlled=(), default: str = HUMAN) -> tuple[str, ...]:
    """A layout of ``vehicles`` positions, ``default`` everywhere but ``CONTROLLER`` at ``controlled``."""
    out = [default] * vehicles
    for j in controlled:
        out[j] = CONTROLLER
    return tuple(out)


@dataclass
class RingTrace:
    """A recorded batch of rings. Arrays are ``(T+1, R, N)``; row 0 is the start, row ``k`` the
    state after step ``k`` and the acceleration applied over it (``a[0]``: the initial one)."""

    t: np.ndarray  # (T+1,) [s]
    s: np.ndarray  # [m] unwrapped front-bumper positions (distance travelled plus the start)
    v: np.ndarray  # [m/s]
    a: np.ndarray  # [m/s^2] applied
    length: float  # [m] the ring's length L
    lengths: np.ndarray  # (N,) [m] the vehicles' lengths
    layout: tuple  # (N,) who drives each position
    seeds: tuple  # (R,) the rings' seeds
    vehicle: VehicleParams = field(default_factory=VehicleParams)  # the vehicles' parameters (shared)
    stats: dict = field(default_factory=dict)  # the MPC drivers' solver counts, (R, N) each (0 elsewhere)

    @property
    def x(self) -> np.ndarray:
        """[m] positions along the ring, in ``[0, L)``."""
        x = np.mod(self.s, self.length)
        return np.where(x >= self.length, 0.0, x)  # np.mod can round up to L itself

    @property
    def gap(self) -> np.ndarray:
        """[m] bumper-to-bumper gap of each vehicle to its leader (``i - 1``; the first's is the last)."""
        return ring_gaps(self.s, self.lengths, self.length)

    @property
    def controlled(self) -> np.ndarray:
        """(N,) bool: the positions the controller under test drives."""
        return np.array([k == CONTROLLER for k in self.layout])

    @property
    def collided(self) -> np.ndarray:
        """(R, N): did the vehicle's gap ever drop to 0 or below."""
        return np.any(self.gap <= 0.0, axis=0)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else 0.0


def ring_gaps(s: np.ndarray, lengths: np.ndarray, length: float) -> np.ndarray:
    """Gaps [m] from unwrapped positions ``s`` ``(..., N)``: vehicle ``i``'s leader is ``i - 1``,
    the first vehicle's the last, one lap ahead (:func:`acc_gym.simulation._ring_kernel.gap_to_leader`)."""
    s = np.asarray(s, dtype=float)
    flat = np.ascontiguousarray(s.reshape(-1, s.shape[-1]))
    out = np.empty_like(flat)
    _gaps(flat, np.ascontiguousarray(np.broadcast_to(np.asarray(lengths, dtype=float), (s.shape[-1],))),
          float(length), out)
    return out.reshape(s.shape)


def _seeds(seeds) -> tuple[int, ...]:
    if isinstance(seeds, (int, np.integer)) and not isinstance(seeds, bool):
        seeds = (int(seeds),)
    out = tuple(seeds)
    if not out:
        raise ValueError("seeds must name at least one ring")
    for s in out:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
            raise ValueError(f"a ring's seed must be an integer >= 0, got {s!r}")
    return tuple(int(s) for s in out)


def ring_rng(seed: int, stream: int = 0) -> np.random.Generator:
    """A generator of a ring's human drivers from only this ring's seed (the same drivers
    whatever the batch): ``SeedSequence(seed)``'s child ``stream``; 0 draws their parameters,
    1 their perception's estimation errors, 2 and 3 the same of the controlled positions'
    stand-ins (:class:`RingWorld`'s ``standins``)."""
    return np.random.default_rng(np.random.SeedSequence(int(seed)).spawn(stream + 1)[stream])


class RingSensors:
    """What the ego sensors of the cells ``(M, 2)`` (rows of ``(ring, position)``) of a batch of
    rings measure: the environments' observation (the table of :class:`acc_gym.envs.acc_env.ACCEnv`,
    built by the environments' compiled :func:`acc_gym.envs._kernel.observe`, float32, with the
    margin features of :mod:`acc_gym.envs.observation` for ``version=1``), one row per cell."""

    def __init__(self, cells: np.ndarray, *, set_speed: float, time_gap: float, sensor_range: float, version: int):
        from acc_gym.envs.acc_env import observation_space
        from acc_gym.envs.config import EnvConfig

        self.cells = cells
        space = observation_space(EnvConfig(v2v=False, sensor_range=float(sensor_range)))
        self.low, self.high = space.low.astype(float), space.high.astype(float)
        m = len(cells)
        self.set_speed, self.time_gap = np.full(m, float(set_speed)), np.full(m, float(time_gap))
        self.sensor_range, self.version = float(sensor_range), int(version)
        self.obs = np.empty((m, self.low.shape[0]), dtype=np.float32)
        self.o = np.zeros((8, m))
        self.o[5] = np.inf  # no second vehicle ahead in the -v0 observation without v2v

    def __call__(self, fields: tuple) -> np.ndarray:
        """(M, 7) or (M, 13) float32: the observation of ``fields`` (:meth:`RingWorld.fields`)."""
        from acc_gym.envs import _kernel as K
        from acc_gym.envs.observation import margin_features

        b, j = self.cells[:, 0], self.cells[:, 1]
        for f in range(5):
            self.o[f] = fields[f][b, j]
        K.observe(self.o, self.set_speed, self.time_gap, self.sensor_range, False, self.low, self.high, self.obs)
        return self.obs if self.version == 0 else margin_features(self.obs.astype(float),
                                                                  self.sensor_range).astype(np.float32)


class _Controllers:
    """The controller under test at the controlled cells of a batch of rings: ``actors(cells)``
    (the string-stability measurement's adapter, :class:`~acc_gym.evaluation.string_stability._Copies`
    for a controller in this process, :class:`~acc_gym.evaluation.string_stability.Remote` for one in
    the leaderboard's sandbox) fed the environments' observation (:class:`RingSensors`)."""

    def __init__(self, actors, cells: np.ndarray, *, set_speed: float, time_gap: float, sensor_range: float,
                 version: int, accel_max: float, decel_max: float, actuators=None, dt: float = 0.2):
        from acc_gym.onboard import Actuators, actuator_config

        self.cells = cells
        cfg = actuator_config(actuators)
        # the controlled vehicles' actuators (acc_gym.onboard.actuators; None: ideal), at rest at the start
        self.actuators = None if cfg.ideal or not len(cells) else Actuators(cfg, len(cells), dt)
        self.copies = actors(cells)
        self.sensors = RingSensors(cells, set_speed=set_speed, time_gap=time_gap, sensor_range=sensor_range,
                                   version=version)
        self.accel_max, self.decel_max = float(accel_max), float(decel_max)
        m = len(cells)
        self.failed = np.zeros(int(cells[:, 0].max()) + 1 if m else 0, dtype=bool)
        self.errors: dict = {}

    def __call__(self, fields: tuple, k: int, t: float) -> np.ndarray:
        from acc_gym.evaluation.string_stability import _Raised

        rows = self.sensors(fields)
        names = [f"ring {r}" for r in range(self.failed.size)]
        try:
            act = self.copies(rows, k, self.failed, self.errors, names, t)
        except _Raised as exc:
            raise ValueError(f"the controller at vehicle {exc.vehicle - 1} raised at t = {t:g} s: "
                             f"{type(exc.exc).__name__}: {exc.exc}") from None
        if self.failed.any():
            e = self.errors[int(np.flatnonzero(self.failed)[0])]
            raise ValueError(f"the controller failed in {e.row} at vehicle {e.vehicle - 1}, t = {e.time_s:g} s: "
                             f"{e.message}")
        from acc_gym.envs.acc_env import actions_to_accel

        acc = actions_to_accel(act, self.accel_max, self.decel_max)
        if self.actuators is not None:  # from what the vehicles realised over the last step
            acc = self.actuators.command(acc, fields[1][self.cells[:, 0], self.cells[:, 1]])
        return acc


def _positive(name: str, value) -> float:
    if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


class RingWorld:
    """A batch of rings stepped one ``dt`` at a time: the ring's one step, which
    :func:`simulate_ring` and :class:`acc_gym.envs.ring_env.RingEnv` both run.

    Arrays are ``(R, N)`` (``R = len(seeds)`` rings of ``N`` vehicles, driving order). Who drives
    each position: ``layout`` (see the module docstring); the positions marked ``"controller"``
    (:attr:`cells`, rows of ``(ring, position)``, ring-major) get their desired accelerations
    from the caller of :meth:`step`.

    **Stand-ins** (``standins=True``): each controlled cell also has a human-like driver of its
    own, drawn as the ring's humans are (same population and model) but from the ring's seed's
    streams 2 (parameters) and 3 (perception), so that the ring's humans are the same with or
    without them. A stand-in decides at every step from the same snapshot as everyone else,
    whether or not it drives; ``step(None)`` lets the stand-ins drive the controlled cells (a
    warm-up, or the all-human ring with the same humans).

    Use: :meth:`reset` (the start, fresh drivers), then per step :meth:`fields` (the snapshot a
    controller decides from, the state at the start of the step) and :meth:`step` (everyone
    else decides from the same snapshot, then every vehicle moves).
    """

    def __init__(self, length: float, vehicles: int, *, layout=None, drivers: str = "naturalistic", seeds=0,
                 dt: float = 0.2, v_desired: float = SUGIYAMA_SPEED, models: dict | None = None,
                 vehicle: VehicleParams | None = None, driver_model: int = MODEL_VERSION, standins: bool = False):
        from acc_gym.drivers.baselines import MODELS
        from acc_gym.drivers.mpc import driver_model as _model

        L = float(length)
        if not (math.isfinite(L) and L > 0):
            raise ValueError(f"length must be a finite number of metres > 0, got {length!r}")
        N = vehicles
        if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or not 1 <= N <= MAX_VEHICLES:
            raise ValueError(f"vehicles must be an integer from 1 to {MAX_VEHICLES}, got {vehicles!r}")
        N = int(N)
        self.dt, self.v_desired = _positive("dt", dt), _positive("v_desired", v_desired)
        _model(driver_model)  # validates the version
        if drivers not in KINDS:
            raise ValueError(f"drivers must be one of {list(KINDS)}, got {drivers!r}")
        self.seeds = _seeds(seeds)
        layout = tuple(ring_layout(N)) if layout is None else tuple(layout)
        if len(layout) != N:
            raise ValueError(f"layout has {len(layout)} entries for {N} vehicles")
        for who in layout:
            if who not in (HUMAN, CONTROLLER) and who not in MODELS:
                raise ValueError(f"unknown driver {who!r} in the layout; use 'human', 'controller' or one of "
                                 f"{sorted(MODELS)}")
        models = dict(models or {})
        for name in models:
            if name not in MODELS:
                raise ValueError(f"models: unknown baseline model {name!r}; known: {sorted(MODELS)}")
        veh = vehicle if vehicle is not None else VehicleParams()
        self.lengths = np.broadcast_to(np.asarray(veh.length, dtype=float), (N,)).copy()
        for name in VehicleParams.__dataclass_fields__:
            if np.shape(getattr(veh, name)) not in ((), (N,)):
                raise ValueError(f"vehicle.{name} must be a scalar or one value per position ({N}), got shape "
                                 f"{np.shape(getattr(veh, name))}")
        R = len(self.seeds)
        self.length, self.vehicles, self.rings, self.layout, self.vehicle = L, N, R, layout, veh
        self.drivers, self.driver_model, self.models, self.standins = drivers, driver_model, models, bool(standins)
        self._vp = np.ascontiguousarray(np.broadcast_to(veh.as_matrix(N), (R, N, 10)))
        self.human_j = np.array([j for j in range(N) if layout[j] == HUMAN], dtype=np.int64)
        ctl_j = np.array([j for j in range(N) if layout[j] == CONTROLLER], dtype=np.int64)
        self.cells = np.array([(b, j) for b in range(R) for j in ctl_j], dtype=np.int64).reshape(-1, 2)
        self._ctl_j = ctl_j
        self._hb = np.repeat(np.arange(R), self.human_j.size)
        self._hj = np.tile(self.human_j, R)
        self._rows = np.empty((5, self._hb.size))
        self._present = np.ones((R, N), dtype=np.bool_)
        self._a_des = np.zeros((R, N))
        self._a_des_out = np.zeros((R, N))
        self.s = self.v = self.a = None
        self.k = 0
        self._fields = None

    # --- start
    def reset(self, v0=0.0, x0=None) -> None:
        """The start (see the module docstring: uniform unless ``x0`` is given, all at ``v0``) and
        fresh drivers: the same drivers for the same seeds at every reset."""
        from acc_gym.drivers.baselines import MODELS
        from acc_gym.drivers.mpc import MPCDriverParams, human_drivers
        from acc_gym.drivers.population import sample_drivers

        L, N, R = self.length, self.vehicles, self.rings
        if x0 is None:
            x_start = np.broadcast_to((N - 1 - np.arange(N)) * L / N, (R, N)).copy()
        else:
            x_start = np.broadcast_to(np.asarray(x0, dtype=float), (R, N)).copy()
            check_finite("x0", x_start)
            if np.any(x_start < 0) or np.any(x_start >= L):
                raise ValueError(f"x0 must lie in [0, L) = [0, {L:g}), got {x_start.min():g} .. {x_start.max():g}")
            if N > 1 and np.any(np.diff(x_start, axis=1) >= 0):
                raise ValueError("x0 must be in driving order: each vehicle behind the one before it "
                                 "(x0[i] < x0[i - 1])")
        v = np.broadcast_to(np.asarray(v0, dtype=float), (R, N)).copy()
        check_finite("v0", v)
        if np.any(v < 0):
            raise ValueError(f"v0 must be >= 0, got {v.min()!r}")
        gaps0 = ring_gaps(x_start, self.lengths, L)
        if np.any(gaps0 <= 0):
            raise ValueError(f"the vehicles do not fit: smallest initial gap {gaps0.min():.3f} m (ring {L:g} m, "
                             f"{N} vehicles of {self.lengths.max():g} m)")
        self.s, self.v, self.a = x_start, v, np.zeros((R, N))
        self.k = 0
        self._fields = None

        # drivers: one MPC batch for every human of every ring, one model per baseline name
        def humans(positions: np.ndarray, stream: int):
            params = MPCDriverParams.stack([sample_drivers(ring_rng(seed, stream), positions.size, self.v_desired,
                                                           self.drivers) for seed in self.seeds])
            # row b * n + i: ring b's i-th
            return human_drivers(params, self.driver_model,
                                 groups=[(ring_rng(seed, stream + 1), positions.size) for seed in self.seeds],
                                 vehicle=self.vehicle.take(np.tile(positions, R)))

        self.mpc = humans(self.human_j, 0) if self.human_j.size else None
        self.standin = humans(self._ctl_j, 2) if self.standins and self._ctl_j.size else None
        self.groups = []  # (model, positions)
        for name in dict.fromkeys(w for w in self.layout if w in MODELS):
            js = np.array([j for j in range(N) if self.layout[j] == name], dtype=np.int64)
            self.groups.append((MODELS[name](self.models.get(name), n=R * js.size, dt=self.dt), js))
        for model, _ in self.groups:
            model.reset()

    # --- one step
    @property
    def t(self) -> float:
        """[s] the time since the start."""
        return self.k * self.dt

    def gaps(self) -> np.ndarray:
        """[m] (R, N) each vehicle's gap to its leader now."""
        return ring_gaps(self.s, self.lengths, self.length)

    def fields(self) -> tuple:
        """The snapshot every driver decides from: ``(v, a, gap, v_lead, a_lead)``, each (R, N), of the
        state now (``a``: the acceleration applied over the last step)."""
        if self._fields is None:
            if self.s is None:
                raise RuntimeError("call reset() before stepping a RingWorld")
            ahead = np.empty((3, self.rings, self.vehicles))  # fresh: a caller may keep the snapshot
            snapshot(self.s, self.v, self.a, self.lengths, float(self.length), ahead, self._hb, self._hj, self._rows)
            self._fields = (self.v, self.a, ahead[0], ahead[1], ahead[2])
        return self._fields

    def step(self, a_controlled=None, out=None) -> None:
        """Advance every ring by one ``dt``: every driver decides from :meth:`fields`, the controlled
        cells take ``a_controlled`` [m/s^2] (one per row of :attr:`cells`; None: the stand-ins'
        decisions), then every vehicle moves (:func:`acc_gym.simulation._world_kernel.advance`).
        ``out``: three (R, N) arrays the new ``s, v, a`` are written into (they become the state)."""
        R, N, L, dt, k = self.rings, self.vehicles, self.length, self.dt, self.k
        fields = self.fields()
        s, v, a, a_des = self.s, self.v, self.a, self._a_des
        if self.mpc is not None:  # their rows of the snapshot: self._rows, written by fields()
            a_des[self._hb, self._hj] = self.mpc.act_rows(self._rows)
        if self.groups:
            # the second vehicle ahead (ACC's Eq. (3)): two places back in the order, the first two
            # vehicles' one lap ahead; none on a ring of two or fewer
            if N > 2:
                s2 = np.roll(s, 2, axis=1)
                s2[:, :2] += L
                ahead2 = (s2 - s - np.roll(self.lengths, 2), np.roll(v, 2, axis=1), np.roll(a, 2, axis=1))
            else:
                ahead2 = (np.full((R, N), np.inf), np.zeros((R, N)), np.zeros((R, N)))
            for model, js in self.groups:
                obs = Observation(*(np.ascontiguousarray(arr[:, js]).reshape(-1)
                                    for arr in (*fields, *ahead2)))
                a_des[:, js] = model.act_checked(obs).reshape(R, js.size)
        if len(self.cells):
            b, j = self.cells[:, 0], self.cells[:, 1]
            stand = None
            if self.standin is not None:
                rows = np.empty((5, len(self.cells)))
                for f in range(5):
                    rows[f] = fields[f][b, j]
                stand = self.standin.act_rows(rows)
            if a_controlled is None:
                if stand is None:
                    raise ValueError("the layout has controlled positions: give their accelerations (this world "
                                     "has no stand-ins)")
                a_des[b, j] = stand
            else:
                a_ctl = np.asarray(a_controlled, dtype=float)
                if a_ctl.shape != (len(self.cells),):
                    raise ValueError(f"a_controlled must have one acceleration per controlled cell, shape "
                                     f"({len(self.cells)},), got {a_ctl.shape}")
                a_des[b, j] = a_ctl
        if not np.all(np.isfinite(a_des)):
            b, j = np.argwhere(~np.isfinite(a_des))[0]
            raise ValueError(f"ring {b} (seed {self.seeds[b]}): vehicle {j} ({self.layout[j]}) asked for an "
                             f"acceleration of {float(a_des[b, j])!r} m/s^2 at t = {k * dt:g} s")
        # phase 2: every vehicle moves
        s_out, v_out, a_out = out if out is not None else (np.empty((R, N)), np.empty((R, N)), np.empty((R, N)))
        advance(a_des, self._present, s, v, self._vp, float(dt), s_out, v_out, a_out, self._a_des_out)
        self.s, self.v, self.a = s_out, v_out, a_out
        self.k = k + 1
        self._fields = None

    @property
    def stats(self) -> dict:
        """The MPC drivers' solver counts so far, (R, N) each (0 where no human drives)."""
        stats = {}
        if self.mpc is not None:
            for name, counts in self.mpc.stats.items():
                full = np.zeros((self.rings, self.vehicles), dtype=np.int64)
                full[self._hb, self._hj] = counts
                stats[name] = full
        return stats


def simulate_ring(length: float, vehicles: int, *, layout=None, drivers: str = "naturalistic", seeds=0,
                  duration: float = 600.0, dt: float = 0.2, v_desired: float = SUGIYAMA_SPEED, v0=0.0, x0=None,
                  controller=None, models: dict | None = None, vehicle: VehicleParams | None = None,
                  set_speed: float | None = None, time_gap: float = 1.5, sensor_range: float = 200.0,
                  version: int = 0, accel_max: float = 3.0, decel_max: float = 8.0,
                  driver_model: int = MODEL_VERSION, actors=None, standins: bool = False,
                  actuators=None) -> RingTrace:
    """Simulate ``len(seeds)`` rings of ``vehicles`` vehicles on a closed lane of ``length`` [m]
    for ``duration`` [s] at steps of ``dt`` [s] (see the module docstring): a :class:`RingWorld`
    stepped ``duration / dt`` times, the controller under test at its controlled cells.

    Parameters
    ----------
    layout: who drives each position (``N`` entries: ``"human"``, ``"controller"`` or a baseline
        model's name; default every position ``"human"``).
    drivers: the human drivers' population kind (:data:`acc_gym.drivers.population.KINDS`).
    seeds: one seed per ring (an int: one ring).
    v_desired: the human drivers' desired speed [m/s] (default Sugiyama's 30 km/h).
    v0: the initial speed [m/s], scalar, ``(N,)`` or ``(R, N)``.
    x0: initial positions along the ring [m] ``(N,)`` or ``(R, N)``, in driving order (each
        vehicle behind the one before it; default evenly spaced).
    controller: the controller under test (an object with ``predict``), if the layout has one.
    actors: instead of ``controller``, ``actors(cells)`` makes the controller's side for the
        controlled cells (the string-stability measurement's interface: the leaderboard's
        sandboxed controller, :func:`acc_gym.evaluation.string_stability.remote_actors`).
    standins: give the controlled positions human stand-ins (:class:`RingWorld`); with neither
        ``controller`` nor ``actors`` they drive there: the all-human ring with the same humans.
    models: baseline parameters by model name (e.g. ``{"idm": IDMParams(...)}``).
    vehicle: every vehicle's parameters (scalars: the default car).
    set_speed, time_gap, sensor_range, version, accel_max, decel_max: the controller's
        observation and action scaling, as :class:`~acc_gym.envs.config.EnvConfig`'s (set speed
        default: ``v_desired``).
    actuators: the controlled vehicles' actuators (:mod:`acc_gym.onboard.actuators`: a preset's
        name, a mapping or an :class:`~acc_gym.onboard.ActuatorConfig`; None: ideal). The human
        drivers' vehicles have none: their reaction is their driver model's.
    driver_model: the human drivers' model version (:data:`acc_gym.drivers.mpc.DRIVER_MODELS`;
        default the newest, 6: with human perception, each ring's estimation errors drawn from
        its own seed's second stream, :func:`ring_rng`).
    """
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a finite number > 0, got {duration!r}")
    if controller is not None and actors is not None:
        raise ValueError("give the controller or its actors, not both")
    world = RingWorld(length, vehicles, layout=layout, drivers=drivers, seeds=seeds, dt=dt, v_desired=v_desired,
                      models=models, vehicle=vehicle, driver_model=driver_model, standins=standins)
    if controller is not None:
        from acc_gym.evaluation.string_stability import _Copies

        actors = lambda cells: _Copies(controller, cells)  # noqa: E731
    if len(world.cells) and actors is None and not standins:
        raise ValueError("the layout has controlled positions but no controller was given")
    world.reset(v0=v0, x0=x0)
    R, N, dt = world.rings, world.vehicles, world.dt
    ctl = None
    if len(world.cells) and actors is not None:
        ctl = _Controllers(actors, world.cells, set_speed=world.v_desired if set_speed is None else float(set_speed),
                           time_gap=time_gap, sensor_range=sensor_range, version=version, accel_max=accel_max,
                           decel_max=decel_max, actuators=actuators, dt=dt)
    T = int(round(float(duration) / dt))
    rec = {k: np.empty((T + 1, R, N)) for k in ("s", "v", "a")}
    rec["s"][0], rec["v"][0], rec["a"][0] = world.s, world.v, world.a
    for k in range(T):
        a_ctl = ctl(world.fields(), k, k * dt) if ctl is not None else None
        world.step(a_ctl, out=(rec["s"][k + 1], rec["v"][k + 1], rec["a"][k + 1]))
    return RingTrace(t=np.arange(T + 1) * dt, s=rec["s"], v=rec["v"], a=rec["a"], length=world.length,
                     lengths=world.lengths, layout=world.layout, seeds=world.seeds, vehicle=world.vehicle,
                     stats=world.stats)
