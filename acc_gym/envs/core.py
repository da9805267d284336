"""The episodes of ``n`` environments as arrays: one core for the single and the vector env.

:class:`EpisodeBatch` owns one :class:`~acc_gym.simulation.single_lane.SingleLaneWorld`
of ``n`` scenes, one :class:`~acc_gym.drivers.slots.SlotDrivers` per surrounding slot (so
the MPC drivers of all scenes are solved together), each scene's random generator,
scenario, step budget and episode record. ``reset_rows`` starts new episodes in some
scenes; ``step`` advances all of them, computes the criteria and rewards as arrays, and
scores every episode that ends. The single environment is this core with ``n = 1``, so a
vector environment equals ``n`` single ones by construction.

With a sensor, actuator or V2V link model in the config (:mod:`acc_gym.onboard`; none with
the ``ideal`` presets, the default) the ego's car (:class:`acc_gym.envs.car.Car`) stands
between the controller and the world: inside the step's kernel the command passes the
actuators before the move and the observation's radar fields pass the radar after it; the V2V
link's fields are replaced after the kernel (the ``-v1`` features are computed from what they
report). The world, the criteria, the reward and the score see the true state.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from acc_gym.drivers.slots import SlotDrivers, SlotView
from acc_gym.envs import _kernel as K
from acc_gym.envs.car import Car, true_fields
from acc_gym.envs.config import EnvConfig
from acc_gym.envs.observation import B0, B1, append_features, feature_bounds
from acc_gym.envs.reward import StepIndicators
from acc_gym.evaluation.scoring import judged_tau1, score_record
from acc_gym.evaluation.trace import EgoTrace
from acc_gym.scenarios.spec import Scenario
from acc_gym.scenarios.world import ABSENT_X, scene_arrays
from acc_gym.simulation.single_lane import SingleLaneWorld

SLOTS = 3
_F_T, _F_Q, _F_GS, _F_A = K.F_T, K.F_Q, K.F_GS, K.F_A  # a step's floats read by info_row
DT = 0.2  # [s] every built-in scenario's step
LANE_WIDTH = 3.75  # [m]
_RECORD = K.RECORD  # the episode record's columns (EgoTrace's)


class EpisodeBatch:
    """``n`` scenes stepped together (see the module docstring)."""

    def __init__(self, n: int, config: EnvConfig, generator, reward_fn, mpc_settings=None):
        self.n = int(n)
        self.config = config
        self.generator = generator
        self.reward_fn = reward_fn
        # the drivers of both surrounding slots of every scene in one batch (row j n + b: slot j + 1
        # of scene b), so that their MPC drivers are one kernel call per step; one view per slot
        self.drivers = SlotDrivers(self.n * (SLOTS - 1), DT, mpc_settings)
        self.slots = [SlotView(self.drivers, j, self.n) for j in range(SLOTS - 1)]
        x0 = np.full((self.n, SLOTS), ABSENT_X)
        self.world = SingleLaneWorld(x0, np.zeros((self.n, SLOTS)), [None, *self.slots],
                                     present=np.zeros((self.n, SLOTS), dtype=bool), dt=DT,
                                     sensor_range=config.sensor_range, joint=self.drivers)
        self._ego_width = np.ascontiguousarray(self.world.width[:, 0])
        self.scenarios: list[Scenario | None] = [None] * self.n
        self.steps = np.zeros(self.n, dtype=np.int64)
        self.set_speed = np.ones(self.n)
        self.time_gap = np.ones(self.n)
        self.tau1 = np.ones(self.n)
        self.declared: list[float | None] = [None] * self.n  # the controllers' declared time gaps [s]
        self.n_lanes = np.ones(self.n)
        self.lane_width = np.full(self.n, LANE_WIDTH)
        self.neg_since = np.full(self.n, np.nan)  # when Q last turned negative [s]
        self.last_change = np.zeros(self.n)  # when the vehicle ahead last changed [s]
        self.lead_prev = np.full(self.n, -1)
        self.done = np.ones(self.n, dtype=bool)
        # the safety-margin features' bounds (none for version 0)
        self._feature_bounds = feature_bounds(config.v2v) if config.version >= 1 else (np.empty(0), np.empty(0))
        self.episode_return = np.zeros(self.n)
        self._set_record(np.zeros((len(_RECORD), self.n, 1)))
        cfg = config.scoring
        # the proper-response grace per scene: the configured response time, or (None) each scene's tau1
        self._grace = np.full(self.n, cfg.response_time) if cfg.response_time is not None else None
        self.obs_bounds: tuple[np.ndarray, np.ndarray] | None = None  # (low, high) float arrays: see step()
        self.last_obs: np.ndarray | None = None
        self._plan: _StepPlan | None = None  # what a step needs of reward_fn and obs_bounds: _step_plan()
        self._core = None  # (world record, plan, the kernels' CORE record): _kernel_core()
        self._python_terms: dict | None = None  # the last step's terms of a reward that is not built in
        self.car = Car.of(config, self.n, DT)  # the ego's radar, actuators and V2V link (None: none modelled)
        self._cfg = np.array([cfg.b0, cfg.b1, cfg.band_width, cfg.steady_dv, cfg.moving_speed, cfg.transient,
                              cfg.sensor_range, cfg.response_decel, cfg.stop_speed, cfg.lead_margin], dtype=float)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_plan"] = state["_scenes"] = state["_core"] = None  # compiled records: made again after unpickling
        return state

    def _set_record(self, arr: np.ndarray) -> None:
        self._rec_arr = arr  # (columns, scenes, steps)
        self._scenes = self._core = None  # the SCENES record holds it: made again

    @property
    def _rec(self) -> dict[str, np.ndarray]:
        """The episode records by column, views ``(scenes, steps)`` into one array."""
        return dict(zip(_RECORD, self._rec_arr))

    # ------------------------------------------------------------------ episodes
    def reset_rows(self, rows, rngs, scenarios=None, time_gaps=None) -> None:
        """Start new episodes in scenes ``rows``: each draws its scenario with its generator
        (``rngs[j]``) unless ``scenarios[j]`` is given; ``time_gaps[j]`` (None: none) is the
        controller's declared time gap the episode is judged at
        (:func:`acc_gym.evaluation.scoring.judged_tau1`)."""
        rows = [int(r) for r in np.atleast_1d(rows)]
        given = scenarios if scenarios is not None else [None] * len(rows)
        missing = [j for j, sc in enumerate(given) if sc is None]
        draw_many = getattr(self.generator, "draw_many", None)
        if draw_many is not None and len(missing) > 1:  # a batched generator: the scenes' draws in one call
            drawn = dict(zip(missing, draw_many([rngs[j] for j in missing])))
            chosen = [drawn[j] if sc is None else sc for j, sc in enumerate(given)]
        else:
            chosen = [sc if sc is not None else self.draw(rngs[j]) for j, sc in enumerate(given)]
        for sc in chosen:
            if not isinstance(sc, Scenario):
                raise TypeError(f"the scenario generator must return a Scenario, got {type(sc).__name__}")
            if sc.dt != DT:
                raise ValueError(f"scenario {sc.id!r} has dt={sc.dt}; the environments step at {DT} s")
            if sc.road.lane_width != LANE_WIDTH:
                raise ValueError(f"scenario {sc.id!r} has {sc.road.lane_width} m lanes; "
                                 f"the environments use {LANE_WIDTH}")
        arr = scene_arrays(chosen, self.world.road)
        self.world.reset_rows(rows, arr.x0, arr.v0, present=arr.present, lateral=arr.lateral, lengths=arr.length,
                              width=arr.width)
        self._ego_width[:] = self.world.width[:, 0]  # for the records (widths change only here)
        for s, slot in enumerate(self.slots, start=1):
            for j, row in enumerate(rows):
                slot.assign(row, arr.drivers[s][j])
        declared = time_gaps if time_gaps is not None else [None] * len(rows)
        for j, (row, sc) in enumerate(zip(rows, chosen)):
            self.scenarios[row] = sc
            self.steps[row] = sc.steps
            self.set_speed[row] = sc.set_speed
            self.time_gap[row] = sc.time_gap
            self.declared[row] = declared[j]
            self.tau1[row] = judged_tau1(sc.time_gap or None, declared[j], self.config.scoring)
            self.n_lanes[row] = sc.road.n_lanes
        rows_a = np.array(rows)
        lead, has, gap, v0 = self._lead_state(rows_a)
        q = self._q(self.world.v[rows_a, 0], v0, gap, has, self.tau1[rows_a])
        self.neg_since[rows_a] = np.where(q < 0, 0.0, np.nan)
        self.last_change[rows_a] = 0.0
        self.lead_prev[rows_a] = lead
        self.done[rows_a] = False
        self.episode_return[rows_a] = 0.0
        need = int(self.steps[rows_a].max()) + 1
        have = self._rec_arr.shape[2]
        if need > have:
            self._set_record(np.concatenate([self._rec_arr, np.zeros((len(_RECORD), self.n, need - have))], axis=2))
        self._record(rows_a)
        if self.car is not None:
            self.car.reset(rows, rngs, chosen, self.world.a[rows, 0])

    def draw(self, rng: np.random.Generator):
        """The next scenario of a scene whose generator is ``rng`` (what :meth:`reset_rows`
        draws when it is not given one)."""
        return self.generator(rng)

    def prepare(self, scenario) -> None:
        """Do ahead of :meth:`reset_rows` the part of starting ``scenario`` that depends only
        on the scenario: its surrounding drivers' condensed cruise QPs (into the shared cache that
        :meth:`reset_rows` then reads)."""
        if isinstance(scenario, Scenario):
            for vehicle in scenario.vehicles:
                self.drivers.prepare(vehicle.driver)

    def _q(self, v1, v0, gap, has, tau1):
        """Q of scenes whose ego speeds, lead speeds, gaps, leads and tau1 are these arrays."""
        cfg = self.config.scoring
        gs = v1 * tau1 + v1 ** 2 / (2.0 * cfg.b1) - v0 ** 2 / (2.0 * cfg.b0)
        return np.where(has, gap - gs, np.inf)

    def _lead_state(self, rows: np.ndarray):
        """The egos' vehicles ahead of scenes ``rows`` (-1: none), whether there is one, the gaps
        [m] and their speeds [m/s] (0 without one)."""
        w = self.world
        lead = w.neighbours.lead[rows, 0]
        has = lead >= 0
        v_lead = np.where(has, w.v[rows, np.maximum(lead, 0)], 0.0)
        return lead, has, w.neighbours.gap[rows, 0], v_lead

    def _record(self, rows) -> None:
        """Write the current state of scenes ``rows`` into their episode records at their step."""
        w = self.world
        nb = w.neighbours
        K.record(np.asarray(rows, dtype=np.int64), w.k, w.t, (w.v, w.a, nb.lead, nb.gap, w.a_y, w.y),
                 self._scenes_record())

    # ------------------------------------------------------------------ observation
    def observe(self, low=None, high=None, dtype=np.float64) -> np.ndarray:
        """Observations ``(n, 7)`` or ``(n, 11)`` with V2V (see the environment docstring), and
        from version 1 the safety-margin features after them, clipped to ``[low, high]`` when
        given (the observation space's bounds), as ``dtype``."""
        m = 11 if self.config.v2v else 7
        extra = self._feature_bounds[0].shape[0]
        low = np.full(m + extra, -np.inf) if low is None else np.asarray(low, dtype=float)
        high = np.full(m + extra, np.inf) if high is None else np.asarray(high, dtype=float)
        out = np.empty((self.n, m), dtype=dtype if not (extra or self.car) else float)
        K.observe(self.world.observation_array(0), self.set_speed, self.time_gap, float(self.config.sensor_range),
                  bool(self.config.v2v), low[:m], high[:m], out)
        if self.car is not None:
            self.car.start_pending(self.world, out)
            self.car.apply(out, low, high)
            if not extra:
                return out.astype(dtype, copy=False)
        return self._with_features(out, dtype) if extra else out

    def _link_after_step(self) -> None:
        """The car's V2V link after the world's step (its radar stepped in the step kernel);
        :attr:`last_obs` with the link's fields (and the ``-v1`` features computed from them)."""
        obs = self.last_obs
        m0 = 11 if self.config.v2v else 7
        if obs is not None:
            low, high = self.obs_bounds
            fields = obs[:, :m0].astype(float)
        else:
            fields = true_fields(self, np.full(m0, -np.inf), np.full(m0, np.inf))
        self.car.receive(fields)
        if obs is None:
            return
        self.car.apply(fields, low, high)
        self.last_obs = self._with_features(fields, np.float32) if obs.shape[1] > m0 else fields.astype(np.float32)

    def _with_features(self, obs0: np.ndarray, dtype) -> np.ndarray:
        """Version 1: the v0 observation ``obs0`` ``(n, m)`` with the safety-margin features
        appended (:func:`acc_gym.envs.observation.append_features`; clipped to their bounds).

        The features are computed from the fields as emitted (rounded to ``dtype``, float32 in
        the envs), so they are exactly what :func:`~acc_gym.envs.observation.margin_features`
        computes from the emitted ``-v0`` fields: a ``-v1`` policy given a ``-v0`` observation
        acts exactly as on the ``-v1`` one (:class:`acc_gym_agents.rl.policy.SB3Policy`)."""
        low, high = self._feature_bounds
        if dtype is np.float32 and obs0.dtype == np.float64:  # the envs' case, in one compiled call
            out32 = np.empty((obs0.shape[0], obs0.shape[1] + low.shape[0]), dtype=np.float32)
            K.features32(obs0, float(self.config.sensor_range), B0, B1, low, high, out32)
            return out32
        out = np.empty((obs0.shape[0], obs0.shape[1] + low.shape[0]))
        fields = np.ascontiguousarray(obs0.astype(dtype, copy=False), dtype=float)
        append_features(fields, float(self.config.sensor_range), B0, B1, low, high, out)
        return out.astype(dtype, copy=False)

    # ------------------------------------------------------------------ step
    def step(self, a_des: np.ndarray, active: np.ndarray | None = None):
        """Advance every scene by one step with the egos' commanded accelerations ``a_des``
        [m/s^2] ``(n,)``.

        Returns ``(reward, terminated, truncated, final)``: arrays over the scenes, the core's
        own (the next step overwrites them: copy to keep), and the final info of each episode
        that ended this step, by scene (those scenes are now done). Scenes not ``active``
        (default: those not done) are stepped, but their results are meaningless (a vector
        env's scenes about to be reset). :meth:`info` and :meth:`info_row` give the step's info;
        with :attr:`obs_bounds` set, :attr:`last_obs` holds the observations after the step.

        Every driver decides from one snapshot (:meth:`SingleLaneWorld.decide
        <acc_gym.simulation.single_lane.SingleLaneWorld.decide>`, compiled where the drivers
        are), then one compiled call moves the world, judges the step and, with a built-in
        reward, ends it (:func:`acc_gym.envs._kernel.step`); a reward that is not built in is
        called on the step's criteria and a second call ends the step
        (:func:`~acc_gym.envs._kernel.finish`). Both read the core as one record
        (:meth:`_kernel_core`). The world's state alternates between two sets of arrays
        (:meth:`SingleLaneWorld.reused_buffers
        <acc_gym.simulation.single_lane.SingleLaneWorld.reused_buffers>`): a state array read
        from :attr:`world` keeps its values until the step after next. With a car in the config
        (:class:`~acc_gym.envs.car.Car`, read by the kernels as part of the core's record) the
        kernel passes the command through its actuators before the move and the observation
        through its radar at the step's end; a V2V link steps after the kernel.
        """
        car = self.car
        if car is not None:
            car.before_step(self)
        core, plan = self._kernel_core()
        w = self.world
        a_all = w.decide(a_des)
        x, v, a = w.x, w.v, w.a
        buf = w.reused_buffers()
        obs, obs32 = plan.fresh_observations(self.n)
        idle = self.done if active is None else ~np.asarray(active, dtype=bool)  # the scenes not stepped
        n_rows, n_ended = K.step(a_all, x, v, a, buf.F, buf.I, buf.obs, obs, obs32, idle, core)
        w.adopt_buffers(buf)  # the world has moved (whatever the reward below does)
        self._python_terms = None
        if n_rows < 0:  # a reward that is not built in, on the step's criteria; then the step's end
            self._python_terms = self._python_reward(plan)
            n_rows, n_ended = K.finish(idle, buf.F, buf.I, buf.obs, obs, obs32, core)
        self.last_obs = obs32 if plan.m0 is not None else None
        if car is not None and car.link is not None:
            self._link_after_step()
        return plan.reward, plan.terminated, plan.truncated, self._ended(plan.ended[:n_ended]) if n_ended else {}

    def _python_reward(self, plan: "_StepPlan") -> dict:
        """A reward that is not built in, on the step's criteria: its reward into the step's
        reward array; returns its terms."""
        ind = StepIndicators.from_rows(plan.fl.copy(), plan.bo.copy(), self.set_speed, self.tau1, plan.a_comfort,
                                       steps_left=self.steps - self.world.k)
        reward, terms = self.reward_fn(ind)
        plan.reward[:] = np.broadcast_to(np.asarray(reward, dtype=float), (self.n,))
        return terms

    # the floats of a step's info: its key and criteria row
    _INFO_ROWS = (("t", K.F_T), ("q", K.F_Q), ("g", K.F_Q), ("gap_safe", K.F_GS), ("a_applied", K.F_A))

    def info(self, active: np.ndarray | None = None) -> dict:
        """The last step's info over the scenes, as fresh arrays: the time ``t`` [s], ``q`` and
        ``g`` (Q [m]), ``gap_safe`` [m], ``a_applied`` [m/s^2], ``violation``, the surrounding
        drivers' ``modes`` ``(n, 2)``, their solver ``fallbacks`` this episode and the reward's
        terms under ``rewards`` (0 for the scenes not ``active``, when given)."""
        plan = self._step_plan()
        info = {key: plan.fl[row].copy() for key, row in self._INFO_ROWS}
        terms = self._python_terms
        if terms is None:  # a built-in reward's terms: one array, masked in one call
            rewards = dict(zip(plan.names, plan.terms.copy() if active is None else np.where(active, plan.terms, 0.0)))
        else:
            rewards = terms if active is None else {k: np.where(active, v, 0.0) for k, v in terms.items()}
        info.update(violation=plan.bo[K.B_VIOLATION].copy(), modes=self.modes(), fallbacks=self.fallbacks(),
                    rewards=rewards)
        return info

    def info_row(self, row: int) -> dict:
        """:meth:`info` of scene ``row``, as Python numbers (the single environment's; the same
        keys and values)."""
        plan = self._plan if self._plan is not None else self._step_plan()
        fl, terms_col = plan.columns[row]
        f = fl.tolist()  # one conversion for every float of the step
        q = f[_F_Q]
        n = self.n
        mode = self.drivers.info.get("mode")  # rows: each slot's scenes in turn
        if mode is None:
            modes = np.full(SLOTS - 1, -1, np.int64)
        else:
            modes = mode.copy() if n == 1 else mode[row::n].copy()
        fb = self.drivers.fallbacks
        terms = self._python_terms
        return {"t": f[_F_T], "q": q, "g": q, "gap_safe": f[_F_GS], "a_applied": f[_F_A],
                "violation": bool(plan.bo[K.B_VIOLATION, row]), "modes": modes,
                "fallbacks": int(fb[row]) + int(fb[row + n]),  # the POV's and the POV2's
                "rewards": (dict(zip(plan.names, terms_col.tolist())) if terms is None
                            else {k: float(np.asarray(v).reshape(-1)[row]) for k, v in terms.items()})}

    def _ended(self, ended: np.ndarray) -> dict:
        """The final info of each scene in ``ended`` (their episodes ended this step, now marked done)."""
        if not ended.shape[0]:
            return {}
        self.done[ended] = True
        return {int(r): self._final(int(r)) for r in ended}

    def _scenes_record(self):
        """The episodes' arrays as one :data:`~acc_gym.envs._kernel.SCENES` record (made again
        when the episode records grow)."""
        if self._scenes is None:
            grace = self._grace if self._grace is not None else self.tau1  # the configured one, or each scene's tau1
            self._scenes = K.record_of(K.SCENE_FIELDS, dict(
                set_speed=self.set_speed, tau1=self.tau1, grace=grace, lead_prev=self.lead_prev,
                last_change=self.last_change, neg_since=self.neg_since, steps=self.steps,
                episode_return=self.episode_return, ego_width=self._ego_width, lane_width=self.lane_width,
                n_lanes=self.n_lanes, time_gap=self.time_gap, rec=self._rec_arr))
        return self._scenes

    def _kernel_core(self) -> tuple:
        """The kernels' :data:`~acc_gym.envs._kernel.CORE` record (the world's, the scenes', the
        plan's and the outputs' records) and the step's plan, made again when one of them is."""
        plan = self._step_plan()
        world = self.world.kernel_record()
        core = self._core
        if core is None or core[0] is not world or core[1] is not plan:
            car = self.car.kernel_record() if self.car is not None else _no_car()
            core = self._core = (world, plan, K.make_core(world, self._scenes_record(), plan.record, plan.out, car))
        return core[2], plan

    def _step_plan(self) -> "_StepPlan":
        """What a step needs that changes only with :attr:`reward_fn` and :attr:`obs_bounds`
        (made again when either is replaced): the built-in reward's code, term names and
        weights (:meth:`CriteriaReward.compiled_terms
        <acc_gym.envs.reward.CriteriaReward.compiled_terms>`; none for another reward), the
        observation's bounds, and the step's output arrays."""
        plan = self._plan
        if plan is not None and plan.reward_fn is self.reward_fn and plan.obs_bounds is self.obs_bounds:
            return plan
        compiled = getattr(self.reward_fn, "compiled_terms", None)
        compiled = compiled() if compiled is not None else None
        code, weights, names = compiled if compiled is not None else (K.REWARD_NONE, self._cfg, K.TERMS)
        f_low, f_high = self._feature_bounds  # the safety-margin features' (empty for version 0)
        if self.obs_bounds is not None:
            low, high = self.obs_bounds
            m0 = low.shape[0] - f_low.shape[0]  # the v0 fields, which the kernel writes
            low, high = np.ascontiguousarray(low[:m0], dtype=float), np.ascontiguousarray(high[:m0], dtype=float)
        else:
            m0, low, high = None, np.zeros(1), np.zeros(1)
        n = self.n
        fl, terms = np.zeros((K.N_FLOAT + 1, n)), np.zeros((len(names), n))
        plan = self._plan = _StepPlan(
            reward_fn=self.reward_fn, obs_bounds=self.obs_bounds, code=code, names=tuple(names), m0=m0,
            extra=f_low.shape[0], a_comfort=float(self.config.scoring.a_x_comfort),
            fl=fl, bo=np.zeros((K.N_BOOL, n), dtype=bool), terms=terms,
            columns=tuple((fl[:, r], terms[:, r]) for r in range(n)),
            reward=np.zeros(n), terminated=np.zeros(n, dtype=bool), truncated=np.zeros(n, dtype=bool),
            rows=np.empty(n, dtype=np.int64), ended=np.empty(n, dtype=np.int64),
            fields=np.empty((n, m0 if m0 is not None else 0)))
        object.__setattr__(plan, "record", K.record_of(K.PLAN_FIELDS, dict(
            cfg=self._cfg, code=code, a_comfort=plan.a_comfort, weights=np.ascontiguousarray(weights, dtype=float),
            terminate=bool(self.config.terminate_on_violation), obs_range=float(self.config.sensor_range),
            v2v=bool(self.config.v2v), low=low, high=high, f_low=f_low, f_high=f_high)))
        object.__setattr__(plan, "out", K.record_of(K.OUT_FIELDS, {f: getattr(plan, f) for f, _ in K.OUT_FIELDS}))
        return plan

    def modes(self) -> np.ndarray:
        """The surrounding drivers' modes after the last step, ``(n, 2)`` (POV, POV2; -1: none)."""
        mode = self.drivers.info.get("mode")  # (slots x scenes): each slot's rows in turn
        if mode is None:
            return np.full((self.n, SLOTS - 1), -1, np.int64)
        return mode.reshape(SLOTS - 1, self.n).T.copy()

    def fallbacks(self) -> np.ndarray:
        """Each scene's solver fallbacks of its two surrounding drivers this episode, ``(n,)``."""
        fb = self.drivers.fallbacks  # (slots x scenes): each slot's rows in turn
        return fb[:self.n] + fb[self.n:]

    def _final(self, row: int) -> dict:
        # the record scored where it is (score_record: as score_episode of self.trace(row))
        sc = self.scenarios[row]
        report = score_record(self._rec_arr[:, row], int(self.world.k[row]) + 1, sc.set_speed, sc.time_gap,
                              self.declared[row], self.config.scoring)
        return {"score": report.score, "qualified": report.qualified, "report": report.to_dict(),
                "scenario": sc.id, "scenario_seed": sc.seed, "episode_return": float(self.episode_return[row])}

    def frame(self, row: int, **kw) -> np.ndarray:
        """A top-view RGB frame of scene ``row`` with its HUD (:func:`acc_gym.rendering.frame_from_batch`)."""
        from acc_gym.rendering import frame_from_batch

        return frame_from_batch(self, row, **kw)

    def trace(self, row: int) -> EgoTrace:
        """The current episode of scene ``row`` so far, as an :class:`EgoTrace`."""
        k = int(self.world.k[row])
        sc = self.scenarios[row]
        return EgoTrace(**{key: self._rec[key][row, :k + 1].copy() for key in _RECORD}, set_speed=sc.set_speed,
                        time_gap=sc.time_gap, declared_time_gap=self.declared[row])


@cache
def _no_car():
    """The :data:`~acc_gym.envs._kernel.CAR` record of a core without a car (one, shared)."""
    return K.record_of(K.CAR_FIELDS, K.no_car())


@dataclass(frozen=True, eq=False)
class _StepPlan:
    """What :meth:`EpisodeBatch.step` needs of a reward and an observation's bounds, and the
    step's output arrays (the core's own): made by :meth:`EpisodeBatch._step_plan`."""

    reward_fn: object  # the reward and bounds it was made for
    obs_bounds: object
    code: int  # the built-in reward's code (acc_gym.envs._kernel.REWARD_*)
    names: tuple  # its terms, the rows of ``terms``
    m0: int | None  # the observation's v0 fields (None: no observation made)
    extra: int  # its safety-margin features (0 for version 0)
    a_comfort: float  # [m/s^2]
    fl: np.ndarray  # the outputs: the kernels' OUT_FIELDS
    bo: np.ndarray
    terms: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    rows: np.ndarray
    ended: np.ndarray
    fields: np.ndarray  # (n, m0) float64: version 1's v0 fields before the features (read within the step)
    columns: tuple  # each scene's column of fl and of terms (views, for info_row)

    def fresh_observations(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """A step's observation arrays: the v0 fields as the kernel writes them and the emitted
        float32 observation, new every step (handed out). Version 0 emits the fields themselves;
        version 1 the fields (written into the plan's own float64 array) with the features."""
        if self.m0 is None:
            empty = np.empty((0, 1), dtype=np.float32)
            return empty, empty
        if not self.extra:
            obs = np.empty((n, self.m0), dtype=np.float32)
            return obs, obs
        return self.fields, np.empty((n, self.m0 + self.extra), dtype=np.float32)
