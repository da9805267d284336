"""Run each controller in its own process, with a per-step and a total time budget.

Why processes: a controller under test is foreign code. In its own process a crash
(an exception, even a segfault in an extension), a hang or a runaway allocation takes
down only that controller: the parent marks it ``failed`` with the reason and the other
controllers finish. The start method is ``spawn`` everywhere (never ``fork``: the
parent may hold threads -- numba, BLAS, a progress bar -- that ``fork`` would copy
half-locked into the child).

What the child gets: the controller *reference* (a built-in name, ``module:attribute``
or a saved model path; loaded in the child by
:func:`acc_gym.evaluation.runner.load_controller`, so a controller that fails to import
fails in its own process too) and its episodes as built
:class:`~acc_gym.scenarios.spec.Scenario` values. ``spawn`` gives the child the parent's
``sys.path`` and working directory (multiprocessing's preparation data), so a module
importable in the parent -- a test helper on ``sys.path``, a package in the current
directory -- is importable in the child; nothing else of the parent's state is.

Budgets:

* **step budget** [s]: each ``predict`` call. The child stamps the start of every call in
  shared memory (``time.monotonic``, a system-wide clock on Linux, macOS and Windows);
  the parent kills a child whose call has been running longer than the budget (a hang),
  and the child itself fails a call that returned late. The first ``predict`` call is
  exempt (it may load weights or compile lazily): only the total budget bounds it.
* **total budget** [s]: from the child's start (imports and loading included) to its
  last episode; past it the parent kills the child.

Everything else that goes wrong in the child -- the controller raises, returns NaN or a
wrong shape (the evaluator and the environment raise ``ValueError`` naming it), the
process dies -- is reported as ``failed`` with the reason and the traceback. Episodes
finished before a failure are kept (reported, not ranked).

The child sends one message per episode (its report's score, qualification and
metrics), so the parent knows how far it got; with ``traces=True`` it then re-runs its
worst episode (lowest score, then a collision first, then the earliest) with
``record=True`` and sends the trace for the report's plots.
"""

from __future__ import annotations

import multiprocessing
import time
import traceback
from dataclasses import dataclass
from multiprocessing.connection import wait

from acc_gym.scenarios.spec import Scenario

START_METHOD = "spawn"
POLL_S = 0.05  # [s] how often the parent looks at its children's clocks


class StepBudgetExceeded(RuntimeError):
    """A ``predict`` call took longer than the step budget."""


def step_budget_message(budget: float) -> str:
    return f"predict() exceeded the step budget of {budget:g} s"


@dataclass(frozen=True)
class Job:
    """One episode for a child: which suite it belongs to and the scenario to run."""

    suite: str
    split: str
    episode: int  # position in the suite's episode list
    env_id: str
    scenario: Scenario


def group_of(scenario_id: str) -> str:
    """The scenario group a report plots scores by: the id, NCAP tests by kind (``ncap/ccrs``)."""
    parts = scenario_id.split("/")
    return "/".join(parts[:2]) if parts[0] == "ncap" else scenario_id


def episode_record(job: Job, info: dict) -> dict:
    """What the results keep of one episode (JSON-safe: the report's own ``to_dict`` form)."""
    report = info["report"]
    return {"suite": job.suite, "split": job.split, "episode": job.episode, "scenario": job.scenario.id,
            "scenario_seed": job.scenario.seed, "group": group_of(job.scenario.id),
            "duration": float(job.scenario.duration), "simulated": float(info["t"]),
            "score": float(report["score"]), "qualified": bool(report["qualified"]), "metrics": report["metrics"]}


def worst_index(records: list[dict]) -> int | None:
    """The worst episode: lowest score, then a collision first, then the earliest."""
    if not records:
        return None
    return min(range(len(records)),
               key=lambda k: (records[k]["score"], not records[k]["metrics"]["collision"], k))


class Guarded:
    """The controller behind a stopwatch (see the module docstring)."""

    def __init__(self, controller, clock, step_budget: float, reference: str):
        self.controller, self.clock, self.step_budget, self.reference = controller, clock, step_budget, reference
        self.calls = 0

    def __repr__(self) -> str:
        return repr(self.reference)

    def reset(self) -> None:
        if hasattr(self.controller, "reset"):
            self.controller.reset()

    def predict(self, obs, deterministic: bool = True):
        first = self.calls == 0
        self.calls += 1
        start = time.monotonic()
        if not first:
            self.clock.value = start
        try:
            out = self.controller.predict(obs, deterministic=deterministic)
        finally:
            self.clock.value = 0.0
        if not first and time.monotonic() - start > self.step_budget:
            raise StepBudgetExceeded(step_budget_message(self.step_budget))
        return out


def child_main(conn, reference: str, jobs: list, step_budget: float, clock, traces: bool) -> None:
    """The child process: load the controller, run the jobs, report each (see the module docstring)."""
    where = "loading the controller"
    try:
        import gymnasium as gym

        import acc_gym  # noqa: F401  (registers the ids)
        from acc_gym.evaluation.runner import load_controller, run_episode

        guarded = Guarded(load_controller(reference), clock, step_budget, reference)
        envs: dict = {}
        records = []
        for job in jobs:
            where = f"{job.suite} episode {job.episode} ({job.scenario.id}, seed {job.scenario.seed})"
            env = envs.get(job.env_id) or envs.setdefault(job.env_id, gym.make(job.env_id))
            info, _ = run_episode(env, guarded, seed=job.scenario.seed, scenario=job.scenario, record=False)
            records.append(episode_record(job, info))
            conn.send(("episode", records[-1]))
        k = worst_index(records)
        if traces and k is not None:
            job = jobs[k]
            where = f"re-running the worst episode, {job.suite} episode {job.episode}"
            info, trace = run_episode(envs[job.env_id], guarded, seed=job.scenario.seed, scenario=job.scenario,
                                      record=True)
            conn.send(("trace", {"position": k, "score": float(info["score"]), "trace": trace}))
        conn.send(("done", None))
    except BaseException as exc:  # noqa: BLE001  (whatever the controller does wrong is a result)
        reason = f"{type(exc).__name__}: {exc}" if not isinstance(exc, StepBudgetExceeded) else str(exc)
        try:
            conn.send(("failed", {"reason": f"{reason} ({where})", "traceback": traceback.format_exc()}))
        except (OSError, EOFError):  # the parent has gone
            pass
    finally:
        conn.close()


@dataclass
class Outcome:
    """What the parent learned about one controller."""

    reference: str
    status: str = "running"  # then "ok" or "failed"
    reason: str | None = None
    traceback: str | None = None
    episodes: list | None = None
    trace: dict | None = None
    wall_time_s: float = 0.0


class _Running:
    def __init__(self, ctx, reference: str, jobs: list, step_budget: float, traces: bool):
        self.reference, self.jobs = reference, jobs
        self.outcome = Outcome(reference, episodes=[])
        self.clock = ctx.RawValue("d", 0.0)
        self.conn, child_conn = ctx.Pipe(duplex=False)
        self.process = ctx.Process(target=child_main, name=f"acc-gym-leaderboard[{reference}]",
                                   args=(child_conn, reference, jobs, step_budget, self.clock, traces), daemon=True)
        self.started = time.monotonic()
        self.process.start()
        child_conn.close()  # the child holds the only writing end: its death closes the pipe

    def where(self) -> str:
        n = len(self.outcome.episodes)
        if n < len(self.jobs):
            job = self.jobs[n]
            return f"{job.suite} episode {job.episode} ({job.scenario.id}), after {n} of {len(self.jobs)} episodes"
        return f"after all {n} episodes"

    def receive(self) -> bool:
        """Read what the child sent; True once it is finished (done, failed or gone)."""
        try:
            while self.conn.poll():
                kind, payload = self.conn.recv()
                if kind == "episode":
                    self.outcome.episodes.append(payload)
                elif kind == "trace":
                    self.outcome.trace = payload
                elif kind == "done":
                    self.outcome.status = "ok"
                    return True
                elif kind == "failed":
                    self.fail(payload["reason"], payload["traceback"])
                    return True
        except (EOFError, OSError):
            self.process.join(5.0)
            self.fail(f"the controller's process died (exit code {self.process.exitcode}) at {self.where()}")
            return True
        return False

    def fail(self, reason: str, tb: str | None = None) -> None:
        self.outcome.status, self.outcome.reason, self.outcome.traceback = "failed", reason, tb

    def check_budgets(self, now: float, step_budget: float, budget: float) -> bool:
        """Kill the child if it is past a budget; True if it was killed."""
        started = self.clock.value
        if started > 0.0 and now - started > step_budget:
            self.kill(f"{step_budget_message(step_budget)} (killed at {self.where()})")
            return True
        if now - self.started > budget:
            self.kill(f"exceeded the total budget of {budget:g} s (killed at {self.where()})")
            return True
        return False

    def kill(self, reason: str) -> None:
        self.receive()  # keep the episodes it finished
        if self.outcome.status == "running":
            self.fail(reason)
        self.process.kill()

    def close(self) -> Outcome:
        self.process.join(10.0)
        if self.process.is_alive():  # pragma: no cover - a child that ignores its end
            self.process.kill()
            self.process.join()
        self.conn.close()
        self.outcome.wall_time_s = time.monotonic() - self.started
        return self.outcome


def run_isolated(references: list[str], jobs: list[Job], *, workers: int, step_budget: float, budget: float,
                 traces: bool = False, progress=None) -> dict[str, Outcome]:
    """Run ``jobs`` for every controller, each in its own process, ``workers`` at a time.

    Returns ``{reference: Outcome}`` in the order of ``references``. ``progress(outcome)``
    is called as each controller finishes."""
    ctx = multiprocessing.get_context(START_METHOD)
    pending = list(references)
    running: list[_Running] = []
    done: dict[str, Outcome] = {}
    try:
        while pending or running:
            while pending and len(running) < workers:
                running.append(_Running(ctx, pending.pop(0), jobs, step_budget, traces))
            wait([r.conn for r in running] + [r.process.sentinel for r in running], timeout=POLL_S)
            now = time.monotonic()
            for r in list(running):
                finished = r.receive()
                if not finished:
                    finished = r.check_budgets(now, step_budget, budget)
                if not finished and not r.process.is_alive():
                    finished = r.receive()  # a last message may have arrived with its exit
                    if not finished:
                        r.fail(f"the controller's process exited (code {r.process.exitcode}) at {r.where()}")
                        finished = True
                if finished:
                    running.remove(r)
                    done[r.reference] = r.close()
                    if progress is not None:
                        progress(done[r.reference])
    finally:
        for r in running:  # interrupted (Ctrl-C, an error here): leave no orphans
            r.process.kill()
            r.process.join()
    return {ref: done[ref] for ref in references}
