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
  20 s long;
* **cut-out** (staged by hand, :func:`staged_cut_out`, id ``r157/cut-out``): the ego at
  ``ego_speed`` (60 / 90 / 120 km/h) follows a lead at its own speed, ``time_headway`` 1 s
  behind it (bumper gap = headway x speed); ahead of the lead in the same lane a slower
  vehicle stands or drives at ``other_speed`` (0 or 20 km/h); the lead moves out to the next
  lane and reveals it ``gap`` = 1.5, 2.5 or 3.5 s x ``ego_speed`` ahead of the ego; 20 s long.

The cut-out's decisions [R]:

* ``gap`` [m] is the ego's bumper distance to the revealed vehicle at the **reveal**, the first
  step whose observation shows it (t = 6 s, :data:`CUT_OUT_REVEAL`), with the ego assumed at
  ``ego_speed`` until then (a controller that holds its speed is exactly there; the linear ACC
  law and ``cc-driver`` settle at ``time_headway x speed + 2.5 m`` and are up to 2.5 m farther
  back). The grid states it as a time headway at the reveal
  (``gap / ego_speed`` = 1.5, 2.5, 3.5 s) because the C&C driver reacts to a cut-out only below
  a 2 s headway to the revealed vehicle; the grid straddles that gate. Below it the C&C
  response (0.4 s perception, 0.75 s reaction at 0.4 m/s^2, a 0.6 s ramp to 0.774 g) needs
  more than 2 s x speed to stop for a stopped vehicle from 60 km/h up, so there it collides;
  above it ``cc-driver`` drives on its careful following law, which brakes at once.
* ``time_headway`` is 1 s, the short end of common ACC settings (ISO 15622 allows 0.8 s):
  the lead must leave the lane before it reaches the revealed vehicle, so the reveal headway
  exceeds ``time_headway`` + 4.7 m / speed, and only a short following headway leaves room
  below the C&C driver's 2 s gate. It is also the scenario's nominal time gap (the
  observation's time-gap field, which ACC laws follow).
* The lead's lateral move is a half-cosine over one lane in 3 s (:data:`CUT_OUT_LC_DURATION`,
  as the cut-in grid's: mean lateral speed 1.25 m/s, peak 1.96 m/s), timed so that its contour
  leaves the ego's lane half a step (0.1 s) before the reveal. The world drops a vehicle from
  the lane corridor once its contour has left the lane (:mod:`acc_gym.simulation.single_lane`),
  for the ego and the lead alike.
* The lead and the revealed vehicle keep their speeds (speed profiles: neither reacts to
  anything), so the lead must not reach the slower vehicle while in its lane: ``gap >
  time_headway x ego_speed + 4.7 m`` (the lead's length), else a ValueError. The environments
  judge the ego's collisions only (its gap to whoever is ahead of it); a lead running into the
  slower vehicle would go unreported, hence the check.
* The revealed vehicle is a 4.7 m car (:data:`CUT_OUT_OTHER_LENGTH`). (At 120 km/h onto a
  stopped car the ego closes 6.7 m in one step, more than a car's length: the world detects
  such a collision inside a step too, :func:`acc_gym.simulation._world_kernel.mark_passed`.)
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
CUT_OUT_GRID = {"ego_speed": (60 / 3.6, 90 / 3.6, 120 / 3.6), "other_speed": (0.0, 20 / 3.6),
                "reveal_headway": (1.5, 2.5, 3.5)}  # [m/s], [m/s], [s] (gap = reveal_headway x ego_speed)
CUT_OUT_HEADWAY = 1.0  # [s] the ego's time headway to the lead before it leaves
CUT_OUT_REVEAL = 6.0  # [s] the reveal: the first step whose observation shows the revealed vehicle
CUT_OUT_LC_DURATION = 3.0  # [s] the lead's half-cosine move over one lane (mean 1.25 m/s lateral)
CUT_OUT_OTHER_LENGTH = 4.7  # [m] the revealed vehicle, a car
CUT_OUT_ID = "r157/cut-out"  # built by staged_cut_out, not a registered scenario type
ENV_ID = "acc_gym/SingleLane-v0"


def _round(params: dict) -> dict:
    return {k: round(float(v), 6) for k, v in params.items()}


def grid():
    """``(family, params, scenario id, scenario parameters)`` of every case, in a fixed order (the
    cut-out family last; its scenario parameters are :func:`staged_cut_out`'s arguments)."""
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
    for v, other, reveal in itertools.product(*CUT_OUT_GRID.values()):
        params = _round({"ego_speed": v, "other_speed": other, "gap": reveal * v, "time_headway": CUT_OUT_HEADWAY})
        out.append(("cut-out", params, CUT_OUT_ID, dict(params)))
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


def staged_cut_out(ego_speed: float, time_headway: float, other_speed: float, gap: float, seed: int = 0,
                   duration: float = DURATION):
    """R157's cut-out: the ego (``"SV"``, lane 1) at ``ego_speed`` [m/s] follows a lead (``"POV"``)
    at the same speed, ``time_headway`` [s] behind it (bumper gap ``time_headway x ego_speed``);
    ahead of the lead in the same lane a vehicle (``"POV2"``, a 4.7 m car) drives at ``other_speed``
    [m/s] (0: stopped). The lead moves to lane 2 in :data:`CUT_OUT_LC_DURATION` s, its contour
    leaving lane 1 half a step before :data:`CUT_OUT_REVEAL`, when the ego, if it held
    ``ego_speed``, is ``gap`` [m] (bumper to bumper) behind POV2. Both others keep their speeds
    (speed profiles). Built by hand (id :data:`CUT_OUT_ID`, ``params`` the four values).

    ValueError, naming the value: a speed out of range, ``other_speed`` not below ``ego_speed``
    (nothing to reveal), a non-positive headway or gap, or a ``gap`` at which the lead would reach
    POV2 before leaving the lane (``gap <= time_headway x ego_speed + 4.7 m``)."""
    import math

    from acc_gym.scenarios.singlelane import DT, EGO_LANE, LENGTH, ROAD, SIDE_LANE, entry_phase
    from acc_gym.scenarios.spec import MAX_SPEED, MAX_TIME_GAP, DriverSpec, LaneChange, Scenario, VehicleSpec
    from acc_gym.simulation.profiles import SpeedProfile

    values = {"ego_speed": ego_speed, "time_headway": time_headway, "other_speed": other_speed, "gap": gap}
    for name, x in {**values, "duration": duration}.items():
        if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)) or not math.isfinite(x):
            raise ValueError(f"staged_cut_out: {name} must be a finite number, got {x!r}")
    if not 0.0 < ego_speed <= MAX_SPEED:
        raise ValueError(f"staged_cut_out: ego_speed must be in (0, {MAX_SPEED:g}] m/s, got {ego_speed!r}")
    if not 0.0 <= other_speed < ego_speed:
        raise ValueError(f"staged_cut_out: other_speed must be >= 0 and below ego_speed ({ego_speed:g} m/s), "
                         f"got {other_speed!r}")
    if not 0.0 < time_headway <= MAX_TIME_GAP:
        raise ValueError(f"staged_cut_out: time_headway must be in (0, {MAX_TIME_GAP:g}] s, got {time_headway!r}")
    if not gap > 0.0:
        raise ValueError(f"staged_cut_out: gap must be > 0 m, got {gap!r}")
    lead_clearance = gap - time_headway * ego_speed - LENGTH  # [m] lead front to POV2's rear at the reveal
    if lead_clearance <= 0.0:
        raise ValueError(f"staged_cut_out: gap {gap!r} m leaves the lead no room: it would reach the other vehicle "
                         f"before leaving the lane (gap must exceed time_headway x ego_speed + {LENGTH:g} m = "
                         f"{time_headway * ego_speed + LENGTH:g} m)")
    if duration <= CUT_OUT_REVEAL:
        raise ValueError(f"staged_cut_out: duration must exceed the reveal at {CUT_OUT_REVEAL:g} s, got {duration!r}")
    # the lead's contour leaves lane 1 at phase 1 - entry_phase() of its move, half a step before the reveal
    t_lc = CUT_OUT_REVEAL - 0.5 * DT - (1.0 - entry_phase()) * CUT_OUT_LC_DURATION

    def steady(speed):  # [m/s] held for the whole scenario
        return DriverSpec.from_profile(SpeedProfile.from_segments(float(speed), [(0.0, float(duration))]))

    x_other = (ego_speed - other_speed) * CUT_OUT_REVEAL + gap + CUT_OUT_OTHER_LENGTH  # [m] POV2's front at t = 0
    vehicles = (VehicleSpec("SV", 0.0, ego_speed, EGO_LANE, None, None, LENGTH),
                VehicleSpec("POV", time_headway * ego_speed + LENGTH, ego_speed, EGO_LANE, steady(ego_speed),
                            LaneChange(SIDE_LANE, t_lc, CUT_OUT_LC_DURATION), LENGTH),
                VehicleSpec("POV2", x_other, other_speed, EGO_LANE, steady(other_speed), None,
                            CUT_OUT_OTHER_LENGTH))
    return Scenario(id=CUT_OUT_ID, seed=seed, params={k: float(v) for k, v in values.items()}, vehicles=vehicles,
                    duration=duration, set_speed=ego_speed, time_gap=time_headway, road=ROAD, dt=DT,
                    drivers="custom", description="R157 cut-out: the lead leaves the ego's lane and reveals a "
                                                  "slower or stopped vehicle.")


def _build_case(k: int, sid: str, sparams: dict):
    """Case ``k`` of :func:`grid` as a Scenario (its generator seeded ``[k, 157]``)."""
    if sid == CUT_OUT_ID:
        return staged_cut_out(**sparams, seed=k)
    from acc_gym.scenarios.registry import scenario_type

    stype = scenario_type(sid)
    return stype.build(stype.sample_params(np.random.default_rng([k, 157]), sparams), k, "typical")


def collides(env, controller, scenario) -> bool:
    """Whether ``controller`` (loaded) collides in ``scenario`` (built), run in ``env`` seeded with
    the scenario's seed (what a car's radar in ``env`` draws, :mod:`acc_gym.envs.car`)."""
    from acc_gym.evaluation.runner import run_episode

    info, _ = run_episode(env, controller, seed=int(scenario.seed), scenario=scenario, record=False)
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


def r157_cases(controller, reference: str = REFERENCE, families=None, car: dict | None = None,
               keep_failures: bool = False) -> dict:
    """Every case of :func:`grid` (or those of ``families``, names of its families) for
    ``controller`` and the C&C ``reference``; JSON-safe:
    ``{"cases": [{"family", "params", "controller_collides", "cc_driver_collides", "preventable"}],
    "preventable_collisions", "non_preventable_collisions", "errors"}`` (``preventable`` is None
    where the controller does not collide). A case the controller fails is named in ``errors``.
    ``car``: the controller's car, as ``gym.make`` settings (``sensors``, ``actuators``:
    :mod:`acc_gym.onboard`; None: ideal); the reference drives without it. ``keep_failures``: also
    ``"_failures"``, ``[{"label", "scenario", "trace"}]`` of the cases the controller collides in
    (their world traces: not JSON)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller, run_episode

    if families is not None:
        known = list(dict.fromkeys(case[0] for case in grid()))
        families = (families,) if isinstance(families, str) else tuple(families)
        unknown = [f for f in families if f not in known]
        if unknown or not families:
            raise ValueError(f"r157_cases: families must name some of {known}, got {list(families)!r}")
    policy = load_controller(controller)
    cc = load_controller(reference)
    env = gym.make(ENV_ID)
    mine_env = gym.make(ENV_ID, **car) if car else env
    cases, errors, failures = [], [], []
    try:
        for k, (family, params, sid, sparams) in enumerate(grid()):  # k: the case's seed, whatever is selected
            if families is not None and family not in families:
                continue
            sc = _build_case(k, sid, sparams)
            try:
                if keep_failures:  # collides(), with the world recorded
                    info, trace = run_episode(mine_env, policy, seed=int(sc.seed), scenario=sc, record=True)
                    mine = bool(info["report"]["metrics"]["collision"])
                    if mine:
                        failures.append({"label": f"r157-{family}-{k}", "scenario": sc, "trace": trace})
                else:
                    mine = collides(mine_env, policy, sc)
            except Exception as exc:  # noqa: BLE001  (a failing controller is a result)
                text = str(exc).splitlines()[0] if str(exc) else ""
                errors.append({"family": family, "params": params, "reason": f"{type(exc).__name__}: {text}"})
                continue
            ref = collides(env, cc, sc)
            cases.append({"family": family, "params": params, "controller_collides": mine,
                          "cc_driver_collides": ref, "preventable": (not ref) if mine else None})
    finally:
        env.close()
        mine_env.close()
    out = {"reference": reference, "cases": cases,
           "preventable_collisions": sum(c["preventable"] is True for c in cases),
           "non_preventable_collisions": sum(c["preventable"] is False for c in cases), "errors": errors}
    if keep_failures:
        out["_failures"] = failures
    return out


def plot_map(result: dict, path=None):
    """The preventability map: each grid case as a marker -- where the C&C driver avoids (circle)
    or collides (cross), filled red where the controller collides -- one panel per family (the
    ego speeds of a cell side by side, slowest left)."""
    from matplotlib.figure import Figure

    from acc_gym.plotting import save_figure

    fig = Figure(figsize=(15.0, 4.2), layout="constrained")
    axes = fig.subplots(1, 3)
    # family, x (from the params), y key, x label, y label, spread of the ego speeds along x, log x
    panels = (("lead deceleration", lambda p: p["lead_decel"], "time_headway", "lead deceleration [m/s$^2$]",
               "headway [s]", 0.15, False),
              ("cut-in", lambda p: p["gap"], "other_speed", "gap at the start [m]", "other's speed [m/s]", 0.25, True),
              ("cut-out", lambda p: p["gap"] / p["ego_speed"], "other_speed",
               "gap at the reveal / ego speed [s]", "revealed vehicle's speed [m/s]", 0.12, False))
    for ax, (family, xf, yk, xl, yl, spread, log) in zip(axes, panels):
        rows = [c for c in result["cases"] if c["family"] == family]
        speeds = sorted({c["params"]["ego_speed"] for c in rows})
        for c in rows:
            p = c["params"]
            dx = (speeds.index(p["ego_speed"]) - (len(speeds) - 1) / 2) * spread
            x = xf(p) * (1 + dx * 0.3) if log else xf(p) + dx
            marker = "x" if c["cc_driver_collides"] else "o"
            colour = "tab:red" if c["controller_collides"] else "tab:green"
            ax.scatter(x, p[yk], marker=marker, color=colour, s=60)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(f"{family}: o / x the C&C driver avoids / collides; red: the controller collides", fontsize=8)
        ax.grid(True, alpha=0.3)
        if log:
            ax.set_xscale("log")
    if path is not None:
        save_figure(fig, path)
    return fig
