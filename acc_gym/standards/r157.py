"""UN Regulation No. 157's preventability: would a careful and competent driver have avoided it?

R157 (ALKS) asks a system to avoid every collision that its careful and competent (C&C)
reference driver avoids (Mattas et al. 2022 [Q]). Here the reference is the built-in
``cc-driver`` (:mod:`acc_gym_agents.controllers.cc_driver`), and a collision of the
controller under test is **preventable** when the C&C driver, put in the same scenario
(same parameters, same seed, same traffic), does not collide; **non-preventable** when it
collides too.

:func:`r157_cases` runs the two over R157-style parameter grids built from the package's
scenarios (each grid a documented choice [R]; the regulation's own sweeps are wider):

* **lead deceleration** (Euro NCAP CCRb geometry, ``ncap/ccrb``): ego and lead at the same
  speed (60 / 90 / 120 km/h), the lead ``time_headway`` (1 or 2 s) ahead, braking at
  ``lead_decel`` (4, 6 or 8 m/s^2) to a stop 2 s in; 20 s long;
* **cut-in** (paper 004's ``singlelane/2/cut-in``): the ego at ``ego_speed`` (20 or 30 m/s),
  the other vehicle ``gap`` (5, 10, 20 or 40 m) ahead in the next lane, ``other_speed`` 2 or
  6 m/s slower, changing lanes from 1 s on over 3 s (``lateral_speed`` = lane width / 3 s);
  20 s long.

Cut-outs are not in the grid yet: the package's cut-out scenarios reveal a free road or a
following vehicle, not the slower or stopped one R157's cut-out test reveals.
"""

from __future__ import annotations

import itertools

import numpy as np

LANE_WIDTH = 3.75  # [m] the single-lane scenarios' (acc_gym.scenarios.singlelane)
REFERENCE = "cc-driver"
DURATION = 20.0  # [s] every case
LEAD_DECEL_GRID = {"ego_speed": (60 / 3.6, 90 / 3.6, 120 / 3.6), "lead_decel": (4.0, 6.0, 8.0),
                   "time_headway": (1.0, 2.0)}
CUT_IN_GRID = {"ego_speed": (20.0, 30.0), "gap": (5.0, 10.0, 20.0, 40.0), "closing": (2.0, 6.0)}
CUT_IN_START, CUT_IN_DURATION = 1.0, 3.0  # [s] the lane change: from 1 s on, over 3 s
ENV_ID = "acc_gym/SingleLane-v0"


def _round(params: dict) -> dict:
    return {k: round(float(v), 6) for k, v in params.items()}


def grid():
    """``(family, params, scenario id, scenario parameters)`` of every case, in a fixed order."""
    out = []
    for v, decel, h in itertools.product(*LEAD_DECEL_GRID.values()):
        params = _round({"ego_speed": v, "lead_decel": decel, "time_headway": h})
        kmh = round(v * 3.6, 6)
        out.append(("lead deceleration", params, "ncap/ccrb/2-40",
                    {"v_ego": kmh, "v_target": kmh, "gap": round(h * v, 6), "decel": decel, "t_brake": 2.0,
                     "duration": DURATION}))
    for v, gap, closing in itertools.product(*CUT_IN_GRID.values()):
        params = _round({"ego_speed": v, "other_speed": v - closing, "gap": gap,
                         "lateral_speed": LANE_WIDTH / CUT_IN_DURATION})
        out.append(("cut-in", params, "singlelane/2/cut-in",
                    {"v_sv": v, "gap": gap, "v_rel": -closing, "t_lc": CUT_IN_START, "lc_duration": CUT_IN_DURATION,
                     "duration": DURATION}))
    return out


def staged_cut_in(gap_at_intrusion: float = 2.0, closing: float = 10.0):
    """A cut-in nobody avoids (for tests and demonstrations): the ego at 30 m/s; a vehicle at
    ``30 - closing`` m/s moves over in 1 s from t = 1 s and is in the ego's lane (0.4 s into its
    move) ``gap_at_intrusion`` [m] ahead. At 2 m and 10 m/s closing, stopping the closing would
    need 25 m/s^2."""
    import dataclasses

    from acc_gym.scenarios.registry import scenario_type
    from acc_gym.scenarios.spec import DriverSpec, LaneChange
    from acc_gym.simulation.profiles import SpeedProfile

    st = scenario_type("singlelane/2/cut-in")
    sc = st.build(st.sample_params(np.random.default_rng(0), {"v_sv": 30.0, "gap": 20.0, "v_rel": -closing,
                                                              "t_lc": 1.0, "lc_duration": 2.5, "duration": 10.0}),
                  0, "typical")
    sv, pov = sc.vehicles[:2]
    v = 30.0 - closing
    x_intrusion = sv.x0 + 30.0 * 1.4 + gap_at_intrusion + pov.length  # its front when it enters the lane
    pov = dataclasses.replace(pov, x0=x_intrusion - v * 1.4, v0=v,
                              driver=DriverSpec.from_profile(SpeedProfile.from_segments(v, [(0.0, 20.0)])),
                              lane_change=LaneChange(to_lane=pov.lane_change.to_lane, t_start=1.0, duration=1.0))
    return dataclasses.replace(sc, vehicles=(sv, pov) + tuple(sc.vehicles[2:]))


def collides(env, controller, scenario) -> bool:
    """Whether ``controller`` (loaded) collides in ``scenario`` (built), run in ``env``."""
    from acc_gym.evaluation.runner import run_episode

    info, _ = run_episode(env, controller, scenario=scenario, record=False)
    return bool(info["report"]["metrics"]["collision"])


def preventability(controller, scenario, reference: str = REFERENCE) -> dict:
    """One scenario: ``{"controller_collides", "cc_driver_collides", "preventable"}`` (``preventable``
    None when the controller does not collide)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller

    env = gym.make(ENV_ID)
    try:
        mine = collides(env, load_controller(controller), scenario)
        ref = collides(env, load_controller(reference), scenario)
    finally:
        env.close()
    return {"controller_collides": mine, "cc_driver_collides": ref, "preventable": (not ref) if mine else None}


def r157_cases(controller, reference: str = REFERENCE) -> dict:
    """Every case of :func:`grid` for ``controller`` and the C&C ``reference``; JSON-safe:
    ``{"cases": [{"family", "params", "controller_collides", "cc_driver_collides", "preventable"}],
    "preventable_collisions", "non_preventable_collisions", "errors"}`` (``preventable`` is None
    where the controller does not collide). A case the controller fails is named in ``errors``."""
    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.scenarios.registry import scenario_type

    policy = load_controller(controller)
    cc = load_controller(reference)
    env = gym.make(ENV_ID)
    cases, errors = [], []
    for k, (family, params, sid, sparams) in enumerate(grid()):
        stype = scenario_type(sid)
        sc = stype.build(stype.sample_params(np.random.default_rng([k, 157]), sparams), k, "typical")
        try:
            mine = collides(env, policy, sc)
        except Exception as exc:  # noqa: BLE001  (a failing controller is a result)
            text = str(exc).splitlines()[0] if str(exc) else ""
            errors.append({"family": family, "params": params, "reason": f"{type(exc).__name__}: {text}"})
            continue
        ref = collides(env, cc, sc)
        cases.append({"family": family, "params": params, "controller_collides": mine, "cc_driver_collides": ref,
                      "preventable": (not ref) if mine else None})
    env.close()
    return {"reference": reference, "cases": cases,
            "preventable_collisions": sum(c["preventable"] is True for c in cases),
            "non_preventable_collisions": sum(c["preventable"] is False for c in cases), "errors": errors}


def plot_map(result: dict, path=None):
    """The preventability map: each grid case as a marker -- where the C&C driver avoids (circle)
    or collides (cross), filled red where the controller collides -- one panel per family."""
    from matplotlib.figure import Figure

    from acc_gym.plotting import save_figure

    fig = Figure(figsize=(11.0, 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    panels = (("lead deceleration", "lead_decel", "time_headway", "lead deceleration [m/s$^2$]", "headway [s]"),
              ("cut-in", "gap", "other_speed", "gap at the start [m]", "other's speed [m/s]"))
    for ax, (family, xk, yk, xl, yl) in zip(axes, panels):
        rows = [c for c in result["cases"] if c["family"] == family]
        speeds = sorted({c["params"]["ego_speed"] for c in rows})
        for c in rows:
            p = c["params"]
            dx = (speeds.index(p["ego_speed"]) - (len(speeds) - 1) / 2) * (0.25 if family == "cut-in" else 0.15)
            x = p[xk] * (1 + dx * 0.3) if family == "cut-in" else p[xk] + dx
            marker = "x" if c["cc_driver_collides"] else "o"
            colour = "tab:red" if c["controller_collides"] else "tab:green"
            ax.scatter(x, p[yk], marker=marker, color=colour, s=60)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(f"{family}: o / x the C&C driver avoids / collides; red: the controller collides", fontsize=9)
        ax.grid(True, alpha=0.3)
        if family == "cut-in":
            ax.set_xscale("log")
    if path is not None:
        save_figure(fig, path)
    return fig
