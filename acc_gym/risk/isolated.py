"""The accelerated estimate through the leaderboard's trust boundary (``acc-gym leaderboard --risk``).

The same rounds as :func:`acc_gym.risk.run.estimate_risk` (:func:`acc_gym.risk.run.search`),
but each round's episodes run as leaderboard jobs (:func:`acc_gym.leaderboard.isolation.run_isolated`):
a trusted simulation process steps them and scores them, the controller answers from its
sandbox, and the records come back from the simulation. Everything the estimate rests on
-- the proposal, each episode's parameters, seed and likelihood ratio, the failure flags
-- is made or read in this (trusted) process: the controller only ever sees observations.
A controller that fails (crashes, exceeds its budgets, answers NaN) gets no estimate, and
the reason.

**Preventability** (UN R157; the ``preventable-collision`` event and the split of the
collisions). The simulation process already drives every episode the controller collided in
again with the careful and competent driver (``cc-driver``, trusted code, in that process:
:func:`acc_gym.leaderboard.isolation.preventable`) and puts the verdict in the episode's
record; :func:`isolated_simulator` takes it from there. The controller's sandbox never runs
the re-drive, never sees it, and has no say in it but its own driving (whether it collided):
code it runs in its own process (patching ``cc-driver``, the scorer) changes nothing the
simulation process computes. Decided: no re-drive on this side either -- the simulation
process's verdict is the one the leaderboard's points use, so both agree by construction.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from acc_gym.risk.episodes import draw_episodes, episode_record, performance, preventability_counts
from acc_gym.risk.proposal import DEFENSIVE, Proposal, tilted_keys
from acc_gym.risk.run import EVENTS, env_for, estimate_records, exposure, other_event, resolve_family, search


class RiskFailed(RuntimeError):
    """The controller failed while its risk episodes ran (the reason is the message)."""


def isolated_simulator(reference: str, scenario_id: str, *, root_seed: int = 0, drivers: str = "typical",
                       run_kwargs: dict | None = None):
    """``simulate(round, proposal, size)`` for :func:`~acc_gym.risk.run.search`, running the
    episodes through :func:`~acc_gym.leaderboard.isolation.run_isolated` (``run_kwargs``: its
    budgets, sandbox, log directory, user ids). Each record's ``preventable`` is the simulation
    process's verdict (True / False for a collision, None otherwise)."""
    from acc_gym.leaderboard.isolation import Job, run_isolated
    from acc_gym.scenarios.registry import scenario_type

    stype = scenario_type(scenario_id)
    env_id = env_for(scenario_id)
    kwargs = {"workers": 1, "step_budget": 1.0, "budget": 600.0, **(run_kwargs or {})}

    def simulate(rnd: int, prop: Proposal, size: int) -> list[dict]:
        draws, log_w = draw_episodes(prop, root_seed, rnd, 0, size)
        jobs = [Job("risk", f"round-{rnd}", i, env_id, stype.build(params, seed, drivers))
                for i, (params, _, seed) in enumerate(draws)]
        outcome = run_isolated([reference], jobs, **kwargs)[reference]
        if outcome.status != "ok":
            raise RiskFailed(outcome.reason or "failed")
        by_episode = {r["episode"]: r for r in outcome.episodes}
        return [episode_record(i, draw, log_w[i], by_episode[i]["metrics"], by_episode[i]["score"],
                               _verdict(by_episode[i]))
                for i, draw in enumerate(draws)]

    return simulate


def _verdict(record: dict) -> bool | None:
    """The simulation process's UN R157 verdict on one record: True / False for a collision,
    None without one. A collision without a verdict is a fault of the simulation, named."""
    if not record["metrics"]["collision"]:
        return None
    if not isinstance(record.get("preventable"), bool):
        raise RuntimeError(f"the simulation's record of episode {record.get('episode')!r} collided without a "
                           "preventability verdict")
    return record["preventable"]


def leaderboard_risk(reference: str, family: str = "cut-in", *, budget: int = 4096, target_rhw: float = 0.2,
                     round_size: int = 256, max_rounds: int = 10, root_seed: int = 0,
                     run_kwargs: dict | None = None, event: str = "collision") -> dict:
    """The estimate of ``event`` (default the collision) for ``reference`` on ``family``, JSON-safe,
    for a leaderboard row: ``p``, ``ci_low``, ``ci_high``, ``upper_bound`` (no failure),
    ``episodes``, ``acceleration``, ``stop``, ``family``; or ``{"failed": reason}``.

    ``event``: ``"collision"`` or ``"preventable-collision"`` (UN R157, verdicts from the
    simulation process; see the module docstring). Decided: for the default event the
    dictionary keeps exactly its keys (the leaderboard's stored cell is unchanged; its
    episodes' R157 split is in the suite columns); for ``preventable-collision`` it adds
    ``event``, ``collision_p`` (P(collision) from the same episodes) and the estimation
    episodes' ``preventable_collisions`` / ``non_preventable_collisions``."""
    from acc_gym.scenarios.registry import scenario_type

    if event not in ("collision", "preventable-collision"):
        raise ValueError(f"unknown event {event!r} for the isolated estimate; use one of "
                         f"{sorted(e for e in EVENTS if e != 'ttc')}")
    sid = resolve_family(family)
    stype = scenario_type(sid)
    prop = Proposal(dict(stype.parameters), {k: stype.parameters[k] for k in tilted_keys(stype.parameters)},
                    DEFENSIVE)
    simulate = isolated_simulator(reference, sid, root_seed=root_seed, run_kwargs=run_kwargs)
    try:
        _, pooled, rounds, stop = search(prop, simulate, functools.partial(performance, event=event), event=event,
                                         budget=budget, round_size=round_size, max_rounds=max_rounds,
                                         target_rhw=target_rhw)
    except RiskFailed as exc:
        return {"family": family, "scenario_id": sid, "failed": str(exc)}
    spent = sum(r["episodes"] for r in rounds)
    s = performance(pooled)
    d = estimate_records(pooled, performance(pooled, event), event, spent, exposure(rounds)).to_dict()
    out = {"family": family, "scenario_id": sid, "p": d["p"], "ci_low": d["ci_low"], "ci_high": d["ci_high"],
           "upper_bound": d["upper_bound"], "failures": d["failures"], "episodes": spent,
           "acceleration": d["acceleration"], "stop": stop, "warnings": d["warnings"],
           "min_ttc": float(np.min(s)) if s.size and math.isfinite(float(np.min(s))) else None}
    if event != "collision":
        second = other_event(event)
        k, m = preventability_counts(pooled)
        out.update(event=event, collision_p=estimate_records(pooled, performance(pooled, second), second, spent,
                                                             exposure(rounds)).p,
                   preventable_collisions=k, non_preventable_collisions=m)
    return out


def format_risk(risk: dict | None) -> str:
    """A leaderboard cell: ``4.0e-03 [3.3e-03, 4.6e-03]``, ``< 3.7e-04`` (no collision) or ``failed``."""
    if not risk:
        return "-"
    if "failed" in risk:
        return "failed"
    if risk["failures"] == 0:
        return f"< {risk['upper_bound']:.1e}"
    return f"{risk['p']:.1e} [{risk['ci_low']:.1e}, {risk['ci_high']:.1e}]"
