"""Write an episode of the package as an ASAM OpenSCENARIO 1.2 file on an OpenDRIVE straight road.

:func:`export` runs a :class:`~acc_gym.scenarios.spec.Scenario` in the environments with a
controller as the ego and writes what every vehicle drove (:func:`write_episode`), with
scenariogeneration (PyPI, the ``osc`` extra):

* **the road**: an OpenDRIVE straight road of the scenario's lanes (3.75 m wide), all on the
  right of the reference line (the package's lane 0, the rightmost, is OpenDRIVE's lane
  ``-n_lanes``), long enough for the whole episode. Lateral positions: ``t = y - (n_lanes -
  0.5) lane_width``; positions along the road: ``s = x + offset`` with an integer
  ``offset`` that keeps every vehicle on the road (:attr:`Export.offset`).
* **the vehicles**: Ego (the scenario's ``SV``), POV and POV2, each a car of its length and
  width whose reference point (OpenSCENARIO's: the rear axle) is ``REAR_AXLE`` of its length
  ahead of its rear bumper; the performance limits of the package's vehicle model. The
  ego's ObjectController carries the scenario's set speed and time gap as Properties
  (``setSpeed`` [m/s], ``timeGap`` [s]), which :func:`~acc_gym.scenarios.openscenario.run_file` reads.
* **the motion**: human-like drivers cannot run outside this package, so each vehicle's
  longitudinal motion is written as the trajectory it drove: a SpeedProfileAction (followingMode
  position) with one entry per 0.2 s step, ``(v_{k+1}, 0.2 s)``. The package's vehicles move
  at a constant acceleration over each step, so the speed is linear in time there and the
  profile is exact; a vehicle that stops inside a step gets two entries (stopping at
  ``2 dx / v_k``, then standing). A lateral move (a cut-in, cut-out or lane change, a
  half-cosine whose start is off the 0.2 s grid) is written as an untimed
  FollowTrajectoryAction: a polyline through the step positions, followed at the profile's
  speed. Along such a segment the profile gives the speed along the path, ``v / cos h``
  (``h`` the segment's heading; a change at once between segments), so that the distance
  along the road and the speed along it at every step are the drive's. With ``ego_motion``
  the ego's drive is written the same way, for a replay in another tool; this package's
  runner ignores it (the controller under test drives the ego) and lists it in ``ignored``.

Reading the file back and driving its ego with the same controller gives the same
trajectories (``tests/scenarios/openscenario/test_export.py``, to 1e-6 m).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acc_gym._io import atomic_write

DT_TOLERANCE = 1e-9  # [m] a step's distance matches its trapezoid within this (else it stopped inside it)
REAR_AXLE = 0.22  # [-] the reference point's distance ahead of the rear bumper, as a share of the length
NAMES = {"SV": "Ego", "POV": "POV", "POV2": "POV2"}
ROAD_MARGIN = 50.0  # [m] road before the rearmost and after the foremost position
VERSION_MINOR = 2  # OpenSCENARIO 1.2: the first with SpeedProfileAction


@dataclass(frozen=True)
class Export:
    """What :func:`write_episode` wrote: the files, the offset ``s = x + offset`` [m], the
    entities' names by slot, and whether a surrounding vehicle reacted to the ego (its
    recorded motion then holds for the controller that drove the episode only)."""

    xosc: Path
    xodr: Path
    offset: float
    names: tuple
    reacts_to_ego: tuple  # names of the vehicles that had the ego as their target at some step


def _need_scenariogeneration():
    try:
        from scenariogeneration import xodr, xosc
    except ImportError as exc:  # pragma: no cover - the osc extra installs it
        raise RuntimeError("writing OpenSCENARIO needs scenariogeneration: pip install 'acc-gym[osc]'") from exc
    return xosc, xodr


def profile_entries(x: np.ndarray, v: np.ndarray, dt: float, scale: np.ndarray | None = None,
                    who: str = "vehicle") -> list:
    """SpeedProfileEntry ``(time, speed)`` pairs reproducing the motion ``x`` [m], ``v`` [m/s]
    (``(n + 1,)``, row 0 the start) stepped by ``dt``: one per step, two for a step in which
    the vehicle stops. ``scale`` ``(n,)``: each step's speeds times it (``1 / cos h`` along a
    path), with a change at once where it changes."""
    out = []
    prev_scale = 1.0
    for k in range(len(x) - 1):
        dx, v0, v1 = x[k + 1] - x[k], v[k], v[k + 1]
        c = 1.0 if scale is None else float(scale[k])
        if c != prev_scale:
            out.append((0.0, v0 * c))  # the speed along the new segment, at once
        if abs(dx - 0.5 * (v0 + v1) * dt) <= DT_TOLERANCE + 1e-12 * abs(dx):
            out.append((dt, v1 * c))
        elif v1 == 0.0 and v0 > 0.0 and 0.0 < 2.0 * dx / v0 <= dt + 1e-12:
            t_stop = min(2.0 * dx / v0, dt)
            out.append((t_stop, 0.0))
            if dt - t_stop > 0.0:
                out.append((dt - t_stop, 0.0))
        else:
            raise ValueError(f"{who}: the step from t = {k * dt:g} s moves {float(dx)!r} m from {float(v0)!r} to "
                             f"{float(v1)!r} m/s, "
                             f"which is no constant acceleration (nor a stop inside the step)")
        prev_scale = c
    return out


def _moves(y: np.ndarray) -> list:
    """The lateral moves of ``y`` ``(n + 1,)``: ``[(k0, k1)]`` so that rows ``k0..k1`` are the
    path's vertices (the steps ``k0..k1 - 1``), ending with one step without lateral motion where
    the drive has one (the heading is the road's again after the path)."""
    moving = np.flatnonzero(np.diff(y) != 0.0)
    out: list = []
    for k in moving:
        if out and k <= out[-1][1]:
            out[-1] = (out[-1][0], min(k + 2, len(y) - 1))
        else:
            out.append((int(k), min(int(k) + 2, len(y) - 1)))
    return out


def write_episode(scenario, trace, out_dir, *, name: str | None = None, controller: str = "",
                  ego_motion: bool = True, time_gap: float | None = None) -> Export:
    """Write ``scenario`` as driven in ``trace`` (a :class:`~acc_gym.simulation.single_lane.WorldTrace`
    of one scene, :func:`acc_gym.evaluation.runner.run_episode`'s) to ``out_dir`` as
    ``NAME.xosc`` and ``NAME.xodr`` (default name: the scenario's id and seed). ``controller``
    names what drove the ego (for the description); ``ego_motion`` writes the ego's drive too;
    ``time_gap`` [s] the one the episode ran with (default the scenario's: a controller's
    declared time gap replaces it, :func:`acc_gym.evaluation.runner.declared_time_gap`)."""
    xosc, xodr = _need_scenariogeneration()
    from acc_gym.vehicle import VehicleParams

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if name is None:
        name = f"{scenario.id.replace('/', '_')}_seed{scenario.seed}"
    dt = float(scenario.dt)
    tau = float(scenario.time_gap if time_gap is None else time_gap)
    road = scenario.road
    w, n_lanes = float(road.lane_width), int(road.n_lanes)
    x, v, y = trace.x[:, 0, :], trace.v[:, 0, :], trace.y[:, 0, :]  # (T + 1, S)
    present = trace.present[0]
    lengths = trace.lengths[0]
    widths = trace.width[0]
    slots = [j for j in range(x.shape[1]) if present[j]]
    specs = {j: scenario.vehicles[j] for j in slots}
    names = tuple(NAMES[specs[j].role] for j in slots)
    rear = min(float(np.min(x[:, j] - lengths[j])) for j in slots)
    front = max(float(np.max(x[:, j])) for j in slots)
    offset = float(ROAD_MARGIN - math.floor(rear))
    t_off = (n_lanes - 0.5) * w  # t = y - t_off
    reacts = tuple(NAMES[specs[j].role] for j in slots if j != 0 and np.any(trace.lead[:, 0, j] == 0))

    # the road
    length = float(math.ceil(front + offset + ROAD_MARGIN))
    odr = xodr.OpenDrive(f"{name}_road")
    odr.add_road(xodr.create_road(xodr.Line(length), id=0, left_lanes=0, right_lanes=n_lanes, lane_width=w))
    odr.adjust_roads_and_lanes()
    xodr_path = out / f"{name}.xodr"
    atomic_write(xodr_path, _xml(odr))

    # the vehicles
    vp = VehicleParams()
    a_max, d_max = float(vp.traction_accel), float(vp.mu_brake) * 9.81
    entities = xosc.Entities()
    for j, nm in zip(slots, names):
        L, W = float(lengths[j]), float(widths[j])
        cx = (0.5 - REAR_AXLE) * L
        bb = xosc.BoundingBox(W, L, 1.5, cx, 0.0, 0.75)
        axle = lambda px: xosc.Axle(0.5 if px > 0 else 0.0, 0.65, W - 0.2, px, 0.33)  # noqa: E731
        veh = xosc.Vehicle(f"{nm}_car", xosc.VehicleCategory.car, bb, axle(0.6 * L), axle(0.0), 70.0, a_max, d_max)
        ctrl = None
        if j == 0:
            props = xosc.Properties()
            props.add_property("setSpeed", repr(float(scenario.set_speed)))
            props.add_property("timeGap", repr(tau))
            ctrl = xosc.Controller("acc_gym_ego", props)
        entities.add_scenario_object(nm, veh, ctrl)

    # Init: positions and speeds
    init = xosc.Init()
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0)
    for j, nm in zip(slots, names):
        s0 = _ref_s(x[0, j], lengths[j], offset)
        init.add_init_action(nm, xosc.TeleportAction(xosc.WorldPosition(s0, float(y[0, j] - t_off), 0.0, 0.0)))
        init.add_init_action(nm, xosc.AbsoluteSpeedAction(float(v[0, j]), step))

    # the storyboard: per vehicle its profile from t = 0, its paths from their first step
    act = xosc.Act("drive", _at(-0.5 * dt))
    for j, nm in zip(slots, names):
        if j == 0 and not ego_motion:
            continue
        s_col = np.array([_ref_s(xk, lengths[j], offset) for xk in x[:, j]])
        t_col = y[:, j] - t_off
        moves = _moves(y[:, j])
        scale = np.ones(len(x) - 1)
        for k0, k1 in moves:
            for k in range(k0, k1):
                ds, dy = s_col[k + 1] - s_col[k], t_col[k + 1] - t_col[k]
                if dy != 0.0 and ds <= 0.0:
                    raise ValueError(f"{nm}: moves sideways while standing at t = {k * dt:g} s; a path followed "
                                     f"at the vehicle's speed cannot write that")
                scale[k] = math.hypot(ds, dy) / ds if ds > 0 else 1.0
        entries = profile_entries(x[:, j], v[:, j], dt, scale, who=nm)
        mg = xosc.ManeuverGroup(f"{nm}_drive")
        mg.add_actor(nm)
        man = xosc.Maneuver(f"{nm}_maneuver")
        ev = xosc.Event(f"{nm}_profile", xosc.Priority.parallel)
        ev.add_action(f"{nm}_speed_profile", xosc.SpeedProfileAction([e[1] for e in entries],
                                                                     xosc.FollowingMode.position,
                                                                     [e[0] for e in entries]))
        ev.add_trigger(_at(-0.5 * dt))
        man.add_event(ev)
        for m, (k0, k1) in enumerate(moves):
            poly = xosc.Polyline([], [xosc.WorldPosition(float(s_col[k]), float(t_col[k]), 0.0, 0.0)
                                      for k in range(k0, k1 + 1)])
            traj = xosc.Trajectory(f"{nm}_path_{m}", False)
            traj.add_shape(poly)
            pe = xosc.Event(f"{nm}_path_{m}", xosc.Priority.parallel)
            pe.add_action(f"{nm}_follow_path_{m}", xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.position))
            pe.add_trigger(_at((k0 - 0.5) * dt))
            man.add_event(pe)
        mg.add_maneuver(man)
        act.add_maneuver_group(mg)
    story = xosc.Story("episode")
    story.add_act(act)
    t_end = float(trace.t[-1])
    stop = xosc.ValueTrigger("end", 0.0, xosc.ConditionEdge.none,
                             xosc.SimulationTimeCondition(t_end - 0.5 * dt, xosc.Rule.greaterThan), "stop")
    sb = xosc.StoryBoard(init, stop)
    sb.add_story(story)
    who = "the surrounding vehicles'" + (" and the ego's" if ego_motion else "")
    description = (f"acc_gym scenario {scenario.id} seed {scenario.seed} ({scenario.description or 'no description'})"
                   f", driven in acc_gym with the ego under {controller or 'a controller'}. Human-like drivers "
                   f"cannot run outside acc_gym, so {who} motion is written as the trajectories driven (speed "
                   f"profiles and paths, 0.2 s steps). Set speed {scenario.set_speed:g} m/s, time gap "
                   f"{tau:g} s (the ego's controller properties)."
                   + (f" {', '.join(reacts)} reacted to the ego: its motion holds for this controller only."
                      if reacts else ""))
    sce = xosc.Scenario(name, "acc_gym", xosc.ParameterDeclarations(), entities, sb,
                        xosc.RoadNetwork(roadfile=xodr_path.name), xosc.Catalog(), osc_minor_version=VERSION_MINOR)
    sce.header.description = description
    xosc_path = out / f"{name}.xosc"
    atomic_write(xosc_path, _xml(sce))
    return Export(xosc_path, xodr_path, offset, names, reacts)


def file_stem(name: str) -> str:
    """``name`` (a controller's, a drive's label) as a file name: letters, digits, ``.``, ``_``
    and ``-`` only, at most 80 characters."""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "controller"
    return stem[:80]


def _ref_s(x_front: float, length: float, offset: float) -> float:
    """The reference point's ``s`` of a vehicle whose front bumper is at ``x_front``."""
    return float(x_front) + offset - (1.0 - REAR_AXLE) * float(length)


def _at(t: float):
    from scenariogeneration import xosc

    return xosc.ValueTrigger("at", 0.0, xosc.ConditionEdge.none,
                             xosc.SimulationTimeCondition(float(t), xosc.Rule.greaterThan))


def _xml(doc):
    """A scenariogeneration document (its ``get_element()``) as indented UTF-8 XML, for
    :func:`acc_gym._io.atomic_write`."""
    import xml.etree.ElementTree as ET

    def write(f):
        tree = ET.ElementTree(doc.get_element())
        ET.indent(tree)
        tree.write(f, encoding="utf-8", xml_declaration=True)

    return write


def export(scenario, controller, out_dir, *, name: str | None = None, ego_motion: bool = True,
           env_id: str = "acc_gym/SingleLane-v0") -> tuple:
    """Run ``scenario`` (a :class:`~acc_gym.scenarios.spec.Scenario`) with ``controller`` (a
    name or an object with ``predict``) as the ego in ``env_id`` and write it
    (:func:`write_episode`). Returns ``(Export, final_info, trace)``."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import declared_time_gap, load_controller, run_episode

    policy = load_controller(controller)
    with warnings.catch_warnings():  # the v0 observation is what run_file feeds a controller: the same inputs
        warnings.simplefilter("ignore")
        env = gym.make(env_id)
    try:
        info, trace = run_episode(env, policy, scenario=scenario, record=True)
        tg = declared_time_gap(policy)
    finally:
        env.close()
    label = controller if isinstance(controller, str) else type(controller).__name__
    ex = write_episode(scenario, trace, out_dir, name=name, controller=label, ego_motion=ego_motion, time_gap=tg)
    return ex, info, trace
