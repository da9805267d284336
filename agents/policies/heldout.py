"""Score controllers on held-out seeds, per scenario family: the shipped policy's bar.

    python -m acc_gym_agents.policies.heldout                      # ppo-acc and acc
    python -m acc_gym_agents.policies.heldout --controllers ppo-acc acc cacc mp-cacc idm gipps gm fuzzy mpc constant \
        --json agents/policies/ppo_acc/heldout.json        # the README table (~2.5 min)

Families: paper 003's car-following test at 60, 90 and 120 km/h
(``acc_gym/CarFollowing-v0`` restricted to one speed each) and paper 004's single-lane
generator (``acc_gym/SingleLane-v0``). Every controller sees the same episodes: each
family's environment is reset once with ``--seed`` and then runs ``--episodes`` episodes
(the single-lane family ``--singlelane-episodes``). The default seed, 20261122, was
never used in training (training seeds are ``seed + env index`` and evaluation seeds
``seed + 1_000_003`` for run seeds below 1000).

A policy meets the shipping bar (issue 5) when, over all these episodes, it is qualified
in at least 90 % of each family's episodes, never collides and beats the linear ACC's
mean score in every family; :func:`meets_bar` checks it.
"""

from __future__ import annotations

import argparse
import json
import time

from acc_gym._io import atomic_write, json_safe

SEED = 20261122
FAMILIES = {  # name -> (env id, scenario ids)
    "car-following 60 km/h": ("acc_gym/CarFollowing-v0", ("carfollowing/60",)),
    "car-following 90 km/h": ("acc_gym/CarFollowing-v0", ("carfollowing/90",)),
    "car-following 120 km/h": ("acc_gym/CarFollowing-v0", ("carfollowing/120",)),
    "single-lane": ("acc_gym/SingleLane-v0", None),
}
BAR_QUALIFIED = 0.9


def heldout(controllers, episodes: int = 40, singlelane_episodes: int = 400, seed: int = SEED) -> dict:
    """``{controller: {family: summary}}`` (summaries of :func:`acc_gym.evaluation.runner.evaluate`)."""
    from acc_gym.evaluation.runner import evaluate

    out = {}
    for name in controllers:
        out[name] = {}
        for family, (env_id, scenarios) in FAMILIES.items():
            n = singlelane_episodes if scenarios is None else episodes
            kwargs = {} if scenarios is None else {"scenarios": scenarios}
            summary = evaluate(name, env_id, episodes=n, seed=seed, **kwargs)
            out[name][family] = {k: v for k, v in summary.items() if k not in ("scores", "scenarios")}
    return out


def meets_bar(results: dict, policy: str, baseline: str = "acc") -> list[str]:
    """The ways ``policy`` misses the shipping bar (empty: it meets it)."""
    misses = []
    for family, s in results[policy].items():
        if s["share_qualified"] < BAR_QUALIFIED:
            misses.append(f"{family}: qualified {s['share_qualified']:.1%} < {BAR_QUALIFIED:.0%}")
        if s["collisions"]:
            misses.append(f"{family}: {s['collisions']} collisions")
        if baseline in results and s["mean_score"] <= results[baseline][family]["mean_score"]:
            misses.append(f"{family}: mean score {s['mean_score']:.1f} <= {baseline}'s "
                          f"{results[baseline][family]['mean_score']:.1f}")
    return misses


def table(results: dict) -> str:
    """Markdown: one row per controller and family (mean score, share qualified, collisions, max jerk)."""
    lines = ["| controller | family | episodes | mean score | qualified | collisions | max jerk [m/s^3] |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for name, families in results.items():
        for family, s in families.items():
            lines.append(f"| {name} | {family} | {s['episodes']} | {s['mean_score']:.1f} | "
                         f"{s['share_qualified']:.1%} | {s['collisions']} | {s['max_jerk']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", nargs="+", default=["ppo-acc", "acc"])
    parser.add_argument("--episodes", type=int, default=40, help="per car-following speed")
    parser.add_argument("--singlelane-episodes", type=int, default=400)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--json", metavar="FILE", help="also write the results to FILE")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    results = heldout(args.controllers, args.episodes, args.singlelane_episodes, args.seed)
    print(table(results))
    from acc_gym_agents.controllers import BUILTINS

    for name in args.controllers:
        if name not in BUILTINS:  # trained policies: the bar is theirs
            misses = meets_bar(results, name)
            print(f"{name}: " + ("meets the shipping bar" if not misses else "misses the bar: " + "; ".join(misses)))
    print(f"seed {args.seed}, {time.perf_counter() - t0:.0f} s")
    if args.json:
        atomic_write(args.json, json.dumps(json_safe({"seed": args.seed, "episodes": args.episodes,
                                                      "singlelane_episodes": args.singlelane_episodes,
                                                      "results": results}), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
