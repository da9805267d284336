"""Speed of whole Monte Carlo campaigns: scenarios per second, end to end.

A campaign of ``--hours`` 1 of ``singlelane-v3``'s test traffic (about 270 scenarios,
with the linear ACC, ``--chunk-size`` 5) is run into a fresh directory with
:func:`acc_gym.campaigns.run_campaign` -- planning, episodes, Parquet files and summary
included:

* ``scenarios_per_s_1_worker``: in the calling process (``workers=1``);
* ``scenarios_per_s_2_workers``: a local pool of 2 processes (``workers=2``). Each campaign
  starts its own pool, so this includes starting the processes and importing acc_gym in
  them (seconds): on a short campaign it can be *slower* than one worker;
  ``pool_start_s`` estimates that fixed cost;
* ``scenarios_per_s_dask_2_workers``: a Dask ``LocalCluster`` of 2 single-threaded worker
  processes on 127.0.0.1, started once (``dask_cluster_start_s``) and reused, as a
  running cluster is.

Each figure is the median of ``--repeats`` timed runs after a warm-up run (numba kernels
compiled and cached, suite data loaded); every run's figure is printed too.

    python benchmarks/bench_campaign.py            # table
    python benchmarks/bench_campaign.py --json     # one JSON object
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from acc_gym.campaigns import run_campaign


def campaign_rate(args, out: Path, **backend) -> tuple[float, int]:
    t0 = time.perf_counter()
    summary = run_campaign(args.suite, args.hours, args.controller, out, chunk_size=args.chunk_size, **backend)
    return summary["episodes"] / (time.perf_counter() - t0), summary["episodes"]


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="singlelane-v3")
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--controller", default="acc")
    parser.add_argument("--chunk-size", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask LocalCluster figure")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    out: dict = {"suite": args.suite, "hours": args.hours, "controller": args.controller,
                 "chunk_size": args.chunk_size}
    with tempfile.TemporaryDirectory(prefix="bench_campaign_") as tmp:
        runs = iter(range(10 ** 6))

        def fresh() -> Path:
            return Path(tmp) / f"run{next(runs)}"

        _, n = campaign_rate(args, fresh(), workers=1)  # warm-up
        out["scenarios"] = n
        one = [campaign_rate(args, fresh(), workers=1)[0] for _ in range(args.repeats)]
        two = [campaign_rate(args, fresh(), workers=2)[0] for _ in range(args.repeats)]
        out.update(scenarios_per_s_1_worker=float(np.median(one)), scenarios_per_s_1_worker_runs=one,
                   scenarios_per_s_2_workers=float(np.median(two)), scenarios_per_s_2_workers_runs=two,
                   pool_start_s=max(0.0, n / np.median(two) - n / (2 * np.median(one))))
        if not args.no_dask:
            import distributed

            t0 = time.perf_counter()
            with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                          dashboard_address=None) as cluster, distributed.Client(cluster) as client:
                out["dask_cluster_start_s"] = time.perf_counter() - t0
                campaign_rate(args, fresh(), scheduler=client)  # warm-up: imports and kernels on the workers
                dask = [campaign_rate(args, fresh(), scheduler=client)[0] for _ in range(args.repeats)]
            out.update(scenarios_per_s_dask_2_workers=float(np.median(dask)), scenarios_per_s_dask_2_workers_runs=dask)
    if args.json:
        print(json.dumps(out))
    else:
        runs_of = lambda key: ", ".join(f"{x:.1f}" for x in out[key + "_runs"])  # noqa: E731
        print(f"campaign: {args.hours} h of {args.suite} ({out['scenarios']} scenarios), controller "
              f"{args.controller!r}, chunks of {args.chunk_size}")
        print(f"1 worker (this process):        {out['scenarios_per_s_1_worker']:6.1f} scenarios/s "
              f"(runs {runs_of('scenarios_per_s_1_worker')})")
        print(f"2 local workers (pool started): {out['scenarios_per_s_2_workers']:6.1f} scenarios/s "
              f"(runs {runs_of('scenarios_per_s_2_workers')}; ~{out['pool_start_s']:.1f} s pool start-up)")
        if "scenarios_per_s_dask_2_workers" in out:
            print(f"Dask LocalCluster, 2 workers:   {out['scenarios_per_s_dask_2_workers']:6.1f} scenarios/s "
                  f"(runs {runs_of('scenarios_per_s_dask_2_workers')}; cluster started once in "
                  f"{out['dask_cluster_start_s']:.1f} s)")
    return out


if __name__ == "__main__":
    main()
