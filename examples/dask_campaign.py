"""A Monte Carlo campaign on a Dask cluster: hours of a suite's traffic with one controller.

    python examples/dask_campaign.py                                   # 0.5 h of singlelane-v3, a 2-worker LocalCluster
    python examples/dask_campaign.py --scheduler tcp://10.1.2.3:8786   # your cluster's scheduler
    python examples/dask_campaign.py --quick                           # a 1-worker LocalCluster, a few scenarios

Needs ``pyarrow`` and ``dask[distributed]`` (``pip install ".[campaign,dist]"``; both are
in the ``test`` extra). The command line does the same: ``acc-gym campaign --suite
singlelane-v3 --hours 0.5 --controller acc --out runs/acc --scheduler local --workers 2``.

What the campaign guarantees (``acc_gym.campaigns``): scenario ``i`` of the split and its
seed are a pure function of ``i`` and the root seed, so the numbers do not depend on the
backend, the number of workers or the order chunks finish in; workers return rows and
this process writes one Parquet file per chunk, atomically, with its checksum, so the
workers need no shared filesystem; and running the same command again resumes: a chunk
whose file verifies is never run twice (the second call below runs nothing). The cluster
made here is ours to close; a ``Client`` given to ``run_campaign`` is left open.

A controller given by ``module:attribute`` must import on the workers too (install it
there, or put it on their ``PYTHONPATH``); a built-in name such as ``acc`` always does.
"""

from __future__ import annotations

import argparse
import sys
import tempfile


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="singlelane-v3")
    parser.add_argument("--controller", default="acc")
    parser.add_argument("--hours", type=float, default=0.5, help="hours of traffic (singlelane-v3: ~275 scenarios "
                                                                 "an hour)")
    parser.add_argument("--workers", type=int, default=2, help="the LocalCluster's worker processes")
    parser.add_argument("--scheduler", default=None, help="a Dask scheduler address (default: a LocalCluster "
                                                          "started here)")
    parser.add_argument("--out", default=None, help="the campaign's directory (default: a temporary one)")
    parser.add_argument("--quick", action="store_true", help="0.01 h in chunks of 2 on one worker (the test runs "
                                                             "this)")
    args = parser.parse_args(argv)
    if args.quick:
        args.hours, args.workers = 0.01, 1
    chunk_size = 2 if args.quick else 16  # scenarios per Dask task and per result file

    from distributed import Client, LocalCluster

    from acc_gym.campaigns import format_summary, run_campaign

    out = args.out or tempfile.mkdtemp(prefix="acc-gym-campaign-")

    def progress(number, done, total):
        print(f"  chunk {number} written ({done} of {total})")

    if args.scheduler:
        cluster = None
        client = Client(args.scheduler)
    else:
        # single-threaded worker processes on the loopback interface, no dashboard
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None)
        client = Client(cluster)
    try:
        print(f"Dask: {len(client.scheduler_info()['workers'])} worker(s) at {client.scheduler.address}")
        summary = run_campaign(args.suite, args.hours, args.controller, out, scheduler=client, chunk_size=chunk_size,
                               on_chunk=progress)
        print(format_summary(summary))
        # The same call again: every chunk's file verifies, so nothing runs and the summary is the same.
        again = run_campaign(args.suite, args.hours, args.controller, out, scheduler=client, chunk_size=chunk_size,
                             on_chunk=progress)
        print(f"resumed: {again['episodes']} episodes, nothing re-run: {again == summary}")
        print(f"campaign directory: {out}")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
