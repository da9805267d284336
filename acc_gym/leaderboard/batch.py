"""Episodes of one environment id stepped together, for the leaderboard's simulation process.

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
nothing of it is recorded or reported.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from acc_gym.envs import _kernel as _K
from acc_gym.envs.acc_env import action_to_accel
from acc_gym.envs.core import EpisodeBatch


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

    def start(self, row: int, scenario, time_gap: float | None = None) -> None:
        """Start ``scenario`` in ``row``, judged at the controller's declared ``time_gap``
        (as ``env.reset(options={"scenario": scenario, "time_gap": time_gap})``)."""
        self.core.reset_rows([row], [None], [scenario], [time_gap])
        self.obs[row] = self.core.observe(*self.bounds, dtype=np.float32)[row]
        self.active[row] = True

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
        self.core.reset_rows(rows, [None] * len(rows), [dataclasses.replace(self.core.scenarios[r],
                                                        vehicles=self.core.scenarios[r].vehicles[:1]) for r in rows])
        self.active[rows] = False

    def step(self, rows: np.ndarray, actions: np.ndarray) -> dict[int, dict]:
        """Apply ``actions`` (float32, finite) to ``rows`` (the active ones; the others get 0);
        the final infos of the episodes that ended, by row."""
        full = np.zeros(self.n)
        full[rows] = actions.astype(float)
        a_des = action_to_accel(full, self.config)
        _, _, _, info = self.core.step(a_des, self.active.copy())
        self.obs[:] = self.core.last_obs
        t = self.core.last_rows[0][_K.F_T]
        out = {}
        for row, final in info["final"].items():
            out[row] = {**final, "t": float(t[row])}
        return out
