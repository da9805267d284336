"""A native vector environment: ``num_envs`` ACC environments stepped as arrays.

All scenes live in one :class:`~acc_gym.envs.core.EpisodeBatch`, so the human-like MPC
drivers of every environment are solved together in one batched kernel call per step.
It is each registered id's ``vector_entry_point``::

    envs = gymnasium.make_vec("acc_gym/SingleLane-v0", num_envs=256, vectorization_mode="vector_entry_point")

Semantics follow :class:`gymnasium.vector.SyncVectorEnv` with next-step autoreset: an
environment whose episode ended is reset by the following ``step`` (its action ignored,
reward 0, not terminated or truncated), drawing its next scenario from its own generator
(seeded ``seed + i`` by ``reset(seed=seed)``). So it equals ``num_envs`` single
environments step for step. Infos are arrays over the environments with ``_key`` masks;
``score``, ``qualified``, ``report`` (an object array of dicts) and ``episode_return`` are
set where an episode ended; ``scenario`` and ``scenario_seed`` where one started.

``workers=k`` (default 1) splits the environments over ``k`` worker processes, one
in-process vector env each (:mod:`acc_gym.envs.shards`): the same results, on ``k``
cores. ``workers_context`` picks the ``multiprocessing`` start method (default
``"fork"`` where available, see :mod:`acc_gym.envs.shards`). Call ``close()`` when done
(the workers are daemons and also end with the program). Each worker draws its next
episodes' scenarios while the caller's policy runs (:meth:`ACCVectorEnv.prepare_resets`),
so a training loop gains more from workers than a loop of pre-drawn actions.

The native vector env runs in the caller's process (its ``workers`` get the config, not
the id). To run single environments in stable-baselines3's ``SubprocVecEnv`` instead, give
the workers the module-qualified id, ``"acc_gym:acc_gym/SingleLane-v0"`` (a worker started
with ``spawn`` or ``forkserver`` has not imported acc_gym), or use
``acc_gym.make_vec_env("acc_gym/SingleLane-v0", n_envs=8, vec_env_cls=SubprocVecEnv)``,
which qualifies it.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from acc_gym.envs.acc_env import (action_to_accel, build_named, check_actions, make_config, make_reward,
                                  observation_space)
from acc_gym.envs.config import CounterScenarioSampler, EnvConfig, ScenarioSampler, make_sampler
from acc_gym.envs.core import EpisodeBatch
from acc_gym.evaluation.scoring import score_episode
from acc_gym.envs.shards import Shards, merge_infos, split
from acc_gym.scenarios.spec import Scenario

_STEP_KEYS = ("t", "q", "g", "gap_safe", "a_applied", "violation", "fallbacks")


class ACCVectorEnv(VectorEnv):
    """``num_envs`` :class:`~acc_gym.envs.acc_env.ACCEnv` as one array environment (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, config: EnvConfig | dict | None = None, *, scenario_generator=None,
                 reward_fn=None, render_mode: str | None = None, mpc_settings=None, default_scenarios=None,
                 workers: int = 1, workers_context: str | None = None, **settings):
        if int(num_envs) != num_envs or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or not 1 <= workers <= num_envs:
            raise ValueError(f"workers must be an integer from 1 to num_envs={num_envs}, got {workers!r}")
        self.num_envs = int(num_envs)
        self.workers = int(workers)
        self.config = make_config(config, settings, default_scenarios)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be 'rgb_array' or None for the vector env, got {render_mode!r}")
        self.render_mode = render_mode
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.single_observation_space = observation_space(self.config)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False
        self._shards = None
        if self.workers > 1:
            self.core = None
            self._shards = Shards(split(self.num_envs, self.workers),
                                  {"config": self.config, "scenario_generator": scenario_generator,
                                   "reward_fn": reward_fn, "render_mode": render_mode, "mpc_settings": mpc_settings},
                                  workers_context)
            return
        self.core = EpisodeBatch(self.num_envs, self.config, make_sampler(self.config, scenario_generator),
                                 make_reward(reward_fn, self.config), mpc_settings)
        space = self.single_observation_space
        self.core.obs_bounds = self._bounds = (space.low.astype(float), space.high.astype(float))
        self._rngs = [seeding.np_random()[0] for _ in range(self.num_envs)]
        self._drawn: dict[int, object] = {}  # row -> its next scenario, drawn ahead (prepare_resets)

    def _obs(self) -> np.ndarray:
        return self.core.observe(*self._bounds, dtype=np.float32)

    def _reset_rows(self, rows, scenarios=None) -> dict:
        if scenarios is None and self._drawn:
            scenarios = [self._drawn.pop(r, None) for r in rows]
            for sc in scenarios:
                if isinstance(sc, BaseException):
                    raise sc  # the draw failed ahead of time: fail where drawing then would have
        self.core.reset_rows(rows, [self._rngs[r] for r in rows], scenarios)
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[rows] = True
        ids = np.empty(self.num_envs, dtype=object)
        seeds = np.zeros(self.num_envs, dtype=np.int64)
        for r in rows:
            ids[r] = self.core.scenarios[r].id
            seeds[r] = self.core.scenarios[r].seed
        return {"scenario": ids, "_scenario": mask.copy(), "scenario_seed": seeds, "_scenario_seed": mask.copy()}

    def reset(self, *, seed=None, options: dict | None = None):
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"reset(seed=...) needs {self.num_envs} seeds, got {len(seeds)}")
        if options is not None and not isinstance(options, dict):
            raise TypeError(f"reset(options=...) must be a dict (keys ['scenarios']) or None, got "
                            f"{type(options).__name__} {options!r}")
        options = dict(options or {})
        scenarios = options.pop("scenarios", None)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; known: ['scenarios']")
        if scenarios is not None and len(scenarios) != self.num_envs:
            raise ValueError(f"options['scenarios'] needs {self.num_envs} entries, got {len(scenarios)}")
        self._drawn = {}
        if self._shards is not None:
            ranges = self._shards.ranges
            outs = self._shards.call("reset", [(seeds[a:b], None if scenarios is None else
                                                {"scenarios": list(scenarios[a:b])}) for a, b in ranges])
            self._autoreset[:] = False
            self._started = True
            return np.concatenate([o for o, _ in outs]), merge_infos([i for _, i in outs], self._shards.sizes)
        self._rngs = [seeding.np_random(s)[0] for s in seeds]
        if scenarios is not None:
            scenarios = [build_named(self.core.generator, self.config, s, int(self._rngs[i].integers(0, 2 ** 31 - 1)))
                         if isinstance(s, str) else s for i, s in enumerate(scenarios)]
            for s in scenarios:
                if s is not None and not isinstance(s, Scenario):
                    raise TypeError(f"options['scenarios'] entries must be ids or Scenarios, got {type(s).__name__}")
        info = self._reset_rows(list(range(self.num_envs)), scenarios)
        info["t"] = np.zeros(self.num_envs)
        info["_t"] = np.ones(self.num_envs, dtype=bool)
        self._autoreset[:] = False
        self._started = True
        return self._obs(), info

    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if self._shards is not None:
            a = check_actions(actions, (self.num_envs, 1))
            outs = self._shards.call("step", [a[lo:hi] for lo, hi in self._shards.ranges])
            obs, reward, term, trunc = (np.concatenate([o[j] for o in outs]) for j in range(4))
            return obs, reward, term, trunc, merge_infos([o[4] for o in outs], self._shards.sizes)
        a = check_actions(actions, (self.num_envs, 1))[:, 0]
        resetting = np.flatnonzero(self._autoreset)
        active = ~self._autoreset
        reward, term, trunc, final = self.core.step(action_to_accel(a, self.config), active=active)
        raw = self.core.info(active)
        reward = np.where(active, reward, 0.0)
        term = term & active
        trunc = trunc & active
        infos: dict = {}
        for key in _STEP_KEYS:
            infos[key] = raw[key]
            infos["_" + key] = active.copy()
        infos["modes"] = raw["modes"]
        infos["_modes"] = active.copy()
        infos["rewards"] = raw["rewards"]
        infos["_rewards"] = active.copy()
        if final:
            done = np.zeros(self.num_envs, dtype=bool)
            done[list(final)] = True
            score = np.zeros(self.num_envs)
            qualified = np.zeros(self.num_envs, dtype=bool)
            ret = np.zeros(self.num_envs)
            report = np.empty(self.num_envs, dtype=object)
            for r, f in final.items():
                score[r], qualified[r], ret[r], report[r] = f["score"], f["qualified"], f["episode_return"], f["report"]
            infos.update({"score": score, "_score": done, "qualified": qualified, "_qualified": done.copy(),
                          "episode_return": ret, "_episode_return": done.copy(), "report": report,
                          "_report": done.copy()})
        if resetting.size:
            info_reset = self._reset_rows(resetting.tolist())
            infos.update(info_reset)
            infos["t"][resetting] = 0.0
            infos["_t"][resetting] = True
        self._autoreset = term | trunc
        # the step's observations, unless some scenes restarted since (then all are made afresh)
        return (self._obs() if resetting.size else self.core.last_obs), reward, term, trunc, infos

    def prepare_resets(self) -> int:
        """Draw now the next scenarios of the environments whose episode just ended, and
        condense their drivers' QPs, so that the next ``step`` (or :meth:`reset_ended`) only
        installs them. Returns how many it drew.

        Results do not change, only when the work is done: each environment's generator is
        used for nothing but its resets, in the same order, and the condensed QPs land in
        the shared cache that the reset reads (``tests/envs/test_shards.py`` checks the
        two agree step for step). A worker of ``workers=k`` calls this right after answering
        a step, while it would otherwise wait for the slowest worker and the caller's policy,
        which takes most of the episodes' start-up work off the critical path. A ``reset()``
        drops what was drawn (it seeds new generators anyway).

        Only with the built-in :class:`~acc_gym.envs.config.ScenarioSampler`, a pure function
        of each environment's generator: an injected scenario generator may keep state of its
        own, so its calls stay where they were. A draw that fails is reported by the reset
        that needs it, as it would have been without this call."""
        if self._shards is not None:
            return sum(self._shards.call("prepare_resets"))
        if type(self.core.generator) not in (ScenarioSampler, CounterScenarioSampler):
            return 0
        count = 0
        for r in np.flatnonzero(self._autoreset).tolist():
            if r in self._drawn:
                continue
            try:
                sc = self.core.draw(self._rngs[r])
            except Exception as exc:  # noqa: BLE001 - raised by the reset that needs this row
                sc = exc
            else:
                try:
                    self.core.prepare(sc)
                except Exception:  # noqa: BLE001, S110 - only a head start: the reset redoes it and reports what fails
                    pass
            self._drawn[r] = sc
            count += 1
        return count

    def reset_ended(self) -> tuple[np.ndarray, np.ndarray]:
        """Reset now, instead of at the next ``step``, the environments whose episode just ended
        (same-step autoreset, as stable-baselines3's vector envs expect). Returns the indices
        reset and the whole observation batch afterwards."""
        if self._shards is not None:
            outs = self._shards.call("reset_ended")
            rows = np.concatenate([r + lo for (r, _), (lo, _) in zip(outs, self._shards.ranges)])
            return rows.astype(np.int64), np.concatenate([o for _, o in outs])
        rows = np.flatnonzero(self._autoreset)
        if rows.size:
            self._reset_rows(rows.tolist())
            self._autoreset[rows] = False
        return rows, self._obs()

    def episode_reports(self) -> list:
        """Each scene's :meth:`ACCEnv.episode_report <acc_gym.envs.acc_env.ACCEnv.episode_report>`:
        the report of its current episode so far (None for a scene not yet stepped since its
        reset). A scene whose episode ended on the last step holds that episode until the
        next ``step()`` resets it (next-step autoreset), so its report then is the ended
        episode's, as in that step's ``info["report"]``."""
        if self._shards is not None:
            return [r for part in self._shards.call("episode_reports") for r in part]
        if not self._started:
            raise RuntimeError("call reset() before episode_reports()")
        scoring = self.config.scoring
        return [score_episode(self.core.trace(row), scoring).to_dict() if int(self.core.world.k[row]) >= 1 else None
                for row in range(self.num_envs)]

    def render(self):
        if self.render_mode is None:
            return None
        if self._shards is not None:
            return tuple(frame for frames in self._shards.call("render") for frame in frames)
        return tuple(self.core.frame(b) for b in range(self.num_envs))

    def close_extras(self, **kwargs) -> None:
        if self._shards is not None:
            self._shards.close()
