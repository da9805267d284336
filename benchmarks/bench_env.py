"""Speed of the environments as users make them: single-env and vector-env steps per second.

Each case is an id made with ``gymnasium.make`` (wrappers included: order enforcing,
passive checker) or ``gymnasium.make_vec`` (the native vector env, ``--num-envs`` = 256),
with its default settings unless named, random actions in [-0.3, 0.3] and episodes ending
and restarting as they come (resets included in the time):

========================  ======================================================
key (``_steps_per_s``)    case
========================  ======================================================
``env``                   ``acc_gym/SingleLane-v0`` (all 22 configurations)
``env_idm``               the same with ``drivers="idm"`` (IDM surrounding drivers)
``env_carfollowing``      ``acc_gym/CarFollowing-v0``
``env_ncap``              ``acc_gym/NCAP-v0``
``env_v1``                ``acc_gym/SingleLane-v1`` (the same draws as ``env``, with the
                          safety-margin features and MarginReward)
``env_v1_idm``            the same with ``drivers="idm"``
``env_v1_carfollowing``   ``acc_gym/CarFollowing-v1`` (its training mixture, naturalistic drivers)
``env_v1_ncap``           ``acc_gym/NCAP-v1``
``env_v1_counter``        ``env_v1`` and ``env_v1_idm`` with ``scenario_generator="counter"``
``env_v1_idm_counter``    (the counter-based, batched scenario generator; opt-in cases,
                          not in the default ``--cases``)
``env_v1_typical``        ``env_v1`` and ``env_v1_carfollowing`` with ``sensors`` and
``env_v1_carfollowing_    ``actuators`` ``"typical"`` (:mod:`acc_gym.onboard`; opt-in);
typical``                 with the ideal case in the same run, ``*_typical_cost`` is
                          their share of a step (``1 - rate / ideal rate``, of the
                          medians; ``*_typical_cost_paired``: 1 - the median of each
                          repeat's ratio, the two runs back to back)
``vector_env``            ``acc_gym/SingleLane-v0``, 256 envs; likewise
                          ``vector_env_idm``, ``vector_env_carfollowing``, ``vector_env_ncap``,
                          ``vector_env_v1``, ``vector_env_v1_idm``, ...
========================  ======================================================

Each figure is the median of ``--repeats`` timed runs after a warm-up (numba kernels
compiled, caches warm), the runs alternating over the cases; the runs are printed too.
``--workers K`` (default: the number of cores, if more than one) also times the default
vector env split over ``K`` worker processes (``make_vec(..., workers=K)``,
:mod:`acc_gym.envs.shards`) as ``vector_env_workers_steps_per_s``; ``--workers 1`` skips
it. ``--parallel`` runs the vector env's MPC drivers on numba's thread pool
(``MPCSettings(parallel=None)``, see :class:`acc_gym.drivers.mpc.MPCSettings`).
``--policy`` times the default vector env as training runs it, with stable-baselines3's
default PPO policy sampling every action (one torch thread), in process and over
``--workers`` processes (``vector_env_policy_steps_per_s``,
``vector_env_workers_policy_steps_per_s``). ``--cases`` picks cases (e.g. ``--cases env
env_idm``).

``--peers`` also times SUMO through libsumo on the same work as ``env_idm`` (a lead, two
IDM followers, an ego whose speed is set and read every step, 0.2 s steps, one reload per
200-step episode; :mod:`sumo_peer`), alternating with ``env_idm`` in the same run, as
``sumo_steps_per_s``, and ``sumo_ratio`` = ``env_idm_steps_per_s / sumo_steps_per_s``
(above 1: acc_gym is faster), and ``sumo_ratio_v1`` = ``env_v1_idm_steps_per_s /
sumo_steps_per_s`` (``env_v1_idm`` is timed in the same alternation; the same SUMO runs
are the denominator of both). It needs ``pip install ".[bench]"`` (libsumo).

``--peers`` also times the core column API against ``cavsandbox`` (a pure-Python peer,
``pip install cavsandbox``, imported as ``cacc_sim``) on the same work: a lead on a speed
profile (25 m/s, down to 15 m/s and back at 1 m/s^2) and 10 IDM followers (a 1.5 m/s^2,
b 2.0 m/s^2, T 1.5 s, s0 2 m, desired speed 25 m/s, no reaction delay, 4.7 m long, 50 m
apart), 3,000 steps of 0.1 s with every step recorded, objects built in the timed run on
both sides (:func:`column_rate`, :func:`cavsandbox_column_rate`). The two alternate in each
repeat; ``column_vehicle_steps_per_s`` and ``cavsandbox_column_vehicle_steps_per_s`` are
vehicles x steps per second, and ``column_ratio_cavsandbox`` = ours / theirs. Without
cavsandbox the ratio is ``null`` and ``column_ratio_cavsandbox_reason`` says why.

``--split`` also times each vector case once more per repeat with the time spent starting
episodes counted apart (the vector env's autoresets: drawing the scenarios, building the
scenes, installing their drivers), and reports ``vector_<case>_reset_share`` (that time over
the run's) and ``vector_<case>_steps_per_s_without_resets`` (the steps over the rest of the
time: what the case would run at if starting an episode were free, the ceiling of any work
on resets), ``vector_<case>_steps_per_episode`` (env-steps per autoreset) and
``vector_<case>_condense_share`` (the part of the run's time spent condensing the new MPC
drivers' QPs: the cruise QP inside the resets, the follow QP at a driver's first real target),
``vector_<case>_condensations_per_episode``, ``vector_<case>_us_per_condensation`` and
``vector_<case>_params_share`` (the part spent drawing the new scenarios' parameters with
numpy's generators), medians over the repeats (:func:`vector_env_split`); and each single case
once more, as ``<case>_reset_share`` (the time in ``env.reset()``), ``<case>_decide_share``
(the surrounding drivers deciding),
``<case>_us_per_reset``, ``<case>_us_per_step`` (a step
without the resets) and ``<case>_steps_per_episode`` (:func:`single_env_split`).

``--against DIR`` times another checkout of the package (e.g. the previous release:
``git worktree add /tmp/prev v0.5.0``) in the same run. Per case and repeat, a fresh worker
process for this checkout and one for ``DIR`` (``PYTHONPATH=DIR``) each make the case's single
env and vector env and warm them up; then ``--rounds`` rounds each time a block of
``--steps`` single steps and ``--vector-steps`` vector steps in both workers back to back (who
goes first alternates), and the repeat's rate is the median of its rounds. It reports both
medians over the repeats and their ratio per key (``against``: ``{key: {"this": .., "other":
.., "ratio": .., "paired_ratio": ..}}``); ``paired_ratio`` is the median over the repeats of
each repeat's own ratio. Rates there are steps per CPU second of the worker
(``time.process_time``, ``"clock": "process_time"``): on a shared machine the wall clock also
counts the time given to others, which drifts by 30-50 % over seconds and minutes, and blocks
one right after the other see the same machine. Fresh processes per repeat because one process
can run 10-15 % faster or slower than another of the same code for all its life (measured here:
31 rounds in one pair of processes gave 0.90 and, in another pair, 1.09 for the same two
checkouts). It times the single and vector envs only (not ``--parallel``, ``--policy``,
``--peers``).

    python benchmarks/bench_env.py            # table
    python benchmarks/bench_env.py --json     # one JSON object
    python benchmarks/bench_env.py --against /tmp/prev --repeats 9
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.drivers.mpc import MPCSettings

CASES = {  # key prefix -> (id, settings)
    "env": ("acc_gym/SingleLane-v0", {}),
    "env_idm": ("acc_gym/SingleLane-v0", {"drivers": "idm"}),
    "env_carfollowing": ("acc_gym/CarFollowing-v0", {}),
    "env_ncap": ("acc_gym/NCAP-v0", {}),
    "env_v1": ("acc_gym/SingleLane-v1", {}),
    "env_v1_idm": ("acc_gym/SingleLane-v1", {"drivers": "idm"}),
    "env_v1_carfollowing": ("acc_gym/CarFollowing-v1", {}),
    "env_v1_ncap": ("acc_gym/NCAP-v1", {}),
    # opt-in: the counter-based, batched scenario generator (acc_gym.scenarios.batched)
    "env_v1_counter": ("acc_gym/SingleLane-v1", {"scenario_generator": "counter"}),
    "env_v1_idm_counter": ("acc_gym/SingleLane-v1", {"drivers": "idm", "scenario_generator": "counter"}),
    # opt-in: the typical radar and actuators (acc_gym.onboard); their cost against the ideal case beside them
    "env_v1_typical": ("acc_gym/SingleLane-v1", {"sensors": "typical", "actuators": "typical"}),
    "env_v1_carfollowing_typical": ("acc_gym/CarFollowing-v1", {"sensors": "typical", "actuators": "typical"}),
}
OPT_IN = ("_counter", "_typical")
DEFAULT_CASES = [case for case in CASES if not case.endswith(OPT_IN)]
PEER_CASES = ("env_idm", "env_v1_idm")  # the cases SUMO's work equals (--peers adds them)


def _single_env(steps: int, seed: int, env_id: str, settings: dict):
    """``(env, actions)``: a fresh ``env_id`` reset with ``seed`` and ``steps`` small random
    actions drawn from ``seed``, the work of every single-env case."""
    env = gym.make(env_id, **settings)
    env.reset(seed=seed)
    return env, np.random.default_rng(seed).uniform(-0.3, 0.3, (steps, 1)).astype(np.float32)


def single_env_rate(steps: int, seed: int, env_id: str = "acc_gym/SingleLane-v0", **settings) -> float:
    env, actions = _single_env(steps, seed, env_id, settings)
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(actions[k])
        if term or trunc:
            env.reset()
    rate = steps / (time.perf_counter() - t0)
    env.close()
    return rate


def warm_up_episode(env_id: str, max_steps: int = 5000, **settings) -> None:
    """One episode of ``env_id`` to its end (at most ``max_steps``), so that what runs only at an
    episode's end (the score, a reset) is compiled or loaded from numba's cache before timing."""
    env = gym.make(env_id, **settings)
    env.reset(seed=99)
    for _ in range(max_steps):
        _, _, term, trunc, _ = env.step(np.zeros(1, dtype=np.float32))
        if term or trunc:
            break
    env.close()


def vector_env_rate(num_envs: int, steps: int, seed: int, parallel: bool = False, workers: int = 1,
                    env_id: str = "acc_gym/SingleLane-v0", **settings) -> float:
    kwargs = {"mpc_settings": MPCSettings(parallel=None)} if parallel else {}
    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", workers=workers,
                        **kwargs, **settings)
    rate = num_envs * steps / _timed_steps(envs, num_envs, steps, seed)
    envs.close()
    return rate


def _timed_steps(envs, num_envs: int, steps: int, seed: int, before=None) -> float:
    """Reset ``envs`` with ``seed``, call ``before()`` (if given), then time ``steps`` steps of
    small random actions drawn from ``seed``: the seconds they took."""
    rng = np.random.default_rng(seed)
    envs.reset(seed=seed)
    actions = rng.uniform(-0.3, 0.3, (steps, num_envs, 1)).astype(np.float32)
    if before is not None:
        before()
    t0 = time.perf_counter()
    for k in range(steps):
        envs.step(actions[k])
    return time.perf_counter() - t0


def vector_env_split(num_envs: int, steps: int, seed: int, env_id: str = "acc_gym/SingleLane-v0",
                     **settings) -> dict:
    """The vector env of :func:`vector_env_rate` (one process) with the time its autoresets take
    counted apart: ``{"steps_per_s", "reset_share", "steps_per_s_without_resets", "resets",
    "steps_per_episode", "condensations", "condense_share", "condensations_per_episode",
    "us_per_condensation", "params_share"}``. The env's own ``_reset_rows``
    (what an autoreset runs: draw, build, install) is wrapped in a timer on this instance
    only; the initial ``reset`` is outside the timed run. ``condensations`` counts the MPC
    drivers' QPs condensed in the run (:class:`~acc_gym.drivers.qp.CondensedQP` built: each
    new driver configuration's cruise QP at its install, inside the resets, and its follow QP
    at its first step with a real target, inside a step) and ``condense_share`` is their time
    over the run's. ``params_share`` is the run's time spent drawing the new scenarios'
    parameters with numpy's generators (:func:`acc_gym.scenarios.registry.scenario_rngs`, the
    two generators of each ``(id, seed)``, and :meth:`ScenarioType.sample_params
    <acc_gym.scenarios.registry.ScenarioType.sample_params>`, the parameter laws): the part of a
    reset that the ids' numpy streams keep in Python (the counter generator replaces it)."""
    from acc_gym.drivers import qp
    from acc_gym.scenarios import registry

    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **settings)
    inner = envs.unwrapped
    timed = inner._reset_rows
    spent = [0.0, 0, 0.0, 0, 0.0, 0]  # [s] in resets, their rows, [s] condensing, QPs condensed, [s] drawing params
    build = qp.CondensedQP.__init__
    rngs, laws = registry.scenario_rngs, registry.ScenarioType.sample_params

    def timing(fn, at: int, count):
        """``fn`` adding its time to ``spent[at]`` and ``count(args)`` to ``spent[at + 1]``."""
        def wrapped(*args, **kwargs):
            t = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[at] += time.perf_counter() - t
                spent[at + 1] += count(args)
        return wrapped

    counted = timing(timed, 0, lambda args: len(args[0]))  # an autoreset's rows
    condensing = timing(build, 2, lambda args: 1)  # (self, ...): one QP

    def restart() -> None:  # the initial reset is not part of the timed run
        spent[:] = [0.0, 0, 0.0, 0, 0.0, 0]

    inner._reset_rows = counted
    qp.CondensedQP.__init__ = condensing
    registry.scenario_rngs = timing(rngs, 4, lambda args: 1)
    registry.ScenarioType.sample_params = timing(laws, 4, lambda args: 0)
    try:
        total = _timed_steps(envs, num_envs, steps, seed, before=restart)
    finally:
        qp.CondensedQP.__init__ = build
        registry.scenario_rngs, registry.ScenarioType.sample_params = rngs, laws
    envs.close()
    return {"steps_per_s": num_envs * steps / total, "reset_share": spent[0] / total,
            "steps_per_s_without_resets": num_envs * steps / (total - spent[0]), "resets": spent[1],
            "steps_per_episode": num_envs * steps / spent[1] if spent[1] else float("inf"),
            "condensations": spent[3], "condense_share": spent[2] / total,
            "condensations_per_episode": spent[3] / spent[1] if spent[1] else 0.0,
            "us_per_condensation": 1e6 * spent[2] / spent[3] if spent[3] else 0.0,
            "params_share": spent[4] / total}


def single_env_split(steps: int, seed: int, env_id: str = "acc_gym/SingleLane-v0", **settings) -> dict:
    """The single env of :func:`single_env_rate` with its time split: ``{"steps_per_s",
    "reset_share", "decide_share", "us_per_reset", "us_per_step", "steps_per_episode"}``.
    ``reset_share`` is the run's time in ``env.reset()`` (drawing the scenario, building the
    scene, installing its drivers), ``decide_share`` the time the surrounding drivers take to
    decide (:meth:`SingleLaneWorld.decide <acc_gym.simulation.single_lane.SingleLaneWorld.decide>`,
    wrapped on this env's world only), ``us_per_reset`` a reset's mean time and ``us_per_step``
    a step's without the resets [us]. The initial reset is outside the timed run."""
    env, actions = _single_env(steps, seed, env_id, settings)
    world = env.unwrapped.core.world
    decide = world.decide
    spent = [0.0, 0.0, 0]  # [s] in resets, [s] deciding, resets

    def timed_decide(*args, **kwargs):
        t = time.perf_counter()
        try:
            return decide(*args, **kwargs)
        finally:
            spent[1] += time.perf_counter() - t

    world.decide = timed_decide  # an instance attribute: this env's world only
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(actions[k])
        if term or trunc:
            t = time.perf_counter()
            env.reset()
            spent[0] += time.perf_counter() - t
            spent[2] += 1
    total = time.perf_counter() - t0
    env.close()
    return {"steps_per_s": steps / total, "reset_share": spent[0] / total, "decide_share": spent[1] / total,
            "us_per_reset": 1e6 * spent[0] / spent[2] if spent[2] else 0.0,
            "us_per_step": 1e6 * (total - spent[0]) / steps,
            "steps_per_episode": steps / spent[2] if spent[2] else float("inf")}


def vector_policy_rate(num_envs: int, steps: int, seed: int, workers: int = 1) -> float:
    """The vector env with a policy in the loop, as in training: stable-baselines3's default
    PPO policy (64-64 MLP, one torch thread) samples every action from the observations."""
    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    torch.set_num_threads(1)
    envs = gym.make_vec("acc_gym/SingleLane-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                        workers=workers)
    torch.manual_seed(seed)
    policy = ActorCriticPolicy(envs.single_observation_space, envs.single_action_space, lambda _: 3e-4)
    obs, _ = envs.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(steps):
        with torch.no_grad():
            actions, _, _ = policy(torch.as_tensor(obs))
        obs = envs.step(np.clip(actions.numpy(), -1.0, 1.0))[0]
    rate = num_envs * steps / (time.perf_counter() - t0)
    envs.close()
    return rate


# The column case (--peers): one lead and COLUMN_FOLLOWERS IDM followers, the same on both sides.
COLUMN_FOLLOWERS = 10
COLUMN_STEPS = 3000
COLUMN_DT = 0.1  # [s]
COLUMN_SPEED = 25.0  # [m/s] every vehicle's initial speed, the lead's cruise and the IDM desired speed
COLUMN_SPACING = 50.0  # [m] initial front bumper to front bumper
COLUMN_LENGTH = 4.7  # [m]
# the lead's profile from COLUMN_SPEED: (acceleration [m/s^2], duration [s]), 300 s in all
COLUMN_LEAD = ((0.0, 100.0), (-1.0, 10.0), (0.0, 90.0), (1.0, 10.0), (0.0, 90.0))
# IDM: a [m/s^2], b [m/s^2], T [s], s0 [m], delta [-] (v0 is COLUMN_SPEED)
COLUMN_IDM = {"a": 1.5, "b": 2.0, "time_gap": 1.5, "s0": 2.0, "delta": 4.0}


def _column_start() -> tuple[np.ndarray, np.ndarray]:
    """Front-bumper positions [m] (lead first) and speeds [m/s] of the column case."""
    n = COLUMN_FOLLOWERS + 1
    return (n - 1 - np.arange(n)) * COLUMN_SPACING, np.full(n, COLUMN_SPEED)


def column_rate() -> float:
    """Vehicle-steps per second of :func:`~acc_gym.simulation.rollout.simulate_column` on the
    column case (the README's first API), the IDM drivers built in the timed run."""
    from acc_gym.drivers.baselines import IDM, IDMParams
    from acc_gym.simulation.profiles import SpeedProfile
    from acc_gym.simulation.rollout import simulate_column
    from acc_gym.vehicle import VehicleParams

    x0, v0 = _column_start()
    t0 = time.perf_counter()
    lead = SpeedProfile.from_segments(COLUMN_SPEED, COLUMN_LEAD)
    params = IDMParams(v_desired=COLUMN_SPEED, **COLUMN_IDM)
    followers = [IDM(params, dt=COLUMN_DT) for _ in range(COLUMN_FOLLOWERS)]
    tr = simulate_column(lead, followers, x0, v0, duration=COLUMN_STEPS * COLUMN_DT, dt=COLUMN_DT,
                         vehicle=VehicleParams(length=COLUMN_LENGTH))
    elapsed = time.perf_counter() - t0
    assert tr.x.shape == (COLUMN_STEPS + 1, COLUMN_FOLLOWERS + 1) and not tr.collided.any()
    return (COLUMN_FOLLOWERS + 1) * COLUMN_STEPS / elapsed


def cavsandbox_available() -> str | None:
    """None if cavsandbox (``cacc_sim``) imports, else the reason it does not."""
    try:
        import cacc_sim  # noqa: F401
    except ImportError as exc:
        return f"cavsandbox is not installed (pip install cavsandbox): {exc}"
    return None


def cavsandbox_column_rate() -> float:
    """Vehicle-steps per second of cavsandbox's headless loop (``SimulationLoop.run``) on the
    column case: its ``LeadVehicleModel`` on the same profile (its ramps run from the previous
    event's value to the event's, hence the event list), ``IDMModel`` followers with the same
    parameters, passthrough sensors, the kinematic response (no actuator lag, as acc_gym's
    vehicle), every step logged (``log_rate_hz = 1 / dt``), the objects built in the timed run."""
    import pandas as pd
    from cacc_sim import (IDMModel, LeadVehicleModel, LeadVehicleProfile, PassthroughFilter, SimConfig,
                          SimulationLoop, Vehicle, VehiclePlant, VehicleResponseModel)

    x0, v0 = _column_start()
    low = COLUMN_SPEED + COLUMN_LEAD[1][0] * COLUMN_LEAD[1][1]  # [m/s] 15
    events = pd.DataFrame({"time_s": [0.0, 100.0, 110.0, 200.0, 210.0],
                           "value": [COLUMN_SPEED, low, low, COLUMN_SPEED, COLUMN_SPEED], "transition": "ramp"})
    t0 = time.perf_counter()
    config = SimConfig(timestep_s=COLUMN_DT, duration_s=COLUMN_STEPS * COLUMN_DT, road_length_m=1e6,
                       response_model="kinematic", log_rate_hz=1.0 / COLUMN_DT)
    vehicles = []
    for i in range(COLUMN_FOLLOWERS + 1):
        model = (LeadVehicleModel(LeadVehicleProfile(events)) if i == 0 else
                 IDMModel(COLUMN_SPEED, COLUMN_IDM["time_gap"], s0=COLUMN_IDM["s0"], a_max=COLUMN_IDM["a"],
                          b=COLUMN_IDM["b"], delta=COLUMN_IDM["delta"], a_min=-8.0))
        vehicles.append(Vehicle(i, model, VehicleResponseModel(mode="kinematic", dt=COLUMN_DT),
                                VehiclePlant(float(x0[i]), float(v0[i]), COLUMN_LENGTH, dt=COLUMN_DT),
                                PassthroughFilter(), leader_id=None if i == 0 else i - 1))
    log = SimulationLoop(vehicles, config).run()
    elapsed = time.perf_counter() - t0
    assert len(log) == (COLUMN_FOLLOWERS + 1) * COLUMN_STEPS  # every step of every vehicle, no collision
    return (COLUMN_FOLLOWERS + 1) * COLUMN_STEPS / elapsed


def _median(out: dict, key: str, runs: list) -> None:
    out[key] = float(np.median(runs))
    # a run too short for any episode to end has infinitely many steps per episode: kept as it is
    out[key + "_runs"] = [x if not math.isfinite(x) else round(x, 3) if key.endswith("_share") else round(x)
                          for x in runs]


def paired_ratio(this_runs: list, other_runs: list) -> float:
    """The median over repeats of ``this_runs[i] / other_runs[i]`` (runs timed back to back)."""
    if len(this_runs) != len(other_runs) or not this_runs:
        raise ValueError(f"paired runs must be non-empty and of one length, got {len(this_runs)} and {len(other_runs)}")
    return float(np.median([a / b for a, b in zip(this_runs, other_runs)]))


def serve(case: str, num_envs: int) -> None:
    """The worker of :func:`against`: ``case``'s single env and vector env of ``num_envs`` made
    once, warmed up, then for each line ``single N`` or ``vector N`` on stdin, ``N`` more steps
    of that env and one line with the CPU seconds they took (``time.process_time``). Runs under
    whichever checkout ``PYTHONPATH`` names, so it uses only the public API."""
    env_id, settings = CASES[case]
    warm_up_episode(env_id, **settings)
    single, actions = _single_env(4096, 0, env_id, settings)
    vec = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **settings)
    vec.reset(seed=0)
    vec_actions = np.random.default_rng(0).uniform(-0.3, 0.3, (256, num_envs, 1)).astype(np.float32)
    clock = {"single": 0, "vector": 0}

    def run(kind: str, steps: int) -> None:
        for _ in range(steps):
            k = clock[kind] = clock[kind] + 1
            if kind == "vector":
                vec.step(vec_actions[k % 256])
            else:
                _, _, term, trunc, _ = single.step(actions[k % 4096])
                if term or trunc:
                    single.reset()

    run("single", 200)
    run("vector", 5)
    print("ready", flush=True)
    for line in sys.stdin:
        kind, steps = line.split()
        t0 = time.process_time()
        run(kind, int(steps))
        print(time.process_time() - t0, flush=True)


def against(args) -> dict:
    """This checkout and ``args.against`` in one run: per case and repeat, one fresh worker
    process each (:func:`serve`) holding the case's envs, then ``args.rounds`` rounds, each
    timing a block of ``args.steps`` single-env steps and one of ``args.vector_steps`` vector
    steps in both workers back to back (who goes first alternating). A repeat's rate is the
    median of its rounds, in steps per CPU second of the worker."""
    if args.parallel or args.policy or args.peers:
        raise SystemExit("--against times the single and vector envs only: run --parallel, --policy or --peers "
                         "without it")
    here = os.path.abspath(__file__)
    envs = {"this": None, "other": {**os.environ, "PYTHONPATH": os.path.abspath(args.against)}}
    table = {}
    for case in args.cases:
        runs = {(who, kind): [] for who in envs for kind in ("single", "vector")}
        for _ in range(args.repeats):
            rounds = _rounds(here, case, envs, args)
            for key, rates in rounds.items():
                runs[key].append(float(np.median(rates)))
        for kind, key in (("single", f"{case}_steps_per_s"), ("vector", f"vector_{case}_steps_per_s")):
            this_runs, other_runs = runs["this", kind], runs["other", kind]
            this, other = float(np.median(this_runs)), float(np.median(other_runs))
            table[key] = {"this": this, "other": other, "ratio": this / other,
                          "paired_ratio": paired_ratio(this_runs, other_runs),
                          "this_runs": [round(x) for x in this_runs], "other_runs": [round(x) for x in other_runs]}
    return {"against": table, "against_dir": os.path.abspath(args.against), "repeats": args.repeats,
            "rounds": args.rounds, "clock": "process_time"}


def _rounds(here: str, case: str, envs: dict, args) -> dict:
    """One repeat of :func:`against`: a worker per checkout, ``args.rounds`` rounds; the rates
    by ``(who, kind)``."""
    workers = {who: subprocess.Popen([sys.executable, here, "--serve", case, "--num-envs", str(args.num_envs)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                                     cwd=os.path.dirname(here)) for who, env in envs.items()}
    rates = {(who, kind): [] for who in workers for kind in ("single", "vector")}
    try:
        for who, w in workers.items():
            if w.stdout.readline().strip() != "ready":
                raise RuntimeError(f"the {who} checkout's worker for {case} did not start (exit {w.wait()})")
        for r in range(args.rounds):
            for who in (("this", "other") if r % 2 == 0 else ("other", "this")):
                w = workers[who]
                for kind, steps in (("single", args.steps), ("vector", args.vector_steps)):
                    w.stdin.write(f"{kind} {steps}\n")
                    w.stdin.flush()
                    rates[who, kind].append(steps * (args.num_envs if kind == "vector" else 1) / float(w.stdout.readline()))
    finally:
        for w in workers.values():
            w.stdin.close()
            w.wait()
    return rates


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="single-env steps per timed run")
    parser.add_argument("--vector-steps", type=int, default=200, help="vector-env steps per timed run")
    parser.add_argument("--num-envs", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), choices=list(CASES),
                        help="which ids to time (each single and as a vector env)")
    parser.add_argument("--parallel", action="store_true", help="also time the vector env with threaded MPC drivers")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="also time the vector env over this many worker processes (1: skip)")
    parser.add_argument("--policy", action="store_true",
                        help="also time the vector env (in-process and with --workers) with a PPO policy in the loop")
    parser.add_argument("--peers", action="store_true",
                        help="also time SUMO (libsumo) on the env_idm work and cavsandbox on the column case, "
                             "alternating, and report sumo_ratio and column_ratio_cavsandbox")
    parser.add_argument("--rounds", type=int, default=5,
                        help="with --against: back-to-back blocks per repeat's pair of worker processes")
    parser.add_argument("--against", default=None, metavar="DIR",
                        help="also time the checkout in DIR (PYTHONPATH=DIR), alternating, and report the ratios")
    parser.add_argument("--split", action="store_true",
                        help="also report each vector case's share of time in autoresets and its rate without them, "
                             "and each single case's time in resets and in the drivers' decisions")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--serve", choices=list(CASES), help=argparse.SUPPRESS)  # against()'s worker
    args = parser.parse_args(argv)
    if args.serve:
        serve(args.serve, args.num_envs)
        return {}
    if args.against:
        out = against(args)
        if args.json:
            print(json.dumps(out))
        else:
            print(f"this checkout against {out['against_dir']} ({args.repeats} pairs of processes, {args.rounds} "
                  f"back-to-back blocks each, steps per CPU second, medians; paired: the median of each pair's ratio):")
            for k, row in out["against"].items():
                print(f"  {k:38s} {row['this']:>12,.0f} vs {row['other']:>12,.0f}  x{row['ratio']:.2f}"
                      f"  paired x{row['paired_ratio']:.2f}")
        return out
    if args.peers:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import sumo_peer

        if not sumo_peer.available():
            parser.error("--peers needs libsumo: pip install '.[bench]'")
        args.cases += [case for case in PEER_CASES if case not in args.cases]
        sumo_peer.rate(400)  # warm-up
        column_rate()  # warm-up: the column kernels compiled or loaded from numba's cache
        cavsandbox_missing = cavsandbox_available()
        if cavsandbox_missing is None:
            cavsandbox_column_rate()  # warm-up
    for case in args.cases:  # warm-up: compile and cache, up to an episode's end (its score's kernels too)
        env_id, settings = CASES[case]
        warm_up_episode(env_id, **settings)
        single_env_rate(200, 99, env_id, **settings)
        vector_env_rate(min(args.num_envs, 16), 10, 99, env_id=env_id, **settings)
    runs: dict[str, list] = {}
    for r in range(args.repeats):  # alternating over the cases
        for case in args.cases:
            env_id, settings = CASES[case]
            runs.setdefault(f"{case}_steps_per_s", []).append(single_env_rate(args.steps, r, env_id, **settings))
            runs.setdefault(f"vector_{case}_steps_per_s", []).append(
                vector_env_rate(args.num_envs, args.vector_steps, r, env_id=env_id, **settings))
            if args.split:
                split = single_env_split(args.steps, r, env_id, **settings)
                for name in ("reset_share", "decide_share", "us_per_reset", "us_per_step", "steps_per_episode"):
                    runs.setdefault(f"{case}_{name}", []).append(split[name])
                split = vector_env_split(args.num_envs, args.vector_steps, r, env_id=env_id, **settings)
                for name in ("reset_share", "steps_per_s_without_resets", "steps_per_episode", "condense_share",
                             "condensations_per_episode", "us_per_condensation", "params_share"):
                    runs.setdefault(f"vector_{case}_{name}", []).append(split[name])
            if args.peers and case == "env_idm":
                runs.setdefault("sumo_steps_per_s", []).append(sumo_peer.rate(args.steps))
        if args.peers:  # the column case, then cavsandbox on the same work
            runs.setdefault("column_vehicle_steps_per_s", []).append(column_rate())
            if cavsandbox_missing is None:
                runs.setdefault("cavsandbox_column_vehicle_steps_per_s", []).append(cavsandbox_column_rate())
    out = {"num_envs": args.num_envs, "cases": {c: {"id": CASES[c][0], **CASES[c][1]} for c in args.cases}}
    for key, values in runs.items():
        _median(out, key, values)
    if args.peers:
        out["sumo_ratio"] = out["env_idm_steps_per_s"] / out["sumo_steps_per_s"]
        out["sumo_ratio_v1"] = out["env_v1_idm_steps_per_s"] / out["sumo_steps_per_s"]
        out["column_ratio_cavsandbox"] = None
        if cavsandbox_missing is None:
            out["column_ratio_cavsandbox"] = (out["column_vehicle_steps_per_s"]
                                              / out["cavsandbox_column_vehicle_steps_per_s"])
        else:
            out["column_ratio_cavsandbox_reason"] = cavsandbox_missing
    for case in args.cases:  # the typical sensors' and actuators' share of a step, where the ideal case ran too
        base = case[:-len("_typical")] if case.endswith("_typical") else None
        if base in args.cases:
            for prefix in ("", "vector_"):
                out[f"{prefix}{case}_cost"] = 1.0 - out[f"{prefix}{case}_steps_per_s"] / out[f"{prefix}{base}_steps_per_s"]
                # each repeat's typical run against the ideal one timed just before it (the machine's state shared)
                out[f"{prefix}{case}_cost_paired"] = 1.0 - paired_ratio(runs[f"{prefix}{case}_steps_per_s"],
                                                                        runs[f"{prefix}{base}_steps_per_s"])
    if "env" in args.cases:
        out["vector_over_single"] = out["vector_env_steps_per_s"] / out["env_steps_per_s"]
    if args.workers > 1:
        out["workers"] = args.workers
        _median(out, "vector_env_workers_steps_per_s",
                [vector_env_rate(args.num_envs, args.vector_steps, r, workers=args.workers) for r in range(args.repeats)])
    if args.policy:
        cases = [(1, "vector_env_policy_steps_per_s")]
        if args.workers > 1:
            cases.append((args.workers, "vector_env_workers_policy_steps_per_s"))
        for workers, key in cases:
            _median(out, key, [vector_policy_rate(args.num_envs, args.vector_steps, r, workers)
                               for r in range(args.repeats)])
    if args.parallel:
        vector_env_rate(min(args.num_envs, 16), 20, 99, parallel=True)
        _median(out, "vector_env_parallel_steps_per_s",
                [vector_env_rate(args.num_envs, args.vector_steps, r, parallel=True) for r in range(args.repeats)])
    if args.json:
        print(json.dumps(out))
    else:
        for key, value in out.items():
            if key.endswith(("_steps_per_s", "_without_resets")):
                unit = "vehicle-steps/s" if "vehicle_steps" in key else "steps/s"
                print(f"{key:42s} {value:>12,.0f} {unit}  (runs {out[key + '_runs']})")
            elif key.endswith(("_reset_share", "_decide_share")):
                print(f"{key:42s} {value:>12.2f}  (runs {out[key + '_runs']})")
            elif key.endswith(("_us_per_reset", "_us_per_step")):
                print(f"{key:42s} {value:>12.1f} us  (runs {out[key + '_runs']})")
        if "sumo_ratio" in out:
            print(f"acc_gym (IDM drivers) / SUMO (libsumo): {out['sumo_ratio']:.2f}x "
                  f"(SingleLane-v1: {out['sumo_ratio_v1']:.2f}x)")
        if "column_ratio_cavsandbox" in out:
            ratio = out["column_ratio_cavsandbox"]
            print(f"simulate_column (lead + {COLUMN_FOLLOWERS} IDM) / cavsandbox, vehicle-steps/s: "
                  + (f"{ratio:.1f}x" if ratio is not None else f"n/a ({out['column_ratio_cavsandbox_reason']})"))
        if "vector_over_single" in out:
            print(f"vector / single (SingleLane-v0 default): {out['vector_over_single']:.1f}x")
    return out


if __name__ == "__main__":
    main()
