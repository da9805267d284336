"""Run each controller against a trusted simulation, with a per-step and a total budget.

The trust boundary. For every controller the runner starts a **simulation process**
(trusted code: ``spawn``, never ``fork``) that owns the environments, the scenarios, the
scoring, the clocks and the episode records, and that starts the controller in a
**sandboxed process** of its own (:mod:`acc_gym.leaderboard.sandbox`). The two talk
through a socket in fixed binary frames (:mod:`acc_gym.leaderboard.protocol`): the
simulation sends the observation rows of the episodes in flight (``IN_FLIGHT``, 16, at a
time, so one round trip serves 16 steps) with episode-start flags; the controller answers
one action per row. The controller never holds a reference to a simulator, a scenario
or a score, and nothing it sends is unpickled. Every record the runner receives was made
by the simulation process, so a controller cannot report a score, skip an episode or
end early: a controller is ``ok`` only when the runner received exactly the scheduled
records -- one per job, each naming that job's (suite, split, episode index, scenario id,
seed), none missing, none twice, none unscheduled (:class:`Ledger`).

Budgets, measured by the simulation process (the controller's clocks are its own):

* **step budget** [s]: per ``predict`` call, so a round trip of ``n`` rows may take
  ``n`` step budgets, from sending the observations to receiving the last byte of the
  actions. The first round trip is exempt (loading weights, compiling lazily): only the
  total budget bounds it. Past it the controller is killed and ``failed``.
* **total budget** [s]: from the controller's start (imports and loading included) to
  its last answer.

Everything else that goes wrong -- the controller raises, returns NaN or a wrong shape,
breaks the protocol, dies -- is reported as ``failed`` with the reason (and the
controller's traceback when it sent one); episodes finished before a failure are kept
(reported, not ranked). With ``traces=True`` the simulation then re-runs the worst
episode (lowest score, then a collision first, then the earliest) with recording, for
the report's plots. The controller's standard output and error go to its own log file.

Then the columns measured through the same sandbox (:class:`Columns`), each a cell whose failure
is its own (the episodes stand): string stability, ISO 15622 (:mod:`acc_gym.leaderboard.iso15622`)
waves on a ring (:mod:`acc_gym.leaderboard.waves`) and the typical car
(:mod:`acc_gym.leaderboard.robustness`). Each column's copies of the controller
are fresh ones (slots no earlier round trip used), and its first round trip is exempt from the
step budget (the sandbox makes those copies then). A controller failure leaves the sandbox's
socket in an unknown state (an answer may still be on its way), so a column after a failed one
starts the controller afresh, under the same total budget.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import time
import traceback
from dataclasses import dataclass
from multiprocessing.connection import wait

from acc_gym.scenarios.spec import Scenario

START_METHOD = "spawn"
POLL_S = 0.05  # [s] how often the runner looks at its simulations
IN_FLIGHT = 16  # episodes a controller answers per round trip


@dataclass(frozen=True)
class Columns:
    """The columns measured after a controller's episodes, through the same sandbox."""

    platoon: bool = False  # string stability (acc_gym.evaluation.string_stability.leaderboard_verdict)
    iso15622: bool = False  # ISO 15622 on the iso15622-v1 battery (acc_gym.leaderboard.iso15622)
    waves: dict | None = None  # the all-human rings (acc_gym.leaderboard.waves.human_baseline); None: no column
    robustness: bool = False  # the typical car's radar and actuators (acc_gym.leaderboard.robustness)
    alks: bool = False  # UN R157's ALKS bundle as alks-v1 (acc_gym.leaderboard.alks)

    def __iter__(self):
        """The columns to measure, in order: ``(name, measure, failed_cell)``; ``measure(column)``
        takes a :class:`_Trips` and returns the cell, raising :class:`ControllerFailed`."""
        from acc_gym.leaderboard import alks, iso15622, robustness, waves

        if self.platoon:
            yield "string_stability", _platoon, lambda reason: {"failed": reason}
        if self.iso15622:
            yield "iso15622", _iso15622, iso15622.failed_cell
        if self.waves is not None:
            yield "waves", lambda column: _waves(column, self.waves), waves.failed_cell
        if self.robustness:
            yield "robustness", _robustness, robustness.failed_cell
        if self.alks:
            yield "alks", _alks, alks.failed_cell


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
    car: tuple = ()  # the ego's car, as gym.make settings ((name, value) pairs: sensors, actuators); () none

    def make_env(self):
        """The job's environment: ``gym.make(env_id, **car)``."""
        import gymnasium as gym

        return gym.make(self.env_id, **dict(self.car))


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
            "score": float(report["score"]), "points": episode_points(report),
            "qualified": bool(report["qualified"]), "metrics": report["metrics"]}


def preventable(job: Job, envs: dict) -> bool:
    """Whether UN R157's careful and competent driver (the built-in ``cc-driver``, trusted code run
    here, in the simulation process) avoids the collision of ``job``'s scenario: it drives the
    same scenario (same seed, same traffic) and does not collide (:mod:`acc_gym.standards.r157`)."""
    import gymnasium as gym

    from acc_gym.evaluation.runner import load_controller
    from acc_gym.standards.r157 import REFERENCE, collides

    env = envs.get(job.env_id) or envs.setdefault(job.env_id, gym.make(job.env_id))
    if "_cc" not in envs:
        envs["_cc"] = load_controller(REFERENCE)
    return not collides(env, envs["_cc"], job.scenario)


def episode_points(report: dict, preventable: bool = True) -> float:
    """The leaderboard's points for one episode: its 100-point score, 0 if it ended in a
    collision that was ``preventable`` (UN R157: the careful and competent driver avoids the same
    scenario, :func:`preventable`); a collision nobody would have avoided keeps the score."""
    return 0.0 if report["metrics"]["collision"] and preventable else float(report["score"])


def worst_index(records: list[dict]) -> int | None:
    """The worst episode: lowest score, then a collision first, then the earliest."""
    if not records:
        return None
    return min(range(len(records)),
               key=lambda k: (records[k]["score"], not records[k]["metrics"]["collision"], k))


def scheduled_key(job: Job) -> tuple:
    """What the schedule says one episode is: (suite, split, episode index, scenario id, seed)."""
    return (job.suite, job.split, job.episode, job.scenario.id, job.scenario.seed)


def record_key(record: dict) -> tuple:
    """The same identity as a record states it (see :func:`episode_record`)."""
    return tuple(record.get(k) for k in ("suite", "split", "episode", "scenario", "scenario_seed"))


class Ledger:
    """The records received for one controller, checked against its schedule (``jobs``).

    :meth:`add` and :meth:`problem` return ``None`` when all is well, else the reason the
    controller cannot be ``ok``: a job number outside the schedule, a record that names
    another episode than the job it arrived for, a job reported twice, or (at the end) any
    scheduled episode missing."""

    def __init__(self, jobs: list):
        self.expected = [scheduled_key(job) for job in jobs]
        self.received: dict[int, dict] = {}

    def add(self, j, record) -> str | None:
        if isinstance(j, bool) or not isinstance(j, int) or not 0 <= j < len(self.expected):
            return f"a record for job {j!r}, which is not scheduled (jobs 0..{len(self.expected) - 1})"
        if not isinstance(record, dict):
            return f"the record for job {j} is a {type(record).__name__}, not a record"
        if j in self.received:
            return f"job {j} ({self._name(j)}) reported twice"
        got = record_key(record)
        if got != self.expected[j]:
            return f"the record for job {j} is for {got}, but the schedule says {self.expected[j]}"
        self.received[j] = record
        return None

    def problem(self) -> str | None:
        missing = [j for j in range(len(self.expected)) if j not in self.received]
        if missing:
            first = ", ".join(f"{j} ({self._name(j)})" for j in missing[:3])
            more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
            return (f"{len(self.received)} of {len(self.expected)} scheduled episodes arrived; missing: "
                    f"{first}{more}")
        return None

    def _name(self, j: int) -> str:
        suite, split, episode, scenario, seed = self.expected[j]
        return f"{suite} {split} episode {episode}, {scenario}, seed {seed}"


class _Where:
    """Where the round trip under way is (the episodes of ``lockstep``'s rows: ``jobs[positions[k]]``
    for its episode ``k``; ``positions`` None: ``k``), formatted only if it failed (formatting it
    every step costs)."""

    __slots__ = ("jobs", "lockstep", "done", "positions")

    def __init__(self, jobs: list, lockstep, done: dict, positions: list[int] | None = None):
        self.jobs, self.lockstep, self.done, self.positions = jobs, lockstep, done, positions

    def _job(self, k: int) -> Job:
        return self.jobs[k if self.positions is None else self.positions[k]]

    def __str__(self) -> str:
        indices = self.lockstep.running
        job = self._job(min(indices))
        n = len(indices)
        more = f" and {n - 1} more in flight" if n > 1 else ""
        return (f"{job.suite} episode {job.episode} ({job.scenario.id}){more}, after {len(self.done)} of "
                f"{len(self.jobs)} episodes")

    def row(self, k: int) -> str:
        """The episode of the round trip's row ``k``."""
        return _job_name(self._job(self.lockstep.running[k]))


class ControllerFailed(Exception):
    def __init__(self, reason: str, tb: str | None = None):
        super().__init__(reason)
        self.reason, self.tb = reason, tb


def _job_name(job: Job) -> str:
    return f"{job.suite} episode {job.episode} ({job.scenario.id})"


def _ended(ctl, grace: float = 5.0) -> str:
    """Why the controller's end of the socket closed: the trusted side killed it (a limit, its
    ``stopped`` reason), its process died (with its exit code), or it closed the connection and
    lives on (the controller's fault either way, never the simulation's)."""
    import subprocess

    if getattr(ctl, "stopped", None):
        return ctl.stopped

    try:
        code = ctl.process.wait(timeout=grace)
    except subprocess.TimeoutExpired:
        return f"the controller closed its connection and kept running (killed after {grace:g} s)"
    return f"the controller's process died (exit code {code})"


def _exchange(ctl, obs, starts, slots, deadline_step: float | None, deadline_total: float, step_budget: float,
              budget: float, where: str):
    """One round trip; the controller's failures as :class:`ControllerFailed`."""
    from acc_gym.leaderboard import protocol

    deadline = deadline_total if deadline_step is None else min(deadline_step, deadline_total)
    try:
        protocol.send_observations(ctl.sock, obs, starts, slots)
        return protocol.recv_actions(ctl.sock, len(slots), deadline)
    except protocol.Timeout:
        if deadline_step is not None and deadline_step < deadline_total:
            raise ControllerFailed(f"{step_budget_message(step_budget)} (killed at {where})") from None
        raise ControllerFailed(f"exceeded the total budget of {budget:g} s (killed at {where})") from None
    except protocol.ControllerError as exc:
        text = str(exc)
        first, _, tb = text.partition("\n")
        raise ControllerFailed(f"{first} (at {where})", tb or None) from None
    except protocol.ProtocolError as exc:
        raise ControllerFailed(f"broke the protocol: {exc} (at {where})") from None
    except (protocol.Closed, OSError):
        raise ControllerFailed(f"{_ended(ctl)} at {where}") from None


def _hello(ctl, budget: float, deadline_total: float) -> float | None:
    """The controller's ready message: the time gap it declares; its failures as :class:`ControllerFailed`."""
    from acc_gym.leaderboard import protocol

    try:
        return protocol.recv_hello(ctl.sock, deadline_total)
    except protocol.Timeout:
        raise ControllerFailed(f"exceeded the total budget of {budget:g} s while loading (killed)") from None
    except protocol.ControllerError as exc:
        first, _, tb = str(exc).partition("\n")
        raise ControllerFailed(first, tb or None) from None
    except (protocol.ProtocolError, OSError) as exc:
        raise ControllerFailed(f"broke the protocol while loading: {exc}") from None
    except protocol.Closed:
        raise ControllerFailed(f"{_ended(ctl)} while loading") from None


def simulate(conn, reference: str, jobs: list, step_budget: float, budget: float, traces: bool, log_path: str,
             uid: int | None, sandbox: str, in_flight: int, runner_pid: int, columns: Columns = Columns()) -> None:
    """The simulation process for one controller (see the module docstring)."""
    from acc_gym._process import become_subreaper, die_with_parent, kill_all
    from acc_gym.leaderboard.sandbox import ControllerProcess

    die_with_parent(runner_pid)
    become_subreaper()
    import shutil
    import tempfile
    import warnings

    private_dir = tempfile.mkdtemp(prefix="acc-gym-simulation-")  # nothing of anyone's to import
    os.chdir(private_dir)

    # a suite pins its env id's version (a result names what it ran): gymnasium's advice to move
    # from -v0 to -v1 is noise in the leaderboard's output
    warnings.filterwarnings("ignore", message=".*is out of date. You should consider upgrading",
                            category=DeprecationWarning)
    started = time.monotonic()
    deadline_total = started + budget
    ctl = None
    try:
        import acc_gym  # noqa: F401  (registers the ids)
        from acc_gym.leaderboard.batch import Episode, Lockstep

        ctl = ControllerProcess(reference, log_path=log_path, budget=budget, uid=uid, sandbox=sandbox)
        declared = _hello(ctl, budget, deadline_total)  # the time gap it is judged at
        episodes = [Episode(job.scenario, job.make_env, (job.env_id, job.car), _job_name(job)) for job in jobs]
        done_records: dict[int, dict] = {}
        trips = _Trips(ctl, declared, step_budget, budget, deadline_total, 0)
        cc_envs: dict = {}

        def record_episode(j: int, finished) -> None:
            done_records[j] = episode_record(jobs[j], finished.info)
            if done_records[j]["metrics"]["collision"]:  # UN R157: would the careful driver have avoided it?
                done_records[j]["preventable"] = preventable(jobs[j], cc_envs)
                done_records[j]["points"] = episode_points(finished.info["report"], done_records[j]["preventable"])
            conn.send(("episode", j, done_records[j]))

        lockstep = Lockstep(episodes, in_flight, declared)
        trips.where = _Where(jobs, lockstep, done_records)
        lockstep.run(trips.exchange, record_episode)
        k = worst_index([done_records[j] for j in range(len(jobs))])
        if traces and k is not None:  # the worst episode again, recorded (the same episode: the same numbers)
            lockstep = Lockstep([episodes[k]], 1, declared, record=True)
            trips.where = _Where(jobs, lockstep, done_records, [k])
            worst = lockstep.run(trips.exchange)[0]
            conn.send(("trace", {"position": k, "score": float(worst.info["score"]), "trace": worst.trace,
                                 "time_gap": declared}))
        killed = None  # why the trusted side killed a controller process replaced since (a limit)
        sound = True  # the sandbox answered every round trip so far (its socket is in step)
        fresh = in_flight  # past every slot used so far: a column's copies are fresh ones
        for name, measure, failed_cell in columns:
            try:
                if not sound:  # the controller failed in the column before: a fresh one, as it was loaded
                    killed = killed or ctl.stopped
                    ctl.close()
                    ctl = ControllerProcess(reference, log_path=log_path, budget=budget, uid=uid, sandbox=sandbox)
                    _hello(ctl, budget, deadline_total)  # judged at the time gap it declared first
                    fresh = 0
                column = _Trips(ctl, declared, step_budget, budget, deadline_total, fresh)
                cell, sound = measure(column), True
                fresh = column.next_slot
            except ControllerFailed as exc:
                cell, sound = failed_cell(exc.reason), False
            conn.send((name, cell))
        problem = killed or ctl.stopped or ctl.disk_problem()  # what it wrote after its last answer counts too
        if problem is not None:
            raise ControllerFailed(problem)
        conn.send(("done", None))
    except ControllerFailed as exc:
        conn.send(("failed", {"reason": exc.reason, "traceback": exc.tb}))
    except BaseException as exc:  # noqa: BLE001  (a fault of the simulation itself: reported, never hidden)
        try:
            conn.send(("failed", {"reason": f"the simulation failed: {type(exc).__name__}: {exc}",
                                  "traceback": traceback.format_exc()}))
        except (OSError, EOFError):
            pass
    finally:
        if ctl is not None:
            ctl.close()
        kill_all(uid)  # anything left of the controller, before the runner hears "done"
        conn.send(("closed", None)) if not conn.closed else None
        conn.close()
        shutil.rmtree(private_dir, ignore_errors=True)


class _Trips:
    """Round trips with the sandboxed controller, for the episodes and for each column: budgets
    measured here (the first round trip is exempt from the step budget: the controller loads, or
    the sandbox makes a column's fresh copies, then; only the total budget bounds it), answers
    checked by :func:`acc_gym.leaderboard.batch.check_answers` (a bad one is the controller's
    failure, named with :attr:`where`), and :attr:`next_slot` raised past every slot used (from
    ``first_slot``), so that a later column's copies are fresh ones."""

    def __init__(self, ctl, declared, step_budget: float, budget: float, deadline_total: float, first_slot: int):
        self.ctl, self.declared, self.first_slot = ctl, declared, first_slot
        self.step_budget, self.budget, self.deadline_total = step_budget, budget, deadline_total
        self.next_slot, self.where, self._first = first_slot, "a column", True

    def exchange(self, obs, starts, slots):
        from acc_gym.leaderboard.batch import BadAnswer, check_answers

        if len(slots):
            self.next_slot = max(self.next_slot, int(max(slots)) + 1)
        step_deadline = None if self._first else time.monotonic() + self.step_budget * len(slots)
        self._first = False
        actions = _exchange(self.ctl, obs, starts, slots, step_deadline, self.deadline_total, self.step_budget,
                            self.budget, self.where)
        try:
            return check_answers(actions, len(slots),
                                 lambda k: self.where.row(k) if isinstance(self.where, _Where) else self.where)
        except BadAnswer as exc:
            raise ControllerFailed(f"ValueError: {exc}") from None


def _platoon(column: _Trips) -> dict:
    """The string-stability cell (:func:`acc_gym.evaluation.string_stability.leaderboard_verdict`),
    its column's copies in the controller's sandbox."""
    from acc_gym.evaluation.string_stability import leaderboard_verdict, remote_actors

    column.where = "the string-stability column"
    return leaderboard_verdict(remote_actors(column.exchange, column.first_slot), column.declared)


def _iso15622(column: _Trips) -> dict:
    """The ISO 15622 cell (:mod:`acc_gym.leaderboard.iso15622`): the battery's episodes run here,
    in the simulation process, with the actions of the controller's copies in the sandbox (the
    battery's 30 fresh copies; a controller that cannot be copied is loaded again for each)."""
    from acc_gym.leaderboard.iso15622 import BATTERY, cell
    from acc_gym.standards.battery import SEEDS, remote_iso15622_report

    column.where = f"the ISO 15622 column ({BATTERY})"
    return cell(remote_iso15622_report(column.exchange, column.declared, BATTERY, SEEDS,
                                       first_slot=column.first_slot))


def _waves(column: _Trips, baseline: dict) -> dict:
    """The wave cell (:mod:`acc_gym.leaderboard.waves`): the controller's rings run here with the
    actions of its copies in the sandbox, against the all-human rings ``baseline``."""
    from acc_gym.leaderboard.waves import remote_cell

    column.where = "the wave column"
    return remote_cell(column.exchange, column.declared, baseline)


def _robustness(column: _Trips) -> dict:
    """The robustness cell (:mod:`acc_gym.leaderboard.robustness`): the suite's episodes run here in
    a car with the typical radar and actuators, with the actions of the controller's fresh copies."""
    from acc_gym.leaderboard.robustness import remote_cell

    column.where = "the robustness column"
    return remote_cell(column.exchange, column.declared, first_slot=column.first_slot)


def _alks(column: _Trips) -> dict:
    """The UN R157 bundle's cell (:mod:`acc_gym.leaderboard.alks`): alks-v1's OpenSCENARIO runs here,
    the ego's actions from the controller's fresh copies in the sandbox, one per episode."""
    from acc_gym.leaderboard.alks import remote_cell

    column.where = "the ALKS column"
    return remote_cell(column.exchange, column.declared, first_slot=column.first_slot)


@dataclass
class Outcome:
    """What the runner learned about one controller."""

    reference: str
    status: str = "running"  # then "ok" or "failed"
    reason: str | None = None
    traceback: str | None = None
    episodes: list | None = None
    trace: dict | None = None
    string_stability: dict | None = None
    iso15622: dict | None = None
    waves: dict | None = None
    robustness: dict | None = None
    alks: dict | None = None
    wall_time_s: float = 0.0
    log: str | None = None


@contextlib.contextmanager
def trusted_start(empty: str):
    """Around starting a simulation process: what multiprocessing's ``spawn`` gives the child
    (and the resource tracker it starts once) is safe. Its interpreter runs ``-c``, which puts
    the working directory first on ``sys.path`` until the parent's path replaces it, and that
    path and the working directory are the parent's: for the start, the runner stands in a
    private empty directory ``empty`` (it must outlive the start: the child changes into it),
    with ``PYTHONSAFEPATH`` set (no directory is prepended) and its
    ``sys.path`` reduced to :func:`~acc_gym.leaderboard.sandbox.trusted_path` (without the
    working directory, where strangers' modules are). The runner is single-threaded here."""
    import sys

    from acc_gym.leaderboard.sandbox import CONTROLLER_PATH_ENV, controller_dirs, trusted_path

    cwd, path = os.getcwd(), list(sys.path)
    saved = {k: os.environ.get(k) for k in ("PYTHONSAFEPATH", CONTROLLER_PATH_ENV)}
    try:
        sys.path[:] = trusted_path()
        os.environ[CONTROLLER_PATH_ENV] = os.pathsep.join(controller_dirs())  # the runner's, for the sandbox
        os.environ["PYTHONSAFEPATH"] = "1"
        os.chdir(empty)
        yield
    finally:
        os.chdir(cwd)
        sys.path[:] = path
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class _Running:
    on_episode = None  # ``(reference, received, scheduled)`` as each accepted record arrives

    def __init__(self, ctx, reference: str, jobs: list, step_budget: float, budget: float, traces: bool,
                 log_path: str, uid: int | None, sandbox: str, in_flight: int, *, columns: Columns = Columns(),
                 start_dir: str | None = None, on_episode=None):
        self.reference, self.jobs = reference, jobs
        self.on_episode = on_episode
        self.outcome = Outcome(reference, episodes=[], log=log_path)
        self.ledger = Ledger(jobs)
        self.finished = False
        self.conn, child_conn = ctx.Pipe(duplex=False)
        self.process = ctx.Process(target=simulate, name=f"acc-gym-leaderboard[{reference}]",
                                   args=(child_conn, reference, jobs, step_budget, budget, traces, log_path, uid,
                                         sandbox, in_flight, os.getpid(), columns), daemon=False)
        self.started = time.monotonic()
        with trusted_start(start_dir):
            self.process.start()
        child_conn.close()

    def receive(self) -> bool:
        """Read what the simulation sent; True once it has closed (after done or failed)."""
        try:
            while self.conn.poll():
                kind, *payload = self.conn.recv()
                if kind == "episode":
                    problem = self.ledger.add(*payload)
                    if problem is not None:
                        self.fail(problem)
                    elif self.on_episode is not None:  # a record the ledger accepted: one more episode
                        self.on_episode(self.reference, len(self.ledger.received), len(self.jobs))
                elif kind == "trace":
                    self.outcome.trace = payload[0]
                elif kind == "string_stability":
                    self.outcome.string_stability = payload[0]
                elif kind == "iso15622":
                    self.outcome.iso15622 = payload[0]
                elif kind == "waves":
                    self.outcome.waves = payload[0]
                elif kind == "robustness":
                    self.outcome.robustness = payload[0]
                elif kind == "alks":
                    self.outcome.alks = payload[0]
                elif kind == "done":
                    problem = self.ledger.problem()
                    if problem is not None:
                        self.fail(problem)
                    elif self.outcome.status == "running":  # never "ok" after a failure
                        self.outcome.status = "ok"
                elif kind == "failed":
                    self.fail(payload[0]["reason"], payload[0]["traceback"])
                elif kind == "closed":
                    return True
        except (EOFError, OSError):
            if self.outcome.status == "running":
                self.fail(f"the simulation process ended (exit code {self.process.exitcode})")
            return True
        return False

    def fail(self, reason: str, tb: str | None = None) -> None:
        if self.outcome.status != "failed":
            self.outcome.status, self.outcome.reason, self.outcome.traceback = "failed", reason, tb

    def close(self) -> Outcome:
        self.process.join(30.0)
        if self.process.is_alive():  # pragma: no cover - a simulation that does not end
            self.process.kill()
            self.process.join()
        self.conn.close()
        self.outcome.episodes = [self.ledger.received[j] for j in sorted(self.ledger.received)]
        if self.outcome.status == "running":
            self.fail("the simulation ended without a result")
        self.outcome.wall_time_s = time.monotonic() - self.started
        return self.outcome


def run_isolated(references: list[str], jobs: list[Job], *, workers: int, step_budget: float, budget: float,
                 traces: bool = False, progress=None, log_dir=None, uids: dict | None = None,
                 sandbox="process", in_flight: int = IN_FLIGHT, columns: Columns = Columns(), limits=None,
                 episode_progress=None) -> dict[str, Outcome]:
    """Run ``jobs`` for every controller, ``workers`` controllers at a time (module docstring).

    ``uids`` maps a reference to the user id its sandbox runs as (None: the runner's);
    ``log_dir`` receives one log file per controller. Returns ``{reference: Outcome}`` in
    the order of ``references``; ``progress(outcome)`` is called as each one finishes, and
    ``episode_progress(reference, received, scheduled)`` as each of its episodes does (``received``
    counts the records the runner accepted for it -- made by its simulation, checked against its
    schedule by :class:`Ledger` -- 1, 2, ... up to ``scheduled``, before its ``progress``).
    ``columns`` (:class:`Columns`): after its episodes, each controller's string stability
    (``Outcome.string_stability``), ISO 15622 verdict on the ``iso15622-v1`` battery
    (``Outcome.iso15622``) and wave cell (``Outcome.waves``), measured through the same sandbox.
    ``sandbox``: a kind or a :class:`~acc_gym.leaderboard.sandbox.Sandbox`; ``limits``: its
    :class:`~acc_gym.leaderboard.sandbox.Limits` (default: the sandbox's)."""
    import tempfile

    from acc_gym.leaderboard.sandbox import Sandbox, as_sandbox

    sandbox = as_sandbox(sandbox) if limits is None else Sandbox(as_sandbox(sandbox).kind, limits)

    import shutil

    ctx = multiprocessing.get_context(START_METHOD)
    log_dir = log_dir or tempfile.mkdtemp(prefix="acc-gym-logs-")
    start_dir = tempfile.mkdtemp(prefix="acc-gym-start-")  # empty: where simulations start (trusted_start)
    uids = uids or {}
    pending = list(references)
    running: list[_Running] = []
    done: dict[str, Outcome] = {}
    backstop = budget + 120.0  # [s] the simulation enforces the budgets; this only catches its own faults
    try:
        while pending or running:
            while pending and len(running) < workers:
                ref = pending.pop(0)
                running.append(_Running(ctx, ref, jobs, step_budget, budget, traces, log_file(log_dir, ref),
                                        uids.get(ref), sandbox, in_flight, columns=columns,
                                        start_dir=start_dir, on_episode=episode_progress))
            wait([r.conn for r in running] + [r.process.sentinel for r in running], timeout=POLL_S)
            now = time.monotonic()
            for r in list(running):
                finished = r.receive()
                if not finished and not r.process.is_alive():
                    finished = r.receive() or True
                if not finished and now - r.started > backstop:
                    r.process.kill()
                    r.fail(f"the simulation did not end within {backstop:g} s")
                    finished = True
                if finished:
                    running.remove(r)
                    done[r.reference] = r.close()
                    if progress is not None:
                        progress(done[r.reference])
    finally:
        for r in running:  # interrupted (Ctrl-C, an error here): the simulations clean up their controllers
            r.process.terminate()
        for r in running:
            r.process.join(10.0)
            if r.process.is_alive():
                r.process.kill()
                r.process.join()
        shutil.rmtree(start_dir, ignore_errors=True)
    return {ref: done[ref] for ref in references}


def log_file(log_dir, reference: str) -> str:
    """The log file of a controller: a readable, unique name derived from its reference."""
    import hashlib
    import re

    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", reference)[:60].strip("._") or "controller"
    tag = hashlib.sha256(reference.encode("utf-8")).hexdigest()[:8]
    return os.path.join(str(log_dir), f"{safe}-{tag}.log")
