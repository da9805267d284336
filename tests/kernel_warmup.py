"""Compile the package's numba kernels once before pytest-xdist's workers start (tests/conftest.py).

Every kernel is compiled with ``cache=True``. In a fresh install (CI) nothing is cached, and
each worker would compile the same kernels at the same time, the work of one compile done
once per worker. :func:`warm` compiles them first, in parts side by side (the leaderboard's
parts, :mod:`acc_gym.leaderboard.warmup`, plus the ``-v1`` ids, the ring and the MPC column),
so the workers load them. With everything cached it does nothing.
"""

from __future__ import annotations

V0_ROWS = {"acc_gym/SingleLane-v0": 4, "acc_gym/CarFollowing-v0": 4, "acc_gym/NCAP-v0": 4}
V1_IDS = ("acc_gym/SingleLane-v1", "acc_gym/CarFollowing-v1", "acc_gym/NCAP-v1", "acc_gym/StopAndGo-v1")


def _v1_part(env_id: str) -> None:
    import gymnasium as gym
    import numpy as np

    import acc_gym  # noqa: F401  (registers the ids)

    for kwargs in ({}, {"drivers": "idm"}, {"sensors": "typical", "actuators": "typical"},
                   {"scenario_generator": "counter"}):
        env = gym.make(env_id, **kwargs)
        env.reset(seed=0)
        for _ in range(300):
            _, _, term, trunc, _ = env.step(np.zeros(1, dtype=np.float32))
            if term or trunc:
                break
        env.close()
    vec = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    for _ in range(20):
        vec.step(np.zeros((2, 1), dtype=np.float32))
    vec.close()


def _ring_part() -> None:
    import numpy as np

    from acc_gym.drivers.baselines import IDM, IDMParams
    from acc_gym.drivers.mpc import MPCDriver
    from acc_gym.drivers.population import sample_drivers
    from acc_gym.simulation.profiles import SpeedProfile
    from acc_gym.simulation.ring import simulate_ring
    from acc_gym.simulation.rollout import simulate_column

    simulate_ring(230.0, 22, seeds=[0], duration=60.0)
    params = sample_drivers(np.random.default_rng(0), 2, np.full(2, 12.0))
    lead = SpeedProfile.from_segments(12.0, [(0.0, 20.0)])
    simulate_column(lead, [MPCDriver(params), IDM(IDMParams(), n=2)],
                    np.array([[60.0, 30.0, 0.0], [60.0, 30.0, 0.0]]), np.full((2, 3), 12.0), duration=20.0, batch=2)


def run(part) -> None:
    """One part: the leaderboard's (``"score"``, ``"single"``, ``(env_id, rows)``), ``("v1", id)`` or ``"ring"``."""
    import warnings

    warnings.filterwarnings("ignore")
    if part == "ring":
        _ring_part()
    elif isinstance(part, tuple) and part[0] == "v1":
        _v1_part(part[1])
    else:
        from acc_gym.leaderboard.warmup import run_part

        run_part(part)


def warm(processes: int = 2) -> None:
    """Compile (or load) every part in ``processes`` spawned processes when the cache lacks the
    score kernel (:func:`acc_gym.leaderboard.warmup.needs_compiling`); else nothing."""
    import multiprocessing

    from acc_gym.leaderboard.warmup import SCORE, SINGLE, needs_compiling

    if not needs_compiling():
        return
    parts = [SCORE, *V0_ROWS.items(), SINGLE, *(("v1", e) for e in V1_IDS), "ring"]
    with multiprocessing.get_context("spawn").Pool(processes) as pool:
        pool.map(run, parts, chunksize=1)
