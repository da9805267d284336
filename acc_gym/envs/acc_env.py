"""The ACC test environment (one scene); the vector version is :mod:`acc_gym.envs.vector`."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import gymnasium as gym
from gymnasium import spaces

from acc_gym.envs import _kernel as _K
from acc_gym.envs.config import CounterScenarioSampler, EnvConfig, make_sampler, mixture
from acc_gym.envs.core import EpisodeBatch
from acc_gym.envs.observation import feature_bounds
from acc_gym.envs.reward import CriteriaReward, MarginReward
from acc_gym.evaluation.scoring import score_episode
from acc_gym.scenarios.registry import build
from acc_gym.scenarios.spec import Scenario

OBS_NAMES = ("v", "a", "gap", "v_rel", "lead_in_range", "set_speed", "time_gap")
OBS_NAMES_V2V = ("a_lead", "gap2", "v_rel2", "lead2_in_range")
V_MAX = 70.0  # [m/s] observation bound for speeds
A_BOUND = 15.0  # [m/s^2] observation bound for accelerations
TIME_GAP_MAX = 10.0  # [s]


def observation_space(config: EnvConfig) -> spaces.Box:
    r = config.sensor_range
    low = [0.0, -A_BOUND, 0.0, -V_MAX, 0.0, 0.0, 0.0]
    high = [V_MAX, A_BOUND, r, V_MAX, 1.0, V_MAX, TIME_GAP_MAX]
    if config.v2v:
        low += [-A_BOUND, 0.0, -V_MAX, 0.0]
        high += [A_BOUND, r, V_MAX, 1.0]
    if config.version >= 1:  # the safety-margin features (acc_gym.envs.observation)
        f_low, f_high = feature_bounds(config.v2v)
        low += f_low.tolist()
        high += f_high.tolist()
    return spaces.Box(np.array(low, dtype=np.float32), np.array(high, dtype=np.float32), dtype=np.float32)


def default_reward(config: EnvConfig):
    """The reward an env uses without ``reward_fn``: :class:`CriteriaReward` for version 0,
    :class:`MarginReward` from version 1."""
    return _default_reward_type(config)()


def _default_reward_type(config: EnvConfig) -> type:
    return MarginReward if config.version >= 1 else CriteriaReward


def make_reward(reward_fn, config: EnvConfig):
    """The reward an env's ``reward_fn=`` asks for: None is :func:`default_reward`; a mapping
    is the version's default reward with these weights (``{"overspeed": 1.0}`` on a ``-v1``
    id is ``MarginReward(overspeed=1.0)``; a key it does not have is a ``ValueError`` naming
    it), so that a config file (rl-zoo3's ``env_kwargs``) can set them; anything else must be
    callable (``reward_fn(StepIndicators) -> (reward, terms)``)."""
    if reward_fn is None:
        return default_reward(config)
    if isinstance(reward_fn, Mapping):
        from acc_gym._validation import from_mapping

        kind = _default_reward_type(config)
        return from_mapping(kind, dict(reward_fn), f"{kind.__name__} (reward_fn)")
    if not callable(reward_fn):
        raise TypeError(f"reward_fn must be a callable, a mapping of the default reward's weights or None, "
                        f"got {type(reward_fn).__name__}")
    return reward_fn


def action_to_accel(action: np.ndarray, config: EnvConfig) -> np.ndarray:
    """Actions in [-1, 1] (clipped) to desired accelerations [m/s^2] with ``config``'s scaling
    (:func:`actions_to_accel`)."""
    return actions_to_accel(action, config.accel_max, config.decel_max)


def actions_to_accel(actions, accel_max: float, decel_max: float) -> np.ndarray:
    """Actions in [-1, 1] (clipped) to desired accelerations [m/s^2]: ``+1 -> accel_max``,
    ``-1 -> -decel_max`` (:func:`acc_gym.envs._kernel.accel_of_action` of each, compiled), as
    float64 of the actions' shape. The one mapping of every env id, the ring and the
    OpenSCENARIO runner."""
    a = np.asarray(actions, dtype=float)
    flat = np.ascontiguousarray(a.reshape(-1))
    out = np.empty(flat.shape[0])
    _K.action_to_accel(flat, float(accel_max), float(decel_max), out)
    return out.reshape(a.shape)


def build_named(generator, config: EnvConfig, scenario_id: str, seed: int) -> Scenario:
    """The scenario ``(scenario_id, seed)`` a reset names (``options={"scenario": id}``): as
    the env's own sampler builds it when that is the ``-v1`` ids'
    :class:`~acc_gym.envs.config.CounterScenarioSampler`, else by
    :func:`acc_gym.scenarios.build` (the ``-v0`` streams)."""
    if isinstance(generator, CounterScenarioSampler):
        return generator.build(scenario_id, seed)
    return build(scenario_id, seed=seed, drivers=config.drivers)


def check_time_gap(value, what: str = "options['time_gap']") -> float | None:
    """A controller's declared time gap [s] (a finite number > 0), or None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{what} (the controller's declared time gap) must be a finite number of seconds > 0, "
                         f"got {value!r}")
    return float(value)


def check_actions(actions, shape: tuple) -> np.ndarray:
    """``actions`` as a float array of ``shape``, or a ``ValueError`` naming what is wrong."""
    if type(actions) is np.ndarray and actions.shape == shape and actions.dtype.kind == "f":  # fast path
        a = actions.astype(float, copy=False)
        if np.isfinite(a).all():
            return a
    if actions is None:
        raise ValueError(f"action must be numeric with shape {shape}, got None")
    raw = np.asarray(actions)
    if raw.dtype.kind not in "fiu":  # no text ("0.5"), booleans or complex numbers passed as numbers
        raise ValueError(f"action must be numeric: real numbers (floats or integers) with shape {shape}, got {actions!r} "
                         f"({raw.dtype})")
    try:
        a = raw.astype(float)
    except (TypeError, ValueError):
        raise ValueError(f"action must be numeric with shape {shape}, got {actions!r}") from None
    if a.shape != shape and a.size == int(np.prod(shape)) and a.ndim <= len(shape):
        a = a.reshape(shape)
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {a.shape}")
    if np.any(np.isnan(a)):
        raise ValueError(f"action is NaN: {actions!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action must be finite, got {actions!r}")
    return a


def make_config(config, overrides: dict, default_scenarios=None) -> EnvConfig:
    """The config: ``config`` (an EnvConfig, a dict or None) with ``overrides``; an id's
    ``default_scenarios`` (ids or families, or a dict of them with their shares,
    :func:`~acc_gym.envs.config.mixture`) apply only when neither names the scenarios."""
    if config is None:
        if default_scenarios is None or "scenarios" in overrides:
            config = EnvConfig()
        elif isinstance(default_scenarios, dict):
            config = EnvConfig(**mixture(default_scenarios))
        else:
            config = EnvConfig(scenarios=default_scenarios)
    elif isinstance(config, dict):
        config = EnvConfig.from_dict(config)
    elif not isinstance(config, EnvConfig):
        raise TypeError(f"config must be an EnvConfig or a dict, got {type(config).__name__}")
    return config.replace(**overrides) if overrides else config


class ACCEnv(gym.Env):
    """Adaptive cruise control among human-like drivers, scored by paper 003's criteria.

    ## Description

    The agent is the longitudinal controller of the ego vehicle (the SV). Each episode is
    one scenario from :mod:`acc_gym.scenarios` -- paper 003's car-following test, paper
    004's single-lane configurations (cut-ins, cut-outs, lane changes, approaches),
    NCAP-style rear tests, stop-and-go -- with up to two vehicles ahead driven by
    human-like MPC drivers (paper 001), scripted profiles or baseline models. The ego's
    physics is :mod:`acc_gym.vehicle` (traction, power and tyre limits, no reversing);
    one step is 0.2 s. At the end the episode gets the 100-point score of paper 003.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the desired acceleration, ``action * accel_max`` for
    ``action >= 0`` and ``action * decel_max`` below (defaults 3 and 8 m/s^2; 0 means
    no acceleration). Values outside [-1, 1] are clipped; NaN or a wrong shape raise
    ``ValueError``. The vehicle model then limits it; ``info["a_applied"]`` is what was
    applied [m/s^2].

    ## Observation Space

    ``Box(float32)`` of what an ACC measures (radar range ``sensor_range``, 200 m):

    | index | observation | unit | range |
    |---|---|---|---|
    | 0 | ego speed | m/s | [0, 70] |
    | 1 | ego acceleration over the last step | m/s^2 | [-15, 15] |
    | 2 | gap (bumper to bumper) to the vehicle ahead; ``sensor_range`` if none in range | m | [0, 200] |
    | 3 | relative speed, vehicle ahead minus ego; 0 if none | m/s | [-70, 70] |
    | 4 | 1 if a vehicle ahead is in range, else 0 | - | {0, 1} |
    | 5 | set speed | m/s | [0, 70] |
    | 6 | nominal time gap | s | [0, 10] |

    With ``v2v=True`` (CACC), also:

    | index | observation | unit | range |
    |---|---|---|---|
    | 7 | acceleration of the vehicle ahead (V2V); 0 if none | m/s^2 | [-15, 15] |
    | 8 | gap to the second vehicle ahead; ``sensor_range`` if none | m | [0, 200] |
    | 9 | its speed minus the ego's; 0 if none | m/s | [-70, 70] |
    | 10 | 1 if a second vehicle ahead is in range | - | {0, 1} |

    From version 1 (the ``-v1`` ids, ``EnvConfig.version = 1``) the safety-margin features
    follow (:mod:`acc_gym.envs.observation`; computed from the fields above, clipped):

    | index | observation | unit | range |
    |---|---|---|---|
    | 7 | Gapsafe / R (R: ``sensor_range``) | - | [-1, 2] |
    | 8 | Q / R, Q = gap - Gapsafe | - | [-2, 1] |
    | 9 | Q / max(Gapsafe, 1 m): 0 to 0.2 inside the score's band | - | [-1, 5] |
    | 10 | time headway gap / max(v, 0.1 m/s) | s | [0, 10] |
    | 11 | inverse time to collision, -v_rel / gap (> 0 closing) | 1/s | [-2, 2] |
    | 12 | required deceleration -v_rel^2 / (2 gap) while closing, else 0 | m/s^2 | [-20, 0] |

    (after the V2V fields with ``v2v=True``, followed by the same six for the second vehicle
    ahead: indices 11-16 for the first, 17-22 for the second). With nothing in range they
    are those of a vehicle at the range moving at the ego's speed.

    ## Rewards

    Per step, from the score's own criteria (:mod:`acc_gym.envs.reward`): +1 inside the
    car-following band on a car-following sample, +0.5 (1 - u_t) efficiency there, +1 for
    holding the set speed when there is nothing to follow, -0.1 (a / 3)^2 comfort, -0.02
    (jerk / 10)^2, -2 per proper-response safety violation, -100 for a collision, and up to
    -0.5 while lagging far behind a vehicle it could follow. Each
    term is in ``info["rewards"]``. Parking, hanging back or oscillating earn less than
    following well. Replace it with ``reward_fn=``.

    From version 1 the default is :class:`~acc_gym.envs.reward.MarginReward`: the band,
    a tent-shaped efficiency highest at the band's centre (not at the safety boundary), a
    graded proper-response term while Q < 0, speed keeping and a lag penalty without
    plateaus (a gradient for a parked ego and one far behind), and a collision that costs
    the rest of the scenario at the worst rate a step can cost. On paper 003's test and
    paper 004's traffic its returns rank acc, cacc, idm, a tailgater, a slow follower, a
    parked ego and full throttle as their points do (``tests/envs/test_margin_reward.py``).

    ## Starting State

    The scenario's initial speeds and gaps (drawn from its parameter laws with the
    environment's generator, or with ``scenario_generator="counter"`` by the counter-based
    generator keyed by the scenario's id and seed, see *Version History*;
    ``reset(options={"scenario": id_or_Scenario})`` forces one).
    ``reset(options={"time_gap": h})`` declares the controller's own time gap [s]: the
    episode (score, reward, violations) is judged at it, floored at 0.8 s and capped at the
    scenario's nominal gap (:func:`acc_gym.evaluation.scoring.judged_tau1`);
    :func:`acc_gym.evaluation.runner.run_episode` passes a controller's ``time_gap``.

    ## Episode End

    ### Termination
    The ego collides with the vehicle ahead (gap <= 0), or -- with
    ``terminate_on_violation=True`` -- violates the proper-response safety rule.

    ### Truncation
    The scenario's end (its duration, e.g. the lead's stop in paper 003's test).

    The last step's ``info`` has ``score`` (0-100), ``qualified`` (bool), ``report`` (the
    full episode report: items, R1, R2, u, j, extra metrics), ``episode_return`` and
    ``scenario_seed``. Every step's ``info`` has ``q`` and ``g`` (D1 - Gapsafe [m], inf with
    nothing ahead), ``gap_safe``, ``a_applied``, ``violation``, ``modes`` (the POV's and
    POV2's MPC modes, -1 without one), ``fallbacks`` (solver fallbacks of the surrounding
    drivers this episode), ``rewards``, ``scenario`` and ``t``.

    ### Time limits of other wrappers
    An outer ``TimeLimit`` (``gymnasium.make(id, max_episode_steps=N)`` or
    ``TimeLimit(env, N)``) may end the episode earlier. The environment cannot see it:
    gymnasium (1.x) records ``max_episode_steps=None`` in the unwrapped env's ``spec`` and
    keeps N in the wrapper only. Such an episode is scored as what was driven
    (:meth:`episode_info`, :meth:`episode_report`):

    * under stable-baselines3's ``DummyVecEnv`` and ``SubprocVecEnv`` with nothing to add:
      they mark the truncating step's info (``info["TimeLimit.truncated"]``) and reset the
      env in that same step, before returning ``infos``; that reset puts ``score``,
      ``qualified``, ``report``, ``episode_return`` and ``scenario_seed`` into that info,
      so ``infos[i]`` (the one with ``terminal_observation``) has them;
    * anywhere else -- your own loop, gymnasium's vector envs -- wrap the time limit in
      :class:`acc_gym.wrappers.ScoreOnTruncation`, which puts them into the truncating
      step's info at once. An info the env has handed over unmarked is never changed
      afterwards (gymnasium's ``check_env`` compares them across resets).

    A cut episode's score is that of the drive so far, not of the scenario (which may not
    have reached its test phase yet).

    ## Arguments

    ``gymnasium.make("acc_gym/CarFollowing-v0", config=None, scenario_generator=None,
    reward_fn=None, render_mode=None, mpc_settings=None, **settings)`` -- in a process that
    has not imported acc_gym (SB3's ``SubprocVecEnv`` workers under ``spawn`` or
    ``forkserver``) name it ``"acc_gym:acc_gym/CarFollowing-v0"``, or use
    :func:`acc_gym.make_vec_env`: ``config`` an
    :class:`~acc_gym.envs.config.EnvConfig` (or dict); ``settings`` override its fields
    (``scenarios``, ``weights``, ``drivers``, ``accel_max``, ``decel_max``,
    ``sensor_range``, ``v2v``, ``terminate_on_violation``, ``scoring``, ``version``); a misspelt setting
    is an error. ``scenario_generator(rng) -> Scenario`` replaces the default sampler;
    ``"counter"`` names :class:`~acc_gym.envs.config.CounterScenarioSampler` (``"numpy"``
    the default, :class:`~acc_gym.envs.config.ScenarioSampler`).
    ``render_mode``: ``"rgb_array"`` (uint8 top view) or ``"human"`` (a matplotlib window).

    ## Version History

    * v0: the observation's measured fields (indices 0-6; 0-10 with ``v2v``) and
      :class:`~acc_gym.envs.reward.CriteriaReward`, the score's own terms, as the reward;
      each id draws its own scenario families. Checked against stored reference episodes
      (``tests/envs/test_v0_reference.py``).
    * v1: the v0 observation plus the safety-margin features
      (:mod:`acc_gym.envs.observation`); :class:`~acc_gym.envs.reward.MarginReward` the
      default reward, with its optional terms at weight 0 and ``behind_outside_margin`` off
      (``info["rewards"]`` lists every term); ``CarFollowing-v1`` trains on varied traffic
      (paper 003's test drawn over 40-130 km/h and gentle to emergency stops, the test
      itself, stop-and-go, paper 004's car-following) behind naturalistic drivers
      (:data:`acc_gym.envs.registration.CARFOLLOWING_V1`); the others draw what their v0
      draws.

    In both versions the surrounding MPC drivers are driver model 5
    (``acc_gym.drivers.mpc.ENV_DRIVER_MODEL``). Either version takes
    ``scenario_generator="counter"`` (opt-in, no id's default): each scenario's parameters
    drawn with a compiled counter-based generator keyed by the scenario's ``(id, seed)``
    (:class:`~acc_gym.envs.config.CounterScenarioSampler`, :mod:`acc_gym.scenarios.batched`;
    a vector env draws the scenes it resets in one call): the same ``(id, seed)`` sequence
    and laws as the default, other numbers.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 5}

    def __init__(self, config: EnvConfig | dict | None = None, *, scenario_generator=None, reward_fn=None,
                 render_mode: str | None = None, mpc_settings=None, default_scenarios=None, **settings):
        self.config = make_config(config, settings, default_scenarios)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self.observation_space = observation_space(self.config)
        self.core = EpisodeBatch(1, self.config, make_sampler(self.config, scenario_generator),
                                 make_reward(reward_fn, self.config), mpc_settings)
        self.core.obs_bounds = self._bounds = (self.observation_space.low.astype(float),
                                               self.observation_space.high.astype(float))
        self._accel_max, self._decel_max = float(self.config.accel_max), float(self.config.decel_max)
        self._needs_reset = True
        self._a_des = np.zeros(1)  # [m/s^2] the usual step's desired acceleration, written in place
        self._scenario_id = None  # the running scenario's id (info["scenario"])
        self._last_info = None  # the last step's info while the episode runs (see reset)
        self._viewer = None

    @property
    def scenario(self) -> Scenario | None:
        return self.core.scenarios[0]

    def _obs(self) -> np.ndarray:
        return self.core.observe(*self._bounds, dtype=np.float32)[0]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise TypeError(f"reset(options=...) must be a dict (keys ['scenario', 'time_gap']) or None, got "
                            f"{type(options).__name__} {options!r}")
        options = dict(options or {})
        scenario = options.pop("scenario", None)
        time_gap = check_time_gap(options.pop("time_gap", None))
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; known: ['scenario', 'time_gap']")
        if isinstance(scenario, str):
            scenario = build_named(self.core.generator, self.config, scenario,
                                   int(self.np_random.integers(0, 2 ** 31 - 1)))
        elif scenario is not None and not isinstance(scenario, Scenario):
            raise TypeError(f"options['scenario'] must be a scenario id or a Scenario, got {type(scenario).__name__}")
        last, self._last_info = self._last_info, None
        if last is not None and bool(last.get("TimeLimit.truncated", False)) and "score" not in last:
            # an outer time limit cut the episode and SB3's vector env, which marks such a step's info, now
            # resets in that same step: that info, not yet handed over, gets the episode's evaluation
            last.update(self.episode_info())
        self.core.reset_rows([0], [self.np_random], [scenario], [time_gap])
        self._needs_reset = False
        sc = self.scenario
        self._scenario_id = sc.id
        if self.render_mode == "human":
            self.render()
        return self._obs(), {"scenario": sc.id, "scenario_seed": sc.seed, "t": 0.0}

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        x = float(action[0]) if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f" else None
        if x is not None and math.isfinite(x):  # the usual action: one finite float, mapped as a Python float
            a_des = self._a_des  # the env's own (1,) array: the step reads it, nothing keeps it
            a_des[0] = _K.accel_of_action(x, self._accel_max, self._decel_max)
        else:
            a_des = action_to_accel(check_actions(action, (1,)), self.config)
        core = self.core
        reward, term, trunc, final = core.step(a_des)
        out = core.info_row(0)
        out["scenario"] = self._scenario_id
        if final:
            out.update(final[0])
            self._needs_reset = True
            self._last_info = None
        else:
            self._last_info = out  # completed by reset() if SB3 marks it truncated by an outer time limit
        if self.render_mode == "human":
            self.render()
        return self.core.last_obs[0], float(reward[0]), bool(term[0]), bool(trunc[0]), out

    def episode_report(self) -> dict:
        """The report of the episode so far (its score, items and metrics, as the last
        step's ``info["report"]``), however the episode ends: when an outer wrapper
        (``TimeLimit``, ``gym.make(..., max_episode_steps=N)``) truncates it before the
        scenario's end, this scores what was driven. After the episode's own end it is that
        end's report. Needs at least one step since :meth:`reset`."""
        if self.scenario is None:
            raise RuntimeError("call reset() and step() before episode_report()")
        if int(self.core.world.k[0]) < 1:
            raise RuntimeError("episode_report() needs at least one step since reset() (a score needs two samples)")
        return score_episode(self.core.trace(0), self.config.scoring).to_dict()

    def episode_info(self) -> dict:
        """What the last step's ``info`` gets at the episode's end, for the episode so far:
        ``score``, ``qualified``, ``report`` (:meth:`episode_report`), ``episode_return``
        and ``scenario_seed`` -- the keys of the env's own last step.
        :class:`acc_gym.wrappers.ScoreOnTruncation` puts it into the info of the step where
        an outer time limit truncates, and :meth:`reset` into such a step's info once
        stable-baselines3's vector env has marked it (see *Episode End*)."""
        report = self.episode_report()
        return {"score": report["score"], "qualified": report["qualified"], "report": report,
                "episode_return": float(self.core.episode_return[0]), "scenario_seed": self.scenario.seed}

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        from acc_gym.rendering import HumanViewer, frame_from_batch

        frame = frame_from_batch(self.core, 0)  # the top view with its HUD (acc_gym.rendering)
        if self.render_mode == "rgb_array":
            return frame
        if self._viewer is None:
            self._viewer = HumanViewer()
        self._viewer.show(frame)
        return None

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
