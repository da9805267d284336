"""Drive the ego of an OpenSCENARIO file with a controller under test.

:func:`run_file` reads the file (:func:`~acc_gym.scenarios.openscenario.reader.read`), runs its
storyboard (:class:`~acc_gym.scenarios.openscenario.runtime.World`) in steps of ``dt`` (the
package's 0.2 s) and, from the moment the ego's longitudinal controller is activated (from
the start when the file activates none), gives the ego to the controller: every step it is
fed the environments' observation of its radar target (:func:`runtime.lead_of`): the ``-v0``
table of :class:`acc_gym.envs.acc_env.ACCEnv`, as the ring and the string-stability measurement
feed it (a ``-v1`` policy appends its margin features itself), built by the same code
(:class:`acc_gym.simulation.ring.RingSensors`),
and its action is scaled to a desired acceleration as the environments do and realised by
the package's vehicle model (:mod:`acc_gym.vehicle`, a mid-size car; the file's dimensions
give the contour). Two phases per step: the storyboard's triggers and actions and the
controller's decision from the snapshot at the step's start, then every entity moves.

Decided here: the set speed is the ego's speed when its controller is activated (a driver
engaging ACC sets it so) and the nominal time gap is 1.5 s, unless given, or unless the ego's
controller has the Properties ``setSpeed`` [m/s] and ``timeGap`` [s] (the package's exports
write them). The run
ends at the storyboard's stop trigger, when every story is complete (a file without a stop
trigger), or at ``duration``. A collision is the ego's contour touching another's, or the
radar target's gap reaching 0 (the package's definition, :mod:`acc_gym.evaluation.scoring`);
the run goes on after it, as the file says.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acc_gym.scenarios.openscenario import model as M
from acc_gym.scenarios.openscenario.reader import read
from acc_gym.scenarios.openscenario.runtime import World, lead_of, overlap, passed_through

DT = 0.2  # [s] the package's step (acc_gym.envs.core.DT)
MAX_DURATION = 600.0  # [s] default cap of a run whose stop trigger never fires
TIME_GAP = 1.5  # [s] the nominal time gap in the ego's observation and score


@dataclass
class Trace:
    """Every step of a run: ``t`` (n,), and per entity (n, m) in :attr:`names` order ``s``
    (reference point along the road), ``y`` (lateral), ``v``, ``a``; the ego's radar target
    ``gap``, ``v_lead``, ``a_lead``, ``lead`` (its index in ``names``, -1: none), and
    ``controlled`` (the controller drove the ego over the step); ``ego_index`` the ego's column."""

    names: list
    t: np.ndarray
    s: np.ndarray
    y: np.ndarray
    v: np.ndarray
    a: np.ndarray
    gap: np.ndarray
    v_lead: np.ndarray
    a_lead: np.ndarray
    lead: np.ndarray
    controlled: np.ndarray
    ego_index: int = 0


def run_file(path, controller, *, parameters: dict | None = None, ego: str | None = None, dt: float = DT,
             duration: float = MAX_DURATION, set_speed: float | None = None, time_gap: float | None = None,
             sensor_range: float = 200.0, scenario: M.OpenScenario | None = None, drivers: str | None = None,
             driver_model: int | None = None, seed: int = 0):
    """Run ``controller`` (an object with SB3's ``predict``) as the ego of the file ``path``.

    Returns ``(result, trace)``: ``result`` a dict (``file``, ``ego``, ``collided``,
    ``collision_with``, ``collision_t``, ``min_gap``, ``min_ttc``, ``activated_at``, ``ended``,
    ``duration``, ``report`` -- paper 003's episode report of the controlled time --,
    ``score``, ``qualified``, ``iso15622`` (ISO 15622's envelope on the controlled drive,
    :func:`acc_gym.standards.iso15622.check_drives`), ``unsupported`` (what the file has that is out of scope here),
    ``ignored`` (the ego's own scripted actions after its controller took over), ``notes``),
    and the :class:`Trace`.

    ``drivers``: a population kind (``"typical"``, ``"atypical"``, ``"malicious"``,
    ``"naturalistic"``): a human-like MPC driver drawn from it (:func:`acc_gym.drivers.population.sample_drivers`,
    driver model ``driver_model``, default the environments' :data:`acc_gym.drivers.mpc.ENV_DRIVER_MODEL`,
    all randomness from ``seed``) takes over the longitudinal control of every other *vehicle* that
    moves when the storyboard starts, its desired speed that initial speed; it follows its own radar
    target by the ego's rule (:func:`runtime.lead_of`) in the package's vehicle model, and the
    storyboard's longitudinal actions on it are listed in ``ignored`` (its lateral ones still move
    it). Pedestrians, objects and vehicles standing at the start keep their scripted motion."""
    from acc_gym.envs.acc_env import check_actions
    from acc_gym.envs.acc_env import actions_to_accel
    from acc_gym.simulation.ring import RingSensors
    from acc_gym.vehicle import VehicleParams, VehicleState, step as vehicle_step

    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number > 0 [s], got {dt!r}")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a finite number > 0 [s], got {duration!r}")
    sc = scenario if scenario is not None else read(path, parameters=parameters, ego=ego)
    set_speed, time_gap = _ego_settings(sc, set_speed, time_gap)
    world = World(sc)
    world.start()
    names = list(world.bodies)
    ie = names.index(sc.ego)
    driven, mpc = _drivers(world, drivers, driver_model, seed)
    ego_body = world.bodies[sc.ego]
    params = VehicleParams()
    sensors = None
    if hasattr(controller, "reset"):
        controller.reset()
    rows: list = []
    collided, collision_with, collision_t = False, None, None
    prev = None  # the contours at the last step
    n_max = int(math.ceil(duration / dt - 1e-9))
    for _ in range(n_max + 1):
        was_active = world.ego_active
        world.update()
        if world.ego_active and not was_active:
            ego_body.a = 0.0  # the controller starts from the ego's current speed
        target = lead_of(world, sensor_range)
        gap, vl, al, li = (math.inf, 0.0, 0.0, -1) if target is None else (
            target[1], target[2], target[3], names.index(target[0]))
        # collisions at this snapshot, or between the last one and this one
        boxes = [b.box() for b in world.bodies.values()]
        for j, (name, b) in enumerate(world.bodies.items()):
            hit = overlap(ego_body, b) or (j == li and gap <= 0.0) or (
                prev is not None and passed_through(prev[j], boxes[j], prev[ie], boxes[ie]))
            if j != ie and hit and not collided:
                collided, collision_with, collision_t = True, name, world.t
        prev = boxes
        rows.append((world.t, [b.s for b in world.bodies.values()], [b.t for b in world.bodies.values()],
                     [b.v for b in world.bodies.values()], [b.a for b in world.bodies.values()], gap, vl, al, li,
                     world.ego_active))
        if world.ended is not None:
            break
        if (sc.stop is None or not sc.stop.groups) and world.all_complete():  # no stop trigger (or an empty one)
            world.ended = "every story complete"
            break
        if len(rows) > n_max:
            world.ended = f"duration ({duration:g} s)"
            break
        state = None
        if world.ego_active:
            if sensors is None:
                v_set = float(set_speed) if set_speed is not None else max(ego_body.v, 0.1)
                sensors = RingSensors(np.array([[0, 0]]), set_speed=v_set, time_gap=time_gap,
                                      sensor_range=sensor_range, version=0)
            f = tuple(np.array([[x]], dtype=float) for x in (ego_body.v, ego_body.a, gap, vl, al))
            obs = sensors(f)[0]
            action, _ = controller.predict(obs, deterministic=True)
            act = check_actions(np.asarray(action, dtype=np.float32).reshape(-1), (1,))
            a_des = actions_to_accel(np.asarray(act, dtype=float), 3.0, 8.0)
            front = ego_body.s + ego_body.ent.front
            nxt = vehicle_step(VehicleState(np.array([front]), np.array([ego_body.v]), np.array([ego_body.a])),
                               a_des, params, dt)
            state = (float(nxt.x[0]) - ego_body.ent.front, float(nxt.v[0]), float(nxt.a[0]))
        moved = None
        if driven:  # the human-like drivers decide from the same snapshot, then everyone moves
            seen = np.empty((5, len(driven)))
            for k, name in enumerate(driven):
                b, tgt = world.bodies[name], lead_of(world, sensor_range, name)
                seen[:, k] = (b.v, b.a, math.inf, 0.0, 0.0) if tgt is None else (b.v, b.a, tgt[1], tgt[2], tgt[3])
            a_des = mpc.act_rows(seen)
            bodies = [world.bodies[n] for n in driven]
            front = np.array([b.s + b.ent.front for b in bodies])
            nxt = vehicle_step(VehicleState(front, seen[0].copy(), seen[1].copy()), a_des, params, dt)
            moved = {n: (float(nxt.x[k]) - b.ent.front, float(nxt.v[k]), float(nxt.a[k]))
                     for k, (n, b) in enumerate(zip(driven, bodies))}
        world.move(dt, state, moved)
    trace = _trace(names, rows)
    trace.ego_index = ie
    return _result(sc, world, trace, ie, collided, collision_with, collision_t, set_speed, time_gap), trace


def _ego_settings(sc: M.OpenScenario, set_speed, time_gap) -> tuple:
    """The set speed and time gap given, else the ego's controller's Properties ``setSpeed``
    [m/s] and ``timeGap`` [s] (as :mod:`~acc_gym.scenarios.openscenario.writer` writes them),
    else None (the speed at activation) and :data:`TIME_GAP`."""
    props = sc.entities[sc.ego].controller_properties
    out = []
    for value, key, default in ((set_speed, "setSpeed", None), (time_gap, "timeGap", TIME_GAP)):
        if value is None and key in props:
            try:
                value = float(props[key])
            except ValueError:
                raise ValueError(f"{sc.path}: the ego's controller property {key}={props[key]!r} is not a "
                                 f"number") from None
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{sc.path}: the ego's controller property {key}={props[key]!r} must be a "
                                 f"finite number > 0")
        out.append(default if value is None else value)
    return tuple(out)


def _trace(names, rows) -> Trace:
    t = np.array([r[0] for r in rows])
    cols = [np.array([r[k] for r in rows], dtype=float) for k in (1, 2, 3, 4)]
    return Trace(names, t, *cols, gap=np.array([r[5] for r in rows]), v_lead=np.array([r[6] for r in rows]),
                 a_lead=np.array([r[7] for r in rows]), lead=np.array([r[8] for r in rows], dtype=int),
                 controlled=np.array([r[9] for r in rows], dtype=bool))


def _result(sc, world, tr: Trace, ie: int, collided, collision_with, collision_t, set_speed, time_gap) -> dict:
    from acc_gym.evaluation.scoring import score_episode
    from acc_gym.evaluation.trace import EgoTrace
    from acc_gym.standards.iso15622 import Drive, check_drives

    on = np.flatnonzero(tr.controlled)
    seen = np.isfinite(tr.gap)
    closing = tr.v[:, ie] - tr.v_lead
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(seen & (closing > 0) & (tr.gap > 0), tr.gap / closing, np.inf)
    report = iso = None
    if len(on) >= 2:
        sl = slice(on[0], on[-1] + 1)
        v_set = float(set_speed) if set_speed is not None else max(float(tr.v[on[0], ie]), 0.1)
        d2, d3, a_y = _lateral(sc, tr, ie)
        ego = EgoTrace(t=tr.t[sl], v=tr.v[sl, ie], a=tr.a[sl, ie], gap=tr.gap[sl], v_lead=tr.v_lead[sl],
                       a_lead=tr.a_lead[sl], lead_id=tr.lead[sl], a_y=a_y[sl], d2=d2[sl], d3=d3[sl],
                       set_speed=v_set, time_gap=time_gap)
        report = score_episode(ego).to_dict()
        # ISO 15622's envelope on the controlled drive (its requirements a drive does not exercise: not exercised)
        iso = check_drives([Drive.from_trace(Path(sc.path).name, ego)]).to_dict()
    finite = lambda x: float(x) if np.isfinite(x) else None  # noqa: E731
    return {"file": sc.path, "ego": sc.ego, "collided": bool(collided), "collision_with": collision_with,
            "collision_t": collision_t, "min_gap": finite(np.min(tr.gap[seen])) if seen.any() else None,
            "min_ttc": finite(np.min(ttc)) if len(ttc) else None, "activated_at": world.activated_at,
            "ended": world.ended, "duration": float(tr.t[-1]),
            "score": None if report is None else report["score"],
            "qualified": None if report is None else report["qualified"], "report": report, "iso15622": iso,
            "unsupported": list(sc.out_of_scope), "ignored": list(world.ignored), "notes": list(world.notes)}


def _lateral(sc: M.OpenScenario, tr: Trace, ie: int) -> tuple:
    """The ego's paper 003 distances and lateral acceleration per step: ``D2`` from its contour
    to the outer edge of the driving lanes on its side of the reference line (the road edge),
    ``D3`` to their inner edge (the carriageway's boundary line), and ``a_y`` [m/s^2] the
    second difference of its lateral position (0 at the first and last step)."""
    e = sc.entities[sc.ego]
    t = tr.y[:, ie] + e.center_y  # [m] the contour's centre line
    side = -1.0 if np.median(t) < 0 else 1.0  # the ego's side of the reference line
    lanes = [ln for ln in sc.road.lanes.values() if ln.driving and ln.centre * side > 0]
    if not lanes:
        lanes = list(sc.road.lanes.values())
    outer = max(side * ln.centre + 0.5 * ln.width for ln in lanes)  # [m] from the reference line, on the ego's side
    inner = min(side * ln.centre - 0.5 * ln.width for ln in lanes)
    d2 = outer - (side * t + 0.5 * e.width)
    d3 = (side * t - 0.5 * e.width) - inner
    a_y = np.zeros_like(t)
    if len(t) >= 3:
        dt = float(tr.t[1] - tr.t[0])
        a_y[1:-1] = (t[2:] - 2.0 * t[1:-1] + t[:-2]) / (dt * dt)
    return d2, d3, a_y


def _drivers(world: World, kind: str | None, model: int | None, seed: int):
    """The vehicles human-like drivers take over (see :func:`run_file`) and their MPC drivers."""
    if kind is None:
        return [], None
    from acc_gym.drivers.mpc import ENV_DRIVER_MODEL, human_drivers
    from acc_gym.drivers.population import KINDS, sample_drivers
    from acc_gym.vehicle import VehicleParams

    if kind not in KINDS:
        raise ValueError(f"drivers must be one of {list(KINDS)}, got {kind!r}")
    driven = [n for n, b in world.bodies.items() if n != world.ego and b.ent.kind == "vehicle" and b.v > 0]
    if not driven:
        world.note(f"drivers={kind!r}: no other vehicle moves at the start, so none is driven")
        return [], None
    for n in driven:  # the driver drives from here: the scripted longitudinal motion ends
        b = world.bodies[n]
        b.long = b.path = None
    world.driven = set(driven)
    v_des = np.array([world.bodies[n].v for n in driven])
    ss = np.random.SeedSequence(int(seed)).spawn(2)
    params = sample_drivers(np.random.default_rng(ss[0]), len(driven), v_des, kind)
    mpc = human_drivers(params, ENV_DRIVER_MODEL if model is None else model,
                        groups=[(np.random.default_rng(ss[1]), len(driven))], vehicle=VehicleParams())
    return driven, mpc
