"""Paper 003's 100-point score of a drive, with every open choice a validated setting.

Table 3 of paper 003 (Yang et al. 2024): four qualitative items, each 15 points or
"unqualified" -- safety (Q >= 0), car-following characteristic (0 < G < 0.2 Gapsafe),
road edge (D2 > 0), boundary line (D3 > 0) -- and two quantitative ones, efficiency
``R1 = (1 - u) 20`` and comfort ``R2 = (1 - j_x) 10 + (1 - j_y) 10``. If all four items
qualify the score is ``60 + R1 + R2``, otherwise ``15 r`` for ``r`` qualified items.
Indicators: :mod:`acc_gym.evaluation.indicators`.

Why the defaults are not the literal reading
--------------------------------------------
Read literally (Q >= 0 at every sample) the safety item fails every follower when its
leader brakes hard: Gapsafe charges a full reaction distance ``v1 tau1`` even while the
follower is already braking, so Q dips below zero in any emergency stop, whatever the
follower does (a prototype of paper 003's test failed Gipps, IDM and every ACC tuning
that way). The paper's own figures are not consistent either: GM and fuzzy score 45 =
band + D2 + D3 while failing safety, impossible if band and safety look at the same
samples, and its comfort means (R2 of 2.4 to 4.8) need j_y > 0 or an unclipped j. The
literal rules stay available (``ScoringConfig.literal()``); the defaults make the score
discriminate -- a collision is never qualified, a well-tuned linear ACC qualifies on
paper 003's test, a tailgater does not -- with these rules:

* **Safety, proper response** (``safety="proper-response"``, after the proper response
  of responsibility-sensitive safety): a collision (D1 <= 0) always fails; Q < 0 is
  tolerated for ``response_time`` (default tau1) after it turns negative, and afterwards
  only while the ego responds -- braking at ``response_decel`` (2 m/s^2) or harder, or
  standing (speed <= ``stop_speed``) -- until Q >= 0 again. A follower that sits inside
  Gapsafe without braking (a tailgater) fails; one that brakes firmly when its leader
  stops does not. ``safety="literal"``: Q >= 0 at every sample with a vehicle ahead.
* **Why proper response stays the default:** a search over candidate rules (the literal
  one, a reacted gap, minimum-TTC floors, caps on the time inside Gapsafe;
  ``python benchmarks/safety_rules.py``) found none that reaches the paper's verdicts on
  GM and fuzzy, and the stricter ones also fail Gipps, which the paper finds safe; the
  table is in ``docs/design/safety-proper-response.md``.
* **Car-following band, share of steady following** (``band="steady-share"``): the band
  judges the following *distance*, so it is checked on *car-following samples*: a vehicle
  ahead at any distance (a follower cannot escape the band by hanging back out of sensor
  range), both moving (speeds > ``moving_speed``), a relative speed within ``steady_dv``
  (paper 004's car-following is following "with a steady velocity"), Gapsafe > 0, and at
  least ``transient`` seconds after the start and after every change of the vehicle ahead.
  The item qualifies if at least ``band_share`` (50 %) of them are in the band. If the test
  has a *followable* vehicle ahead (moving, and not faster than the ego's set speed when
  that is known) but the ego never follows it steadily (it hangs back at another speed),
  the item fails; if there is never one (free flow, a stationary target, a lead that
  drives away faster than the set speed) the item does not apply and counts as
  qualified. "Faster than the set speed" is meant strictly (``lead_margin`` = 0): an ACC
  does not exceed its driver's set speed, so a lead above it cannot be followed in the
  band, and counting it (within ``steady_dv``) would fail ACCs that hold their set speed
  and teach learnt policies to speed. "Above" means by more than
  ``SPEED_TOL`` (1e-6 m/s): a scripted lead that cruises *at* the set speed is followable
  on every machine, although its simulated speed may land a last bit above or below it
  (it did: one ulp flipped a car-following/120 episode of the linear ACC by 34 points). An ego that is still *closing in
  efficiently* at every such sample is not hanging back: the test ended before steady following was reachable (paper 004's
  approach scenarios start up to 200 m behind a slower lead and may last only seconds),
  so the band is not judged (qualified, ``detail["approaching"]``) and efficiency is
  speed keeping, as when the band does not apply. Closing in efficiently means faster
  than the lead by more than ``steady_dv`` and either at the set speed (within
  ``steady_dv``) or already too close to stop closing before the band's far edge at
  ``approach_decel`` (0.5 m/s^2): ``(v1 - v0)^2 >= 2 approach_decel (D1 - 1.2 Gapsafe)``.
  Dawdling behind (slower than the lead, or closing slowly from far back below the set
  speed) still fails. ``band="literal"``: every sample with a vehicle ahead and
  Gapsafe > 0 must be in the band. (Without the closing-in exemption an approach cut
  short by the end of the test -- unavoidable in some of paper 004's approach scenarios --
  would fail.)
* Because Gapsafe's steady-state value is ``v tau1``, the band ``0 < G < 0.2 Gapsafe`` in
  effect asks for a time gap between tau1 and 1.2 tau1. So ``tau1`` defaults to the
  scenario's nominal time gap (``EgoTrace.time_gap``; 1.5 s when unknown), and **a
  controller that declares its own time gap is judged at it** (paper 003's Gapsafe takes
  the driver's own reaction time; a Gipps driver with a 0.6 s reaction and 0.3 s safety
  margin is judged at 0.9 s, as the paper judges it): ``EgoTrace.declared_time_gap``
  (a controller's ``time_gap`` attribute, passed by :func:`acc_gym.evaluation.runner.run_episode`,
  ``evaluate`` and the leaderboard) sets tau1 to ``min(max(declared, tau1_floor),
  nominal)`` (:func:`judged_tau1`). The floor, ``tau1_floor`` = 0.8 s, is the shortest
  time gap ISO 15622 allows an ACC to offer: a controller cannot make Gapsafe lenient by
  declaring 0.3 s. The ceiling is the scenario's nominal gap, the longest the driver asks
  for: declaring 3 s would otherwise make hanging back "efficient". (Judged at the
  scenario's gap instead, Gipps, which declares 0.9 s, fails.)
* ``b0 = b1 = 8 m/s^2``: the maximum deceleration of a passenger car on dry asphalt
  (about 0.8 g; this package's vehicle model allows 0.87 g). Equal values make Gapsafe
  ``v tau1`` in steady following, as the band's reading above assumes.
* **Efficiency**: ``u`` is the mean of ``u_t`` over the car-following samples with each
  ``u_t`` clipped to [0, 1] (``clip=True``): closer than Gapsafe counts as fully efficient
  (safety judges it), beyond the band as not at all. When the band does not apply, ``u``
  measures speed keeping instead over the samples with nothing to follow in view,
  ``u_t = clip((v_set - v1) / (0.2 v_set), 0, 1)`` (the same 20 % band, below the set
  speed); without a set speed or such samples it is undefined and R1 = 0.
* **Comfort**: ``j_x = max |a_x| / 3 m/s^2`` and ``j_y = max |a_y| / 5 m/s^2`` over the
  episode (paper 003's values), clipped to [0, 1] so that R2 stays in [0, 20].
* **D2, D3**: the ego's contour distances to the road edge and to the boundary line must
  stay positive at every sample (a longitudinal simulation keeps the ego in its lane, so
  these pass unless a scripted lane change leaves the carriageway; they stay in the score
  so totals compare with the paper's).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from acc_gym._io import json_leaf, json_safe
from acc_gym._validation import from_mapping
from acc_gym.evaluation import _score_kernel as _K
from acc_gym.evaluation.metrics import MIN_DEVIATION, STEADY_ACCEL, STEADY_TIME, damping_ratio
from acc_gym.evaluation.trace import _ARRAY_COLUMNS, _EMPTY, _LANE_CENTRED, EgoTrace, _scalars_valid

DEFAULT_TAU1 = 1.5  # [s] when neither the config nor the trace gives one
SAFETY_RULES = ("proper-response", "literal")
BAND_RULES = ("steady-share", "literal")
ITEM_POINTS = 15.0


SPEED_TOL = 1e-6  # [m/s] a lead counts as faster than the set speed only by more than this


@dataclass(frozen=True)
class ScoringConfig:
    """Every choice paper 003 leaves open (see the module docstring for the reasons)."""

    safety: str = "proper-response"  # or "literal"
    band: str = "steady-share"  # or "literal"
    tau1: float | None = None  # [s] ego reaction time; None: judged_tau1 (declared / nominal gap, else 1.5)
    tau1_floor: float = 0.8  # [s] a declared time gap counts at least this (ISO 15622's shortest)
    b0: float = 8.0  # [m/s^2] maximum deceleration of the vehicle ahead
    b1: float = 8.0  # [m/s^2] maximum deceleration of the ego
    response_decel: float = 2.0  # [m/s^2] braking that counts as a proper response
    response_time: float | None = None  # [s] grace after Q turns negative; None: tau1
    stop_speed: float = 0.5  # [m/s] at or below this the ego counts as standing
    sensor_range: float = 200.0  # [m] beyond it nothing is "in view" (speed-keeping efficiency)
    band_width: float = 0.2  # [-] the band's upper edge as a fraction of Gapsafe
    band_share: float = 0.5  # [-] share of car-following samples that must be in the band
    steady_dv: float = 1.0  # [m/s] |v0 - v1| of car-following samples
    lead_margin: float = 0.0  # [m/s] a lead this much above the set speed still counts as followable
    moving_speed: float = 1.0  # [m/s] both vehicles faster than this to count as following
    transient: float = 5.0  # [s] skipped after the start and after a new vehicle ahead
    approach_decel: float = 0.5  # [m/s^2] an approach this close to the band counts as closing in
    clip: bool = True  # clip u_t and j to [0, 1]
    a_x_comfort: float = 3.0  # [m/s^2] paper 003
    a_y_comfort: float = 5.0  # [m/s^2] paper 003

    def __post_init__(self) -> None:
        if self.safety not in SAFETY_RULES:
            raise ValueError(f"ScoringConfig.safety must be one of {SAFETY_RULES}, got {self.safety!r}")
        if self.band not in BAND_RULES:
            raise ValueError(f"ScoringConfig.band must be one of {BAND_RULES}, got {self.band!r}")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("safety", "band", "clip") or value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"ScoringConfig.{f.name} must be a finite number, got {value!r}")
            positive = f.name in ("tau1", "tau1_floor", "b0", "b1", "band_width", "a_x_comfort", "a_y_comfort", "response_decel",
                                  "approach_decel")
            if positive and value <= 0:
                raise ValueError(f"ScoringConfig.{f.name} must be > 0, got {value!r}")
            if value < 0:
                raise ValueError(f"ScoringConfig.{f.name} must be >= 0, got {value!r}")
        if not 0.0 < self.band_share <= 1.0:
            raise ValueError(f"ScoringConfig.band_share must be in (0, 1], got {self.band_share!r}")
        if not isinstance(self.clip, bool):
            raise ValueError(f"ScoringConfig.clip must be True or False, got {self.clip!r}")

    @classmethod
    def literal(cls, **changes) -> "ScoringConfig":
        """Paper 003 read literally: Q >= 0 and the band at every sample, nothing clipped."""
        return cls(**{"safety": "literal", "band": "literal", "clip": False, **changes})

    def to_dict(self) -> dict:
        if "_as_dict" not in self.__dict__:  # frozen: made once (every scored episode reports it)
            object.__setattr__(self, "_as_dict", asdict(self))
        return dict(self._as_dict)

    def to_json_dict(self) -> dict:
        """:meth:`to_dict` made JSON-safe (:func:`acc_gym._io.json_safe`), made once like it."""
        if "_as_json" not in self.__dict__:
            object.__setattr__(self, "_as_json", json_safe(self.to_dict()))
        return dict(self._as_json)

    @classmethod
    def from_dict(cls, d: dict) -> "ScoringConfig":
        return from_mapping(cls, d, "scoring")


@dataclass(frozen=True)
class ItemResult:
    """One qualitative item of Table 3."""

    name: str
    requirement: str
    qualified: bool
    applicable: bool = True
    detail: dict = field(default_factory=dict)

    @property
    def points(self) -> float:
        return ITEM_POINTS if self.qualified else 0.0


@dataclass(frozen=True)
class EpisodeReport:
    """The score of one episode with every indicator behind it."""

    score: float  # [0, 100]
    qualified: bool  # all four qualitative items qualified
    items: tuple  # ItemResult: safety, car_following, road_edge, boundary_line
    r1: float  # efficiency points [0, 20] (may leave the range with clip=False)
    r2: float  # comfort points [0, 20]
    u: float  # efficiency indicator
    j_x: float
    j_y: float
    tau1: float  # [s] the reaction time used
    metrics: dict  # extra metrics (acc_gym.evaluation.metrics)
    config: ScoringConfig

    def item(self, name: str) -> ItemResult:
        for it in self.items:
            if it.name == name:
                return it
        raise KeyError(name)

    def to_dict(self) -> dict:
        """JSON-safe (NaN -> None, infinities -> ``"inf"``): :func:`acc_gym._io.json_safe` of
        ``{"score", "qualified", "r1", "r2", "u", "j_x", "j_y", "tau1", "items": {name:
        {"qualified", "applicable", "points", "requirement", **detail}}, "metrics"}`` and then
        ``"config"`` (:meth:`ScoringConfig.to_json_dict`), built leaf by leaf without the
        nested dicts made twice (every ended episode's info holds one;
        ``tests/evaluation/test_score_kernel.py`` compares it with that definition)."""
        leaf = json_leaf
        items = {}
        for it in self.items:
            d = {"qualified": leaf(it.qualified), "applicable": leaf(it.applicable), "points": leaf(it.points),
                 "requirement": leaf(it.requirement)}
            for k, v in it.detail.items():
                d[k if type(k) is str else str(k)] = leaf(v)
            items[it.name if type(it.name) is str else str(it.name)] = d
        return {"score": leaf(self.score), "qualified": leaf(self.qualified), "r1": leaf(self.r1), "r2": leaf(self.r2),
                "u": leaf(self.u), "j_x": leaf(self.j_x), "j_y": leaf(self.j_y), "tau1": leaf(self.tau1),
                "items": items,
                "metrics": {k if type(k) is str else str(k): leaf(v) for k, v in self.metrics.items()},
                "config": self.config.to_json_dict()}

    def summary(self) -> str:
        """The report as text (:func:`report_text`)."""
        return report_text(self.to_dict())


def report_text(report: dict, header: bool = True) -> str:
    """An episode report in :meth:`EpisodeReport.to_dict` form as the lines ``acc-gym score``,
    ``demo`` and :meth:`EpisodeReport.summary` print (``header``: the score line first). An
    undefined ``u`` (no car-following sample and no set speed) reads ``n/a``, a ``min_ttc``
    that never came (never closing in) and a ``min_gap`` with nothing ahead ``none``."""
    def num(x, fmt: str, missing: str, unit: str = "") -> str:
        if x is None or isinstance(x, str) or not math.isfinite(x):
            return missing
        return f"{x:{fmt}}{unit}"

    lines = [f"score {report['score']:.1f} / 100 ({'qualified' if report['qualified'] else 'NOT qualified'})"] \
        if header else []
    for name, item in report["items"].items():
        state = "qualified" if item["qualified"] else "unqualified"
        lines.append(f"  {name:<14} {item['requirement']:<26} {state}{'' if item['applicable'] else ' (not applicable)'}")
    lines.append(f"  efficiency     R1 = (1 - u) 20 = {report['r1']:.2f}  (u = {num(report['u'], '.3f', 'n/a')})")
    lines.append(f"  comfort        R2 = {report['r2']:.2f}  (j_x = {report['j_x']:.3f}, j_y = {report['j_y']:.3f})")
    m = report["metrics"]
    lines.append(f"  collision {m['collision']}, comfortable {m['share_comfortable']:.1%}, "
                 f"safe spacing {num(m['share_safe_spacing'], '.1%', 'n/a')}, "
                 f"min TTC {num(m['min_ttc'], '.2f', 'none', ' s')}, max jerk {m['max_jerk']:.2f} m/s^3, "
                 f"min gap {num(m['min_gap'], '.2f', 'none', ' m')}")
    return "\n".join(lines)


def judged_tau1(nominal: float | None, declared: float | None, config: ScoringConfig) -> float:
    """The reaction time tau1 an episode is judged at [s]: the config's ``tau1`` if set;
    else the controller's declared time gap, at least ``tau1_floor`` and at most the
    scenario's ``nominal`` gap; else the nominal gap; else :data:`DEFAULT_TAU1`."""
    if config.tau1 is not None:
        return float(config.tau1)
    base = float(nominal) if nominal is not None else DEFAULT_TAU1
    if declared is None:
        return base
    return min(max(float(declared), config.tau1_floor), base)


_F64 = np.dtype(np.float64)
_DEFAULT_CONFIG = ScoringConfig()
_SCALAR_TYPES = (float, int, np.float64)  # a set speed of these types is read where it is (others: via EgoTrace)


def _kernel_params(cfg: ScoringConfig) -> tuple:
    """What the compiled path needs of a config: the parameter vector of
    :func:`acc_gym.evaluation._score_kernel.score`, the two requirements' texts and the band's
    share needed. Made once per config and kept on it (frozen; like :meth:`ScoringConfig.to_dict`)."""
    kp = cfg.__dict__.get("_kernel")
    if kp is not None:
        return kp
    literal_band = cfg.band == "literal"
    values = {
        _K.P_B0: cfg.b0, _K.P_B1: cfg.b1, _K.P_BAND_WIDTH: cfg.band_width, _K.P_STEADY_DV: cfg.steady_dv,
        _K.P_MOVING: cfg.moving_speed, _K.P_TRANSIENT: cfg.transient, _K.P_SENSOR: cfg.sensor_range,
        _K.P_RESPONSE_DECEL: cfg.response_decel, _K.P_STOP_SPEED: cfg.stop_speed, _K.P_LEAD_MARGIN: cfg.lead_margin,
        _K.P_SPEED_TOL: SPEED_TOL, _K.P_APPROACH_DECEL: cfg.approach_decel,
        _K.P_BAND_NEEDED: 1.0 if literal_band else cfg.band_share, _K.P_A_X: cfg.a_x_comfort,
        _K.P_A_Y: cfg.a_y_comfort, _K.P_LANE_CENTRED: _LANE_CENTRED, _K.P_STEADY_ACCEL: STEADY_ACCEL,
        _K.P_STEADY_TIME: STEADY_TIME, _K.P_MIN_DEVIATION: MIN_DEVIATION,
        _K.P_LITERAL_SAFETY: cfg.safety == "literal", _K.P_LITERAL_BAND: literal_band, _K.P_CLIP: cfg.clip,
        _K.P_ITEM_POINTS: ITEM_POINTS,
    }
    p = np.empty(_K.N_PARAMS)
    for k, value in values.items():
        p[k] = float(value)
    kp = (p, "Q >= 0" if cfg.safety == "literal" else "Q >= 0 or proper response",
          f"0 < G < {cfg.band_width:g} Gapsafe", 1.0 if literal_band else cfg.band_share)
    object.__setattr__(cfg, "_kernel", kp)
    return kp


def score_episode(trace: EgoTrace, config: ScoringConfig | None = None) -> EpisodeReport:
    """Score one episode (paper 003 Table 3 under ``config``; defaults: module docstring), in
    one compiled call (:func:`acc_gym.evaluation._score_kernel.score`). The trace's columns
    are float64 after its checks; a set speed of another numeric type is read as a float."""
    cfg = config if config is not None else _DEFAULT_CONFIG
    if not isinstance(trace, EgoTrace):
        raise TypeError(f"score_episode needs an EgoTrace, got {type(trace).__name__}")
    if not isinstance(cfg, ScoringConfig):
        raise TypeError(f"score_episode's config must be a ScoringConfig, got {type(cfg).__name__}")
    set_speed = trace.set_speed
    cols = tuple(_EMPTY if c is None else np.ascontiguousarray(c, dtype=np.float64)
                 for c in (trace.t, trace.v, trace.a, trace.gap, trace.v_lead, trace.lead_id, trace.a_y, trace.d2,
                           trace.d3))
    kp = _kernel_params(cfg)
    tau1, grace = _tau1_grace(trace.time_gap, trace.declared_time_gap, cfg)
    out = np.empty(_K.N_OUT)
    _K.score(cols, kp[0], tau1, grace, np.nan if set_speed is None else float(set_speed), out)
    return _report(out.tolist(), cfg, kp, tau1)


def score_record(rec: np.ndarray, n: int, set_speed: float | None = None, time_gap: float | None = None,
                 declared_time_gap: float | None = None, config: ScoringConfig | None = None) -> EpisodeReport:
    """:func:`score_episode` of the trace of the first ``n`` samples of ``rec``, a float64
    array whose rows are :class:`EgoTrace`'s columns in their order (``t, v, a, gap, v_lead,
    a_lead, lead_id, a_y, d2, d3``: the environments' episode record), without making the
    trace: the trace's checks and the score in one compiled call
    (:func:`acc_gym.evaluation._score_kernel.score_record`), reading the record where it is.

    The same report as ``score_episode(EgoTrace(**dict(zip(columns, rec[:, :n])), set_speed=...,
    time_gap=..., declared_time_gap=...), config)`` (``tests/evaluation/test_score_kernel.py``
    compares the two), which is what a record the checks would change or reject, or values
    off the compiled path's types, take: it converts, or raises naming the bad value. A
    record of another number of rows, or an ``n`` that is not a count of its samples, is an
    error naming it.
    """
    cfg = config if config is not None else _DEFAULT_CONFIG
    if (type(rec) is np.ndarray and rec.dtype is _F64 and rec.ndim == 2 and rec.shape[0] == len(_ARRAY_COLUMNS)
            and type(n) is int and 2 <= n <= rec.shape[1] and isinstance(cfg, ScoringConfig)
            and (set_speed is None or type(set_speed) in _SCALAR_TYPES)
            and _scalars_valid(set_speed, time_gap, declared_time_gap)):
        kp = _kernel_params(cfg)
        tau1, grace = _tau1_grace(time_gap, declared_time_gap, cfg)
        out = np.empty(_K.N_OUT)
        if _K.score_record(rec, n, kp[0], tau1, grace, np.nan if set_speed is None else float(set_speed), out):
            return _report(out.tolist(), cfg, kp, tau1)
    arr = np.asarray(rec, dtype=float)
    if arr.ndim != 2 or arr.shape[0] != len(_ARRAY_COLUMNS):
        raise ValueError(f"a record has one row per trace column {_ARRAY_COLUMNS}: shape ({len(_ARRAY_COLUMNS)}, "
                         f"samples), got {arr.shape}")
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or not 0 <= n <= arr.shape[1]:
        raise ValueError(f"n must be a number of the record's samples, 0 to {arr.shape[1]}, got {n!r}")
    trace = EgoTrace(**dict(zip(_ARRAY_COLUMNS, arr[:, :n].copy())), set_speed=set_speed, time_gap=time_gap,
                     declared_time_gap=declared_time_gap)
    return score_episode(trace, config)


def _tau1_grace(time_gap, declared_time_gap, cfg: ScoringConfig) -> tuple[float, float]:
    """The compiled score's ``tau1`` (:func:`judged_tau1`) and proper-response grace time [s]:
    the config's response time, else ``tau1``."""
    tau1 = float(judged_tau1(time_gap, declared_time_gap, cfg))
    return tau1, float(cfg.response_time) if cfg.response_time is not None else tau1


def _report(o: list, cfg: ScoringConfig, kp: tuple, tau1: float) -> EpisodeReport:
    """The report of the compiled score's outputs ``o`` (``out.tolist()``) under ``cfg``
    (``kp``: :func:`_kernel_params`), judged at ``tau1``."""
    _, safety_rule, band_rule, share_needed = kp
    violations = int(o[_K.O_VIOLATIONS])
    min_q = o[_K.O_MIN_Q]
    collision = o[_K.O_COLLISION] != 0.0
    safety = ItemResult("safety", safety_rule, o[_K.O_SAFE_OK] != 0.0, True, {
        "violations": violations, "first_violation_t": o[_K.O_FIRST_VIOLATION_T] if violations else None,
        "min_q": None if min_q != min_q else min_q, "collision": collision})
    car_following = ItemResult("car_following", band_rule, o[_K.O_BAND_OK] != 0.0, o[_K.O_APPLICABLE] != 0.0,
                               {"share_in_band": o[_K.O_SHARE], "samples": int(o[_K.O_SAMPLES]),
                                "share_needed": share_needed, "approaching": o[_K.O_APPROACHING] != 0.0})
    edge = ItemResult("road_edge", "D2 > 0", o[_K.O_EDGE_OK] != 0.0, True, {"min_d2": o[_K.O_MIN_D2]})
    line = ItemResult("boundary_line", "D3 > 0", o[_K.O_LINE_OK] != 0.0, True, {"min_d3": o[_K.O_MIN_D3]})
    overshoot = o[_K.O_OVERSHOOT]
    metrics = {
        "collision": collision,
        "share_comfortable": o[_K.O_SHARE_COMFORTABLE],
        "share_safe_spacing": o[_K.O_SHARE_SAFE_SPACING],
        "min_ttc": o[_K.O_MIN_TTC],
        "max_jerk": o[_K.O_MAX_JERK],
        "speed_overshoot": overshoot,
        "damping_ratio": damping_ratio(overshoot),
        "transients": int(o[_K.O_TRANSIENTS]),
        "min_gap": o[_K.O_MIN_GAP],
        "duration": o[_K.O_DURATION],
    }
    return EpisodeReport(score=o[_K.O_SCORE], qualified=o[_K.O_QUALIFIED] != 0.0,
                         items=(safety, car_following, edge, line), r1=o[_K.O_R1], r2=o[_K.O_R2], u=o[_K.O_U],
                         j_x=o[_K.O_J_X], j_y=o[_K.O_J_Y], tau1=tau1, metrics=metrics, config=cfg)


def score_world(trace, scenarios, config: ScoringConfig | None = None) -> list[EpisodeReport]:
    """Score the ego of every scene of a :class:`~acc_gym.simulation.single_lane.WorldTrace`."""
    scenarios = list(scenarios)
    if len(scenarios) != trace.x.shape[1]:
        raise ValueError(f"{len(scenarios)} scenarios for a trace of {trace.x.shape[1]} scenes")
    return [score_episode(EgoTrace.from_world(trace, b, sc), config) for b, sc in enumerate(scenarios)]
