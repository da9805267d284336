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
between the controller and the world: its command passes the actuators before the step and
the observation's radar and V2V fields pass the radar and the link after it (the ``-v1``
features are computed from what they report). The world, the criteria, the reward and the
score see the true state.
"""

from __future__ import annotations

import numpy as np

from acc_gym._validation import check_finite
from acc_gym.drivers.slots import SlotDrivers, SlotView
from acc_gym.envs import _kernel as K
from acc_gym.envs.car import Car, true_fields
from acc_gym.envs.config import EnvConfig
from acc_gym.envs.observation import B0, B1, append_features, feature_bounds
from acc_gym.envs.reward import CriteriaReward, MarginReward, StepIndicators
from acc_gym.evaluation.scoring import judged_tau1, score_record
from acc_gym.evaluation.trace import EgoTrace
from acc_gym.scenarios.spec import Scenario
from acc_gym.scenarios.world import ABSENT_X, scene_arrays
from acc_gym.simulation.single_lane import SingleLaneWorld

SLOTS = 3
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
        self._no_bounds = np.zeros(1)
        self._plan = None  # (reward_fn, obs_bounds, what step() needs of them): _step_plan()
        self._scratch_buf = None  # step(arrays=False)'s arrays: _scratch()
        self._prepared = None  # the single env's step's argument list, reused until a reset: _step_prepared()
        self._rows_buf = np.empty((2, self.n), dtype=np.int64)  # finish()'s rows recorded and rows ended
        self.car = Car.of(config, self.n, DT)  # the ego's radar, actuators and V2V link (None: none modelled)
        self._cfg = np.array([cfg.b0, cfg.b1, cfg.band_width, cfg.steady_dv, cfg.moving_speed, cfg.transient,
                              cfg.sensor_range, cfg.response_decel, cfg.stop_speed, cfg.lead_margin], dtype=float)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_prepared"] = None  # made again after unpickling (pickle copies views: the list's would be stale)
        return state

    def _set_record(self, arr: np.ndarray) -> None:
        self._rec_arr = arr  # (columns, scenes, steps)

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
        self._prepared = None  # step()'s argument list is made again for the new episodes
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
        self._ego_width = np.ascontiguousarray(self.world.width[:, 0])  # for _record (widths change only here)
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
        K.record(np.asarray(rows, dtype=np.int64), w.k, w.t, w.v, w.a, nb.lead, nb.gap, w.a_y, w.y,
                 self._ego_width, self.lane_width, self.n_lanes, self._rec_arr)

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

    def _car_after_step(self) -> None:
        """The car's radar and link after the world's step; :attr:`last_obs` with their fields (and
        the ``-v1`` features computed from them)."""
        obs = self.last_obs
        m0 = 11 if self.config.v2v else 7
        if obs is not None:
            low, high = self.obs_bounds
            fields = obs[:, :m0].astype(float)
        else:
            low = high = None
            fields = true_fields(self, np.full(m0, -np.inf), np.full(m0, np.inf))
        self.car.sense(self.world, fields)
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
    def step(self, a_des: np.ndarray, active: np.ndarray | None = None, arrays: bool = True):
        """Advance every scene by one step with the egos' commanded accelerations ``a_des``
        [m/s^2] (:meth:`advance`), through their car when the config models one (module
        docstring)."""
        car = self.car
        if car is None:
            return self.advance(a_des, active, arrays)
        if car.pending:
            m0 = 11 if self.config.v2v else 7
            car.start_pending(self.world, true_fields(self, np.full(m0, -np.inf), np.full(m0, np.inf)))
        if car.actuators is not None:
            if not np.isfinite(a_des).all():
                check_finite("ego_a_des", a_des)  # raises, naming it, before it enters the actuators' history
            a_des = car.command(a_des, self.world.a[:, 0])
        out = self.advance(a_des, active, arrays)
        self._car_after_step()
        return out

    def advance(self, a_des: np.ndarray, active: np.ndarray | None = None, arrays: bool = True):
        """Advance every scene by one step with desired ego accelerations ``a_des`` [m/s^2].

        Returns ``(reward, terminated, truncated, info)`` as arrays over the scenes;
        ``info`` holds per-step arrays and, under ``"final"``, a dict row -> final info for
        the episodes that ended. Scenes not ``active`` are stepped but their results are
        meaningless (a vector env's scenes that are about to be reset). With
        :attr:`obs_bounds` set, :attr:`last_obs` holds the observations after the step.
        With ``arrays=False`` (the single env, which reads :attr:`last_rows` and the drivers
        itself) ``info`` holds only ``"final"`` and, for a reward that is not built in,
        ``"rewards"``: the per-step arrays are not assembled, and with a built-in reward the
        returned ``reward``, ``terminated``, ``truncated`` and :attr:`last_rows` are the core's
        own arrays, which the next such step overwrites (read them before; :attr:`last_obs` is
        always fresh, and so is everything a caller's ``reward_fn`` is given).

        The drivers decide in :meth:`SingleLaneWorld.decide
        <acc_gym.simulation.single_lane.SingleLaneWorld.decide>`; everything after them (the
        world's move, the criteria, a built-in reward, the end of the step, the record and
        the observations) is one compiled call, :func:`acc_gym.envs._kernel.step_finish`
        (with the caller's reward, computed between them: :func:`acc_gym.envs._kernel.step`
        and :func:`~acc_gym.envs._kernel.finish`). When the surrounding drivers decide in one
        compiled call themselves (baseline models without a reaction delay, profiles, absent
        vehicles: :meth:`SlotDrivers.compiled_laws
        <acc_gym.drivers.slots.SlotDrivers.compiled_laws>`) and the reward is built in, their
        decision joins that call too (:func:`acc_gym.envs._kernel.laws_step_finish`; ``a_des``
        a float64 array ``(n,)``), and the world's state then moves between two sets of arrays
        in turn (:meth:`SingleLaneWorld.reused_buffers
        <acc_gym.simulation.single_lane.SingleLaneWorld.reused_buffers>`): a state array read
        from :attr:`world` keeps its values until the step after next (copy it to keep it).
        The single env's steps (``arrays=False``) after the first of an episode on that path
        reuse its argument list with the entries that change every step replaced
        (:meth:`_step_prepared`; made again after every :meth:`reset_rows`).
        These are the same kernels, in the same order, that
        :meth:`SingleLaneWorld.decide`, :meth:`SingleLaneWorld.move` and the separate
        criteria, reward, settle, record and observe calls run
        (``tests/envs/test_env_fast_paths.py`` checks the two agree).
        """
        w = self.world
        n = self.n
        step_plan = self._step_plan()
        prepared = self._prepared
        if (prepared is not None and prepared[0] is step_plan and not arrays and active is None
                and prepared[-1] == self.drivers.assignments  # no driver given since (a reset, or by hand)
                and type(a_des) is np.ndarray and a_des.dtype == np.float64 and a_des.shape == (n,)):
            return self._step_prepared(a_des, prepared)
        (code, names, weights, a_comfort, grace, low, high, m0, extra, f_low, f_high, obs_range, v2v,
         terminate) = step_plan
        laws = None
        if code != K.REWARD_NONE and type(a_des) is np.ndarray and a_des.dtype == np.float64 and a_des.shape == (n,):
            joint = getattr(w, "joint", None)
            laws = joint.compiled_laws() if joint is not None else None  # the drivers' decision joins the step
        if laws is None:
            a_all = w.decide(a_des)
            F, I, obs_all = w.move_buffers()
        else:  # nobody but this step reads the state's arrays: two sets reused in turn
            buf = w.reused_buffers()
            F, I, obs_all = buf.F, buf.I, buf.obs
            obs_all.setflags(write=True)
        if arrays or code == K.REWARD_NONE:  # arrays handed out (in info, or to the caller's reward): fresh ones
            fl = np.empty((K.N_FLOAT + 1, n))  # criteria rows, then the time (K.F_T)
            bo = np.empty((K.N_BOOL, n), dtype=bool)
            terms_arr = np.empty((len(names), n))
            reward = np.empty(n)
            terminated, truncated = np.empty((2, n), dtype=bool)
        else:  # the single env with a built-in reward reads them before the next step (last_rows): the core's own
            fl, bo, terms_arr, reward, terminated, truncated = self._scratch(len(names))
        rows, ended = self._rows_buf
        own_active = active is None  # which scenes step: the not-done ones (the single env's case)
        if own_active:
            active = ~self.done
        if m0 is not None:  # obs_bounds set: the observations after the step, fresh (handed out)
            obs = np.empty((n, m0), dtype=float if extra else np.float32)
            obs32 = np.empty((n, m0 + extra), dtype=np.float32) if extra else obs  # version 1: the emitted one
        else:
            obs = obs32 = np.empty((0, 1), dtype=np.float32)
        lat = w.lateral
        terms = None  # made below only for the arrays' info (the single env reads terms_arr)
        if code != K.REWARD_NONE:  # a built-in reward: the whole step in one compiled call
            # step_finish's arguments after the drivers' accelerations (laws_step_finish's after the laws)
            world_and_scenes = (
                w.present, w.x, w.v, w.a, w._vp, w.dt, w.k, lat.y0, lat.y1, lat.t_start, lat.duration, w.lengths,
                w.width, float(w.road.lane_width), w.collided, w.sensor_range, F, I, obs_all, self.set_speed,
                self.tau1, grace, self._cfg, self.lead_prev, self.last_change, self.neg_since, fl, bo, code, a_comfort,
                weights, terms_arr, reward, self.steps, active, terminate, self.episode_return, terminated, truncated,
                rows, ended, self._ego_width, self.lane_width, self.n_lanes, self._rec_arr, self.time_gap, obs_range,
                v2v, low, high, obs, f_low, f_high, obs32)
            if laws is not None:  # drivers of one compiled call too: they decide inside it
                w.observation_array(0)  # every slot's observations of the state, (S, 8, B), made if not yet
                args = [a_des, w._obs, *laws, *world_and_scenes]
                n_ended = self._laws_call(args, buf)
                if (not arrays and own_active and m0 is not None and args[self._L_EGO] is a_des
                        and args[self._L_F] is F and args[self._L_OBS_ALL] is obs_all and args[self._L_ACTIVE] is active
                        and args[self._L_OBS] is obs and args[self._L_OBS32] is obs32):  # (the positions below hold)
                    # the single env's next steps until a reset: these arguments with the per-step ones replaced
                    self._prepared = (step_plan, args, (fl, bo, terms_arr), names, reward, terminated, truncated,
                                      ended, (n, m0), np.float32 if not extra else float, (n, m0 + extra),
                                      self.drivers.assignments)
            else:
                n_rows, n_ended = K.step_finish(a_all, *world_and_scenes)
                w.adopt(F, I, obs_all)
        else:  # the caller's reward, from the criteria rows, between the two halves
            K.step(a_all, w.present, w.x, w.v, w.a, w._vp, w.dt, w.k, lat.y0, lat.y1, lat.t_start, lat.duration,
                   w.lengths, w.width, float(w.road.lane_width), w.collided, w.sensor_range, F, I, obs_all,
                   self.set_speed, self.tau1, grace, self._cfg, self.lead_prev, self.last_change, self.neg_since,
                   fl, bo, code, a_comfort, self._cfg, terms_arr, reward, self.steps)
            w.adopt(F, I, obs_all)
            ind = StepIndicators.from_rows(fl, bo, self.set_speed, self.tau1, a_comfort,
                                           steps_left=self.steps - w.k)
            reward, terms = self.reward_fn(ind)
            reward = np.asarray(reward, dtype=float)
            if reward.shape != (n,):
                reward = np.broadcast_to(reward, (n,)).copy()
            terms_arr = None
            names = tuple(terms)
            n_rows, n_ended = K.finish(active, reward, bo, w.k, self.steps, terminate, self.episode_return,
                                       terminated, truncated, rows, ended, fl, F, I, self._ego_width, self.lane_width,
                                       self.n_lanes, self._rec_arr, obs_all, self.set_speed, self.time_gap, obs_range,
                                       v2v, low, high, obs, f_low, f_high, obs32)
        self.last_obs = obs32 if obs32.shape[0] else None
        # the step's criteria rows and, for the built-in rewards, their terms as one array (rows: names)
        self.last_rows = (fl, bo, terms_arr)
        self.last_term_names = names
        if not arrays:
            return reward, terminated, truncated, self._ended_info({} if terms_arr is not None else {"rewards": terms},
                                                                   ended, n_ended)
        if terms is None:
            terms = dict(zip(names, terms_arr))
        q = fl[K.F_Q]
        info = {"t": fl[K.F_T], "q": q, "g": q, "gap_safe": fl[K.F_GS], "a_applied": fl[K.F_A],
                "violation": bo[K.B_VIOLATION], "modes": self.modes(), "fallbacks": self.fallbacks(), "rewards": terms}
        return reward, terminated, truncated, self._ended_info(info, ended, n_ended)

    def _ended_info(self, info: dict, ended: np.ndarray, n_ended: int) -> dict:
        """``info`` with ``"final"``: the final info of each of the first ``n_ended`` scenes in
        ``ended`` (their episodes ended this step, now marked done)."""
        if n_ended:
            ended = ended[:n_ended]
            info["final"] = {int(r): self._final(int(r)) for r in ended}
            self.done[ended] = True
        else:
            info["final"] = {}
        return info

    # positions in laws_step_finish's arguments (step()'s list) of those that change every step
    _L_EGO, _L_OBS_NOW, _L_X, _L_V, _L_A, _L_F, _L_I, _L_OBS_ALL, _L_ACTIVE, _L_OBS, _L_OBS32 = (
        0, 1, 10, 11, 12, 25, 26, 27, 43, 59, 62)

    def _laws_call(self, args: list, buf) -> int:
        """:func:`acc_gym.envs._kernel.laws_step_finish` on ``args``, then the world takes the
        state it wrote into ``buf``; a non-finite ego command raises before anything moves,
        naming it as :meth:`SingleLaneWorld.decide` does. Returns how many episodes ended."""
        n_rows, n_ended = K.laws_step_finish(*args)
        if n_rows < 0:
            buf.obs.setflags(write=False)
            check_finite("ego_a_des", args[self._L_EGO])  # raises, naming the value (nothing moved)
        self.world.adopt_buffers(buf)
        return n_ended

    def _step_prepared(self, a_des: np.ndarray, prepared: tuple):
        """:meth:`step` of the single env (``arrays=False``) once a step of this episode has
        taken the drivers-inside path (:func:`acc_gym.envs._kernel.laws_step_finish`): its
        argument list again, with the entries that change every step replaced (the ego's
        command, the current state's observations and arrays, the buffers it moves into, which
        scenes are active, the fresh observation arrays) -- the same call, without the
        per-step assembly. Made again after every :meth:`reset_rows`, change of the plan and
        driver given to a slot (:attr:`SlotDrivers.assignments <acc_gym.drivers.slots.SlotDrivers.assignments>`)."""
        (_, args, rows3, names, reward, terminated, truncated, ended, obs_shape, obs_dtype, obs32_shape, _) = prepared
        w = self.world
        buf = w.reused_buffers()
        obs_all = buf.obs
        obs_all.setflags(write=True)
        w.observation_array(0)
        obs = np.empty(obs_shape, dtype=obs_dtype)
        obs32 = np.empty(obs32_shape, dtype=np.float32) if obs_dtype is float else obs
        args[self._L_EGO] = a_des
        args[self._L_OBS_NOW] = w._obs
        args[self._L_X], args[self._L_V], args[self._L_A] = w.x, w.v, w.a
        args[self._L_F], args[self._L_I], args[self._L_OBS_ALL] = buf.F, buf.I, obs_all
        args[self._L_ACTIVE] = ~self.done
        args[self._L_OBS], args[self._L_OBS32] = obs, obs32
        n_ended = self._laws_call(args, buf)
        self.last_obs = obs32
        self.last_rows = rows3
        self.last_term_names = names
        return reward, terminated, truncated, self._ended_info({}, ended, n_ended)

    def _step_plan(self) -> tuple:
        """What a step needs that changes only with :attr:`reward_fn` and :attr:`obs_bounds`
        (made again when either is replaced): the built-in reward's code, term names and
        weights, the comfort bound, the proper-response grace per scene, the observation's
        bounds (the v0 fields' part; ``m0`` None without bounds) and the features'."""
        plan = self._plan
        if plan is not None and plan[0] is self.reward_fn and plan[1] is self.obs_bounds:
            return plan[2]
        kind = type(self.reward_fn)
        code = K.REWARD_CRITERIA if kind is CriteriaReward else K.REWARD_MARGIN if kind is MarginReward \
            else K.REWARD_NONE  # MarginReward: the -v1 ids' default
        cfg = self.config.scoring
        f_low, f_high = self._feature_bounds  # the safety-margin features' (empty for version 0)
        extra = f_low.shape[0]
        if self.obs_bounds is not None:
            low, high = self.obs_bounds
            m0 = low.shape[0] - extra  # the v0 fields, which the kernel writes
            low, high = low[:m0], high[:m0]
        else:
            m0, low, high = None, self._no_bounds, self._no_bounds
        # the proper-response grace per scene: the configured response time, or each scene's tau1 (the array
        # reset_rows writes in place)
        grace = self._grace if self._grace is not None else self.tau1
        step = (code, K.MARGIN_TERMS if code == K.REWARD_MARGIN else K.TERMS,
                self.reward_fn._w if code != K.REWARD_NONE else self._cfg, float(cfg.a_x_comfort), grace, low, high,
                m0, extra, f_low, f_high, float(self.config.sensor_range), bool(self.config.v2v),
                bool(self.config.terminate_on_violation))
        self._plan = (self.reward_fn, self.obs_bounds, step)
        return step

    def _scratch(self, n_terms: int) -> tuple:
        """The core's own per-step arrays for ``arrays=False`` (criteria rows, flags, reward terms,
        reward, terminated, truncated): overwritten by every such step."""
        buf = self._scratch_buf
        if buf is None or buf[2].shape[0] != n_terms:
            n = self.n
            buf = self._scratch_buf = (np.empty((K.N_FLOAT + 1, n)), np.empty((K.N_BOOL, n), dtype=bool),
                                       np.empty((n_terms, n)), np.empty(n), np.empty(n, dtype=bool),
                                       np.empty(n, dtype=bool))
        return buf

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
