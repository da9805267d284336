"""The wave-damping ring (``acc_gym/Ring-v1``): one controlled vehicle among human-like drivers
on a closed single lane, rewarded for the whole ring's flow and smoothness."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from acc_gym.envs.acc_env import V_MAX, actions_to_accel, check_actions, observation_space
from acc_gym.envs.config import EnvConfig
from acc_gym.simulation.ring import SUGIYAMA_SPEED, RingSensors, RingTrace, RingWorld, ring_layout

DRIVER_MODEL = 6  # the human drivers' model version (acc_gym.drivers.mpc.DRIVER_MODELS): with human perception
VEHICLES = 22  # the ego and 21 human-like drivers (Sugiyama's and Flow's 22, Stern's one among 21)
LENGTHS = (220.0, 270.0)  # [m] the ring's length, drawn uniformly per episode (Flow's ring)
WARMUP = 120.0  # [s] the humans drive alone (the ego by its stand-in) before the ego takes over
HORIZON = 300.0  # [s] the ego's control time: the episode's length after the warm-up
DT = 0.2  # [s] one step
CONNECTED_NAMES = ("ring_mean_speed", "ring_speed_sd")


def _number(name: str, value, low: float = 0.0, strict: bool = True) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or (value <= low if strict else value < low):
        raise ValueError(f"{name} must be a finite number {'>' if strict else '>='} {low:g}, got {value!r}")
    return float(value)


class RingEnv(gym.Env):
    """Damping stop-and-go waves on a ring road with one controlled vehicle.

    ## Description

    A closed single lane of length ``L`` with ``vehicles`` (22) vehicles: 21 human-like MPC
    drivers (driver model 6, with human perception: :mod:`acc_gym.drivers.perception`; a
    naturalistic population, desired speed Sugiyama's 30 km/h) and the ego, the last vehicle
    of the driving order (:func:`acc_gym.simulation.ring.controlled_positions`'s one vehicle).
    Such a ring jams on its own within minutes from a uniform start, as Sugiyama et al.'s
    drivers did (``docs/ring.md``); the task is Flow's ring benchmark and Stern et al.'s
    experiment: drive the ego so that the whole ring flows faster and more smoothly. The
    simulation is :class:`acc_gym.simulation.ring.RingWorld`, the same step as
    :func:`~acc_gym.simulation.ring.simulate_ring` (two phases: every driver decides from one
    snapshot, then every vehicle moves by :mod:`acc_gym.vehicle`); one step is 0.2 s.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``, as the other ``-v1`` ids: the ego's desired acceleration,
    ``action * accel_max`` for ``action >= 0`` and ``action * decel_max`` below (3 and 8
    m/s^2), clipped to [-1, 1]; the vehicle model then limits it (``info["a_applied"]``). NaN,
    infinite values or a wrong shape raise ``ValueError`` naming the action.

    ## Observation Space

    ``Box(float32)``: the ego's own sensors, exactly the ``-v1`` observation of
    :class:`~acc_gym.envs.acc_env.ACCEnv` (13 fields: speed, acceleration, gap, relative speed,
    lead in range, set speed, time gap, then the six safety-margin features of
    :mod:`acc_gym.envs.observation`), built by the ring's controller adapter
    (:class:`~acc_gym.simulation.ring.RingSensors`); set speed ``v_desired`` (8.33 m/s), time
    gap 1.5 s. With ``connected=True`` (what a connected vehicle could be told by the
    infrastructure or the other vehicles), two more fields:

    | index | observation | unit | range |
    |---|---|---|---|
    | 13 | mean speed of all the ring's vehicles now | m/s | [0, 70] |
    | 14 | standard deviation of their speeds now | m/s | [0, 70] |

    ## Rewards

    Per step, after the move, over all ``N`` vehicles of the ring (every term in
    ``info["rewards"]``; the reward is their sum):

    * ``flow``: ``+flow_weight * mean(v) / v_desired`` (the ring's mean speed, normalised by
      the humans' desired speed; default weight 1);
    * ``smoothness``: ``-smooth_weight * mean(a^2)`` with ``a`` the applied accelerations
      [m/s^2] over the step (default weight 0.2);
    * ``collision``: ``-collision_penalty`` (100) at a step where some vehicle's gap reaches 0.

    ## Starting State

    ``L`` uniform in ``lengths`` ([220, 270] m) and the ring's seed (its humans' parameters
    and perception errors: :func:`~acc_gym.simulation.ring.ring_rng`) are drawn from the env's
    ``np_random`` only. The vehicles start evenly spaced and standing (nothing perturbed).
    Then a **warm-up** of ``warmup`` seconds (120 s; Flow's ring warms up too) in which the
    ego's position is driven by a human-like stand-in (drawn from the ring's seed as the
    others, :class:`~acc_gym.simulation.ring.RingWorld`'s ``standins``), so the episode
    starts in a ring that has had time to jam; the first observation is at its end.
    ``reset(options={"ego": "human"})`` keeps the stand-in driving for the whole episode
    (actions are then ignored): the all-human ring on the same seed, the baseline a
    controller's wave damping is measured against.

    ## Episode End

    ### Termination
    A collision anywhere in the ring (some vehicle's gap <= 0), with the collision penalty.

    ### Truncation
    After ``horizon`` seconds of control (300 s: 1,500 steps after the warm-up).

    Every step's ``info`` has ``t`` [s since the start, warm-up included], ``rewards``,
    ``a_applied`` (the ego's, m/s^2), ``gap`` (the ego's, m), ``mean_speed`` and ``speed_sd``
    (the ring's now, m/s), ``collided`` (the vehicles whose gap is <= 0), ``length`` and
    ``ring_seed``. The last step's ``info`` also has, as the other envs give it, ``score``,
    ``qualified``, ``report`` (paper 003's report of the ego's drive over the control time:
    Q, D, G, u, j and the rest, :func:`acc_gym.evaluation.scoring.score_episode`) and
    ``episode_return``; and ``ring``: the ring's wave measures over the control time
    (:func:`acc_gym.evaluation.waves.ring_waves` with the warm-up as its warm-up: ``speed_sd``,
    Stern et al.'s measure, ``mean_speed``, ``stops``, ``jam``, ``braking_events``,
    ``energy_kwh_per_100km``, ``collisions``, ...).

    ## Arguments

    ``gymnasium.make("acc_gym/Ring-v1", connected=False, lengths=(220.0, 270.0), warmup=120.0,
    horizon=300.0, vehicles=22, drivers="naturalistic", v_desired=8.33, flow_weight=1.0,
    smooth_weight=0.2, collision_penalty=100.0, time_gap=1.5, sensor_range=200.0,
    accel_max=3.0, decel_max=8.0)``. ``lengths``: ``(low, high)`` [m] (equal: a fixed length).

    ## Version History

    * v1: initial version (driver model 6; the ``-v1`` observation and action).
    """

    metadata = {"render_modes": [], "render_fps": 5}

    def __init__(self, *, connected: bool = False, lengths=LENGTHS, warmup: float = WARMUP, horizon: float = HORIZON,
                 vehicles: int = VEHICLES, drivers: str = "naturalistic", v_desired: float = SUGIYAMA_SPEED,
                 flow_weight: float = 1.0, smooth_weight: float = 0.2, collision_penalty: float = 100.0,
                 time_gap: float = 1.5, sensor_range: float = 200.0, accel_max: float = 3.0, decel_max: float = 8.0,
                 render_mode: str | None = None):
        if render_mode is not None:
            raise ValueError(f"acc_gym/Ring-v1 does not render; render_mode must be None, got {render_mode!r}")
        if not isinstance(connected, bool):
            raise ValueError(f"connected must be True or False, got {connected!r}")
        try:
            lo, hi = (float(x) for x in lengths)
        except (TypeError, ValueError):
            raise ValueError(f"lengths must be (low, high) in metres, got {lengths!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
            raise ValueError(f"lengths must be (low, high) with 0 < low <= high [m], got {lengths!r}")
        if isinstance(vehicles, bool) or not isinstance(vehicles, (int, np.integer)) or vehicles < 2:
            raise ValueError(f"vehicles must be an integer >= 2 (the ego and at least one driver), got {vehicles!r}")
        self.connected, self.lengths, self.vehicles, self.drivers = connected, (lo, hi), int(vehicles), drivers
        self.warmup = _number("warmup", warmup, strict=False)
        self.horizon = _number("horizon", horizon)
        self.v_desired = _number("v_desired", v_desired)
        self.flow_weight = _number("flow_weight", flow_weight, strict=False)
        self.smooth_weight = _number("smooth_weight", smooth_weight, strict=False)
        self.collision_penalty = _number("collision_penalty", collision_penalty, strict=False)
        self.time_gap = _number("time_gap", time_gap)
        self.sensor_range = _number("sensor_range", sensor_range)
        self.accel_max, self.decel_max = _number("accel_max", accel_max), _number("decel_max", decel_max)
        self.render_mode = None
        self.ego = self.vehicles - 1
        self.warmup_steps = int(round(self.warmup / DT))
        self.horizon_steps = max(1, int(round(self.horizon / DT)))
        self.action_space = spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        base = observation_space(EnvConfig(version=1, sensor_range=self.sensor_range))
        low, high = base.low, base.high
        if connected:
            low = np.concatenate([low, np.zeros(2, np.float32)])
            high = np.concatenate([high, np.full(2, V_MAX, np.float32)])
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._sensors = RingSensors(np.array([[0, self.ego]], dtype=np.int64), set_speed=self.v_desired,
                                    time_gap=self.time_gap, sensor_range=self.sensor_range, version=1)
        self.world = None
        self._needs_reset = True

    # --- helpers
    def _obs(self) -> np.ndarray:
        obs = self._sensors(self.world.fields())[0]
        if not self.connected:
            return obs.copy()
        v = self.world.v[0]
        extra = np.clip(np.array([v.mean(), v.std()]), 0.0, V_MAX).astype(np.float32)
        return np.concatenate([obs, extra])

    def _record(self) -> None:
        k = self.world.k
        self._s[k], self._v[k], self._a[k] = self.world.s[0], self.world.v[0], self.world.a[0]
        self._gap[k] = self.world.gaps()[0]

    def _move(self, a_ego) -> None:
        self.world.step(a_ego)
        self._record()

    # --- Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise TypeError(f"reset(options=...) must be a dict (key 'ego') or None, got {type(options).__name__}")
        options = dict(options or {})
        ego = options.pop("ego", "agent")
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; known: ['ego']")
        if ego not in ("agent", "human"):
            raise ValueError(f"options['ego'] must be 'agent' or 'human' (the all-human ring), got {ego!r}")
        self._human_ego = ego == "human"
        lo, hi = self.lengths
        self.length = float(self.np_random.uniform(lo, hi)) if hi > lo else lo
        self.ring_seed = int(self.np_random.integers(0, 2 ** 31 - 1))
        self.world = RingWorld(self.length, self.vehicles, layout=ring_layout(self.vehicles, (self.ego,)),
                               drivers=self.drivers, seeds=(self.ring_seed,), dt=DT, v_desired=self.v_desired,
                               driver_model=DRIVER_MODEL, standins=True)
        self.world.reset()
        n = self.warmup_steps + self.horizon_steps + 1
        self._s, self._v, self._a, self._gap = (np.empty((n, self.vehicles)) for _ in range(4))
        self._record()
        for _ in range(self.warmup_steps):
            self._move(None)
        self._return = 0.0
        self._needs_reset = False
        return self._obs(), {"t": self.world.t, "length": self.length, "ring_seed": self.ring_seed}

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        a = check_actions(action, (1,))
        self._move(None if self._human_ego else actions_to_accel(a, self.accel_max, self.decel_max))
        w = self.world
        v, acc, gap = w.v[0], w.a[0], self._gap[w.k]
        hit = np.flatnonzero(gap <= 0.0)
        rewards = {"flow": self.flow_weight * float(v.mean()) / self.v_desired,
                   "smoothness": -self.smooth_weight * float(np.mean(acc * acc)),
                   "collision": -self.collision_penalty if hit.size else 0.0}
        reward = sum(rewards.values())
        self._return += reward
        terminated = bool(hit.size)
        truncated = not terminated and w.k >= self.warmup_steps + self.horizon_steps
        info = {"t": w.t, "rewards": rewards, "a_applied": float(acc[self.ego]), "gap": float(gap[self.ego]),
                "mean_speed": float(v.mean()), "speed_sd": float(v.std()), "collided": hit.tolist(),
                "length": self.length, "ring_seed": self.ring_seed}
        if terminated or truncated:
            info.update(self.episode_info())
            self._needs_reset = True
        return self._obs(), float(reward), terminated, truncated, info

    def trace(self) -> RingTrace:
        """The episode so far as a :class:`~acc_gym.simulation.ring.RingTrace` of one ring (warm-up
        included)."""
        k = self.world.k
        w = self.world
        return RingTrace(t=np.arange(k + 1) * DT, s=self._s[:k + 1, None].copy(), v=self._v[:k + 1, None].copy(),
                         a=self._a[:k + 1, None].copy(), length=self.length, lengths=w.lengths, layout=w.layout,
                         seeds=w.seeds, vehicle=w.vehicle)

    def episode_info(self) -> dict:
        """What the last step's ``info`` gets (see *Episode End*), for the episode so far (at least one
        step after the warm-up)."""
        from acc_gym.evaluation.scoring import score_episode
        from acc_gym.evaluation.trace import EgoTrace
        from acc_gym.evaluation.waves import ring_waves

        k0, k = self.warmup_steps, self.world.k
        if k <= k0:
            raise RuntimeError("episode_info() needs at least one step after the warm-up")
        e, lead = self.ego, self.ego - 1
        sl = slice(k0, k + 1)
        ego = EgoTrace(t=np.arange(k0, k + 1) * DT, v=self._v[sl, e].copy(), a=self._a[sl, e].copy(),
                       gap=self._gap[sl, e].copy(), v_lead=self._v[sl, lead].copy(), a_lead=self._a[sl, lead].copy(),
                       set_speed=self.v_desired, time_gap=self.time_gap)
        report = score_episode(ego).to_dict()
        (waves,) = ring_waves(self.trace(), warmup=k0 * DT)
        return {"score": report["score"], "qualified": report["qualified"], "report": report,
                "episode_return": float(self._return), "ring": waves.to_dict(), "length": self.length,
                "ring_seed": self.ring_seed}

