"""The accelerated evaluation: adaptive cross-entropy rounds, then estimation rounds, resumable.

:func:`estimate_risk` runs, for one controller and one scenario family:

1. **Adaptive rounds** (``method="is"``): round 0 draws ``round_size`` episodes from the
   nominal laws; each round's episodes give the level ``gamma = max(L, rho-quantile of
   S)`` (``S``: the episode's smallest time-to-collision, 0 for a collision;
   ``L``: the failure level, 0 for ``event="collision"``, 1 s for ``event="ttc"``) and
   the elite ``S <= gamma`` -- the failures themselves once a round has at least
   ``max(MIN_FAILURES, rho n / 5)`` of them, and then the failures of every adaptive round
   so far, each weighed by its own round's ratio (all unbiased for the CE objective
   ``E_p[f log g]``), unsmoothed -- from which :meth:`Proposal.fit
   <acc_gym.risk.proposal.Proposal.fit>` makes the next proposal. The rounds stop when
   ``gamma`` reaches ``L`` (the proposal is then fitted to failures themselves), when two
   rounds lowered it by less than 5 % (stalled: a controller that never fails keeps a
   positive smallest time-to-collision however the scenario is tilted), or after
   ``max_rounds``.
   For ``event="preventable-collision"`` ``S`` is that of
   :func:`acc_gym.risk.episodes.performance` for the event (a non-preventable collision
   counts as uninformative) and ``L`` is 0.
2. **Estimation rounds**: episodes from the last proposal -- a pilot round of
   ``round_size``, then rounds sized from the estimate so far to reach the target (see
   ``_planned``) -- until the relative half-width of the estimate is at most
   ``target_rhw`` with at least ``MIN_FAILURES`` failures, or ``budget`` episodes
   (adaptive rounds included) are spent; :class:`RiskResult` says which. ``budget`` is a
   hard ceiling: an adaptive round runs only if it leaves the estimation at least one chunk
   (``CHUNK`` episodes), and estimation rounds are cut to whole chunks of what is left, so a
   run never spends more (and spends less when what is left is not a whole chunk). The estimate pools the estimation rounds
   only (the adaptive rounds' weights are valid too, but their proposals are poor).

**Events.** ``collision``: the controller collides; ``ttc``: its smallest time-to-collision
is under 1 s; ``preventable-collision`` (UN R157, :mod:`acc_gym.standards.r157`): it collides
*and* the careful and competent driver (the built-in ``cc-driver``), driving the same
scenario (same parameters, scenario seed and surrounding drivers), does not. Every run also
estimates a second event from the same episodes (:attr:`RiskResult.other`): ``ttc`` for a
``collision`` run, ``collision`` for the two others -- so a ``preventable-collision`` run
reports ``P(collision)`` beside it. Runs of the two collision events re-drive each episode
the controller collided in with cc-driver (:mod:`acc_gym.risk.episodes`; only those, so
the cost grows with the collisions, not the episodes) and report how many of the
estimation rounds' collisions were preventable and how many not
(:attr:`RiskResult.preventable_collisions`, :attr:`RiskResult.non_preventable_collisions`:
plain counts of the episodes, not weighted; ``ttc`` runs judge nothing and report None).
Since every preventable collision is a collision, a run's ``P(preventable collision)`` is at
most its ``P(collision)``: always so for crude Monte Carlo (plain frequencies of the same
episodes). With importance sampling the regression estimator (:mod:`acc_gym.risk.estimate`)
is linear in the failure flags, so ``P(collision) - P(preventable collision)`` is its
estimate of P(non-preventable collision) from the same episodes -- below 0 only by
sampling noise (weights far from 1 on those collisions and their mean off 1), within that
estimate's interval; the two are not forced into order (decided: no clipping that would
bias either).

``method="crude"`` skips step 1: the proposal is the nominal law (every weight 1). When
no adaptive round saw a single failure and the level never reached ``L`` (the controller
does not fail anywhere the rounds looked), the estimation rounds draw from the nominal
law too: what is left to report is an upper bound, and nominal draws give the tightest
exact one (:func:`acc_gym.risk.estimate.upper_bound`).

Stopping when the interval is narrow enough is a sequential rule; its effect on the
interval's coverage is small at the sample sizes used here, and the coverage study
(``tests/risk/test_risk_coverage.py``, ``benchmarks/bench_risk.py``) measures it.

**Resume.** With ``out`` set, every finished chunk is written there
(``r<round>-c<chunk>.json``, atomically) beside ``risk.json`` (the settings). A run
started again with the same settings reads the chunks it finds and runs the rest: the
proposals are recomputed from the stored episodes, so they come out the same. Different
settings in the same directory are refused, naming the difference.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acc_gym._io import atomic_write
from acc_gym.risk.episodes import CHUNK, RiskChunk, performance, preventability_counts, run_chunk
from acc_gym.risk.estimate import MIN_FAILURES, Estimate, estimate
from acc_gym.risk.proposal import SMOOTHING, Proposal, tilted_keys

FAMILIES = {  # short names of the single-lane families (any scenario id is accepted too)
    "cut-in": "singlelane/2/cut-in", "approach": "singlelane/2/approach", "following": "singlelane/2/car-following",
    "cut-out": "singlelane/2/cut-out", "lane-change": "singlelane/2/lane-change", "separate": "singlelane/2/separate",
}
# failure level L of S [s]: collision S <= 0, min TTC < 1 s, preventable collision S <= 0 (episodes.performance)
EVENTS = {"collision": 0.0, "ttc": 1.0, "preventable-collision": 0.0}
JUDGED = ("collision", "preventable-collision")  # events whose runs re-drive collisions with cc-driver (UN R157)
RHO = 0.1  # elite share of an adaptive round
STALL = 0.95  # adaptive rounds stop when two rounds lowered the level by less than 5 %
SETTINGS_FILE = "risk.json"


def resolve_family(family: str) -> str:
    """The scenario id a family name stands for; ``ValueError`` naming an unknown one."""
    from acc_gym.scenarios.registry import list_scenarios

    if not isinstance(family, str):
        raise ValueError(f"family must be a name or a scenario id, got {family!r}")
    sid = FAMILIES.get(family, family)
    if sid not in list_scenarios():
        raise ValueError(f"unknown family {family!r}: use one of {sorted(FAMILIES)} or a scenario id "
                         "(acc-gym scenarios lists them)")
    return sid


def env_for(scenario_id: str) -> str:
    from acc_gym.envs.registration import ENV_IDS
    from acc_gym.scenarios.registry import scenario_type

    fam = scenario_type(scenario_id).family
    for env_id, (families, settings) in ENV_IDS.items():
        if not settings and fam in families:  # risk estimates run on the family's -v0 id
            return env_id
    raise ValueError(f"no environment runs the {fam!r} family of {scenario_id!r}")


def failed(s: np.ndarray, event: str) -> np.ndarray:
    """Which performances ``S`` (:func:`acc_gym.risk.episodes.performance` for ``event``) are failures of ``event``."""
    return s <= 0.0 if event in ("collision", "preventable-collision") else s < EVENTS[event]


def other_event(event: str) -> str:
    """The second event a run estimates from its episodes (see the module docstring)."""
    return "ttc" if event == "collision" else "collision"


@dataclass
class RiskResult:
    """What :func:`estimate_risk` found."""

    controller: str
    family: str
    scenario_id: str
    method: str
    event: str
    estimate: Estimate  # of the event the run targeted
    other: Estimate  # of the other event, from the same episodes
    stop: str  # "target reached" or "budget spent"
    episodes: int  # all of them, adaptive rounds included
    rounds: list = field(default_factory=list)  # per round: kind, episodes, level, elite, failures
    proposal: dict | None = None
    occurrence_rate: float | None = None  # [1/h] of the family in an hour of traffic
    wall_time_s: float = 0.0
    min_ttc: float | None = None  # the smallest time-to-collision seen in the whole run [s]
    # UN R157 (collision events only, else None): the estimation rounds' collisions that cc-driver avoids / has too
    preventable_collisions: int | None = None
    non_preventable_collisions: int | None = None
    # the estimation episodes' first collisions written as OpenSCENARIO (with out and the osc extra): their
    # files relative to out, episode numbers and whether the re-run collided too
    failures: list = field(default_factory=list)

    def per_hour(self, est: Estimate | None = None) -> dict | None:
        """The estimate as events per hour of driving (times the family's occurrence rate)."""
        est = est or self.estimate
        if self.occurrence_rate is None:
            return None
        r = self.occurrence_rate
        return {"rate": est.p * r, "ci_low": est.ci_low * r, "ci_high": est.ci_high * r,
                "upper_bound": None if est.upper_bound is None else est.upper_bound * r}

    def to_dict(self) -> dict:
        return {"controller": self.controller, "family": self.family, "scenario_id": self.scenario_id,
                "method": self.method, "event": self.event, "estimate": self.estimate.to_dict(),
                "per_hour": self.per_hour(), "other": self.other.to_dict(), "other_per_hour": self.per_hour(self.other),
                "stop": self.stop, "episodes": self.episodes, "rounds": self.rounds, "proposal": self.proposal,
                "occurrence_rate": self.occurrence_rate, "wall_time_s": self.wall_time_s, "min_ttc": self.min_ttc,
                "preventable_collisions": self.preventable_collisions,
                "non_preventable_collisions": self.non_preventable_collisions, "failures": self.failures}


def _check(name: str, value, *, positive=True, integer=False, upper=None):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or (integer and int(value) != value) or not math.isfinite(float(value)) \
            or (positive and value <= 0) or (upper is not None and value > upper):
        what = "a positive integer" if integer else "a positive number"
        raise ValueError(f"{name} must be {what}" + (f" at most {upper}" if upper else "") + f", got {value!r}")
    return int(value) if integer else float(value)


class _Store:
    """The run's directory: settings and finished chunks (or nothing when ``out`` is None)."""

    def __init__(self, out, settings: dict):
        self.dir = None if out is None else Path(out)
        self.settings = settings
        if self.dir is None:
            return
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.dir / SETTINGS_FILE
        if path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, ValueError) as exc:
                raise ValueError(f"{path}: not a risk run's settings ({exc}); use another directory") from None
            if old != settings:
                diff = sorted(k for k in set(old) | set(settings) if old.get(k) != settings.get(k))
                raise ValueError(f"{self.dir} holds a risk run with other settings ({', '.join(diff)}); "
                                 "use another directory or the same settings")
        else:
            atomic_write(path, json.dumps(settings, indent=1, sort_keys=True))

    def _path(self, rnd: int, number: int) -> Path:
        return self.dir / f"r{rnd:03d}-c{number:04d}.json"

    def load(self, chunk: RiskChunk) -> list[dict] | None:
        if self.dir is None:
            return None
        path = self._path(chunk.round, chunk.number)
        if not path.exists():
            return None
        try:
            data = json.loads(path.read_text())
            ok = (data["proposal"] == chunk.proposal and data["start"] == chunk.start and data["size"] == chunk.size
                  and len(data["episodes"]) == chunk.size)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{path}: a damaged chunk file ({exc}); delete it and run again (it is recomputed)") \
                from None
        if not ok:
            raise ValueError(f"{path}: this chunk was run with another proposal or other episodes; delete it and "
                             "run again (it is recomputed)")
        for r in data["episodes"]:
            r["min_ttc"] = math.inf if r["min_ttc"] is None else r["min_ttc"]
            r["min_gap"] = math.inf if r["min_gap"] is None else r["min_gap"]
            if chunk.preventability and r.get("collision") and r.get("preventable") is None:
                raise ValueError(f"{path}: a chunk written without UN R157's preventability (an older acc-gym); "
                                 "delete it and run again (it is recomputed)")
            r.setdefault("preventable", None)
        return data["episodes"]

    def save(self, chunk: RiskChunk, records: list[dict]) -> None:
        if self.dir is None:
            return
        clean = [{**r, "min_ttc": r["min_ttc"] if math.isfinite(r["min_ttc"]) else None,
                  "min_gap": r["min_gap"] if math.isfinite(r["min_gap"]) else None} for r in records]
        atomic_write(self._path(chunk.round, chunk.number), json.dumps(
            {"proposal": chunk.proposal, "start": chunk.start, "size": chunk.size, "episodes": clean}))


def _fingerprint(settings: dict) -> str:
    return hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:16]


def estimate_risk(controller, family: str = "cut-in", *, event: str = "collision", method: str = "is",
                  target_rhw: float = 0.2, budget: int = 20000, round_size: int = 256, max_rounds: int = 10,
                  root_seed: int = 0, drivers: str = "typical", workers: int = 1, scheduler=None, out=None,
                  progress: bool = False, beta: float | None = None, params: dict | None = None) -> RiskResult:
    """P(``event``) per encounter of ``family`` for ``controller``: ``event`` one of
    :data:`EVENTS` -- ``"collision"``, ``"ttc"`` (min TTC < 1 s) or ``"preventable-collision"``
    (a collision UN R157's careful driver, cc-driver, avoids in the same scenario; see the
    module docstring).

    ``controller``: a registered name, ``"module:attribute"``, a saved model's path (what
    the leaderboard accepts) or, with ``workers=1`` and no scheduler, an object with
    ``predict``. See the module docstring for the rounds and :mod:`acc_gym.risk` for the
    method. ``round_size`` is rounded up to whole chunks of 64 episodes. ``params`` fixes
    some of the scenario's parameters (name -> value; a correlated pair both or neither):
    the estimate is then conditional on them (e.g. ``{"v_sv": 33.3}``: cut-ins at 120 km/h),
    and only the others are tilted.
    """
    from acc_gym.scenarios.registry import scenario_type

    if event not in EVENTS:
        raise ValueError(f"unknown event {event!r}; use one of {sorted(EVENTS)}")
    judged = event in JUDGED
    if method not in ("is", "crude"):
        raise ValueError(f"unknown method {method!r}; use 'is' (importance sampling) or 'crude' (Monte Carlo)")
    target_rhw = _check("target_rhw", target_rhw, upper=1.0)
    budget = _check("budget", budget, integer=True)
    if budget < CHUNK:
        raise ValueError(f"budget must be at least {CHUNK} episodes (one chunk), got {budget!r}")
    round_size = CHUNK * math.ceil(_check("round_size", round_size, integer=True) / CHUNK)
    max_rounds = _check("max_rounds", max_rounds, integer=True)
    workers = _check("workers", workers, integer=True)
    if isinstance(root_seed, bool) or not isinstance(root_seed, (int, np.integer)) or root_seed < 0:
        raise ValueError(f"root_seed must be a non-negative integer, got {root_seed!r}")
    is_object = not isinstance(controller, str)
    if is_object and (workers > 1 or scheduler is not None or out is not None):
        raise ValueError("a controller given as an object runs in this process only (workers=1, no scheduler, no "
                         "out directory); give its name or 'module:attribute' to run in parallel or resume")
    from acc_gym.evaluation.runner import load_controller

    from acc_gym.scenarios.registry import DRIVER_CHOICES

    if not isinstance(drivers, str) or drivers not in DRIVER_CHOICES:
        raise ValueError(f"unknown drivers {drivers!r}; use one of {list(DRIVER_CHOICES)}")
    load_controller(controller)  # a bad reference fails here, by name, before any episode
    sid = resolve_family(family)
    stype = scenario_type(sid)
    env_id = env_for(sid)
    from acc_gym.scenarios.registry import check_params

    fixed = check_params(sid, params)
    stype.sample_params(np.random.default_rng(0), fixed)  # unknown or half-given pairs named here
    keys = [k for k in tilted_keys(stype.parameters) if not set((k,) if isinstance(k, str) else k) & set(fixed)]
    if not keys:
        raise ValueError(f"every parameter of {sid!r} that could be tilted is fixed by params={fixed!r}")
    if method == "crude":
        beta = 1.0
    elif beta is None:
        from acc_gym.risk.proposal import DEFENSIVE

        beta = DEFENSIVE
    proposal = Proposal(dict(stype.parameters), {k: stype.parameters[k] for k in keys}, beta)
    label = controller if isinstance(controller, str) else repr(controller)
    settings = {"controller": label, "scenario_id": sid, "event": event, "method": method, "target_rhw": target_rhw,
                "budget": budget, "round_size": round_size, "max_rounds": max_rounds, "root_seed": int(root_seed),
                "drivers": drivers, "beta": beta, "params": fixed, "version": _version()}
    if out is not None and isinstance(controller, str):
        from acc_gym.leaderboard.provenance import code_digest

        settings["controller_code"] = code_digest(controller).get("sha256")
    store = _Store(out, settings)
    fp = _fingerprint(settings)
    bar = _progress(progress, budget)
    started = time.monotonic()
    spent = 0
    min_ttc = math.inf

    def run_round(rnd: int, prop: Proposal, size: int) -> list[dict]:
        nonlocal spent, min_ttc
        pdict = prop.to_dict()
        chunks = [RiskChunk(sid, pdict, controller, int(root_seed), rnd, k * CHUNK, CHUNK, env_id, drivers, k, fixed,
                            judged) for k in range(size // CHUNK)]
        got: dict[int, list[dict]] = {}
        todo = []
        for c in chunks:
            old = store.load(c)
            if old is None:
                todo.append(c)
            else:
                got[c.number] = old
                bar(len(old))
        if todo:
            from acc_gym.campaigns.backends import execute

            for c, recs in execute(todo, workers=workers, scheduler=scheduler, fingerprint=f"risk-{fp}-r{rnd}",
                                   fn=run_chunk):
                store.save(c, recs)
                got[c.number] = recs
                bar(len(recs))
        recs = [r for k in sorted(got) for r in got[k]]
        spent += len(recs)
        s = performance(recs)
        if s.size:
            min_ttc = min(min_ttc, float(np.min(s)))
        return recs

    adaptive = method == "is"
    try:
        proposal, pooled, rounds, stop = search(proposal, run_round, functools.partial(performance, event=event),
                                                event=event, budget=budget, round_size=round_size,
                                                max_rounds=max_rounds if adaptive else 0, target_rhw=target_rhw)
    finally:
        bar(None)
    e = exposure(rounds)
    est = estimate_records(pooled, performance(pooled, event), event, spent, e)
    second = other_event(event)
    other = estimate_records(pooled, performance(pooled, second), second, spent, e)
    rate = stype.occurrence_rate
    split = preventability_counts(pooled) if judged else (None, None)
    failures = [] if out is None or is_object else write_failures(controller, stype, fixed, drivers, env_id,
                                                                   pooled, Path(out))
    return RiskResult(label, family, sid, method, event, est, other, stop, spent, rounds,
                      proposal.to_dict() if adaptive else None,
                      None if rate is None else float(rate.mean), time.monotonic() - started,
                      None if not math.isfinite(min_ttc) else min_ttc, *split, failures)


MAX_FAILURES_WRITTEN = 5  # the estimation episodes' collisions write_failures writes, at most


def write_failures(controller: str, stype, fixed: dict, drivers: str, env_id: str, records: list, out: Path) -> list:
    """The first :data:`MAX_FAILURES_WRITTEN` collisions of ``records`` (the estimation episodes)
    as OpenSCENARIO in ``out/failures/`` (``<family>-episode<N>.xosc`` and ``.xodr``): each
    scenario is built again from its draw and driven again by ``controller`` in ``env_id``
    (:func:`acc_gym.scenarios.openscenario.writer.export`, the trajectories driven, the
    controller's too). ``[{"xosc", "xodr", "episode", "collided"}]`` (paths relative to
    ``out``; ``collided``: the re-run collided as the recorded one did). Needs the ``osc``
    extra; without it nothing is written."""
    try:
        import scenariogeneration  # noqa: F401
    except ImportError:
        return []
    from acc_gym.scenarios.openscenario.writer import export, file_stem

    written = []
    for r in [r for r in records if r["collision"]][:MAX_FAILURES_WRITTEN]:
        sc = stype.build({**fixed, **r["params"]}, r["seed"], drivers)
        ex, info, _ = export(sc, controller, out / "failures", name=f"{file_stem(sc.id)}-episode{r['episode']}",
                             env_id=env_id)
        written.append({"xosc": f"failures/{ex.xosc.name}", "xodr": f"failures/{ex.xodr.name}",
                        "episode": int(r["episode"]), "collided": bool(info["report"]["metrics"]["collision"])})
    return written


def search(proposal: Proposal, simulate, perf, *, event: str = "collision", budget: int, round_size: int,
           max_rounds: int, target_rhw: float) -> tuple[Proposal, list[dict], list[dict], str]:
    """The rounds of the module docstring, for any simulation.

    ``simulate(round, proposal, size)`` returns ``size`` records (dicts with ``params``:
    name -> value of the tilted parameters, ``log_w`` and ``nominal`` as
    :func:`acc_gym.risk.episodes.run_chunk` makes them); ``perf(records)`` their
    performances ``S`` for ``event`` (:func:`acc_gym.risk.episodes.performance`). Returns the
    last proposal, the estimation rounds' records, a summary per round and why it stopped
    (``"target reached"`` or ``"budget spent"``).
    """
    level = EVENTS[event]
    rounds: list[dict] = []
    spent = 0
    rnd = 0
    failures_seen: list[dict] = []  # of every adaptive round: each weighed against its own round's proposal
    if budget < CHUNK:
        raise ValueError(f"budget must be at least {CHUNK} episodes (one chunk), got {budget!r}")
    for _ in range(max_rounds):
        if spent + round_size + CHUNK > budget:  # an adaptive round must leave the estimation a chunk
            break
        recs = simulate(rnd, proposal, round_size)
        spent += len(recs)
        s = perf(recs)
        finite = s[np.isfinite(s)]
        gamma = max(level, float(np.quantile(finite, RHO))) if finite.size else math.inf
        fails = failed(s, event)
        if fails.sum() >= max(MIN_FAILURES, RHO * len(recs) / 5):
            gamma = level  # enough failures to fit to (a collision's S jumps from ~0.4 s to 0: no level between)
        elite = fails if gamma <= level else (s <= gamma)
        rounds.append({"round": rnd, "kind": "adaptive", "episodes": len(recs), "level": gamma,
                       "elite": int(elite.sum()), "failures": int(fails.sum()), "beta": proposal.beta})
        rnd += 1
        failures_seen.extend(r for r, f in zip(recs, fails) if f)
        if not elite.any():
            break  # nothing ever closed in: no direction to tilt towards
        chosen = failures_seen if gamma <= level else [r for r, e in zip(recs, elite) if e]
        w = np.exp(np.array([r["log_w"] for r in chosen]))
        x = {n: np.array([r["params"][n] for r in chosen]) for n in proposal.names}
        proposal = proposal.fit(x, w, 1.0 if gamma <= level else SMOOTHING)
        if gamma <= level:
            break
        if len(rounds) >= 3 and gamma >= STALL * rounds[-3]["level"]:
            break  # two rounds without getting 5 % closer: the failure region is out of reach (or not there)
    if rounds and not any(r["failures"] for r in rounds) and rounds[-1]["level"] > level:
        # nothing failed however the rounds tilted it: what is left is a bound, and the nominal
        # law gives the tightest exact one (every draw counts fully in the exposure)
        proposal = Proposal(proposal.nominal, {k: proposal.nominal[k] for k in proposal.tilted}, 1.0)
    pooled: list[dict] = []
    stop = "budget spent"
    size = round_size  # the pilot round; then rounds planned from the estimate so far
    while True:
        remaining = budget - spent
        if pooled and remaining < CHUNK:
            break
        size = min(size, max(CHUNK, CHUNK * (remaining // CHUNK)))
        recs = simulate(rnd, proposal, size)
        spent += len(recs)
        pooled.extend(recs)
        rounds.append({"round": rnd, "kind": "estimation", "episodes": len(recs), "level": level, "elite": None,
                       "failures": int(failed(perf(recs), event).sum()), "beta": proposal.beta})
        rnd += 1
        est = estimate_records(pooled, perf(pooled), event, spent, exposure(rounds))
        if est.failures >= MIN_FAILURES and est.rhw <= target_rhw:
            stop = "target reached"
            break
        size = _planned(est, len(pooled), target_rhw, round_size)
    return proposal, pooled, rounds, stop


def _planned(est: Estimate, n: int, target_rhw: float, round_size: int) -> int:
    """Episodes to add so that the pooled estimate reaches ``target_rhw`` (its half-width
    shrinks as ``1 / sqrt(n)``), with a 10 % margin, in whole chunks; a round's worth while
    there are too few failures to plan from. Planning the rest in one round, rather than
    looking after every round, keeps the number of looks -- and the optimism that stopping
    at a lucky look adds to the interval -- small."""
    if est.failures < MIN_FAILURES or not math.isfinite(est.rhw):
        return round_size
    need = n * ((est.rhw / target_rhw) ** 2 * 1.1 - 1.0)
    return max(CHUNK, CHUNK * math.ceil(need / CHUNK))


def exposure(rounds: list[dict]) -> float:
    """The run's exposure: every episode's nominal share, summed (:func:`acc_gym.risk.estimate.upper_bound`)."""
    return float(sum(r["episodes"] * r["beta"] for r in rounds))


def estimate_records(recs: list[dict], s: np.ndarray, event: str, spent: int, exposure: float) -> Estimate:
    """The estimate of ``event`` from records and their performances ``s`` for that event
    (:func:`acc_gym.risk.episodes.performance` with ``event``)."""
    return estimate(np.array([r["log_w"] for r in recs]), failed(s, event), event=event, episodes_total=spent,
                    exposure=exposure, nominal=np.array([r["nominal"] for r in recs]))


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("acc-gym")
    except metadata.PackageNotFoundError:  # pragma: no cover
        return "unknown"


def _progress(enabled: bool, total: int):
    """A callable ``bar(n)`` advancing a progress bar on stderr by ``n`` episodes of at most
    ``total`` (``bar(None)`` closes it; :mod:`acc_gym._progress`: shown on a terminal only)."""
    from acc_gym._progress import progress_bar

    bar = progress_bar("risk", total, unit="episodes", enabled=enabled).start()

    def advance(n):
        if n is None:
            bar.close()
        else:
            bar.advance(n)

    return advance
