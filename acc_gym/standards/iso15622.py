"""ISO 15622:2018 (adaptive cruise control): the envelope, checked on drives as the standard checks it.

The standard's text is not public. Every number used here is in :data:`LIMITS` and the
constants below, each with where it comes from and how sure it is -- **[Q]** read in an
official text or a source quoting it, **[S]** read in an open implementation or a
secondary summary, **[R]** this package's reading where nothing public says -- so a user
who holds the standard can check them and pass their own (``check_drives(...,
limits=...)``).

Requirements (each a :class:`Requirement` in the report: measured value, limit, pass or
fail, where the worst case happened):

* **mean automatic deceleration over 2 s**: ``-(v(t) - v(t - 2 s)) / 2 s`` at most 3.5 m/s^2
  at 20 m/s and above, 5 m/s^2 at 5 m/s and below, linear between; the limit is taken at
  the window's mean speed;
* **mean jerk over 1 s**: ``|a(t) - a(t - 1 s)| / 1 s`` at most 2.5 m/s^3 at 20 m/s and
  above, 5 m/s^3 at 5 m/s and below (``5.83 - v/6`` between, which is the same line);
* **mean automatic acceleration over 2 s**: at most 2 m/s^2 at 20 m/s and above,
  4 m/s^2 at 5 m/s and below, linear between;
* **steady-state time gap** at least 0.8 s: ``gap / v`` wherever the ego has followed a
  vehicle steadily for 5 s (speed above 5 m/s, relative speed within 0.5 m/s,
  acceleration within 0.3 m/s^2 throughout) [R: what "steady state" means here];
* **automatic stop** (full-speed-range ACC): where the ego, moving when the vehicle ahead
  stopped, comes to a stop behind it, the standstill gap is 2-5 m [S, unverified], and the
  ego stays stopped (moves at most 0.5 m) while the vehicle ahead stays stopped -- "go"
  needs a driver request, which a simulation does not have, so an automatic go while the
  target stays stopped is what fails [R]. (Collisions are the score's business.)

Window means are means of derivatives, i.e. difference quotients over the window: a
one-step spike of jerk inside an otherwise smooth 1 s window is diluted five-fold at the
0.2 s step, as the standard's averaging intends; a sustained one is not. A requirement
that no drive exercises (no steady following, no stop) is reported as not exercised,
not as passed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

STANDARD = "ISO 15622:2018"


@dataclass(frozen=True)
class SpeedDependentLimit:
    """A limit that depends on speed: ``at_high`` at ``v >= v_high``, ``at_low`` at ``v <= v_low``,
    linear between."""

    name: str
    unit: str
    at_high: float
    at_low: float
    window: float  # [s] the averaging window
    source: str
    confidence: str
    v_high: float = 20.0  # [m/s]
    v_low: float = 5.0  # [m/s]

    def at(self, v) -> np.ndarray:
        w = np.clip((np.asarray(v, dtype=float) - self.v_low) / (self.v_high - self.v_low), 0.0, 1.0)
        return self.at_low + w * (self.at_high - self.at_low)


LIMITS = {
    "deceleration": SpeedDependentLimit(
        "mean automatic deceleration over 2 s", "m/s^2", 3.5, 5.0, 2.0,
        "ISO 15622:2018 limits as open ACC implementations cite them; the line between 5 and 20 m/s is this "
        "package's reading", "[S] (values), [R] (interpolation)"),
    "jerk": SpeedDependentLimit(
        "mean jerk over 1 s", "m/s^3", 2.5, 5.0, 1.0,
        "ISO 15622:2018 as open ACC implementations cite it (sunnypilot's Hyundai longitudinal README: "
        "5.83 - v/6 between 5 and 20 m/s)", "[S]"),
    "acceleration": SpeedDependentLimit(
        "mean automatic acceleration over 2 s", "m/s^2", 2.0, 4.0, 2.0,
        "ISO 15622:2018 limits as open ACC implementations cite them; the 2 s window and the line between 5 and "
        "20 m/s are this package's reading", "[S] (values), [R] (window, interpolation)"),
}
MIN_TIME_GAP = 0.8  # [s] the shortest selectable steady-state time gap [S]
STEADY_TIME = 5.0  # [s] steady following lasts at least this [R]
STEADY_SPEED = 5.0  # [m/s] ... above this speed [R]
STEADY_V_REL = 0.5  # [m/s] ... with the relative speed within this [R]
STEADY_ACCEL = 0.3  # [m/s^2] ... and the acceleration within this [R]
STANDSTILL_GAP = (2.0, 5.0)  # [m] the gap behind a stopped target [S, unverified]
STOPPED = 0.1  # [m/s] a vehicle slower than this is stopped [R]
HOLD_MOVE = 0.5  # [m] the most the ego may creep while the target stays stopped [R]

SOURCES = {
    "min_time_gap": ("minimum selectable steady-state time gap 0.8 s", "[S]"),
    "steady": ("steady following: 5 s above 5 m/s, |v_rel| <= 0.5 m/s, |a| <= 0.3 m/s^2", "[R]"),
    "standstill_gap": ("full-speed-range ACC standstill gap 2-5 m", "[S, unverified]"),
    "hold": ("after an automatic stop, no automatic go while the target stays stopped (go needs a driver request)",
             "[Q] (go after a driver request), [R] (0.5 m creep allowance)"),
}


@dataclass
class Requirement:
    """One requirement's verdict over a set of drives."""

    name: str
    measured: float | None  # the worst value over the drives (None: not exercised)
    limit: float | None  # the limit at the worst case (for a speed-dependent limit: at its speed)
    unit: str
    passed: bool | None  # None: no drive exercised it
    where: str  # the worst case: drive, time, speed
    source: str
    confidence: str
    failures: int = 0  # windows (or events) outside the limit, over all drives

    def to_dict(self) -> dict:
        def num(x):
            return None if x is None or not math.isfinite(x) else round(float(x), 6)
        return {"name": self.name, "measured": num(self.measured), "limit": num(self.limit), "unit": self.unit,
                "passed": self.passed, "where": self.where, "failures": self.failures, "source": self.source,
                "confidence": self.confidence}


@dataclass
class Drive:
    """One drive to check: ``t`` [s], ego speed ``v`` [m/s], applied acceleration ``a`` [m/s^2]
    (over the step ending at each sample), ``gap`` [m] to the vehicle ahead (inf: none),
    ``v_lead`` [m/s]; ``label`` names it in the report."""

    label: str
    t: np.ndarray
    v: np.ndarray
    a: np.ndarray
    gap: np.ndarray
    v_lead: np.ndarray
    x: np.ndarray | None = None  # [m] ego position (default: integrated from v)

    @classmethod
    def from_trace(cls, label: str, trace) -> "Drive":
        """From an :class:`~acc_gym.evaluation.trace.EgoTrace`."""
        return cls(label, np.asarray(trace.t, float), np.asarray(trace.v, float), np.asarray(trace.a, float),
                   np.asarray(trace.gap, float), np.asarray(trace.v_lead, float))

    def position(self) -> np.ndarray:
        if self.x is not None:
            return np.asarray(self.x, float)
        dt = np.diff(self.t)
        return np.concatenate([[0.0], np.cumsum(0.5 * (self.v[1:] + self.v[:-1]) * dt)])


@dataclass
class Report:
    """The requirements' verdicts; ``passed`` when every exercised one passed."""

    requirements: list = field(default_factory=list)
    drives: list = field(default_factory=list)  # labels
    errors: list = field(default_factory=list)  # drives that could not be run: (label, reason)
    # drives that ended in a collision: not an envelope requirement (the envelope says nothing of
    # safety; a controller that ignores the traffic can stay inside it), reported beside it
    collisions: list = field(default_factory=list)

    @property
    def passed(self) -> bool | None:
        exercised = [r.passed for r in self.requirements if r.passed is not None]
        return None if not exercised else all(exercised)

    def to_dict(self) -> dict:
        return {"standard": STANDARD, "passed": self.passed, "requirements": [r.to_dict() for r in self.requirements],
                "drives": list(self.drives), "errors": [{"drive": d, "reason": r} for d, r in self.errors],
                "collisions": list(self.collisions)}


def window_means(drive: Drive, window: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Over every window of ``window`` seconds ending at a sample: its end time, its mean speed,
    the mean acceleration ``(v(t) - v(t - W)) / W`` and the mean jerk ``(a(t) - a(t - W)) / W``."""
    t, v, a = drive.t, drive.v, drive.a
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    k = int(round(window / dt)) if dt > 0 else 0
    if k < 1 or t.size <= k:
        empty = np.empty(0)
        return empty, empty, empty, empty
    span = t[k:] - t[:-k]
    csum = np.concatenate([[0.0], np.cumsum(v)])
    mean_v = (csum[k + 1:] - csum[:-k - 1]) / (k + 1)
    return t[k:], mean_v, (v[k:] - v[:-k]) / span, (a[k:] - a[:-k]) / span


def _envelope(drives, key: str, limit: SpeedDependentLimit) -> Requirement:
    worst = None  # (ratio, value, limit, where)
    failures = 0
    for d in drives:
        t_end, mean_v, mean_a, mean_j = window_means(d, limit.window)
        if t_end.size == 0:
            continue
        value = {"deceleration": -mean_a, "acceleration": mean_a, "jerk": np.abs(mean_j)}[key]
        lim = limit.at(mean_v)
        ratio = value / lim
        failures += int(np.sum(value > lim + 1e-9))
        i = int(np.argmax(ratio))
        if worst is None or ratio[i] > worst[0]:
            worst = (float(ratio[i]), float(value[i]), float(lim[i]),
                     f"{d.label} at t = {t_end[i]:.1f} s, {mean_v[i]:.1f} m/s")
    if worst is None:
        return Requirement(limit.name, None, None, limit.unit, None, "no drive long enough", limit.source,
                           limit.confidence)
    return Requirement(limit.name, max(worst[1], 0.0) + 0.0, worst[2], limit.unit, failures == 0, worst[3], limit.source,
                       limit.confidence, failures)


def _steady_runs(d: Drive) -> list[tuple[int, int]]:
    ok = (np.isfinite(d.gap) & (d.v > STEADY_SPEED) & (np.abs(d.v_lead - d.v) <= STEADY_V_REL)
          & (np.abs(d.a) <= STEADY_ACCEL))
    runs, start = [], None
    dt = float(np.median(np.diff(d.t))) if d.t.size > 1 else 1.0
    for i, flag in enumerate(list(ok) + [False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            if (i - start) * dt >= STEADY_TIME:
                runs.append((start, i))
            start = None
    return runs


def _time_gap(drives) -> Requirement:
    text, conf = SOURCES["min_time_gap"]
    worst = None
    failures = 0
    for d in drives:
        for s, e in _steady_runs(d):
            h = d.gap[s:e] / d.v[s:e]
            failures += int(np.sum(h < MIN_TIME_GAP))
            i = int(np.argmin(h))
            if worst is None or h[i] < worst[0]:
                worst = (float(h[i]), f"{d.label} at t = {d.t[s + i]:.1f} s, {d.v[s + i]:.1f} m/s")
    if worst is None:
        return Requirement("steady-state time gap", None, MIN_TIME_GAP, "s", None, "no steady following", text, conf)
    return Requirement("steady-state time gap", worst[0], MIN_TIME_GAP, "s", worst[0] >= MIN_TIME_GAP, worst[1],
                       text, conf, failures)


def _stops(drives) -> tuple[Requirement, Requirement]:
    """The standstill gap and the hold, over every stop of the vehicle ahead that lasts 2 s."""
    gtext, gconf = SOURCES["standstill_gap"]
    htext, hconf = SOURCES["hold"]
    gaps, holds = [], []  # (value, where, ok)
    for d in drives:
        dt = float(np.median(np.diff(d.t))) if d.t.size > 1 else 1.0
        lead_stopped = np.isfinite(d.gap) & (d.v_lead < STOPPED)
        x = d.position()
        i, n = 0, d.t.size
        while i < n:
            if not lead_stopped[i]:
                i += 1
                continue
            j = i
            while j < n and lead_stopped[j]:
                j += 1
            # the target stands from i to j; an automatic stop: the ego, moving when the target
            # stopped, comes to a stop before it moves again (a target that moves off before the
            # ego reaches it asks for no stop; a queue at rest from the start is no automatic stop)
            stopped = np.flatnonzero(d.v[i:j] < STOPPED)
            if (j - i) * dt >= 2.0 and stopped.size and d.v[i] >= 1.0:
                k = i + int(stopped[0])
                where = f"{d.label}, the ego stopped at t = {d.t[k]:.1f} s"
                g = float(d.gap[k])
                gaps.append((g, where, STANDSTILL_GAP[0] <= g <= STANDSTILL_GAP[1]))
                moved = float(np.max(x[k:j]) - x[k])
                holds.append((moved, where, moved <= HOLD_MOVE))
            i = j
    name_g, name_h = "standstill gap behind a stopped target", "no automatic go while the target stays stopped"
    if gaps:
        bad = [r for r in gaps if not r[2]]
        w = min(bad or gaps, key=lambda z: z[0])  # the worst failure, else the smallest gap
        bound = STANDSTILL_GAP[1] if w[0] > STANDSTILL_GAP[1] else STANDSTILL_GAP[0]
        gap_req = Requirement(name_g, w[0], bound, "m", not bad, w[1], gtext, gconf, len(bad))
    else:
        gap_req = Requirement(name_g, None, STANDSTILL_GAP[0], "m", None, "no stop of the vehicle ahead", gtext, gconf)
    if holds:
        w = max(holds, key=lambda z: z[0])
        hold_req = Requirement(name_h, w[0], HOLD_MOVE, "m", w[0] <= HOLD_MOVE, w[1], htext, hconf,
                               sum(not r[2] for r in holds))
    else:
        hold_req = Requirement(name_h, None, HOLD_MOVE, "m", None, "no stop of the ego behind a stopped target", htext,
                               hconf)
    return gap_req, hold_req


def check_drives(drives, limits: dict | None = None) -> Report:
    """Every requirement over ``drives`` (:class:`Drive` objects); ``limits`` replaces entries of
    :data:`LIMITS` (e.g. with the numbers of the standard's own text)."""
    lim = {**LIMITS, **(limits or {})}
    unknown = set(lim) - set(LIMITS)
    if unknown:
        raise ValueError(f"unknown ISO 15622 limit(s) {sorted(unknown)}; the limits are {sorted(LIMITS)}")
    drives = list(drives)
    reqs = [_envelope(drives, key, lim[key]) for key in ("deceleration", "jerk", "acceleration")]
    reqs.append(_time_gap(drives))
    reqs.extend(_stops(drives))
    collided = [d.label for d in drives if np.any(np.asarray(d.gap) <= 0.0)]
    return Report(reqs, [d.label for d in drives], collisions=collided)
