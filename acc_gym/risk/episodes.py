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

**Preventability** (UN R157, :mod:`acc_gym.standards.r157`; a chunk with ``preventability``
set, as the ``collision`` and ``preventable-collision`` events make them): after the
controller's batch, the episodes it collided in are driven again by the careful and
competent driver (the built-in ``cc-driver``, loaded afresh by name) -- the same scenarios
(same parameters, scenario seed and surrounding drivers), rebuilt from their draws, as the
rows of a second, fresh :class:`~acc_gym.leaderboard.batch.BatchRuns` -- and each record
says whether the collision was ``preventable`` (the C&C driver does not collide). Decided:
batched, not one :func:`acc_gym.standards.r157.collides` per episode -- the same verdicts
(a batch's rows step exactly as single environments do; ``tests/risk/test_preventable.py``
checks the verdicts against single environments) at about a tenth of the cost, which
keeps the re-drive cheap when most of an importance-sampling round collides. Only
collided episodes are re-driven. The controller takes no part in the re-drive: its only
say in the verdict is its own driving (whether it collided). Run in-process, its code shares the process with the re-drive, as it shares it
with the simulator -- the in-process tool trusts the controller it is given; for a
stranger's controller use the leaderboard's isolation (:mod:`acc_gym.risk.isolated`), where
the re-drive happens in the trusted simulation process.
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
    preventability: bool = False  # re-drive the collided episodes with cc-driver (UN R157)


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


def episode_record(episode: int, draw: tuple, log_w: float, metrics: dict, score: float,
                   preventable: bool | None = None) -> dict:
    """What a risk run keeps of one episode: its draw and its outcome (the report's metrics);
    ``preventable``: whether UN R157's careful driver avoids its collision (None: no collision,
    or not judged)."""
    params, nominal, seed = draw
    return {"episode": episode, "params": params, "nominal": nominal, "seed": seed, "log_w": float(log_w),
            "collision": bool(metrics["collision"]), "min_ttc": float(metrics["min_ttc"]),
            "min_gap": float(metrics["min_gap"]), "score": float(score),
            "preventable": None if preventable is None or not metrics["collision"] else bool(preventable)}


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


def drive(env_id: str, controller, scenarios: list) -> list[dict]:
    """The final infos of ``scenarios`` driven by ``controller`` (loaded), in order, as the rows
    of one fresh :class:`~acc_gym.leaderboard.batch.BatchRuns` of ``env_id``."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import declared_time_gap
    from acc_gym.leaderboard.batch import BatchRuns

    n = len(scenarios)
    if n == 0:
        return []
    vectorised = bool(getattr(controller, "vectorised", False))
    batch = BatchRuns(gym.make(env_id).unwrapped, n)
    batch.start_many(range(n), scenarios, declared_time_gap(controller))
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
    return [finals[row] for row in range(n)]


def cc_driver_collides(env_id: str, scenarios: list) -> list[bool]:
    """Whether UN R157's careful and competent driver (the built-in ``cc-driver``, loaded afresh)
    collides in each of ``scenarios`` (built), run as the rows of one batch of ``env_id``."""
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.standards.r157 import REFERENCE

    if not scenarios:
        return []
    return [bool(f["report"]["metrics"]["collision"]) for f in drive(env_id, load_controller(REFERENCE), scenarios)]


def run_chunk(chunk: RiskChunk) -> list[dict]:
    """The chunk's episodes, in order: each a dict of its draw (``params``, ``nominal``,
    ``seed``, ``log_w``) and its outcome (``collision``, ``min_ttc`` [s] (``inf``: never
    closing in), ``min_gap`` [m], ``score``, ``preventable``: True / False for a collision
    when the chunk judges ``preventability``, else None)."""
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.scenarios.registry import scenario_type

    stype = scenario_type(chunk.scenario_id)
    proposal = Proposal.from_dict(stype.parameters, chunk.proposal)
    controller = load_controller(chunk.controller)
    draws, log_w = draw_episodes(proposal, chunk.root_seed, chunk.round, chunk.start, chunk.size)
    fixed = dict(chunk.fixed or {})

    def build(draw):
        params, _, seed = draw
        return stype.build({**fixed, **params}, seed, chunk.drivers)

    finals = drive(chunk.env_id, controller, [build(d) for d in draws])
    verdicts: list = [None] * len(draws)
    if chunk.preventability:
        hit = [k for k, f in enumerate(finals) if f["report"]["metrics"]["collision"]]
        # rebuilt from the draws: nothing the controller's batch touched is reused
        for k, cc_hit in zip(hit, cc_driver_collides(chunk.env_id, [build(draws[k]) for k in hit])):
            verdicts[k] = not cc_hit
    return [episode_record(chunk.start + row, draw, log_w[row], finals[row]["report"]["metrics"],
                           finals[row]["score"], verdicts[row]) for row, draw in enumerate(draws)]


def performance(records: list[dict], event: str = "collision") -> np.ndarray:
    """The cross-entropy performance ``S`` of each episode for ``event`` (smaller is more
    dangerous; the event is ``S <= 0`` for the collision events, ``S < 1 s`` for ``ttc``):
    its smallest time-to-collision [s] (``inf`` when never closing in), 0 for a collision.

    For ``preventable-collision``, 0 for a preventable collision and ``inf`` for a
    non-preventable one. Decided: a collision the careful driver has too is no failure of
    this event, and its time-to-collision (0) says nothing about how near a preventable one
    it was, so it counts as uninformative (``inf``, like never closing in): the
    cross-entropy rounds tilt towards the controller's near misses and its preventable
    collisions, not towards cut-ins nobody survives. Any ``S`` keeps the estimate unbiased;
    it only steers the proposal. A record whose collision was not judged
    (``preventable`` None) is refused for this event."""
    if event != "preventable-collision":
        return np.array([0.0 if r["collision"] else (r["min_ttc"] if math.isfinite(r["min_ttc"]) else math.inf)
                         for r in records])
    out = np.empty(len(records))
    for k, r in enumerate(records):
        if r["collision"]:
            if r.get("preventable") is None:
                raise ValueError(f"episode {r.get('episode')!r} collided but its preventability was not judged "
                                 "(no cc-driver re-drive): cannot count a preventable collision")
            out[k] = 0.0 if r["preventable"] else math.inf
        else:
            out[k] = r["min_ttc"] if math.isfinite(r["min_ttc"]) else math.inf
    return out


def preventability_counts(records: list[dict]) -> tuple[int, int]:
    """``(preventable, non-preventable)`` collisions among ``records`` (plain counts, unweighted)."""
    return (sum(r["collision"] and r.get("preventable") is True for r in records),
            sum(r["collision"] and r.get("preventable") is False for r in records))
