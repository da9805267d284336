"""Accelerated evaluation against crude Monte Carlo: agreement, acceleration, coverage.

    python benchmarks/bench_risk.py            # the full table (about 10 minutes on 2 cores)
    python benchmarks/bench_risk.py --json     # ... and one JSON object on the last line
    python benchmarks/bench_risk.py --quick    # a smoke run (small budgets; the numbers mean little)

Cases (each a row; ``validates`` names the crude row an accelerated one is checked against):

1. **Feasible, validated**: GM and the fuzzy model on cut-ins collide often enough
   (p ~ 4e-3 and 1e-3) for crude Monte Carlo to be run here; the importance-sampling
   estimate's 95 % interval must overlap crude Monte Carlo's (``agrees``).
2. **Rare**: the fuzzy model on approaches (p ~ 4e-5), the linear ACC limited to 3 m/s^2
   of braking on cut-ins (below ISO 15622's 3.5 m/s^2 ACC braking authority), and GM's
   time-to-collision under 1 s on approaches (p ~ 4e-6): crude Monte Carlo would need
   ``acceleration`` times more episodes for the same relative half-width.
3. **Never colliding**: the linear ACC and IDM on cut-ins: no collision anywhere the
   cross-entropy rounds looked (their smallest time-to-collision stays above 1 s: the
   generator makes every cut-in survivable by braking at 6 m/s^2 after 0.5 s), so the
   estimate is an exact 95 % upper bound, not 0.
4. **Coverage study**: a Gaussian tail P(X > 4) = 3.17e-5, known in closed form, estimated
   by the whole procedure (cross-entropy rounds, then estimation to a 10 % half-width)
   ``--coverage-runs`` times with independent seeds: the share of 95 % intervals that
   cover the truth (aim: 93-97 %).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy.special import ndtr

from acc_gym.risk import estimate_risk
from acc_gym.risk.episodes import draw_episodes
from acc_gym.risk.estimate import estimate
from acc_gym.risk.proposal import Proposal
from acc_gym.risk.run import search
from acc_gym.scenarios.distributions import Normal



def weak_acc_3():
    """The linear ACC braking at most 3 m/s^2 (``bench_risk:weak_acc_3``)."""
    from acc_gym_agents.controllers.linear import iso_acc

    return iso_acc(3.0)


def _row(r, label: str | None = None, validates: str | None = None) -> dict:
    e = r.estimate
    return {"controller": label or r.controller, "family": r.family, "event": r.event, "method": r.method,
            "p": e.p, "ci_low": e.ci_low, "ci_high": e.ci_high, "rhw": None if not math.isfinite(e.rhw) else e.rhw,
            "failures": e.failures, "episodes": e.episodes_total,
            "acceleration": 1.0 if r.method == "crude" else e.acceleration, "upper_bound": e.upper_bound,
            "validates": validates, "stop": r.stop, "wall_time_s": round(r.wall_time_s, 1),
            "min_ttc": r.min_ttc, "warnings": e.warnings}


def coverage_study(runs: int, budget: int) -> dict:
    """The whole procedure on P(X > 4), X ~ N(0, 1) truncated to [-10, 10], ``runs`` times."""
    laws = {"x": Normal(0.0, 1.0, low=-10.0, high=10.0)}
    truth = float(ndtr(-4.0) - ndtr(-10.0))
    covered, ests, used = 0, [], []
    for seed in range(runs):
        def simulate(rnd, prop, size, seed=seed):
            draws, lw = draw_episodes(prop, 1000 + seed, rnd, 0, size)
            return [{"params": d[0], "nominal": d[1], "log_w": float(lw[i]), "S": 4.0 - d[0]["x"]}
                    for i, d in enumerate(draws)]

        def perf(recs):
            return np.array([r["S"] for r in recs])

        _, pooled, rounds, _ = search(Proposal.nominal_only(laws), simulate, perf, budget=budget, round_size=256,
                                      max_rounds=10, target_rhw=0.1)
        s = perf(pooled)
        est = estimate(np.array([r["log_w"] for r in pooled]), s <= 0)
        covered += est.ci_low <= truth <= est.ci_high
        ests.append(est.p)
        used.append(sum(x["episodes"] for x in rounds))
    return {"case": "gaussian tail P(X > 4)", "p_true": truth, "runs": runs, "coverage": covered / runs,
            "mean_estimate_over_truth": float(np.mean(ests) / truth), "median_episodes": float(np.median(used))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object on the last line")
    ap.add_argument("--quick", action="store_true", help="small budgets: a smoke run")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--crude-episodes", type=int, default=20480)
    ap.add_argument("--budget", type=int, default=40000, help="episodes per accelerated estimate at most")
    ap.add_argument("--coverage-runs", type=int, default=200)
    args = ap.parse_args(argv)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # bench_risk:weak_acc_3 in the workers
    crude_n, budget, cov_runs = args.crude_episodes, args.budget, args.coverage_runs
    cov_budget = 8192
    if args.quick:
        crude_n, budget, cov_runs, cov_budget = 128, 256, 2, 1024
    kw = dict(workers=args.workers, root_seed=0)
    cases: list[dict] = []
    started = time.monotonic()

    def show(row):
        cases.append(row)
        ci = f"[{row['ci_low']:.2e}, {row['ci_high']:.2e}]"
        acc = "-" if row["acceleration"] is None else f"{row['acceleration']:,.0f}x"
        print(f"{row['controller']:>12} {row['family']:>9} {row['event']:>9} {row['method']:>5}  p {row['p']:.2e} "
              f"{ci}  {row['failures']:>5} failures  {row['episodes']:>6} episodes  {acc:>8}  "
              f"{row['wall_time_s']:>6.0f} s  {row['stop']}" + (f"  validates {row['validates']}"
                                                                  if row["validates"] else ""), flush=True)

    print("controller      family     event method  p [95 % interval]   failures  episodes  acceleration  wall")
    # 1. feasible: crude Monte Carlo and importance sampling side by side
    for ctl in ("gm", "fuzzy"):
        crude = estimate_risk(ctl, "cut-in", method="crude", budget=crude_n, round_size=1024, target_rhw=0.01,
                              **kw)
        show(_row(crude))
        acc = estimate_risk(ctl, "cut-in", budget=budget, target_rhw=0.2, **kw)
        row = _row(acc, validates=f"{ctl}/cut-in")
        row["agrees"] = bool(row["ci_low"] <= crude.estimate.ci_high and crude.estimate.ci_low <= row["ci_high"])
        show(row)
    # 2. rare
    show(_row(estimate_risk("fuzzy", "approach", budget=budget, target_rhw=0.2, **kw)))
    show(_row(estimate_risk("bench_risk:weak_acc_3", "cut-in", budget=budget, target_rhw=0.2, **kw),
              label="acc-brake-3"))
    show(_row(estimate_risk("gm", "approach", event="ttc", budget=budget, target_rhw=0.2, **kw)))
    # 3. never colliding: an exact upper bound
    for ctl in ("acc", "idm"):
        show(_row(estimate_risk(ctl, "cut-in", budget=max(budget // 4, 512), target_rhw=0.2, **kw)))
    # 4. coverage
    cov = coverage_study(cov_runs, cov_budget)
    print(f"coverage: {cov['coverage']:.1%} of {cov['runs']} runs' 95 % intervals cover P(X > 4) = "
          f"{cov['p_true']:.3g}; mean estimate / truth {cov['mean_estimate_over_truth']:.3f}; median "
          f"{cov['median_episodes']:.0f} episodes per run")
    print(f"total {time.monotonic() - started:.0f} s on {args.workers} worker(s)")
    if args.json:
        print(json.dumps({"cases": cases, "coverage": cov, "workers": args.workers, "quick": args.quick}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
