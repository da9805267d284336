"""The ego's car between its controller and the world, for :class:`~acc_gym.envs.core.EpisodeBatch`:
its actuators, its radar and its V2V link (:mod:`acc_gym.onboard`), over the batch's scenes.

:class:`Car` is made only when the config models one of them (:meth:`Car.of`); without it the
core's step and observations are untouched. Per step, inside the core's step kernel (it reads
the car as one record, :meth:`Car.kernel_record`): the actuators turn the command into what the
vehicle is asked to realise before the world moves (:func:`acc_gym.onboard._actuator_kernel.command`),
and after it the radar steps and its fields replace the true ones in the observation, whose
``-v1`` features are then computed from them (:func:`acc_gym.envs._kernel.radar_step`). The V2V
link steps after the kernel (:meth:`receive`, then :meth:`apply`). Scenes reset since the
last observation or step start their radar and link at the next one (:meth:`start_pending`),
from the world's state then.

**Randomness**: at each reset a scene spawns one generator from its own (its scenarios stay
those without a car model) and spawns from that, in order, the randomisation's draws
(:mod:`acc_gym.onboard.randomisation`), the radar's and the link's generators. A scene reset
without a generator (a given scenario in the leaderboard's batches) takes them from its
scenario's seed: the generator a single env reset with that seed spawns first
(``SeedSequence(seed).spawn(1)[0]``), so that such an episode draws the car an
``env.reset(seed=scenario.seed, options={"scenario": scenario})`` episode draws.
"""

from __future__ import annotations

import numpy as np

from acc_gym.envs import _kernel as K
from acc_gym.onboard import Actuators, Radar
from acc_gym.onboard.v2v import V2V_FIELDS, Link

RADAR_FIELDS = slice(K.RADAR_LO, K.RADAR_LO + 3)  # gap, relative speed, in range
V2V_SLICE = slice(V2V_FIELDS[0], V2V_FIELDS[-1] + 1)  # the vehicle ahead's acceleration, the second vehicle


class Car:
    """The car of every scene of a batch (module docstring)."""

    def __init__(self, config, n: int, dt: float):
        dr = config.randomise
        self.config = config
        self.n = int(n)
        self.radar = None if config.sensors.ideal else Radar(config.sensors, self.n, dt, config.sensor_range)
        self.actuators = None if config.actuators.ideal and not (dr and dr.actuated) else \
            Actuators(config.actuators, self.n, dt, max_dead_time=dr.dead_time[1] if dr else None)
        self.link = Link(config.v2v_link, self.n, dt, config.sensor_range) \
            if config.v2v and not config.v2v_link.ideal else None
        self.seen = np.zeros((self.n, 11))  # the last observed v0 fields the car changes (2-4, 7-10)
        self._pending: dict[int, tuple] = {}  # row -> ((bit generator class, parent seed sequence), error scale)
        self._record = None  # the kernels' CAR record (made on first use)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_record"] = None  # a compiled record: made again after unpickling, of the copies' arrays
        return state

    @property
    def pending(self) -> bool:
        """Whether scenes reset since the last observation or step have yet to start their radar and link."""
        return bool(self._pending)

    @classmethod
    def of(cls, config, n: int, dt: float) -> "Car | None":
        """The car of ``config``, or None when it models nothing."""
        car = cls(config, n, dt)
        return car if car.radar is not None or car.actuators is not None or car.link is not None else None

    # ------------------------------------------------------------------ episodes
    def reset(self, rows: list[int], rngs, scenarios, a0: np.ndarray) -> None:
        """New episodes in ``rows``: their generators ``rngs`` (None: from ``scenarios[j].seed``),
        the ego's starting accelerations ``a0``."""
        dr = self.config.randomise
        parents = []
        for j, rng in enumerate(rngs):
            kind = type(rng.bit_generator) if rng is not None else np.random.PCG64
            seq = rng.bit_generator.seed_seq if rng is not None else np.random.SeedSequence(int(scenarios[j].seed))
            parents.append((kind, seq.spawn(1)[0]))  # its children: randomisation, radar, link
        drawn = [dr.draw(_child(parent, 0)) for parent in parents] if dr is not None else None
        if self.actuators is not None:
            self.actuators.reset(np.array(rows), a0, None if drawn is None else [a for a, _ in drawn])
        for j, row in enumerate(rows):
            self._pending[row] = (parents[j], 1.0 if drawn is None else drawn[j][1])

    def start_pending(self, world, fields: np.ndarray) -> None:
        """Start the radars and links of the scenes reset since the last call, in the world's
        current state (``fields``: its true v0 observation fields ``(n, m)``)."""
        if not self._pending:
            return
        rows = np.array(sorted(self._pending), dtype=np.int64)
        starts = [self._pending[r] for r in rows.tolist()]
        self._pending.clear()
        if self.radar is not None:
            self.seen[rows, RADAR_FIELDS] = self.radar.reset(rows, [_child(s[0], 1) for s in starts], _truth(world),
                                                             scales=[s[1] for s in starts])
        if self.link is not None:
            self.link.reset(rows, [_child(s[0], 2) for s in starts])
            self.seen[rows, V2V_SLICE] = self.link.receive(fields[:, V2V_SLICE], rows)

    # ------------------------------------------------------------------ steps
    def kernel_record(self):
        """The car as the core's step kernel reads it (a :data:`~acc_gym.envs._kernel.CAR`
        record holding the actuators', the radar's and this object's own arrays; made once)."""
        if self._record is None:
            values = K.no_car()
            act, radar = self.actuators, self.radar
            if act is not None:
                values.update(actuated=True, vehicles=act.vehicles, hist=act.hist, head=act.head,
                              realised=np.zeros(self.n))
            if radar is not None:
                values.update(sensing=True, radar=radar.radar, tracks=radar.scenes, reports=radar.reports,
                              draws=radar.draws, every=radar._all, sensed=np.zeros((self.n, 3)),
                              pos_max=radar.pos_max)
            values.update(seen=self.seen, fields=np.zeros((self.n, 11 if self.config.v2v else 7)))
            self._record = K.record_of(K.CAR_FIELDS, values)
        return self._record

    def before_step(self, batch) -> None:
        """What a step of ``batch`` (the core) needs first: the radars and links of scenes reset
        since the last observation started, and a draw left for every radar."""
        if self._pending:
            m = 11 if self.config.v2v else 7
            self.start_pending(batch.world, true_fields(batch, np.full(m, -np.inf), np.full(m, np.inf)))
        if self.radar is not None:
            self.radar.ready()

    def receive(self, fields: np.ndarray) -> None:
        """The links' step after the world's (the radar's is in the step kernel); ``fields`` the
        true v0 fields after it."""
        if self.link is not None:
            self.seen[:, V2V_SLICE] = self.link.receive(fields[:, V2V_SLICE])

    def apply(self, fields: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
        """The observed fields written into the v0 ``fields`` ``(n, m)`` (in place), clipped to the bounds."""
        if self.radar is not None:
            K.clip_columns(self.seen, fields, RADAR_FIELDS.start, RADAR_FIELDS.stop, low, high)
        if self.link is not None:
            K.clip_columns(self.seen, fields, V2V_SLICE.start, V2V_SLICE.stop, low, high)


def _child(parent: tuple, k: int) -> np.random.Generator:
    """``Generator(kind(seq)).spawn(3)[k]`` of ``parent = (kind, seq)`` (a bit generator class and
    a seed sequence that has spawned nothing), made alone: a seed sequence's ``k``-th child is
    the one with its entropy and pool size and ``k`` appended to its spawn key
    (:meth:`numpy.random.SeedSequence.spawn`), so the children not used are not made."""
    kind, seq = parent
    child = np.random.SeedSequence(seq.entropy, spawn_key=seq.spawn_key + (k,), pool_size=seq.pool_size)
    return np.random.Generator(kind(child))


def _truth(world) -> tuple:
    """What the egos' radars look at in the world's current state: ``(obs, y, width, lead, lead2)``
    (:func:`acc_gym.onboard._radar_kernel.sense`'s world arrays)."""
    nb = world.neighbours
    return world.observation_array(0), world.y, world.width, nb.lead, nb.lead2


def true_fields(batch, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The true v0 observation fields ``(n, m)`` of ``batch``'s current state, clipped (float64)."""
    m = 11 if batch.config.v2v else 7
    out = np.empty((batch.n, m))
    K.observe(batch.world.observation_array(0), batch.set_speed, batch.time_gap, float(batch.config.sensor_range),
              bool(batch.config.v2v), low[:m], high[:m], out)
    return out
