"""Compile the simulation's numba kernels once, in parallel, before the controllers start.

Every kernel is compiled with ``cache=True``, so a run loads what an earlier run compiled.
On a machine's first run nothing is cached, and each simulation process (one per
controller, ``workers`` at a time) would compile the same kernels at the same time: the
work of one compile done ``workers`` times over, on a machine with as many cores. So
:func:`warm_kernels` compiles them first, split into independent parts run side by side
in ``processes`` spawned processes, started as the simulations are
(:func:`acc_gym.leaderboard.isolation.trusted_start`; trusted code only, no controller):

* ``"score"`` -- the episode score (:func:`acc_gym.evaluation.scoring.score_record` on a
  record laid out as the environments keep theirs: a scene's slice of a
  ``(columns, scenes, steps)`` array);
* one part per environment id -- its :class:`~acc_gym.leaderboard.batch.BatchRuns` of
  the simulation's row count, stepped until an episode ends (the environment, the world,
  the surrounding drivers, the scenario generator);
* ``"single"`` -- one episode of the careful driver in a single environment (what the
  preventability check and the report's re-run take).

The parts share some callees, so the split is not perfectly disjoint; what each compiles
goes to the same cache the simulations then read (``NUMBA_CACHE_DIR`` or the package's
``__pycache__``). With everything cached the parts only load, in about a second each.
:func:`needs_compiling` tells, without compiling, whether the cache lacks the score
kernel's entry (the notice the CLI prints).
"""

from __future__ import annotations

import multiprocessing
import os

SCORE = "score"
SINGLE = "single"


def _score_part() -> None:
    import numpy as np

    from acc_gym.evaluation.scoring import _ARRAY_COLUMNS, score_record

    steps = 50
    arr = np.zeros((len(_ARRAY_COLUMNS), 2, steps))  # (columns, scenes, steps), as the environments keep it
    cols = {name: k for k, name in enumerate(_ARRAY_COLUMNS)}
    arr[cols["t"]] = np.arange(steps) * 0.1
    arr[cols["v"]] = 20.0
    arr[cols["gap"]] = 40.0
    arr[cols["v_lead"]] = 20.0
    arr[cols["lead_id"]] = 1.0
    for name in ("d2", "d3"):
        if name in cols:
            arr[cols[name]] = 1.0
    score_record(arr[:, 0], steps, 25.0, 1.5, None)
    score_record(arr[:, 0], steps, None, None, None)


def _env_part(env_id: str, rows: int) -> None:
    import gymnasium as gym
    import numpy as np

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.leaderboard.batch import BatchRuns
    from acc_gym.suites import get_suite, list_suites

    scenarios = [sc for name in list_suites() if get_suite(name).env_id == env_id
                 for sc in get_suite(name).episodes("dev")][:rows]
    if not scenarios:
        return
    batch = BatchRuns(gym.make(env_id).unwrapped, len(scenarios))
    batch.start_many(range(len(scenarios)), scenarios)
    rows_all = np.arange(batch.n)
    actions = np.zeros(batch.n, dtype=np.float32)
    for _ in range(100_000):  # until the first episode ends (its score, the row's idling)
        ended = batch.step(rows_all, actions)
        if ended:
            batch.idle_many(list(ended))
            return


def _single_part() -> None:
    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller, run_episode
    from acc_gym.standards.r157 import ENV_ID, REFERENCE
    from acc_gym.suites import get_suite

    env = gym.make(ENV_ID)
    sc = get_suite("ncap-v2").episodes("dev")[0]
    run_episode(env, load_controller(REFERENCE), scenario=sc, record=True)
    env.close()


def run_part(part) -> None:
    """Compile (or load) one part (see the module docstring): ``"score"``, ``"single"`` or
    ``(env_id, rows)``."""
    import warnings

    warnings.filterwarnings("ignore", category=DeprecationWarning)
    warnings.filterwarnings("ignore", message=".*is out of date")
    if part == SCORE:
        _score_part()
    elif part == SINGLE:
        _single_part()
    else:
        _env_part(*part)


def needs_compiling() -> bool:
    """Whether the score kernel has no cached code for this interpreter yet (a first run):
    looks at numba's cache index, compiles nothing."""
    try:
        from acc_gym.evaluation import _score_kernel as K

        return not os.path.exists(K.score_record._cache._cache_file._index_path)
    except Exception:  # noqa: BLE001  (numba's private layout changed: say nothing rather than guess)
        return False


def warm_kernels(env_rows: dict, processes: int = 2) -> None:
    """Compile (or load) the kernels of the environments of ``env_rows`` (``{env_id: rows}``:
    each stepped with as many rows as the simulation steps it with), the score and the single
    environment, in ``processes`` spawned processes side by side. An error in a part is raised."""
    parts = [SCORE, *env_rows.items(), SINGLE]
    if processes <= 1:
        for part in parts:
            run_part(part)
        return
    import shutil
    import tempfile

    from acc_gym.leaderboard.isolation import START_METHOD, trusted_start

    ctx = multiprocessing.get_context(START_METHOD)
    empty = tempfile.mkdtemp(prefix="acc-gym-warmup-")
    try:
        with trusted_start(empty):  # started as the simulations are: nothing of the working directory's imports
            pool = ctx.Pool(min(processes, len(parts)))
        with pool:
            pool.map(run_part, parts, chunksize=1)
    finally:
        shutil.rmtree(empty, ignore_errors=True)
