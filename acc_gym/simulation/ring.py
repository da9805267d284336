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

**Step.** Two phases, as in every simulation of the package: every driver decides from the
same snapshot (gaps, speeds and accelerations at the start of the step), then every vehicle
moves by the package's vehicle model (Eq. (3) and the exact integration,
:func:`acc_gym.simulation._world_kernel.advance`, the compiled form of
:mod:`acc_gym.vehicle`). Positions are kept unwrapped internally (the distance each front
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
from acc_gym.drivers.population import KINDS
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
    the first vehicle's the last, one lap ahead."""
    lead = np.roll(s, 1, axis=-1)
    lead[..., 0] += length
    return lead - s - np.roll(lengths, 1)


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


def ring_rng(seed: int) -> np.random.Generator:
    """The generator of a ring's human drivers: ``SeedSequence(seed)``'s first child (only this
    ring's seed: the same drivers whatever the batch)."""
    return np.random.default_rng(np.random.SeedSequence(int(seed)).spawn(1)[0])


class _Controllers:
    """The controller under test at the controlled cells of a batch of rings: the string-stability
    measurement's adapter (:class:`~acc_gym.evaluation.string_stability._Copies`) fed the
    environments' observation (built by the environments' compiled :func:`acc_gym.envs._kernel.observe`,
    float32, with the margin features for ``version=1``)."""

    def __init__(self, controller, cells: np.ndarray, *, set_speed: float, time_gap: float, sensor_range: float,
                 version: int, accel_max: float, decel_max: float):
        from acc_gym.envs.acc_env import observation_space
        from acc_gym.envs.config import EnvConfig
        from acc_gym.evaluation.string_stability import _Copies

        self.cells = cells
        self.copies = _Copies(controller, cells)
        space = observation_space(EnvConfig(v2v=False, sensor_range=float(sensor_range)))
        self.low, self.high = space.low.astype(float), space.high.astype(float)
        m = len(cells)
        self.set_speed, self.time_gap = np.full(m, float(set_speed)), np.full(m, float(time_gap))
        self.sensor_range, self.version = float(sensor_range), int(version)
        self.accel_max, self.decel_max = float(accel_max), float(decel_max)
        self.obs = np.empty((m, self.low.shape[0]), dtype=np.float32)
        self.o = np.zeros((8, m))
        self.o[5] = np.inf  # no second vehicle ahead in the -v0 observation without v2v
        self.failed = np.zeros(int(cells[:, 0].max()) + 1 if m else 0, dtype=bool)
        self.errors: dict = {}

    def __call__(self, fields: tuple, k: int, t: float) -> np.ndarray:
        from acc_gym.envs import _kernel as K
        from acc_gym.envs.observation import margin_features
        from acc_gym.evaluation.string_stability import _Raised

        b, j = self.cells[:, 0], self.cells[:, 1]
        for f in range(5):
            self.o[f] = fields[f][b, j]
        K.observe(self.o, self.set_speed, self.time_gap, self.sensor_range, False, self.low, self.high, self.obs)
        rows = self.obs if self.version == 0 else margin_features(self.obs.astype(float),
                                                                  self.sensor_range).astype(np.float32)
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
        acc = np.empty(len(act))
        K.action_to_accel(np.asarray(act, dtype=float), self.accel_max, self.decel_max, acc)
        return acc


def simulate_ring(length: float, vehicles: int, *, layout=None, drivers: str = "naturalistic", seeds=0,
                  duration: float = 600.0, dt: float = 0.2, v_desired: float = SUGIYAMA_SPEED, v0=0.0, x0=None,
                  controller=None, models: dict | None = None, vehicle: VehicleParams | None = None,
                  set_speed: float | None = None, time_gap: float = 1.5, sensor_range: float = 200.0,
                  version: int = 0, accel_max: float = 3.0, decel_max: float = 8.0) -> RingTrace:
    """Simulate ``len(seeds)`` rings of ``vehicles`` vehicles on a closed lane of ``length`` [m]
    for ``duration`` [s] at steps of ``dt`` [s] (see the module docstring).

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
    models: baseline parameters by model name (e.g. ``{"idm": IDMParams(...)}``).
    vehicle: every vehicle's parameters (scalars: the default car).
    set_speed, time_gap, sensor_range, version, accel_max, decel_max: the controller's
        observation and action scaling, as :class:`~acc_gym.envs.config.EnvConfig`'s (set speed
        default: ``v_desired``).
    """
    from acc_gym.drivers.baselines import MODELS
    from acc_gym.drivers.mpc import MPCDriver, MPCDriverParams
    from acc_gym.drivers.population import sample_drivers

    L = float(length)
    if not (math.isfinite(L) and L > 0):
        raise ValueError(f"length must be a finite number of metres > 0, got {length!r}")
    N = vehicles
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)) or not 1 <= N <= MAX_VEHICLES:
        raise ValueError(f"vehicles must be an integer from 1 to {MAX_VEHICLES}, got {vehicles!r}")
    for name, value in (("duration", duration), ("dt", dt), ("v_desired", v_desired)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    if drivers not in KINDS:
        raise ValueError(f"drivers must be one of {list(KINDS)}, got {drivers!r}")
    seeds = _seeds(seeds)
    R = len(seeds)
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
    if CONTROLLER in layout and controller is None:
        raise ValueError("the layout has controlled positions but no controller was given")
    veh = vehicle if vehicle is not None else VehicleParams()
    lengths = np.broadcast_to(np.asarray(veh.length, dtype=float), (N,)).copy()
    for name in VehicleParams.__dataclass_fields__:
        if np.shape(getattr(veh, name)) not in ((), (N,)):
            raise ValueError(f"vehicle.{name} must be a scalar or one value per position ({N}), got shape "
                             f"{np.shape(getattr(veh, name))}")
    vp = np.ascontiguousarray(np.broadcast_to(veh.as_matrix(N), (R, N, 10)))

    # --- start
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
    s = x_start
    v = np.broadcast_to(np.asarray(v0, dtype=float), (R, N)).copy()
    check_finite("v0", v)
    if np.any(v < 0):
        raise ValueError(f"v0 must be >= 0, got {v.min()!r}")
    gaps0 = ring_gaps(s, lengths, L)
    if np.any(gaps0 <= 0):
        raise ValueError(f"the vehicles do not fit: smallest initial gap {gaps0.min():.3f} m (ring {L:g} m, "
                         f"{N} vehicles of {lengths.max():g} m)")
    a = np.zeros((R, N))

    # --- drivers: one MPC batch for every human of every ring, one model per baseline name
    human_j = np.array([j for j in range(N) if layout[j] == HUMAN], dtype=np.int64)
    mpc = None
    if human_j.size:
        params = MPCDriverParams.stack([sample_drivers(ring_rng(seed), human_j.size, v_desired, drivers)
                                        for seed in seeds])
        mpc = MPCDriver(params, vehicle=veh.take(np.tile(human_j, R)))  # row b * n_h + i: ring b's i-th human
    groups = []  # (model, positions)
    for name in dict.fromkeys(w for w in layout if w in MODELS):
        js = np.array([j for j in range(N) if layout[j] == name], dtype=np.int64)
        groups.append((MODELS[name](models.get(name), n=R * js.size, dt=float(dt)), js))
    ctl_j = np.array([j for j in range(N) if layout[j] == CONTROLLER], dtype=np.int64)
    ctl = None
    if ctl_j.size:
        cells = np.array([(b, j) for b in range(R) for j in ctl_j], dtype=np.int64)
        ctl = _Controllers(controller, cells, set_speed=v_desired if set_speed is None else float(set_speed),
                           time_gap=time_gap, sensor_range=sensor_range, version=version, accel_max=accel_max,
                           decel_max=decel_max)
    for model, _ in groups:
        model.reset()

    # --- run
    T = int(round(float(duration) / float(dt)))
    rec = {k: np.empty((T + 1, R, N)) for k in ("s", "v", "a")}
    rec["s"][0], rec["v"][0], rec["a"][0] = s, v, a
    present = np.ones((R, N), dtype=np.bool_)
    a_des = np.zeros((R, N))
    a_des_out = np.zeros((R, N))
    hb = np.repeat(np.arange(R), human_j.size)
    hj = np.tile(human_j, R)
    rows = np.empty((5, hb.size))
    for k in range(T):
        # phase 1: every driver decides from the same snapshot
        gap = ring_gaps(s, lengths, L)
        v_lead, a_lead = np.roll(v, 1, axis=1), np.roll(a, 1, axis=1)
        fields = (v, a, gap, v_lead, a_lead)
        if mpc is not None:
            for f in range(5):
                rows[f] = fields[f][hb, hj]
            a_des[hb, hj] = mpc.act_rows(rows)
        if groups:
            # the second vehicle ahead (ACC's Eq. (3)): two places back in the order, the first two
            # vehicles' one lap ahead; none on a ring of two or fewer
            if N > 2:
                s2 = np.roll(s, 2, axis=1)
                s2[:, :2] += L
                ahead2 = (s2 - s - np.roll(lengths, 2), np.roll(v, 2, axis=1), np.roll(a, 2, axis=1))
            else:
                ahead2 = (np.full((R, N), np.inf), np.zeros((R, N)), np.zeros((R, N)))
            for model, js in groups:
                obs = Observation(*(np.ascontiguousarray(arr[:, js]).reshape(-1)
                                    for arr in (*fields, *ahead2)))
                a_des[:, js] = model.act_checked(obs).reshape(R, js.size)
        if ctl is not None:
            a_des[ctl.cells[:, 0], ctl.cells[:, 1]] = ctl(fields, k, k * float(dt))
        if not np.all(np.isfinite(a_des)):
            b, j = np.argwhere(~np.isfinite(a_des))[0]
            raise ValueError(f"ring {b} (seed {seeds[b]}): vehicle {j} ({layout[j]}) asked for an acceleration of "
                             f"{a_des[b, j]!r} m/s^2 at t = {k * dt:g} s")
        # phase 2: every vehicle moves
        advance(a_des, present, s, v, vp, float(dt), rec["s"][k + 1], rec["v"][k + 1], rec["a"][k + 1], a_des_out)
        s, v, a = rec["s"][k + 1], rec["v"][k + 1], rec["a"][k + 1]
    stats = {}
    if mpc is not None:
        for name, counts in mpc.stats.items():
            full = np.zeros((R, N), dtype=np.int64)
            full[hb, hj] = counts
            stats[name] = full
    return RingTrace(t=np.arange(T + 1) * float(dt), s=rec["s"], v=rec["v"], a=rec["a"], length=L, lengths=lengths,
                     layout=layout, seeds=seeds, vehicle=veh, stats=stats)
