"""Run a chunk of risk episodes: draw each episode's parameters, build it, simulate it in a batch.

A :class:`RiskChunk` is self-contained and picklable (a local process pool or a Dask
worker runs it): the scenario type, the proposal, the controller reference, which round
and which episode numbers. Episode ``i`` of round ``r`` draws from its own generator
``default_rng([root_seed, r, i])`` -- whether it takes the nominal component, its tilted
parameters, then its scenario seed (the untilted parameters and the surrounding drivers
come from the scenario's own generators, :func:`acc_gym.scenarios.registry.scenario_rngs`)
-- so an episode is the same however the episodes are split among chunks and workers.

The chunk's episodes start together as the rows of one
:class:`~acc_gym.leaderboard.batch.BatchRuns` (the compiled world, every surrounding
driver of every row in one call per step) and each row runs until its episode ends
(collision or duration); rows that end early idle. The controller is asked once per step:

* a **vectorised** controller (its ``vectorised`` attribute is true: the built-ins, the
  shipped policies, stable-baselines3 models loaded by acc-gym) gets the whole
  ``(rows, obs)`` array in one ``predict`` call, the idle rows included so that its
  input keeps one shape;
* any other controller gets one copy per row (``copy.deepcopy`` of the loaded one,
  ``reset()`` at its episode's start), called one observation at a time, as the
  leaderboard calls it -- slower, the same episodes.

Chunks have a fixed size, so the batch each episode runs in never depends on the number of
workers: results are the same on 1 worker or 16. The controller runs in this process (the
risk tool evaluates your own controller; the leaderboard's sandbox is for strangers').
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from acc_gym.risk.proposal import Proposal

CHUNK = 64  # episodes per chunk (one batch)


@dataclass(frozen=True)
class RiskChunk:
    """Episodes ``start .. start + size - 1`` of round ``round`` of a risk run."""

    scenario_id: str
    proposal: dict  # Proposal.to_dict()
    controller: object  # a reference (name, module:attr, path) or, in-process only, an object
    root_seed: int
    round: int
    start: int
    size: int
    env_id: str
    drivers: str = "typical"
    number: int = 0  # the chunk's number within its round (a key for backends and files)
    fixed: dict | None = None  # parameters held at given values (not drawn, not weighted)


def episode_draw(proposal: Proposal, root_seed: int, rnd: int, i: int) -> tuple[dict, bool, int]:
    """Episode ``i`` of round ``rnd``: its tilted parameters, whether the nominal component
    drew them, and its scenario seed."""
    rng = np.random.default_rng([int(root_seed), int(rnd), int(i)])
    params, nominal = proposal.sample(rng)
    seed = int(rng.integers(0, 2 ** 31 - 1))
    return params, nominal, seed


def draw_episodes(proposal: Proposal, root_seed: int, rnd: int, start: int, n: int) -> tuple[list, np.ndarray]:
    """Episodes ``start .. start + n - 1`` of round ``rnd``: their draws (:func:`episode_draw`)
    and their log-weights."""
    draws = [episode_draw(proposal, root_seed, rnd, start + k) for k in range(n)]
    return draws, proposal.log_weight({name: np.array([d[0][name] for d in draws]) for name in proposal.names})


def episode_record(episode: int, draw: tuple, log_w: float, metrics: dict, score: float) -> dict:
    """What a risk run keeps of one episode: its draw and its outcome (the report's metrics)."""
    params, nominal, seed = draw
    return {"episode": episode, "params": params, "nominal": nominal, "seed": seed, "log_w": float(log_w),
            "collision": bool(metrics["collision"]), "min_ttc": float(metrics["min_ttc"]),
            "min_gap": float(metrics["min_gap"]), "score": float(score)}


def _actions(controller, vectorised: bool, copies: list, obs: np.ndarray, starts: np.ndarray,
             rows: np.ndarray) -> np.ndarray:
    from acc_gym.evaluation.runner import _action, as_action

    if vectorised:
        out = np.asarray(_action(controller, obs), dtype=float).reshape(-1)
        if out.shape != (obs.shape[0],):
            raise ValueError(f"controller {controller!r} answered {obs.shape[0]} observations with an array of "
                             f"{out.size} values")
        bad = ~np.isfinite(out[rows])
        if bad.any():
            raise ValueError(f"controller {controller!r} returned an action that is not finite: "
                             f"{float(out[rows][bad][0])!r}")
        return np.clip(out[rows], -1.0, 1.0).astype(np.float32)
    acts = np.empty(rows.size, dtype=np.float32)
    for j, r in enumerate(rows):
        if starts[r] and hasattr(copies[r], "reset"):
            copies[r].reset()
        acts[j] = as_action(_action(copies[r], obs[r]), copies[r])[0]
    return acts


def run_chunk(chunk: RiskChunk) -> list[dict]:
    """The chunk's episodes, in order: each a dict of its draw (``params``, ``nominal``,
    ``seed``, ``log_w``) and its outcome (``collision``, ``min_ttc`` [s] (``inf``: never
    closing in), ``min_gap`` [m], ``score``)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import declared_time_gap, load_controller
    from acc_gym.leaderboard.batch import BatchRuns
    from acc_gym.scenarios.registry import scenario_type

    stype = scenario_type(chunk.scenario_id)
    proposal = Proposal.from_dict(stype.parameters, chunk.proposal)
    controller = load_controller(chunk.controller)
    vectorised = bool(getattr(controller, "vectorised", False))
    declared = declared_time_gap(controller)
    n = chunk.size
    draws, log_w = draw_episodes(proposal, chunk.root_seed, chunk.round, chunk.start, n)
    batch = BatchRuns(gym.make(chunk.env_id).unwrapped, n)
    fixed = dict(chunk.fixed or {})
    batch.start_many(range(n), [stype.build({**fixed, **params}, seed, chunk.drivers) for params, _, seed in draws],
                     declared)
    copies = [] if vectorised else [copy.deepcopy(controller) for _ in range(n)]
    starts = np.ones(n, dtype=bool)
    finals: dict[int, dict] = {}
    while len(finals) < n:
        rows = np.flatnonzero(batch.active)
        acts = _actions(controller, vectorised, copies, batch.obs.astype(float), starts, rows)
        starts[:] = False
        ended = batch.step(rows, acts)
        finals.update(ended)
        if ended:
            batch.idle_many(sorted(ended))
    return [episode_record(chunk.start + row, draw, log_w[row], finals[row]["report"]["metrics"],
                           finals[row]["score"]) for row, draw in enumerate(draws)]


def performance(records: list[dict]) -> np.ndarray:
    """The cross-entropy performance ``S`` of each episode: its smallest time-to-collision
    [s], 0 for a collision (smaller is more dangerous; ``inf`` when never closing in)."""
    return np.array([0.0 if r["collision"] else (r["min_ttc"] if math.isfinite(r["min_ttc"]) else math.inf)
                     for r in records])
