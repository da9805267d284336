"""Where a campaign's chunks run: in this process, a local process pool, or a Dask cluster.

Each backend is a generator of ``(task, rows)`` pairs in completion order (which varies:
the caller stores every chunk under its own number, so order never matters). Closing the
generator early (an error, Ctrl-C) cancels the chunks not yet started and releases the
pool or the cluster connection.

* ``workers == 1`` without a scheduler: chunks run one after the other in the calling
  process (no start-up cost, plain tracebacks).
* ``workers > 1``: ``concurrent.futures.ProcessPoolExecutor`` with the ``spawn`` start
  method -- never ``fork``, which would copy the caller's threads (numba, BLAS) into the
  children, and not ``forkserver``, whose server outlives a SIGKILLed campaign and keeps
  its idle workers (about 450 MB each time). Each worker asks the kernel to SIGKILL it
  when the campaign's process dies (:func:`acc_gym._process.die_with_parent`), so a
  killed campaign leaves no worker behind (the resource tracker then ends too).
* ``scheduler``: a Dask distributed cluster -- a scheduler address (``tcp://host:8786``),
  ``"local"`` to start a ``LocalCluster`` of ``workers`` single-threaded processes on
  127.0.0.1 (closed afterwards), or a ``distributed.Client`` you made (left open). Each chunk
  is one task with a deterministic key (``acc-gym-chunk-FINGERPRINT-NUMBER``: the same chunk
  of the same campaign is the same computation) and ``retries=2``, so a chunk whose worker
  dies is re-run elsewhere; a chunk that still fails stops the campaign with its error.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from acc_gym._process import die_with_parent
from acc_gym.campaigns.episodes import run_chunk
from acc_gym.campaigns.errors import CampaignError, require_distributed

RETRIES = 2


def _number(task) -> int:
    """A task's chunk number (a campaign's ``ChunkTask.chunk.number``, or the task's own ``number``)."""
    return task.number if hasattr(task, "number") else task.chunk.number


def run_inline(tasks: list, fn=run_chunk) -> Iterator[tuple[object, list[dict]]]:
    for task in tasks:
        yield task, fn(task)


def pool_context():
    return multiprocessing.get_context("spawn")


def run_pool(tasks: list, workers: int, fn=run_chunk) -> Iterator[tuple[object, list[dict]]]:
    if not tasks:
        return
    pool = ProcessPoolExecutor(max_workers=min(workers, len(tasks)), mp_context=pool_context(),
                               initializer=die_with_parent, initargs=(os.getpid(),))
    try:
        pending = {pool.submit(fn, task): task for task in tasks}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in sorted(done, key=lambda f: _number(pending[f])):
                task = pending.pop(fut)
                yield task, fut.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def run_dask(tasks: list, scheduler, workers: int, fingerprint: str, fn=run_chunk) \
        -> Iterator[tuple[object, list[dict]]]:
    distributed = require_distributed()
    cluster = None
    if isinstance(scheduler, distributed.Client):
        client, own_client = scheduler, False
    else:
        if scheduler == "local":
            cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                               host="127.0.0.1", dashboard_address=None)
            scheduler = cluster
        try:
            client, own_client = distributed.Client(scheduler), True
        except (OSError, TimeoutError) as exc:
            if cluster is not None:
                cluster.close()
            raise CampaignError(f"cannot connect to the Dask scheduler {scheduler!r}: {exc}") from None
    futures = []
    try:
        if not tasks:
            return
        by_key = {}
        for task in tasks:
            key = f"acc-gym-chunk-{fingerprint}-{_number(task)}"
            fut = client.submit(fn, task, key=key, retries=RETRIES, pure=False)
            by_key[fut.key] = task
            futures.append(fut)
        for fut in distributed.as_completed(futures):
            yield by_key[fut.key], fut.result()
    finally:
        if futures:
            client.cancel(futures)
        if own_client:
            client.close()
        if cluster is not None:
            cluster.close()


def execute(tasks: list, *, workers: int, scheduler, fingerprint: str, fn=run_chunk):
    """The ``(task, rows)`` pairs of ``tasks`` run on the chosen backend (``fn(task)``: a
    campaign's :func:`~acc_gym.campaigns.episodes.run_chunk` by default, or another
    module-level function, e.g. :func:`acc_gym.risk.episodes.run_chunk`)."""
    if scheduler is not None:
        return run_dask(tasks, scheduler, workers, fingerprint, fn)
    if workers == 1:
        return run_inline(tasks, fn)
    return run_pool(tasks, workers, fn)
