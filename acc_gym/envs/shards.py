"""A vector environment's scenes split over worker processes (``ACCVectorEnv(workers=k)``).

One :class:`~acc_gym.envs.vector.ACCVectorEnv` runs in one process, so it uses one core.
With ``workers=k`` its ``num_envs`` environments are split into ``k`` contiguous shards
(sizes differing by at most one), each an in-process ``ACCVectorEnv`` in its own
process; every call goes to all shards at once and their answers are joined. Nothing
else changes: environment ``i`` still draws its scenarios from its own generator seeded
``seed + i``, so the results equal those of the in-process vector env (and so of
``num_envs`` single environments), step for step (``tests/envs/test_shards.py``).

Costs: starting the workers (each imports the package, about a second, in parallel),
and per call a round trip through a pipe with the pickled actions and results (some
tens of microseconds per shard). Worth it for many environments on several cores; for
a few environments the in-process vector env is faster.

Right after answering a step, each worker draws the next scenarios of its environments
whose episode just ended and condenses their drivers' QPs
(:meth:`~acc_gym.envs.vector.ACCVectorEnv.prepare_resets`), work that the next step's
autoreset would otherwise do; it runs while the worker would wait for the slowest shard
and for the caller's policy, and changes no result. An error in it is reported by the
next call.

The workers are daemon processes started with ``multiprocessing``'s ``"fork"`` method where
there is one (Linux: fast, and no ``if __name__ == "__main__":`` guard needed in the
calling script), else ``"spawn"``; pass ``workers_context="spawn"`` or ``"forkserver"``
when the parent runs threads that a fork could catch mid-lock (the workers themselves only
use numpy and numba). ``close()`` stops them. An error in a worker is raised again in the parent as a
:class:`ShardError` carrying the worker's traceback; the shards are then closed.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback

import numpy as np


class ShardError(RuntimeError):
    """An error inside a worker process (its traceback is in the message)."""


def split(n: int, k: int) -> list[tuple[int, int]]:
    """``k`` contiguous ``(start, stop)`` ranges covering ``range(n)``, sizes differing by at most one."""
    bounds = np.linspace(0, n, k + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def _worker(conn, n: int, kwargs: dict) -> None:  # pragma: no cover - runs in the worker process
    from acc_gym.envs.vector import ACCVectorEnv

    try:
        env = ACCVectorEnv(n, **kwargs)
        conn.send(("ok", None))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        conn.send(("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))
        conn.close()
        return
    late = None
    while True:
        try:
            cmd, arg = conn.recv()
        except EOFError:
            break
        if cmd == "close":
            env.close()
            conn.send(("ok", None))
            break
        try:
            if late is not None:  # prepare_resets failed after the last answer: this call reports it
                raise late
            if cmd == "step":
                conn.send(("ok", env.step(arg)))
                try:
                    env.prepare_resets()  # the next episodes' start-up, while the caller is busy
                except BaseException as exc:  # noqa: BLE001 - reported by the next call
                    late = exc
                continue
            elif cmd == "prepare_resets":
                out = env.prepare_resets()
            elif cmd == "reset":
                out = env.reset(seed=arg[0], options=arg[1])
            elif cmd == "reset_ended":
                out = env.reset_ended()
            elif cmd == "render":
                out = env.render()
            elif cmd == "episode_reports":
                out = env.episode_reports()
            else:
                raise ValueError(f"unknown command {cmd!r}")
            conn.send(("ok", out))
        except BaseException as exc:  # noqa: BLE001 - reported to the parent
            late = None
            conn.send(("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))


def _fill(like, n: int):
    """What an in-process vector env holds for a key in the rows that did not set it."""
    if isinstance(like, dict):
        return {k: _fill(v, n) for k, v in like.items()}
    like = np.asarray(like)
    if like.dtype == object:
        return np.empty((n,) + like.shape[1:], dtype=object)
    return np.zeros((n,) + like.shape[1:], dtype=like.dtype)


def merge_infos(infos: list[dict], sizes: list[int]) -> dict:
    """Join the shards' info dicts (arrays over their environments, ``_key`` masks, nested
    dicts) into one over all environments, filling what a shard lacks as the in-process
    vector env would (zeros, False, None)."""
    keys: list = []
    for info in infos:
        keys.extend(k for k in info if k not in keys)
    out = {}
    for key in keys:
        like = next(info[key] for info in infos if key in info)
        parts = [info[key] if key in info else _fill(like, n) for info, n in zip(infos, sizes)]
        if isinstance(like, dict):
            out[key] = merge_infos(parts, sizes)
        else:
            out[key] = np.concatenate([np.asarray(p) for p in parts])
    return out


class Shards:
    """``len(ranges)`` worker processes, each an ``ACCVectorEnv`` over one range of environments."""

    def __init__(self, ranges: list[tuple[int, int]], kwargs: dict, context: str | None = None):
        self.ranges = ranges
        self.sizes = [b - a for a, b in ranges]
        if context is None:
            context = "fork" if "fork" in mp.get_all_start_methods() else "spawn"
        ctx = mp.get_context(context)
        self._conns, self._procs = [], []
        try:
            for n in self.sizes:
                parent, child = ctx.Pipe()
                proc = ctx.Process(target=_worker, args=(child, n, kwargs), daemon=True)
                proc.start()
                child.close()
                self._conns.append(parent)
                self._procs.append(proc)
            self._gather()  # every worker built its environments
        except BaseException:
            self.close()
            raise

    def _gather(self) -> list:
        outs, errors = [], []
        for conn, proc in zip(self._conns, self._procs):
            try:
                status, value = conn.recv()
            except EOFError:
                status, value = "error", f"the worker process died (exit code {proc.exitcode})"
            if status == "error":
                errors.append(value)
            outs.append(value)
        if errors:
            self.close()
            raise ShardError("a vector env worker failed:\n" + errors[0])
        return outs

    def call(self, cmd: str, args: list | None = None) -> list:
        """Send ``cmd`` (with ``args[j]`` to shard ``j``) to every worker, then collect the answers."""
        if not self._conns:
            raise RuntimeError("the vector env's workers are closed")
        for j, conn in enumerate(self._conns):
            conn.send((cmd, None if args is None else args[j]))
        return self._gather()

    def close(self) -> None:
        for conn in self._conns:
            try:
                conn.send(("close", None))
                conn.recv()
            except (OSError, EOFError, BrokenPipeError):
                pass
            conn.close()
        for proc in self._procs:
            proc.join(timeout=5)
            if proc.is_alive():
                proc.terminate()
        self._conns, self._procs = [], []
