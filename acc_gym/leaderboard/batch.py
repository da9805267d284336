"""Episodes stepped together with a controller that lives elsewhere: the leaderboard's one episode runner.

:class:`BatchRuns` holds ``n`` rows of an :class:`~acc_gym.envs.core.EpisodeBatch` built
with the configuration, scenario generator and reward of ``gym.make(env_id)``'s
environment, starts a given scenario in a row, and steps every row with one action each.
It does per row what :class:`acc_gym.envs.acc_env.ACCEnv` does for its one scene -- the
same observation bounds and dtype (float32), the same action mapping
(:func:`~acc_gym.envs.acc_env.action_to_accel`: the single env's
:func:`~acc_gym.envs._kernel.accel_of_action`), the same final info -- and the rows of an ``EpisodeBatch`` do not interact
(``tests/envs/test_vector_env.py``: a vector env equals single envs exactly), so an
episode's score here is the score ``acc-gym evaluate`` gives it
(``tests/leaderboard/test_leaderboard.py`` checks every built-in). Stepping 16 scenes in
one call instead of 16 single environments is what keeps the trusted simulation process
cheaper than running the controller in-process was.

A row whose episode ended with nothing left to run restarts its last scenario's ego alone
and is no longer active: it steps along with the others (an ``EpisodeBatch`` steps every row) but
nothing of it is recorded or reported. A row started with ``record=True`` keeps its whole scene
(every vehicle) after each step, as :class:`~acc_gym.evaluation.runner.EpisodeRun` does, for
:meth:`BatchRuns.trace`.

:class:`Lockstep` is the trusted process's one episode runner (the suites' episodes, the worst
episode's trace, the ISO 15622 battery, the robustness column): episodes in ``in_flight`` rows of a
:class:`BatchRuns` per group (an env id and its car), one round trip ``exchange(obs, starts,
slots) -> actions`` per step for the rows still running, and :func:`check_answers`, the one check
of a controller's answers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Hashable

import numpy as np

from acc_gym.envs.acc_env import action_to_accel
from acc_gym.envs.core import EpisodeBatch
from acc_gym.scenarios.spec import Scenario
from acc_gym.simulation.single_lane import SceneRecord, WorldTrace


class BatchRuns:
    """``n`` rows of episodes of one environment (``env``: an unwrapped ``ACCEnv``)."""

    def __init__(self, env, n: int):
        self.n = int(n)
        self.config = env.config
        self.core = EpisodeBatch(self.n, env.config, env.core.generator, env.core.reward_fn)
        self.bounds = tuple(np.array(b, dtype=float) for b in env.core.obs_bounds)
        self.core.obs_bounds = self.bounds
        self.obs = np.zeros((self.n, self.bounds[0].shape[0]), dtype=np.float32)
        self.active = np.zeros(self.n, dtype=bool)
        self._tracks: dict[int, SceneRecord] = {}  # recorded rows: their scene after each step

    def start(self, row: int, scenario, time_gap: float | None = None, record: bool = False) -> None:
        """Start ``scenario`` in ``row``, judged at the controller's declared ``time_gap``
        (as ``env.reset(options={"scenario": scenario, "time_gap": time_gap})``); with ``record``
        the row's scene is kept for :meth:`trace`."""
        self.core.reset_rows([row], [None], [scenario], [time_gap])
        self.obs[row] = self.core.observe(*self.bounds, dtype=np.float32)[row]
        self.active[row] = True
        self._tracks.pop(row, None)
        if record:
            self._tracks[row] = SceneRecord(self.core.world, row)

    def trace(self, row: int) -> WorldTrace:
        """The scene of recorded ``row`` so far (every vehicle; arrays ``(T+1, 1, S)``), as
        :meth:`EpisodeRun.trace <acc_gym.evaluation.runner.EpisodeRun.trace>` gives it."""
        return self._tracks[row].trace(self.core.scenarios[row].road)

    def start_many(self, rows, scenarios, time_gap: float | None = None) -> None:
        """:meth:`start` for several rows in one reset (the same result, fewer calls)."""
        rows = [int(r) for r in rows]
        self.core.reset_rows(rows, [None] * len(rows), list(scenarios), [time_gap] * len(rows))
        self.obs[rows] = self.core.observe(*self.bounds, dtype=np.float32)[rows]
        self.active[rows] = True

    def idle(self, row: int) -> None:
        """Nothing more to run in ``row``: its last scenario's ego alone (no surrounding
        drivers to solve for), unrecorded, unreported."""
        self.idle_many([row])

    def idle_many(self, rows) -> None:
        """:meth:`idle` for several rows in one reset."""
        rows = [int(r) for r in rows]
        for r in rows:
            self._tracks.pop(r, None)
        self.core.reset_rows(rows, [None] * len(rows), [dataclasses.replace(self.core.scenarios[r],
                                                        vehicles=self.core.scenarios[r].vehicles[:1]) for r in rows])
        self.active[rows] = False

    def step(self, rows: np.ndarray, actions: np.ndarray) -> dict[int, dict]:
        """Apply ``actions`` (float32, finite) to ``rows`` (the active ones; the others get 0);
        the final infos of the episodes that ended, by row."""
        full = np.zeros(self.n)
        full[rows] = actions.astype(float)
        a_des = action_to_accel(full, self.config)
        _, _, _, final = self.core.step(a_des, self.active.copy())
        self.obs[:] = self.core.last_obs
        if self._tracks:
            modes = self.core.modes()
            for row, scene in self._tracks.items():
                scene.snap(modes[row])
        t = self.core.world.t  # [s] each scene's time after the step
        return {row: {**info, "t": float(t[row])} for row, info in final.items()}


class BadAnswer(ValueError):
    """A controller's answers that are not one finite number per row."""


def check_answers(raw, n: int, where: Callable[[int], str]) -> np.ndarray:
    """The one check of a controller's answers to ``n`` observation rows in the trusted process:
    ``n`` real, finite numbers, else :class:`BadAnswer` naming the count, or the value and where
    its row was (``where(k)`` for row ``k``, formatted only then). Returns them clipped to
    [-1, 1] and rounded to float32, as :func:`~acc_gym.evaluation.runner.as_action` does with a
    local controller's answer."""
    raw = np.asarray(raw)
    if raw.dtype.kind not in "fiu" or raw.size != n:
        raise BadAnswer(f"the controller answered {n} observations with {raw.size} values ({raw.dtype}); "
                        f"expected {n} numbers")
    actions = raw.astype(np.float64).reshape(-1)
    bad = ~np.isfinite(actions)
    if bad.any():
        k = int(np.argmax(bad))
        value = float(actions[k])
        what = "is NaN" if np.isnan(value) else "must be finite"
        raise BadAnswer(f"action {what}: {value!r} (at {where(k)})")
    return np.clip(actions, -1.0, 1.0).astype(np.float32)


@dataclasses.dataclass(frozen=True)
class Episode:
    """One episode for :class:`Lockstep`: its scenario, its environment (``make_env()``, an
    ACC environment; only its configuration, scenario generator and reward are used) and its
    ``group`` (episodes of one group share a :class:`BatchRuns`: the same ``make_env``), and
    its ``name`` for messages."""

    scenario: Scenario
    make_env: Callable
    group: Hashable
    name: str


@dataclasses.dataclass(frozen=True)
class Finished:
    """An episode :class:`Lockstep` ran: its final info (the env's: ``score``, ``qualified``,
    ``report``, ...; and ``t``, the time it ended [s]) and, recorded, its scene."""

    info: dict
    trace: WorldTrace | None = None


class Lockstep:
    """Run ``episodes`` with a controller reached through ``exchange(obs, starts, slots) ->
    actions``: each group's episodes in turn, ``in_flight`` at a time (None: all of the group's)
    in the rows of one :class:`BatchRuns`, row ``r`` answered by the controller's copy in slot
    ``first_slot + r`` (a row's next episode reuses its slot; ``starts`` marks a row's first
    observation, when its copy is ``reset()``). One round trip per step carries a row for every
    episode still running; the answers pass :func:`check_answers`. Episodes are judged at the
    controller's declared ``time_gap`` [s] (None: none); with ``record`` each keeps its scene.

    :attr:`running` holds the episodes (indices) of the round trip under way, for an
    ``exchange`` that names where it failed."""

    def __init__(self, episodes: list[Episode], in_flight: int | None = None, time_gap: float | None = None,
                 first_slot: int = 0, record: bool = False):
        self.episodes, self.in_flight, self.time_gap = list(episodes), in_flight, time_gap
        self.first_slot, self.record = int(first_slot), bool(record)
        self.running: list[int] = []

    def run(self, exchange, on_done: Callable[[int, Finished], None] | None = None) -> dict[int, Finished]:
        """Run every episode; ``on_done(k, finished)`` as each ends. Returns them by index."""
        groups: dict = {}
        for k, episode in enumerate(self.episodes):
            groups.setdefault(episode.group, []).append(k)
        done: dict[int, Finished] = {}
        for queue in groups.values():
            env = self.episodes[queue[0]].make_env()
            try:
                self._run_group(exchange, BatchRuns(env.unwrapped, min(self.in_flight or len(queue), len(queue))),
                                queue, done, on_done)
            finally:
                env.close()
        self.running = []
        return done

    def _run_group(self, exchange, batch: BatchRuns, queue: list[int], done: dict, on_done) -> None:
        rows_of: dict[int, int] = {}  # row -> episode index
        starts = np.zeros(batch.n, dtype=bool)

        def start(row: int) -> None:
            k = rows_of[row] = queue.pop(0)
            batch.start(row, self.episodes[k].scenario, self.time_gap, record=self.record)
            starts[row] = True

        for row in range(batch.n):
            start(row)
        while rows_of:
            rows = np.array(sorted(rows_of))
            self.running = [rows_of[r] for r in rows]
            raw = exchange(batch.obs[rows].astype(float), starts[rows], self.first_slot + rows)
            starts[:] = False
            actions = check_answers(raw, len(rows), lambda i: self.episodes[self.running[i]].name)
            for row, info in batch.step(rows, actions).items():
                k = rows_of.pop(row)
                done[k] = Finished(info, batch.trace(row) if self.record else None)
                if on_done is not None:
                    on_done(k, done[k])
                if queue:
                    start(row)
                else:
                    batch.idle(row)
