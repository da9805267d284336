"""What a worker does: run one chunk of a campaign's episodes and return their rows.

:func:`run_chunk` is a top-level function of a plain task (picklable), so it runs alike in
the calling process, a local process pool or on a Dask worker. It returns the rows rather
than writing them: the process that drives the campaign writes each chunk's file, so
Dask workers need no shared filesystem and a retried task cannot leave a half-written file.

Every chunk makes its own environment and controller, so a chunk's rows depend only on
the chunk (never on what the same worker ran before) -- results are the same with any
number of workers, in any order.

**Preventability** (UN R157, :mod:`acc_gym.standards.r157`): each episode the controller
collided in is driven again by the careful and competent driver (the built-in
``cc-driver``) -- the same scenario (rebuilt by :func:`~acc_gym.campaigns.plan.scenario_at`
from its index: same parameters, scenario seed and traffic) with the same reset seed, in an
environment and a cc-driver of the chunk's own, not the controller's -- and the row's
``preventable`` says whether the collision was preventable (True: cc-driver does not
collide) or not (False); null without a collision. Only collided episodes are re-driven, so
a campaign without collisions costs what it did. The re-drive is a pure function of the
episode's index, so a resumed campaign's rows are an uninterrupted one's. Decided: one
single-environment episode per collision (:func:`acc_gym.evaluation.runner.run_episode`,
as ``acc-gym evaluate`` does), not a batch: campaign chunks run single environments too, and
collisions are rare in a campaign's traffic.

**Schema version.** The ``preventable`` column (added in campaign format
``acc_gym.campaign/2``, :data:`acc_gym.campaigns.manifest.FORMAT`) changes the chunk files'
schema, which readers check exactly (:mod:`acc_gym.campaigns.store`); the format is pinned in
the fingerprint, so a ``/1`` campaign is refused as one of an older version, never mixed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from acc_gym.campaigns.plan import Chunk, resolve_suite, scenario_at, seed_for

# (column, Arrow type name, nullable, meaning); the Parquet schema of every chunk file.
COLUMNS = (
    ("index", "int64", False, "scenario index in the campaign"),
    ("scenario_id", "string", False, "scenario type id, e.g. singlelane/2/cut-in"),
    ("scenario_seed", "int64", False, "the Scenario's own seed"),
    ("seed", "int64", False, "the episode's reset seed: seed_for(index, root_seed)"),
    ("duration", "float64", False, "[s] the scenario's duration (its share of the simulated traffic)"),
    ("simulated", "float64", False, "[s] time actually simulated (shorter if the episode ended early)"),
    ("score", "float64", False, "paper 003's 100-point score"),
    ("qualified", "bool_", False, "all four qualitative items qualified"),
    ("r1", "float64", False, "efficiency points"),
    ("r2", "float64", False, "comfort points"),
    ("collision", "bool_", False, "the gap to the vehicle ahead reached 0"),
    ("preventable", "bool_", True, "UN R157: the careful and competent driver (cc-driver) avoids this collision in "
                                   "the same scenario (null: no collision)"),
    ("share_comfortable", "float64", False, "share of samples with comfortable acceleration"),
    ("share_safe_spacing", "float64", True, "share of samples with a vehicle ahead where Q >= 0 (null: never one)"),
    ("min_ttc", "float64", False, "[s] smallest time-to-collision (inf: never closing in)"),
    ("max_jerk", "float64", False, "[m/s^3] largest |jerk|"),
    ("min_gap", "float64", False, "[m] smallest gap (inf: never a vehicle ahead)"),
    ("speed_overshoot", "float64", True, "largest relative speed overshoot after a lead transient (null: none)"),
    ("damping_ratio", "float64", True, "damping ratio of that overshoot (null: no transient)"),
    ("transients", "int64", False, "lead transients evaluated for the overshoot"),
)
COLUMN_NAMES = tuple(c[0] for c in COLUMNS)


@dataclass(frozen=True)
class ChunkTask:
    """Everything a worker needs to run one chunk."""

    suite: object  # a suite name (resolved on the worker) or a picklable suite object
    split: str
    root_seed: int
    controller: str
    env_id: str
    chunk: Chunk


def _number(x, nullable: bool):
    """A metric from ``EpisodeReport.to_dict`` (NaN as None, inf as the string "inf") as a float."""
    if x is None:
        if nullable:
            return None
        raise ValueError("a required episode metric is missing (None)")
    if isinstance(x, str):
        return float(x)  # "inf" / "-inf"
    x = float(x)
    if math.isnan(x):
        if nullable:
            return None
        raise ValueError("a required episode metric is NaN")
    return x


def row_from_info(index: int, seed: int, scenario, info: dict, preventable: bool | None = None) -> dict:
    """One result row from an episode's final ``info``; ``preventable``: the UN R157 verdict on
    its collision (required with a collision, None without one)."""
    report = info["report"]
    m = report["metrics"]
    if bool(m["collision"]) != (preventable is not None):
        raise ValueError(f"scenario index {index}: a collision needs a preventability verdict and only a collision "
                         f"has one (collision {bool(m['collision'])}, preventable {preventable!r})")
    return {
        "index": int(index), "scenario_id": str(scenario.id), "scenario_seed": int(scenario.seed), "seed": int(seed),
        "duration": float(scenario.duration), "simulated": _number(m["duration"], False),
        "score": _number(report["score"], False), "qualified": bool(report["qualified"]),
        "r1": _number(report["r1"], False), "r2": _number(report["r2"], False),
        "collision": bool(m["collision"]), "preventable": None if preventable is None else bool(preventable),
        "share_comfortable": _number(m["share_comfortable"], False),
        "share_safe_spacing": _number(m["share_safe_spacing"], True), "min_ttc": _number(m["min_ttc"], False),
        "max_jerk": _number(m["max_jerk"], False), "min_gap": _number(m["min_gap"], False),
        "speed_overshoot": _number(m["speed_overshoot"], True), "damping_ratio": _number(m["damping_ratio"], True),
        "transients": int(m["transients"]),
    }


def run_chunk(task: ChunkTask) -> list[dict]:
    """Run the chunk's episodes (in index order) and return one row per episode (a collision's
    with cc-driver's verdict, see the module docstring)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import load_controller, run_episode
    from acc_gym.standards.r157 import REFERENCE

    suite = resolve_suite(task.suite)
    if hasattr(suite, "run_chunk"):  # an OpenSCENARIO variation runs its files (acc_gym.campaigns.sweep)
        return suite.run_chunk(task)
    controller = load_controller(task.controller)
    env = gym.make(task.env_id)
    judge: dict = {}  # the careful driver's env and controller, made at the chunk's first collision
    rows = []
    try:
        for i in task.chunk.indices:
            scenario = scenario_at(suite, i, task.split, task.root_seed)
            seed = seed_for(i, task.root_seed)
            info, _ = run_episode(env, controller, seed=seed, scenario=scenario, record=False)
            preventable = None
            if info["report"]["metrics"]["collision"]:
                if not judge:
                    judge.update(env=gym.make(task.env_id), cc=load_controller(REFERENCE))
                again = scenario_at(suite, i, task.split, task.root_seed)  # nothing the controller's run touched
                cc_info, _ = run_episode(judge["env"], judge["cc"], seed=seed, scenario=again, record=False)
                preventable = not cc_info["report"]["metrics"]["collision"]
            rows.append(row_from_info(i, seed, scenario, info, preventable))
    finally:
        env.close()
        if judge:
            judge["env"].close()
    return rows
