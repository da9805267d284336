"""Score controllers on versioned suites and rank them (what ``acc-gym leaderboard`` runs).

Defaults, and why:

* **suites**: all five (``carfollowing-v1``, ``malicious-v3``, ``ncap-v1``, ``ncap-v2``,
  ``singlelane-v3``) -- the leaderboard is about behaviour in every kind of traffic; the
  four before ``ncap-v2`` (365 episodes, 1.7 simulated hours) took a built-in controller
  about 10 s in its process, and ``ncap-v2`` (Euro NCAP 2026's 57 points) adds a few
  seconds each. ``episodes=N`` caps each suite at its first ``N`` episodes for quick runs
  (the manifest records the cap, and the table says how many ran).
* **split**: ``test`` (tune on ``dev``).
* **controllers**: every registered name (:mod:`acc_gym.controllers`): the built-ins, the
  shipped trained policy and any installed package's controllers.
* **columns**: string stability and ISO 15622 (the ``iso15622-v1`` battery's 30 episodes,
  about 3-5 s more per controller; 50 s -> 64-71 s for the built-ins at ``episodes=2`` on
  two cores) are measured for every controller; ``string_stability=False`` /
  ``iso15622=False`` skip them. Neither changes points or ranks.
* **workers**: 2 controllers at a time; **step budget** 1 s per ``predict`` call (a
  hand-written law takes microseconds, a small policy network about a millisecond);
  **total budget** 600 s per controller.

Each episode is run by :func:`acc_gym.evaluation.runner.run_episode` on
``gym.make(suite.env_id)`` with the suite's scenario and its seed, in the controller's
own process (:mod:`acc_gym.leaderboard.isolation`); the results are aggregated and
ranked by :mod:`acc_gym.leaderboard.results`, and, with ``out``, written there with the
HTML report (:mod:`acc_gym.leaderboard.report`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import platform
import shutil
import sys
import tempfile
import time
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from acc_gym.leaderboard.isolation import IN_FLIGHT, START_METHOD, Columns, Job, run_isolated
from acc_gym.leaderboard.results import (
    RANKING_RULE,
    json_safe,
    rank,
    results_key,
    signature,
    summarise_controller,
    write_files,
)

DEFAULT_WORKERS = 2
DEFAULT_STEP_BUDGET = 1.0  # [s]
DEFAULT_BUDGET = 600.0  # [s]
VERSIONED = ("acc-gym", "numpy", "gymnasium", "scipy", "numba", "matplotlib", "proxsuite", "qpsolvers", "daqp",
             "stable-baselines3", "torch")


def default_controllers() -> list[str]:
    from acc_gym.controllers import registered_controllers

    return list(registered_controllers())


def versions() -> dict:
    """Python and the installed versions of the packages results depend on (None: not installed)."""
    out = {"python": platform.python_version()}
    for name in VERSIONED:
        try:
            out[name.replace("-", "_")] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name.replace("-", "_")] = None
    import acc_gym
    from acc_gym.drivers.mpc import ENV_DRIVER_MODEL

    out["acc_gym"] = acc_gym.__version__
    out["driver_model"] = ENV_DRIVER_MODEL  # the surrounding MPC drivers' behaviour (acc_gym.drivers.mpc)
    return out


def _positive(name: str, value, integer: bool = False):
    bad = isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0
    if not bad and integer and int(value) != value:
        bad = True
    if bad:
        kind = "a positive integer" if integer else "a positive number of seconds"
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    return int(value) if integer else float(value)


def check_controllers(controllers) -> list[str]:
    if controllers is None:
        return default_controllers()
    if isinstance(controllers, str):
        controllers = [controllers]
    refs = list(controllers)
    if not refs:
        raise ValueError("controllers must name at least one controller")
    for ref in refs:
        if not isinstance(ref, str) or not ref:
            raise ValueError(f"a controller must be given by reference (a built-in name, 'module:attribute' or a "
                             f"saved model path) so that it can be loaded in its own process, got {ref!r}")
    dup = sorted({r for r in refs if refs.count(r) > 1})
    if dup:
        raise ValueError(f"controller(s) {dup} given more than once")
    return refs


def _path_like(ref: str) -> bool:
    return ":" not in ref and (os.sep in ref or "/" in ref or ref.endswith(".zip") or ref.startswith("."))


def resolve_references(refs: list[str]) -> dict[str, str]:
    """``{reference as given: reference as the controller's process is given it}``, resolved
    here, in the trusted runner, from the directory the leaderboard is run from (the
    controller's process runs in a directory of its own): a registered name and a
    ``module:attribute`` stay as they are (the module is looked up from this directory too,
    :func:`acc_gym.leaderboard.sandbox.search_path`); an existing file or directory (a saved
    model, a run directory of ``acc-gym train``) becomes its absolute path. A reference that
    looks like a path (a ``/``, a ``.zip``) and names nothing is a ``ValueError`` naming it and
    the directory it was looked up in; two references to one path are one too."""
    from acc_gym.controllers import registered_controllers

    registered = registered_controllers()
    out = {}
    for ref in refs:
        if ref in registered:
            out[ref] = ref
        elif os.path.exists(ref):
            out[ref] = os.path.abspath(ref)
        elif _path_like(ref):
            raise ValueError(f"controller {ref!r}: no such file or directory (looked up from {os.getcwd()!r})")
        else:
            out[ref] = ref
    seen: dict[str, str] = {}
    for ref, resolved in out.items():
        if resolved in seen:
            raise ValueError(f"controllers {seen[resolved]!r} and {ref!r} are the same ({resolved!r})")
        seen[resolved] = ref
    return out


class OutputError(OSError):
    """The results could not be written to ``path``; ``results`` holds them all the same."""

    def __init__(self, path, reason: str, results: dict | None = None):
        super().__init__(f"could not write the leaderboard to {str(path)!r}: {reason}")
        self.path, self.results = str(path), results


def check_output(out) -> Path:
    """``out`` as a directory the results can be written to (checked before anything runs):
    an existing directory, or a new one in an existing, writable parent; an existing file,
    a missing parent or a read-only place is an :class:`OutputError` naming the path."""
    out = Path(out).absolute()
    if out.exists() and not out.is_dir():
        raise OutputError(out, "it exists and is not a directory")
    parent = out.parent
    if not parent.is_dir():
        raise OutputError(out, f"its parent directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK) or (out.exists() and not os.access(out, os.W_OK | os.X_OK)):
        raise OutputError(out, "it is not writable")
    return out


def publish(staging: Path, out: Path) -> None:
    """Move the finished ``staging`` directory into place as ``out`` (renames in one parent:
    a reader finds the old complete directory or the new one, never a mix)."""
    old = None
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
        os.replace(out, old / out.name)
    try:
        os.replace(staging, out)
    except BaseException:
        if old is not None:  # put the previous results back
            os.replace(old / out.name, out)
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def sandbox_settings(refs: list[str], sandbox: str, allow_root: bool = False, private: bool = False) \
        -> tuple[dict, dict]:
    """Per-controller user ids and what the manifest says about the sandbox (refusals:
    :func:`acc_gym.leaderboard.sandbox.vet`)."""
    from acc_gym.leaderboard.sandbox import SANDBOXES, UID_BASE, bwrap_problem, own_uid_possible, vet

    if sandbox not in SANDBOXES:
        raise ValueError(f"unknown sandbox {sandbox!r}; use one of {list(SANDBOXES)}")
    possible, why = own_uid_possible([r for r in refs if os.path.exists(r)])
    warning = vet(refs, possible, why, allow_root, private)
    base = UID_BASE + 100 * (os.getpid() % 1_000_000)
    uids = {ref: base + k for k, ref in enumerate(refs)} if possible else {}
    if sandbox == "bwrap":  # refuse before anything runs, rather than rank every controller as crashed
        problem = bwrap_problem(base + 99 if possible else None)
        if problem is not None:
            raise RuntimeError(f"sandbox 'bwrap' is not usable: {problem}")
    return uids, {"kind": sandbox, "uid_isolated": possible, "why_not": why or None, "warning": warning}


def _risk_settings(risk) -> dict | None:
    """``risk`` with its defaults; ``ValueError`` naming an unknown option or a bad family."""
    if risk is None or risk is False:
        return None
    if risk is True:
        risk = {}
    if not isinstance(risk, dict):
        raise ValueError(f"risk must be a dict of options (family, budget, target_rhw) or True, got {risk!r}")
    unknown = set(risk) - {"family", "budget", "target_rhw"}
    if unknown:
        raise ValueError(f"unknown risk option(s) {sorted(unknown)}; use family, budget, target_rhw")
    from acc_gym.risk.run import _check, resolve_family

    out = {"family": "cut-in", "budget": 4096, "target_rhw": 0.2, **risk}
    resolve_family(out["family"])
    out["budget"] = _check("risk budget", out["budget"], integer=True)
    out["target_rhw"] = _check("risk target_rhw", out["target_rhw"], upper=1.0)
    return out


def _platoon_settings() -> dict:
    from acc_gym.evaluation.string_stability import LEADERBOARD_CONFIG, LEADERBOARD_FREQUENCIES, TOLERANCE

    c = LEADERBOARD_CONFIG
    return {"vehicles": c.vehicles, "speed": c.speed, "set_speed": c.cruise_speed, "settle_s": c.settle,
            "frequencies_hz": list(LEADERBOARD_FREQUENCIES), "tolerance": TOLERANCE,
            "rule": "string stable when the largest vehicle-to-vehicle speed gain over the frequencies is at most "
                    f"1 + {TOLERANCE:g}"}


def _waves_settings(baseline) -> dict:
    from acc_gym.leaderboard.waves import settings

    return settings(baseline)


def _car(car: dict | None) -> tuple[tuple, dict | None]:
    """``car`` as a job's ``car`` (its settings validated into configs, as pairs) and as the manifest
    records it; ``((), None)`` for none or the ideal car."""
    from dataclasses import asdict

    from acc_gym.onboard import actuator_config, sensor_config

    if not car:
        return (), None
    unknown = set(car) - {"sensors", "actuators"}
    if unknown:
        raise ValueError(f"car settings {sorted(unknown)} unknown; known: ['actuators', 'sensors']")
    cfg = {"sensors": sensor_config(car.get("sensors")), "actuators": actuator_config(car.get("actuators"))}
    if cfg["sensors"].ideal and cfg["actuators"].ideal:
        return (), None
    return tuple(sorted(cfg.items())), {k: asdict(v) for k, v in cfg.items()}


def _alks_settings() -> dict:
    from acc_gym.leaderboard.alks import settings

    return settings()


def _robustness_settings() -> dict:
    from acc_gym.leaderboard.robustness import settings

    return settings()


def _iso15622_settings() -> dict:
    from acc_gym.leaderboard.iso15622 import settings

    return settings()


def run_leaderboard(suites=None, split: str = "test", controllers=None, *, out=None, workers: int = DEFAULT_WORKERS,
                    step_budget: float = DEFAULT_STEP_BUDGET, budget: float = DEFAULT_BUDGET,
                    episodes: int | None = None, report: bool = True, progress=None, sandbox: str = "process",
                    show=None, secret=None, risk: dict | None = None, string_stability: bool = True,
                    iso15622: bool = True, waves: bool = True, robustness: bool = True, alks: bool = False,
                    car: dict | None = None,
                    allow_root: bool = False, limits=None, phase=None,
                    warm: bool = True, episode_progress=None) -> dict:
    """Score ``controllers`` on ``suites`` (names; default all) and rank them; returns the results dict.

    ``out``: a directory to write results.json, results.csv, leaderboard.md, (with
    ``report``) report.html and the controllers' logs (``logs/``) into; it is checked
    before anything runs, everything is written into a temporary directory beside it that
    then replaces it, and a failed write raises :class:`OutputError` carrying the results.
    ``show(results)`` is called with the ranking before anything is written (the CLI
    prints it there). ``progress(outcome)`` is called as each controller ends, and
    ``episode_progress(name, received, scheduled)`` as each of its episodes does
    (:func:`~acc_gym.leaderboard.isolation.run_isolated`; the count is the trusted side's).
    ``controllers``: references resolved from the working directory (:func:`resolve_references`;
    results name each controller as given, its ``reference`` is what ran).
    ``warm``: compile the simulation's kernels first, in ``workers`` processes side by side
    (:mod:`acc_gym.leaderboard.warmup`; seconds when they are cached). ``phase(name, notice)`` is
    called as each stage starts: ``("kernels", text)`` before that (``text``: a notice when nothing
    is cached yet, a first run: minutes; else None), ``("controllers", None)`` when they start.
    ``sandbox``: ``"process"`` or ``"bwrap"`` (:mod:`acc_gym.leaderboard.sandbox`).
    ``split``: ``"dev"``, ``"test"`` or ``"private"``; the private split's episodes come from
    ``secret`` (bytes or text, read by :func:`acc_gym.suites.private.read_secret` from a file
    only its owner can read) and the manifest records only its commitment
    (:mod:`acc_gym.suites.private`); a private run's files are the host's only (0600 in 0700).
    ``risk``: also estimate each controller's collision probability per encounter of a
    family by importance sampling, through the same sandbox
    (:func:`acc_gym.risk.isolated.leaderboard_risk`; a dict of its options: ``family``
    (default ``"cut-in"``), ``budget`` (episodes, default 4096), ``target_rhw`` (0.2)); the
    estimate goes into each controller's ``risk`` and a column of the table.
    ``string_stability``: after its episodes, each controller's column of 8 copies is measured
    in the same sandbox (:func:`acc_gym.evaluation.string_stability.leaderboard_verdict`; a few
    seconds each); the verdict goes into each controller's ``string_stability`` and a column.
    ``iso15622``: then each controller drives the ``iso15622-v1`` battery (30 episodes) in the same
    sandbox and ISO 15622's envelope is checked on its drives (:mod:`acc_gym.leaderboard.iso15622`;
    a few seconds each); the cell goes into each controller's ``iso15622`` and a column.
    ``waves``: then each controller drives one vehicle of five rings of 22 human-like drivers
    (:mod:`acc_gym.leaderboard.waves`; the all-human rings are run once, here, about 10 s; each
    controller's about 5 s); the ratio of speed sds goes into each controller's ``waves`` and a
    column. ``robustness``: then each controller drives the ncap-v2 test episodes in a car with the
    typical radar and actuators (:mod:`acc_gym.leaderboard.robustness`; a few seconds each): the
    share qualified and the collisions (preventable or not) go into each controller's
    ``robustness`` and a column. ``alks``: then each controller drives UN R157's ALKS bundle as
    the suite alks-v1 (43 OpenSCENARIO episodes, :mod:`acc_gym.leaderboard.alks`; about 25 s each,
    so off by default): the cell goes into each controller's ``alks`` and a column. No column
    changes points or ranks.
    ``car``: the suites' episodes in a car with these ``gym.make`` settings (``sensors``,
    ``actuators``: presets or configs, :mod:`acc_gym.onboard`; None: the ideal car), recorded in the
    manifest (``settings.car``); the ranking is then the ranking in that car.
    ``allow_root``: run strangers' code as root without a user id of its own (refused otherwise,
    :func:`acc_gym.leaderboard.sandbox.vet`); the reports then carry the warning.
    ``limits``: each controller's :class:`acc_gym.leaderboard.sandbox.Limits` (log, memory,
    processes, /tmp, file size; default ``Limits()``).
    """
    from acc_gym.leaderboard.provenance import code_digest
    from acc_gym.suites import SPLITS, get_suite, list_suites
    from acc_gym.suites import private as private_split
    from acc_gym.suites.suite import content_digest, entry, sha256_of

    names = list_suites() if suites is None else ([suites] if isinstance(suites, str) else list(suites))
    if not names:
        raise ValueError("suites must name at least one suite")
    if len(set(names)) != len(names):
        raise ValueError(f"suites {names} name a suite more than once")
    car_items, car_settings = _car(car)
    suite_objs = [get_suite(n) for n in names]  # ValueError naming an unknown one
    if split not in (*SPLITS, private_split.PRIVATE):
        raise ValueError(f"unknown split {split!r}; use one of {[*SPLITS, private_split.PRIVATE]}")
    if split == private_split.PRIVATE:
        secret = private_split.read_secret() if secret is None else private_split.check_secret(secret)
    elif secret is not None:
        raise ValueError(f"a secret is for the private split only (split {split!r} is public)")
    refs = check_controllers(controllers)
    resolved = resolve_references(refs)
    given = {v: k for k, v in resolved.items()}  # what ran -> the name it was given
    workers = _positive("workers", workers, integer=True)
    step_budget = _positive("step_budget", step_budget)
    budget = _positive("budget", budget)
    if episodes is not None:
        episodes = _positive("episodes", episodes, integer=True)
    traces = out is not None and report
    key = results_key(run=True)  # read (and checked) before anything runs; controllers never see it
    from acc_gym.leaderboard.sandbox import Limits, Sandbox, containment

    sandbox = Sandbox(sandbox, limits or Limits())  # ValueError naming an unknown kind or a bad limit
    uids, sandbox_info = sandbox_settings(list(resolved.values()), sandbox.kind, allow_root, split == private_split.PRIVATE)
    sandbox_info.update(containment(sandbox))
    out_dir = check_output(out) if out is not None else None

    jobs, suite_info = [], []
    for s in suite_objs:
        if split == private_split.PRIVATE:  # nothing shipped identifies these, nor their order
            built = private_split.private_episodes(s, secret)
            info = {"root_seed": None, "hash": sha256_of([entry(sc) for sc in built]),
                    "content_sha256": content_digest(built), "content_matches": None}
        else:
            built = s.episodes(split)
            definition = s.to_dict()
            info = {"root_seed": s.root_seed(split), "hash": s.hash(split),
                    "content_sha256": definition["content_sha256"][split],
                    "content_matches": content_digest(built) == definition["content_sha256"][split]}
        run = built if episodes is None else built[:episodes]
        jobs += [Job(s.name, split, k, s.env_id, sc, car_items) for k, sc in enumerate(run)]
        suite_info.append({"name": s.name, "version": s.version, "family": s.family, "env_id": s.env_id,
                           "split": split, **info, "definition_hash": s.hash(),
                           "episodes_defined": len(built), "episodes_run": len(run),
                           "hours": sum(sc.duration for sc in run) / 3600.0})
    code = {ref: code_digest(resolved[ref]) for ref in refs}  # located, never run, in this process
    risk = _risk_settings(risk)

    t0 = time.monotonic()
    created = datetime.now(timezone.utc).isoformat(timespec="seconds")
    if out_dir is not None:
        staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", suffix=".tmp", dir=out_dir.parent))
        logs = staging / "logs"
    else:
        staging, logs = None, Path(tempfile.mkdtemp(prefix="acc-gym-logs-"))
    logs.mkdir(exist_ok=True)
    try:
        if warm:
            from acc_gym.leaderboard.warmup import needs_compiling, warm_kernels

            if phase is not None:
                phase("kernels", "compiling the simulation's kernels: the first run on this machine takes minutes "
                                 "longer, later runs load them in seconds" if needs_compiling() else None)
            per_env: dict[str, int] = {}
            for job in jobs:
                per_env[job.env_id] = per_env.get(job.env_id, 0) + 1
            warm_kernels({e: min(IN_FLIGHT, n) for e, n in per_env.items()}, processes=workers)

        baseline = None
        if waves:
            from acc_gym.leaderboard.waves import human_baseline

            if phase is not None:
                phase("waves", None)
            baseline = human_baseline()  # trusted code, once: every controller's cell divides by it
        if phase is not None:
            phase("controllers", None)

        def told(outcome):  # the controller by the name it was given
            progress(dataclasses.replace(outcome, reference=given.get(outcome.reference, outcome.reference)))

        def ticked(reference, received, scheduled):
            episode_progress(given.get(reference, reference), received, scheduled)

        outcomes = run_isolated(list(resolved.values()), jobs, workers=workers, step_budget=step_budget,
                                budget=budget, traces=traces, progress=None if progress is None else told,
                                episode_progress=None if episode_progress is None else ticked,
                                log_dir=logs, uids=uids, sandbox=sandbox,
                                columns=Columns(platoon=bool(string_stability), iso15622=bool(iso15622),
                                                waves=baseline, robustness=bool(robustness),
                                                alks=bool(alks)))
    except BaseException:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        raise
    outcomes = {given[ran]: o for ran, o in outcomes.items()}
    risks = {}
    if risk is not None:
        from acc_gym.risk.isolated import leaderboard_risk

        run_kwargs = {"workers": 1, "step_budget": step_budget, "budget": budget, "log_dir": logs, "uids": uids,
                      "sandbox": sandbox}
        risks = {ref: leaderboard_risk(resolved[ref], **risk, run_kwargs=run_kwargs) for ref, o in outcomes.items()
                 if o.status == "ok"}
    trace_map = {}
    for ref, o in outcomes.items():
        if o.trace is not None:
            ep = o.episodes[o.trace["position"]]
            scenario = next((j.scenario for j in jobs if (j.suite, j.episode) == (ep["suite"], ep["episode"])), None)
            trace_map[ref] = {**o.trace, "scenario": scenario}  # the report re-scores it to say what cost points
    failing = {}
    if staging is not None and trace_map:  # each failing worst episode as OpenSCENARIO (acc_gym.leaderboard.failures)
        from acc_gym.leaderboard.failures import write_failing_episodes

        failing = write_failing_episodes(trace_map, {ref: o.episodes for ref, o in outcomes.items()}, staging)
    entries = []
    for ref, o in outcomes.items():
        notes = []
        if o.trace is not None:
            recorded = o.episodes[o.trace["position"]]["score"]
            if o.trace["score"] != recorded:
                notes.append(f"not deterministic: its worst episode scored {recorded:.3f}, then "
                             f"{o.trace['score']:.3f} when re-run for the report")
        entries.append({"name": ref, "reference": resolved[ref], "code": code[ref], "status": o.status, "reason": o.reason,
                        "traceback": o.traceback, "wall_time_s": o.wall_time_s, "notes": notes,
                        "log": f"logs/{Path(o.log).name}" if staging is not None else o.log,
                        "summary": summarise_controller(o.episodes, names) if o.status == "ok" else None,
                        "episodes": o.episodes, **({"risk": risks.get(ref)} if risk is not None else {}),
                        **({"failing_episode": failing[ref]} if ref in failing else {}),
                        **({"string_stability": o.string_stability} if string_stability else {}),
                        **({"iso15622": o.iso15622} if iso15622 else {}),
                        **({"waves": o.waves} if waves else {}),
                        **({"robustness": o.robustness} if robustness else {}),
                        **({"alks": o.alks} if alks else {})})
    ranking = rank(entries)
    manifest = {
        "format": "acc_gym.leaderboard/1", "created": created, "versions": versions(),
        "platform": platform.platform(), "cpu_count": os.cpu_count(), "command": list(sys.argv),
        "suites": suite_info, "split": split, "episodes_cap": episodes, "controllers": refs,
        "secret_commitment": private_split.commitment(secret) if split == private_split.PRIVATE else None,
        "settings": {"workers": workers, "step_budget_s": step_budget, "budget_s": budget,
                     "start_method": START_METHOD, "in_flight": IN_FLIGHT, "risk": risk,
                     "string_stability": _platoon_settings() if string_stability else None,
                     "iso15622": _iso15622_settings() if iso15622 else None,
                     "waves": _waves_settings(baseline) if waves else None,
                     "robustness": _robustness_settings() if robustness else None,
                     "alks": _alks_settings() if alks else None,
                     "car": car_settings},
        "sandbox": sandbox_info, "ranking_rule": RANKING_RULE,
        "results_key_id": None if key is None else signature({}, key)["key_id"],
        "timings": {"total_wall_s": time.monotonic() - t0,
                    "controllers_wall_s": {e["name"]: e["wall_time_s"] for e in entries}},
    }
    results = json_safe({"manifest": manifest, "ranking": ranking, "controllers": entries})
    if show is not None:
        show(results)
    if out_dir is None:
        return results
    try:
        html = None
        if report:
            from acc_gym.leaderboard.report import render_html

            html = render_html(results, trace_map)
        names = write_files(results, staging, html, key)
        umask = os.umask(0)
        os.umask(umask)
        if split == private_split.PRIVATE:  # its episodes are the secret's: the host's eyes only
            from acc_gym.leaderboard.sandbox import host_only

            host_only(staging)
        else:
            os.chmod(staging, 0o777 & ~umask)  # as a directory made with mkdir would be (mkdtemp's is private)
        publish(staging, out_dir)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise OutputError(out_dir, f"{type(exc).__name__}: {exc}", results) from exc
    results["files"] = {k: str(out_dir / Path(v).name) for k, v in names.items()}  # not in results.json
    return results
