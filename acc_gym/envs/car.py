"""The ego's car between its controller and the world, for :class:`~acc_gym.envs.core.EpisodeBatch`:
its actuators, its radar and its V2V link (:mod:`acc_gym.onboard`), over the batch's scenes.

:class:`Car` is made only when the config models one of them (:meth:`Car.of`); without it the
core's step and observations are untouched. Per step: :meth:`command` before the world moves
(the actuators), :meth:`sense` after (the radar's and the link's fields replace the true ones
in the observation, and the ``-v1`` features are computed from them). Scenes reset since the
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

RADAR_FIELDS = slice(2, 5)  # gap, relative speed, in range
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
        self._pending: dict[int, tuple] = {}  # row -> (radar's generator, error scale, link's generator)

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
        gens = []
        for j, rng in enumerate(rngs):
            parent = rng.spawn(1)[0] if rng is not None else \
                np.random.default_rng(np.random.SeedSequence(int(scenarios[j].seed)).spawn(1)[0])
            gens.append(parent.spawn(3))  # randomisation, radar, link
        drawn = [dr.draw(g[0]) for g in gens] if dr is not None else None
        if self.actuators is not None:
            self.actuators.reset(np.array(rows), a0, None if drawn is None else [a for a, _ in drawn])
        for j, row in enumerate(rows):
            self._pending[row] = (gens[j][1], 1.0 if drawn is None else drawn[j][1], gens[j][2])

    def start_pending(self, world, fields: np.ndarray) -> None:
        """Start the radars and links of the scenes reset since the last call, in the world's
        current state (``fields``: its true v0 observation fields ``(n, m)``)."""
        if not self._pending:
            return
        rows = np.array(sorted(self._pending), dtype=np.int64)
        starts = [self._pending[r] for r in rows.tolist()]
        self._pending.clear()
        if self.radar is not None:
            self.seen[rows, RADAR_FIELDS] = self.radar.reset(rows, [s[0] for s in starts], _truth(world),
                                                             scales=[s[1] for s in starts])
        if self.link is not None:
            self.link.reset(rows, [s[2] for s in starts])
            self.seen[rows, V2V_SLICE] = self.link.receive(fields[:, V2V_SLICE], rows)

    # ------------------------------------------------------------------ steps
    def command(self, a_des, a_prev: np.ndarray) -> np.ndarray:
        """What the egos' vehicles are asked to realise for commands ``a_des`` [m/s^2]."""
        if self.actuators is None:
            return a_des
        return self.actuators.command(a_des, a_prev)  # (which takes them as float64 arrays)

    def sense(self, world, fields: np.ndarray) -> None:
        """The radars' and links' step after the world's; ``fields`` the true v0 fields after it."""
        if self.radar is not None:
            self.seen[:, RADAR_FIELDS] = self.radar.sense(_truth(world))
        if self.link is not None:
            self.seen[:, V2V_SLICE] = self.link.receive(fields[:, V2V_SLICE])

    def apply(self, fields: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
        """The observed fields written into the v0 ``fields`` ``(n, m)`` (in place), clipped to the bounds."""
        if self.radar is not None:
            K.clip_columns(self.seen, fields, RADAR_FIELDS.start, RADAR_FIELDS.stop, low, high)
        if self.link is not None:
            K.clip_columns(self.seen, fields, V2V_SLICE.start, V2V_SLICE.stop, low, high)


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
