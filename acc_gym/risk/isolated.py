"""The accelerated estimate through the leaderboard's trust boundary (``acc-gym leaderboard --risk``).

The same rounds as :func:`acc_gym.risk.run.estimate_risk` (:func:`acc_gym.risk.run.search`),
but each round's episodes run as leaderboard jobs (:func:`acc_gym.leaderboard.isolation.run_isolated`):
a trusted simulation process steps them and scores them, the controller answers from its
sandbox, and the records come back from the simulation. Everything the estimate rests on
-- the proposal, each episode's parameters, seed and likelihood ratio, the failure flags
-- is made or read in this (trusted) process: the controller only ever sees observations.
A controller that fails (crashes, exceeds its budgets, answers NaN) gets no estimate, and
the reason.
"""

from __future__ import annotations

import math

import numpy as np

from acc_gym.risk.episodes import draw_episodes, episode_record, performance
from acc_gym.risk.proposal import DEFENSIVE, Proposal, tilted_keys
from acc_gym.risk.run import env_for, estimate_records, exposure, resolve_family, search


class RiskFailed(RuntimeError):
    """The controller failed while its risk episodes ran (the reason is the message)."""


def isolated_simulator(reference: str, scenario_id: str, *, root_seed: int = 0, drivers: str = "typical",
                       run_kwargs: dict | None = None):
    """``simulate(round, proposal, size)`` for :func:`~acc_gym.risk.run.search`, running the
    episodes through :func:`~acc_gym.leaderboard.isolation.run_isolated` (``run_kwargs``: its
    budgets, sandbox, log directory, user ids)."""
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
        return [episode_record(i, draw, log_w[i], by_episode[i]["metrics"], by_episode[i]["score"])
                for i, draw in enumerate(draws)]

    return simulate


def leaderboard_risk(reference: str, family: str = "cut-in", *, budget: int = 4096, target_rhw: float = 0.2,
                     round_size: int = 256, max_rounds: int = 10, root_seed: int = 0,
                     run_kwargs: dict | None = None) -> dict:
    """The collision estimate of ``reference`` on ``family``, JSON-safe, for a leaderboard row:
    ``p``, ``ci_low``, ``ci_high``, ``upper_bound`` (no collision), ``episodes``,
    ``acceleration``, ``stop``, ``family``; or ``{"failed": reason}``."""
    from acc_gym.scenarios.registry import scenario_type

    sid = resolve_family(family)
    stype = scenario_type(sid)
    prop = Proposal(dict(stype.parameters), {k: stype.parameters[k] for k in tilted_keys(stype.parameters)},
                    DEFENSIVE)
    simulate = isolated_simulator(reference, sid, root_seed=root_seed, run_kwargs=run_kwargs)
    try:
        _, pooled, rounds, stop = search(prop, simulate, performance, budget=budget, round_size=round_size,
                                         max_rounds=max_rounds, target_rhw=target_rhw)
    except RiskFailed as exc:
        return {"family": family, "scenario_id": sid, "failed": str(exc)}
    spent = sum(r["episodes"] for r in rounds)
    s = performance(pooled)
    d = estimate_records(pooled, s, "collision", spent, exposure(rounds)).to_dict()
    return {"family": family, "scenario_id": sid, "p": d["p"], "ci_low": d["ci_low"], "ci_high": d["ci_high"],
            "upper_bound": d["upper_bound"], "failures": d["failures"], "episodes": spent,
            "acceleration": d["acceleration"], "stop": stop, "warnings": d["warnings"],
            "min_ttc": float(np.min(s)) if s.size and math.isfinite(float(np.min(s))) else None}


def format_risk(risk: dict | None) -> str:
    """A leaderboard cell: ``4.0e-03 [3.3e-03, 4.6e-03]``, ``< 3.7e-04`` (no collision) or ``failed``."""
    if not risk:
        return "-"
    if "failed" in risk:
        return "failed"
    if risk["failures"] == 0:
        return f"< {risk['upper_bound']:.1e}"
    return f"{risk['p']:.1e} [{risk['ci_low']:.1e}, {risk['ci_high']:.1e}]"
