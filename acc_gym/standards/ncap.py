"""Euro NCAP 2026's ACC performance score, computed by Euro NCAP's own rating calculator.

From 2026 Euro NCAP rates ACC performance itself (Safe Driving > Vehicle Assistance >
ACC performance). The official rating calculator is on PyPI, ``euroncap-rating-2026``
(Apache-2.0; the optional extra ``acc-gym[ncap]``). This module

1. **drives the test points** -- those of the calculator's template (``sd_template.xlsx``,
   sheet "VA - ACC pred.", read by its ``crash_avoidance.matrix_processing.get_test_matrix``
   with ``safe_driving.data_model.ACC_MATRIX_INDICES``), copied into :data:`ACC_POINTS` so
   that the simulation needs no extra, and checked against the installed template by a test
   -- through the scenarios of :mod:`acc_gym.scenarios.ncap2026`, one nominal run each
   (no test-track deviations), in ``acc_gym/SingleLane-v0`` (the ``-v0`` observation every
   controller reads);
2. **measures** each test's speed reduction ``v_reduction`` [km/h], the calculator's
   "Expected value": the test's conflict speed minus the ego's speed at impact, or the whole
   conflict speed when it does not collide (decided here: the conflict speed is the point's
   "VUT speed", and for a cut-out the lead's, "Target speed" -- the speed the ego has when
   the stopped vehicle is revealed, as the calculator's
   ``acc_performance.get_green_v_reduction_threshold`` explains; the impact speed is the
   ego's speed at the end of the 0.2 s step in which the gap first reached 0);
3. **scores** them with the calculator's ``safe_driving.acc_performance.compute_score``:
   the verification sheet ("VA - ACC verif.") is built from the measurements, one row per
   matrix row at 100 % overlap ("Impact location" is not modelled). Euro NCAP scores each
   verification test against the manufacturer's prediction; here every point is simulated,
   so each row carries a **green prediction**, under which the calculator awards what the
   measured reduction earns -- the whole point when ``v_reduction`` exceeds the green
   threshold (``v_VUT - v_target - 2``; ``v_VUT - 2`` for CCRb; ``v_lead - 2`` for cut-out),
   half above 15 km/h, else nothing (an orange prediction gives the same, a red one 0).
   A test type's score is the calculator's (each matrix row ``1 / rows`` of it), its
   maximum one point (the template's "Scenario Scores" sheet: 1 point each).

**Scope.** Of the ACC performance items the calculator scores, this package's longitudinal
single-lane model can run CCRs straight, CCRm, CCRb, CCR cut-in and CCR cut-out; the
overall percentage is over those five points. Named and not run (:data:`OUT_OF_SCOPE`): CCRs
curved (no road curvature), the car-to-motorcyclist and car-to-VRU matrices (no such road
users), road features and auto-resume (no map, no driver). One point is named and not run
either: the cut-in at 50 / 10 km/h with a TTC of 0.00 s -- taken as the TTC at lane
intrusion (:mod:`acc_gym.scenarios.ncap2026`), it puts the target against the ego's bumper
as it enters the lane, a collision no controller could avoid; the calculator's template
does not say where that TTC is measured. It scores 0, as an untested point does.

The frontal-collision (AEB) points of the crash-avoidance template (:data:`FC_POINTS`) are
driven and reported test by test (avoided, impact speed, reduction) but not scored: the
calculator scores Crash Avoidance from a whole workbook (driver state link, robustness
layers, AEB function), which a longitudinal controller alone does not fill.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass

from acc_gym.scenarios import ncap2026 as sc

DISTRIBUTION = "euroncap-rating-2026"
ENV_ID = "acc_gym/SingleLane-v0"
PROTOCOL = "Euro NCAP 2026 Safe Driving: ACC performance (car-to-car)"
GREEN_OFFSET = 2.0  # [km/h] only for the report when the calculator is missing; the calculator decides the score
SCORED = ("CCRs straight", "CCRm", "CCRb", "CCR cut-in", "CCR cut-out")
OUT_OF_SCOPE = {
    "CCRs curved": "no road curvature in the single-lane longitudinal model",
    "CMRs straight / CMRs curved / CMRm / CMRb / CMR cut-in / CMR cut-out": "no motorcyclist targets",
    "CPLA / CBLA": "no pedestrian or cyclist targets",
    "Road features (curves, roundabouts, intersections, traffic lights, stop signs)": "no road map",
    "Auto-resume": "no driver to resume; the package's automatic stop holds until a driver request (ISO 15622)",
}


@dataclass(frozen=True)
class TestPoint:
    """One row of a calculator matrix: the scenario name the calculator uses, the VUT and
    target speeds [km/h] as its template writes them, the TTC [s] where the row has one, the
    package's scenario id, and why it is not run (None: it is)."""

    __test__ = False  # not a pytest class

    scenario: str
    vut_speed: int  # [km/h]
    target_speed: int  # [km/h]
    ttc: float | None  # [s]
    scenario_id: str
    skip: str | None = None

    @property
    def conflict_speed(self) -> float:
        """[km/h] the speed the ego meets the conflict at (the lead's for a cut-out)."""
        return float(self.target_speed if self.scenario == "CCR cut-out" else self.vut_speed)


ACC_POINTS = (
    tuple(TestPoint("CCRs straight", v, 0, None, f"ncap2026/acc/ccrs/{v}") for v in sc.ACC_CCRS)
    + tuple(TestPoint("CCRm", v, vt, None, f"ncap2026/acc/ccrm/{v}-{vt}") for v, vt in sc.ACC_CCRM)
    + tuple(TestPoint("CCRb", v, vt, None, f"ncap2026/acc/ccrb/{v}-{vt}") for v, vt in sc.ACC_CCRB)
    + tuple(TestPoint("CCR cut-in", v, vt, ttc, f"ncap2026/acc/cut-in/{v}-{vt}",
                      "a TTC of 0 s at lane intrusion puts the target against the ego's bumper: no controller avoids "
                      "it (the template does not say where this TTC is measured)" if ttc == 0 else None)
            for v, vt, ttc in sc.ACC_CUT_IN)
    + tuple(TestPoint("CCR cut-out", v, vt, ttc, f"ncap2026/acc/cut-out/{v}-{vt}") for v, vt, ttc in sc.ACC_CUT_OUT)
)
FC_POINTS = (
    tuple(TestPoint("CCRs", v, 0, None, f"ncap2026/fc/ccrs/{v}") for v in sc.FC_CCRS)
    + tuple(TestPoint("CCRm", v, vt, None, f"ncap2026/fc/ccrm/{v}-{vt}") for v, vt in sc.FC_CCRM)
    + tuple(TestPoint("CCRb", v, v, None, f"ncap2026/fc/ccrb/{v}") for v in sc.FC_CCRB)
)


def calculator_version() -> str | None:
    """The installed rating calculator's version, or None."""
    from importlib import metadata

    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return None


def template_path(name: str = "sd_template.xlsx"):
    """The installed calculator's template (it ships them as top-level ``data/`` files)."""
    from importlib import metadata

    return metadata.distribution(DISTRIBUTION).locate_file(f"data/{name}")


def template_points(kind: str = "acc") -> dict:
    """A template's car-to-car matrix rows as the installed calculator reads them: ``kind`` "acc"
    (``sd_template.xlsx``, "VA - ACC pred.", every ACC matrix) or "fc" (``ca_template.xlsx``,
    "FC - Car & PTW pred.", CCRs / CCRm / CCRb); ``{scenario: [(vut_speed, target_speed, ttc or
    None), ...]}`` [km/h, km/h, s]."""
    import re

    import pandas as pd
    from euroncap_rating_2026.crash_avoidance import data_model as ca_data_model
    from euroncap_rating_2026.crash_avoidance import matrix_processing
    from euroncap_rating_2026.safe_driving import data_model

    if kind == "acc":
        df = pd.read_excel(template_path("sd_template.xlsx"), sheet_name="VA - ACC pred.", header=None)
        names, key, indices = list(data_model.ACC_MATRIX_INDICES), ca_data_model.StageSubelementKey.LSC, \
            data_model.ACC_MATRIX_INDICES
    elif kind == "fc":
        df = pd.read_excel(template_path("ca_template.xlsx"), sheet_name="FC - Car & PTW pred.", header=None)
        names, key, indices = ["CCRs", "CCRm", "CCRb"], ca_data_model.StageSubelementKey.FC, \
            ca_data_model.MATRIX_INDICES
    else:
        raise ValueError(f"unknown template kind {kind!r}; use 'acc' or 'fc'")
    out = {}
    for name in names:
        rows = {}
        for tp in matrix_processing.get_test_matrix(df, name, key, matrix_indices_dict=indices) or []:
            a = tp.attributes
            ttc = a.get("TTC")
            rows[tp.row] = (int(re.search(r"\d+", str(a["VUT speed"])).group()),
                            int(re.search(r"\d+", str(a["Target speed"])).group()),
                            None if ttc is None else float(str(ttc).rstrip("s")))
        out[name] = [rows[k] for k in sorted(rows)]
    return out


def measure_point(env, policy, point: TestPoint) -> dict:
    """Run one test point's nominal scenario; ``{"collision", "impact_speed", "v_reduction"}`` [km/h]."""
    import numpy as np

    from acc_gym.evaluation.runner import run_episode
    from acc_gym.scenarios import build

    sc = build(point.scenario_id)
    _, trace = run_episode(env, policy, seed=int(sc.seed), scenario=sc)
    hit = np.flatnonzero(trace.gap[:, 0, 0] <= 0.0)
    impact = float(trace.v[hit[0], 0, 0]) * 3.6 if hit.size else None
    reduction = point.conflict_speed if impact is None else max(point.conflict_speed - impact, 0.0)
    return {"collision": bool(hit.size), "impact_speed": None if impact is None else round(impact, 3),
            "v_reduction": round(reduction, 3)}


def run_points(controller, points=ACC_POINTS, progress=None, car: dict | None = None) -> tuple[list, list]:
    """Each runnable point driven by ``controller``: ``(rows, errors)``; a row is the point's
    fields plus :func:`measure_point`'s; a point the controller fails (it raises, answers NaN)
    is in ``errors`` as ``{"scenario_id", "reason"}`` and the others still run. ``car``: the ego's
    car, as ``gym.make`` settings (:mod:`acc_gym.onboard`; None: ideal)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller

    policy = load_controller(controller)
    with warnings.catch_warnings():  # the pinned -v0 is deliberate: gymnasium's "upgrade to v1" is noise here
        warnings.filterwarnings("ignore", message=".*is out of date", category=DeprecationWarning)
        env = gym.make(ENV_ID, **(car or {}))
    rows, errors = [], []
    try:
        for p in points:
            row = asdict(p)
            if p.skip is None:
                try:
                    row.update(measure_point(env, policy, p))
                except Exception as exc:  # noqa: BLE001  (a failing controller is a result)
                    text = str(exc).splitlines()[0] if str(exc) else ""
                    errors.append({"scenario_id": p.scenario_id, "reason": f"{type(exc).__name__}: {text}"})
                    row.update({"collision": None, "impact_speed": None, "v_reduction": None})
            else:
                row.update({"collision": None, "impact_speed": None, "v_reduction": None})
            rows.append(row)
            if progress is not None:
                progress(p.scenario_id)
    finally:
        env.close()
    return rows, errors


def verification_frame(rows: list):
    """The calculator's "VA - ACC verif." sheet for ``rows`` (one per run point, green prediction)."""
    import pandas as pd

    recs = []
    for r in rows:
        if r["v_reduction"] is None:
            continue
        recs.append({"Category": _category(r["scenario"]), "Scenario": r["scenario"], "Test point": r["scenario_id"],
                     "VUT speed": f"{r['vut_speed']} km/h", "Target speed": f"{r['target_speed']} km/h",
                     "Impact location": "100%", "TTC": "" if r["ttc"] is None else f"{r['ttc']:.2f}s",
                     "OEM Prediction": "Green", "Expected value": "v_reduction", "Value": float(r["v_reduction"])})
    return pd.DataFrame(recs, columns=["Category", "Scenario", "Test point", "VUT speed", "Target speed",
                                       "Impact location", "TTC", "OEM Prediction", "Expected value", "Value"])


def _category(scenario: str) -> str:
    return "Car-to-Car - Cut-in / Cut-out" if "cut" in scenario else "Car-to-Car - Longitudinal"


def score(rows: list) -> dict:
    """Score measured ``rows`` with the installed calculator: ``{"score_percent", "test_types":
    {scenario: {"score", "max", "percent"}}, "tests": rows with "green_threshold", "colour",
    "score"}``. Raises ImportError naming the extra when the calculator is not installed."""
    try:
        import numpy as np
        from euroncap_rating_2026.safe_driving import acc_performance
    except ImportError as exc:
        raise ImportError(f"Euro NCAP scoring needs Euro NCAP's rating calculator: pip install 'acc-gym[ncap]' "
                          f"({exc})") from None
    frame = verification_frame(rows)
    scored, totals = acc_performance.compute_score({"VA - ACC verif.": frame.copy()})
    by_id = {}
    if len(scored):
        colour_col = "" if "" in scored.columns else "Color"
        for _, rec in scored.iterrows():
            by_id[rec["Test point"]] = (str(rec[colour_col]), float(rec["Score"]))
    tests = []
    for r in rows:
        colour, points = by_id.get(r["scenario_id"], (None, 0.0))
        threshold = acc_performance.get_green_v_reduction_threshold(r["scenario"], r["vut_speed"], r["target_speed"])
        tests.append({**r, "green_threshold": float(threshold), "colour": colour, "score": round(points, 6)})
    types = {}
    for name in SCORED:
        value = totals.get(name, float("nan"))
        value = 0.0 if value is None or (isinstance(value, float) and math.isnan(value)) else float(value)
        types[name] = {"score": round(value, 6), "max": 1.0, "percent": round(100.0 * value, 2)}
    overall = 100.0 * float(np.sum([t["score"] for t in types.values()])) / len(SCORED)
    return {"score_percent": round(overall, 2), "test_types": types, "tests": tests}


def ncap_report(controller, progress=None, car: dict | None = None) -> dict:
    """The Euro NCAP section of a conformance report (JSON-safe): ``{"protocol", "calculator",
    "score_percent", "test_types", "tests", "frontal_collisions", "out_of_scope", "errors"}``.
    Without the calculator the measurements are still reported and ``score_percent`` is None
    with the reason under ``"calculator"``."""
    rows, errors = run_points(controller, ACC_POINTS, progress, car)
    fc_rows, fc_errors = run_points(controller, FC_POINTS, progress, car)
    version = calculator_version()
    out = {"protocol": PROTOCOL, "calculator": f"{DISTRIBUTION} {version}" if version else
           f"not installed: pip install 'acc-gym[ncap]' ({DISTRIBUTION})",
           "frontal_collisions": fc_rows, "out_of_scope": dict(OUT_OF_SCOPE), "errors": errors + fc_errors}
    if version is None:
        out.update({"score_percent": None, "test_types": None, "tests": rows})
    else:
        out.update(score(rows))
    return out
