"""The code behind each suite: scenario ``index`` of a split from its own generator.

Every function here maps ``(index, rng)`` to a :class:`~acc_gym.scenarios.spec.Scenario`,
with ``rng = numpy.random.default_rng([index, root_seed])`` made by
:meth:`acc_gym.suites.Suite.scenario` -- so scenario ``i`` depends on nothing but
``(i, split)``: not on the scenarios before it, nor on the order they are asked for.
The scenario's own seed (which draws its missing parameters, surrounding drivers and
speed profiles in :func:`acc_gym.scenarios.build`) is drawn from ``rng``.

* ``carfollowing-v1`` (paper 003's test): ids ``carfollowing/60``, ``/90``, ``/120`` in
  turn (``index % 3``); each seed is another scripted human-like lead driver.
* ``singlelane-v3`` (paper 004's traffic): a configuration drawn by occurrence rate
  among the 22 paper configurations (``in_paper``), as
  :func:`acc_gym.scenarios.traffic_hour` does -- rates drawn from their laws, then one
  pick proportional to them -- but from the per-index generator, so each index is
  independent (``traffic_hour`` draws a whole hour from one generator instead).
* ``ncap-v1``: the 24 CCRs / CCRm / CCRb catalogue ids in turn (``index % 24``). NCAP
  targets are scripted, so a seed alone would change nothing; instead each run is the
  catalogue test with the small speed and distance deviations a real test track allows
  (of the order of Euro NCAP's test tolerances): ego speed ``+U(0, 1)`` km/h, a moving
  target's speed ``+U(-1, 1)`` km/h, CCRb's initial gap ``+U(-0.5, 0.5)`` m and its
  target deceleration ``+U(-0.25, 0.25)`` m/s^2; CCRs / CCRm start again at the nominal
  4 s time-to-collision from the actual speeds. Durations keep their nominal values
  (they leave seconds of margin). The catalogue id is kept; the deviations are in
  ``params``. So dev and test hold the same tests, run slightly differently.
* ``ncap-v2``: Euro NCAP 2026's car-to-car points (:mod:`acc_gym.scenarios.ncap2026`: the
  ACC-performance matrices and the frontal-collision CCRs / CCRm / CCRb, 57 ids) in turn
  (``index % 57``), with the same kind of test-track deviations: ego speed ``+U(0, 1)``
  km/h, a moving target's ``+U(-1, 1)`` km/h (an approach then starts again at its nominal
  distance: 210 m for the ACC approaches, a 4 s time-to-collision for the frontal ones),
  CCRb's gap ``+U(-0.5, 0.5)`` m and deceleration ``+U(-0.25, 0.25)`` m/s^2, a cut-in's or
  cut-out's TTC ``+U(-0.1, 0.1)`` s. Left out: the cut-in at 50 / 10 km/h with a TTC of
  0 s, which no controller can avoid (:mod:`acc_gym.standards.ncap`).
* ``malicious-v3``: surrounding MPC drivers at the limits (``drivers="malicious"``: short
  time gaps, late hard braking, high jerk) in the single-lane configurations where a
  vehicle enters the ego's path or the vehicle ahead must brake -- cut-ins (SV-POV, and
  POV2 cutting in front of the POV) and approaches of the POV to a slower POV2 -- plus
  the hard-braking CCRb cases (6 m/s^2, 12 and 40 m, jittered as in ``ncap-v1``); in
  turn (``index % 9``).
"""

from __future__ import annotations

import numpy as np

from acc_gym.scenarios import build, list_scenarios, scenario_type
from acc_gym.scenarios.spec import Scenario

SEED_HIGH = 2 ** 31 - 1  # scenario seeds are drawn in [0, SEED_HIGH)
CARFOLLOWING_IDS = ("carfollowing/60", "carfollowing/90", "carfollowing/120")
MALICIOUS_SINGLELANE = (
    "singlelane/2/cut-in",
    "singlelane/3/car-following+cut-in",
    "singlelane/3/approach+cut-in",
    "singlelane/3/lane-change+cut-in",
    "singlelane/3/car-following+approach",
    "singlelane/3/approach+approach",
    "singlelane/3/lane-change+approach",
)
MALICIOUS_NCAP = ("ncap/ccrb/6-12", "ncap/ccrb/6-40")
TTC0 = 4.0  # [s] CCRs / CCRm start at this time-to-collision (as acc_gym.scenarios.ncap)


def _seed(rng: np.random.Generator) -> int:
    return int(rng.integers(0, SEED_HIGH))


def carfollowing(index: int, rng: np.random.Generator) -> Scenario:
    return build(CARFOLLOWING_IDS[index % len(CARFOLLOWING_IDS)], seed=_seed(rng), drivers="typical")


def paper_configurations() -> list[str]:
    """Paper 004's 22 single-lane configurations (with occurrence rates), in registry order."""
    return [i for i in list_scenarios("singlelane")
            if scenario_type(i).in_paper and scenario_type(i).occurrence_rate is not None]


def singlelane(index: int, rng: np.random.Generator) -> Scenario:
    ids = paper_configurations()
    rates = np.array([max(float(scenario_type(i).occurrence_rate.sample(rng)), 0.0) for i in ids])
    if rates.sum() <= 0:
        raise ValueError("every single-lane occurrence rate is zero")
    sid = ids[int(rng.choice(len(ids), p=rates / rates.sum()))]
    return build(sid, seed=_seed(rng), drivers="typical")


def ncap_params(scenario_id: str, rng: np.random.Generator) -> dict:
    """The catalogue test's parameters with test-track deviations (see the module docstring)."""
    p, kind = _track_deviations(scenario_id, scenario_id.split("/")[1], rng)
    if kind != "ccrb":
        p["gap"] = TTC0 * (p["v_ego"] - p["v_target"]) / 3.6
    return p


def _track_deviations(scenario_id: str, kind: str, rng: np.random.Generator) -> tuple[dict, str]:
    """The test's constant parameters with the speed deviations (and CCRb's gap and deceleration
    ones) every NCAP suite draws, in this order: ``(params, kind)``."""
    p = dict(build(scenario_id, seed=0).params)  # every NCAP parameter is a constant law
    p["v_ego"] += float(rng.uniform(0.0, 1.0))
    if p["v_target"] > 0:
        p["v_target"] += float(rng.uniform(-1.0, 1.0))
    if kind == "ccrb":
        p["gap"] += float(rng.uniform(-0.5, 0.5))
        p["decel"] += float(rng.uniform(-0.25, 0.25))
    return p, kind


def _ncap(scenario_id: str, rng: np.random.Generator) -> Scenario:
    params = ncap_params(scenario_id, rng)
    return build(scenario_id, params, seed=_seed(rng), drivers="typical")


def ncap(index: int, rng: np.random.Generator) -> Scenario:
    ids = list_scenarios("ncap")
    return _ncap(ids[index % len(ids)], rng)


def malicious(index: int, rng: np.random.Generator) -> Scenario:
    ids = MALICIOUS_SINGLELANE + MALICIOUS_NCAP
    sid = ids[index % len(ids)]
    if sid.startswith("ncap/"):
        return _ncap(sid, rng)
    return build(sid, seed=_seed(rng), drivers="malicious")


def ncap2026_ids() -> list[str]:
    """``ncap-v2``'s ids: every ``ncap2026`` id but the unavoidable TTC-0 cut-in."""
    return [i for i in list_scenarios("ncap2026") if i != "ncap2026/acc/cut-in/50-10"]


def ncap2026_params(scenario_id: str, rng: np.random.Generator) -> dict:
    """The 2026 test point's parameters with test-track deviations (see the module docstring)."""
    from acc_gym.scenarios.ncap2026 import ACC_START_GAP, FC_TTC0

    p, kind = _track_deviations(scenario_id, scenario_id.split("/")[2], rng)
    if kind in ("cut-in", "cut-out"):
        p["ttc"] = max(p["ttc"] + float(rng.uniform(-0.1, 0.1)), 0.0)
    elif kind != "ccrb":  # an approach starts again at its nominal distance
        p["gap"] = FC_TTC0 * (p["v_ego"] - p["v_target"]) / 3.6 if "/fc/" in scenario_id else ACC_START_GAP
    return p


def ncap2026(index: int, rng: np.random.Generator) -> Scenario:
    ids = ncap2026_ids()
    sid = ids[index % len(ids)]
    return build(sid, ncap2026_params(sid, rng), seed=_seed(rng), drivers="typical")
