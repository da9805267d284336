"""Run a read OpenSCENARIO storyboard: the entities' motion and the storyboard's states.

**Coordinates.** A straight road's ``s`` (along the reference line) and ``t`` (lateral, left
positive); every entity has a reference point at ``(s, t)``, a heading ``h`` relative to the
road (radians, default 0: along the lane), a speed ``v`` along its heading and an
acceleration ``a``. Its contour is its bounding box aligned with the road.

**Motion of the storyboard's entities** (every entity but the ego once its controller is
active) is kinematic, as OpenSCENARIO's default controller is: the speed follows the
running SpeedAction's transition exactly and the position is its exact integral over each
step; lateral actions move ``t`` along their transition. Transitions (decided here and in
``docs/openscenario.md``):

* shape ``f(tau)``, ``tau`` in [0, 1]: step (at once), linear ``tau``, cubic ``3 tau^2 - 2
  tau^3``, sinusoidal ``(1 - cos(pi tau)) / 2``;
* duration ``T`` by dimension: ``time``: the value; ``distance``: ``2 d / (v0 + v1)`` (the
  distance covered during the transition, as every shape is symmetric); ``rate``: the value
  is the transition's *peak* rate of change (an acceleration for a speed, a lateral speed
  for a lane change), so ``T = k |delta| / rate`` with ``k`` = 1, 3/2 and pi/2 for linear,
  cubic and sinusoidal;
* a LaneOffsetAction's ``maxLateralAcc`` is its peak lateral acceleration: ``T = pi
  sqrt(|delta| / (2 a))`` (sinusoidal), ``sqrt(6 |delta| / a)`` (cubic);
* a LongitudinalDistanceAction keeps the entity at the distance (or the time gap times the
  follower's speed) from its reference, at the reference's speed; not continuous, it ends
  once placed.

A new action of the same domain (longitudinal; lateral) on an entity stops the running one
(OpenSCENARIO's rule for conflicting actions).

**Storyboard states** follow OpenSCENARIO's state machine (standby, running, complete with
start, end, stop and skip transitions) for stories, acts, maneuver groups, maneuvers,
events and actions. Each step, every condition is evaluated on the snapshot at the step's
start (so edges are defined every step), delayed by its ``delay``; then triggers start and
stop elements, started actions take effect, and the entities move. A transition is visible
to a StoryboardElementStateCondition in the step after it happened. Event priorities:
``override`` stops the maneuver's other running events, ``skip`` is not started while one
runs, ``parallel`` runs beside them; ``maximumExecutionCount`` re-arms events and groups.
"""

from __future__ import annotations

import math
from collections import deque

from acc_gym.scenarios.openscenario import model as M
from acc_gym.scenarios.openscenario._xml import OpenScenarioError
from acc_gym.scenarios.openscenario.expressions import compare

SHAPE_RATE = {"linear": 1.0, "cubic": 1.5, "sinusoidal": 0.5 * math.pi}  # peak rate x T / |delta|


def shape_value(shape: str, tau: float) -> float:
    """The share of the change done at ``tau`` in [0, 1]."""
    tau = min(max(tau, 0.0), 1.0)
    if shape == "step":
        return 1.0
    if shape == "linear":
        return tau
    if shape == "cubic":
        return tau * tau * (3.0 - 2.0 * tau)
    return 0.5 * (1.0 - math.cos(math.pi * tau))


def shape_integral(shape: str, tau: float) -> float:
    """``integral_0^tau f``: for a transition's exact distance."""
    tau = min(max(tau, 0.0), 1.0)
    if shape == "linear":
        return 0.5 * tau * tau
    if shape == "cubic":
        return tau ** 3 - 0.5 * tau ** 4
    if shape == "sinusoidal":
        return 0.5 * tau - math.sin(math.pi * tau) / (2.0 * math.pi)
    return tau


class Body:
    """An entity's motion state."""

    def __init__(self, ent: M.Entity):
        self.ent = ent
        self.s = self.t = self.v = self.a = self.h = 0.0
        self.course = None  # [rad] the direction of motion when it is not the heading (on a path whose vertices give
        # the orientation), relative to the road; None: along the heading
        self.placed = False
        self.travelled = 0.0  # [m]
        self.still = 0.0  # [s] standing still for
        self.long = None  # running longitudinal action (a _Run)
        self.lat = None  # running lateral action
        self.path = None  # running trajectory (position from it)

    def box(self):
        """(rear, front, right, left) of the contour on the road."""
        e = self.ent
        c, sn = math.cos(self.h), math.sin(self.h)
        cs, ct = self.s + e.center_x * c - e.center_y * sn, self.t + e.center_x * sn + e.center_y * c
        hl = 0.5 * (abs(e.length * c) + abs(e.width * sn))
        hw = 0.5 * (abs(e.length * sn) + abs(e.width * c))
        return cs - hl, cs + hl, ct - hw, ct + hw


def overlap(a: Body, b: Body) -> bool:
    ar, af, aR, aL = a.box()
    br, bf, bR, bL = b.box()
    return ar < bf and br < af and aR < bL and bR < aL


def gap_along(a: Body, b: Body, freespace: bool) -> float:
    """Signed longitudinal distance from ``a`` to ``b`` (positive: ``b`` ahead), between the
    reference points or (freespace) between the contours (0 when they overlap lengthwise)."""
    if not freespace:
        return b.s - a.s
    ar, af, _, _ = a.box()
    br, bf, _, _ = b.box()
    if br >= af:
        return br - af
    if ar >= bf:
        return -(ar - bf)
    return 0.0


def gap_across(a: Body, b: Body, freespace: bool) -> float:
    if not freespace:
        return abs(b.t - a.t)
    _, _, aR, aL = a.box()
    _, _, bR, bL = b.box()
    return max(0.0, bR - aL, aR - bL)


class _Run:
    """A running action on one entity."""

    done = False

    def __init__(self, action: M.Action, element):
        self.action, self.element = action, element


class SpeedRun(_Run):
    def __init__(self, action, element, body: Body, t0: float, target: float, world):
        super().__init__(action, element)
        sa: M.SpeedAction = action.payload
        self.t0, self.v0, self.v1, self.shape = t0, body.v, target, sa.dynamics.shape
        self.ref = sa.relative_to if sa.continuous else None
        self.world = world
        dv = target - body.v
        dyn = sa.dynamics
        if dyn.shape == "step" or abs(dv) < 1e-12:
            self.T = 0.0
        elif dyn.dimension == "time":
            self.T = dyn.value
        elif dyn.dimension == "distance":
            self.T = 2.0 * dyn.value / (body.v + target) if body.v + target > 0 else 0.0
        elif dyn.value <= 0.0:
            world.note(f"{action.where}: action {action.name!r}: a rate of 0 never changes the speed (held)")
            self.T = math.inf
        else:
            self.T = SHAPE_RATE[dyn.shape] * abs(dv) / dyn.value

    def speed_and_distance(self, t: float, dt: float, body: Body):
        """Speed at ``t + dt`` and the distance covered over ``[t, t + dt]``."""
        if self.ref is not None and t + dt > self.t0 + self.T + 1e-9:
            return self._following(t, dt, body)
        if self.T == math.inf:
            return self.v0, self.v0 * dt
        if self.T <= 0.0:
            v1 = self._target(body)
            return v1, v1 * dt
        dv = self.v1 - self.v0

        def pos(tt):  # distance covered since t0 at time tt
            tau = (tt - self.t0) / self.T
            if tau >= 1.0:
                return self.v0 * self.T + dv * self.T * shape_integral(self.shape, 1.0) + self.v1 * (tt - self.t0 - self.T)
            return self.v0 * (tt - self.t0) + dv * self.T * shape_integral(self.shape, tau)

        t_end = t + dt
        v = self.v0 + dv * shape_value(self.shape, (t_end - self.t0) / self.T)
        d = pos(t_end) - pos(t)
        if self.ref is not None and t_end >= self.t0 + self.T:
            v = self._target(body)
        return v, d

    def _following(self, t: float, dt: float, body: Body):
        """Continuous, past its transition: the reference's speed (plus the delta, times the factor)
        and, as distance, its integral: the reference's own distance over the step (it has moved:
        :meth:`World.move` moves the followers last)."""
        sa, ref = self.action.payload, self.world.bodies[self.ref]
        te = max(t, self.t0 + self.T)  # where the following starts in this step
        d = 0.0
        if te > t:  # the transition's last part
            tau = (t - self.t0) / self.T
            d = self.v0 * (te - t) + (self.v1 - self.v0) * self.T * (
                shape_integral(self.shape, 1.0) - shape_integral(self.shape, tau))
        ref_d = (ref.travelled - self.world.travelled_at_start.get(self.ref, ref.travelled)) * (t + dt - te) / dt
        d += ref_d + sa.value * (t + dt - te) if sa.value_type == "delta" else sa.value * ref_d
        return self._target(body), max(d, 0.0)

    def _target(self, body):
        if self.ref is None:
            return self.v1
        sa = self.action.payload
        r = self.world.bodies[self.ref].v
        return max(0.0, r + sa.value if sa.value_type == "delta" else r * sa.value)

    def finished(self, t: float) -> bool:
        return self.ref is None and t >= self.t0 + self.T - 1e-9


class ProfileRun(_Run):
    """A SpeedProfileAction, followingMode position (decided, as esmini reads the standard):
    the vertices are the speed when the action starts, then each entry's speed (plus the
    reference's speed at the start, with ``entityRef``) at the previous vertex's time plus
    the entry's ``time``; the speed is linear in time between vertices (an entry with time 0
    changes it at once) and held after the last. An entry without a time is reached at the
    dynamic constraints' acceleration or deceleration; one that asks for more than those
    limits takes longer (its time extended to the limit's, noted). The position is the exact
    integral of that speed over each step."""

    ref = None  # not continuous: nothing to follow

    def __init__(self, action, element, body: Body, t0: float, world):
        super().__init__(action, element)
        sp: M.SpeedProfileAction = action.payload
        offset = 0.0 if sp.relative_to is None else world._ref(sp.relative_to, action.where).v
        T, V = [t0], [body.v]
        for tv, v in sp.entries:
            v = v + offset
            if v < 0:
                raise OpenScenarioError(f"action {action.name!r}: a profile speed of {v:g} m/s < 0 (no reversing "
                                        f"here)", action.where.file, action.where.line)
            dv = v - V[-1]
            limit = sp.max_acceleration if dv > 0 else sp.max_deceleration
            if tv is None:
                tv = abs(dv) / limit
            elif limit is not None and abs(dv) > limit * tv + 1e-12:
                world.note(f"{action.where}: action {action.name!r}: a profile entry asks for "
                           f"{abs(dv) / tv if tv > 0 else math.inf:g} m/s^2, beyond the dynamic constraints' "
                           f"{limit:g} m/s^2: reached later, at the limit")
                tv = abs(dv) / limit
            T.append(T[-1] + tv)
            V.append(v)
        self.T, self.V = T, V
        self.i = 0  # the segment [T[i], T[i + 1]] the last step ended in

    def _at(self, i: int, tt: float) -> float:
        """The speed on segment ``i`` at ``tt`` (its vertices' own values at its ends)."""
        Ta, Tb = self.T[i], self.T[i + 1]
        if tt <= Ta + 1e-9:
            return self.V[i]
        if tt >= Tb - 1e-9:
            return self.V[i + 1]
        return self.V[i] + (tt - Ta) / (Tb - Ta) * (self.V[i + 1] - self.V[i])

    def speed_and_distance(self, t: float, dt: float, body: Body):
        """Speed at ``t + dt`` (the speed reached: before a change at once there) and the
        distance covered over ``[t, t + dt]``."""
        T, V, n = self.T, self.V, len(self.T)
        te = t + dt
        i = self.i
        while i < n - 1 and T[i + 1] <= t + 1e-9:  # segments ended before this step (and changes at once)
            i += 1
        d, tt, v_end = 0.0, t, None
        while tt < te - 1e-12:
            if i >= n - 1:  # past the last vertex: its speed held
                d += V[-1] * (te - tt)
                v_end = V[-1]
                break
            Tb = T[i + 1]
            end = te if Tb >= te - 1e-9 else Tb
            va, vb = self._at(i, tt), self._at(i, end)
            d += 0.5 * (va + vb) * (end - tt)
            tt, v_end = end, vb
            if Tb <= te + 1e-9:
                i += 1
        self.i = i
        return (V[-1] if v_end is None else v_end), d

    def finished(self, t: float) -> bool:
        return t >= self.T[-1] - 1e-9


class DistanceRun(_Run):
    def __init__(self, action, element, world):
        super().__init__(action, element)
        self.world = world

    def place(self, body: Body) -> None:
        la: M.LongitudinalDistanceAction = self.action.payload
        ref = self.world.bodies[la.entity]
        lead_is_actor = la.displacement != "trailingReferencedEntity"
        if la.displacement == "any":
            lead_is_actor = body.s >= ref.s
        d = la.distance if la.distance is not None else la.time_gap * ref.v  # the follower's speed once placed
        e, r = body.ent, ref.ent
        if lead_is_actor:  # the actor ahead of its reference by d
            body.s = ref.s + (d + r.front - e.rear if la.freespace else d)
        else:
            body.s = ref.s - (d + e.front - r.rear if la.freespace else d)
        body.v, body.a = ref.v, ref.a
        if not la.continuous:
            self.done = True


class LateralRun(_Run):
    def __init__(self, action, element, body: Body, t0: float, y1: float, world):
        super().__init__(action, element)
        self.t0, self.y0, self.y1 = t0, body.t, y1
        p = action.payload
        dy = abs(y1 - body.t)
        if isinstance(p, M.LaneChangeAction):
            dyn = p.dynamics
            self.shape = dyn.shape
            if dyn.shape == "step" or dy < 1e-12:
                self.T = 0.0
            elif dyn.dimension == "time":
                self.T = dyn.value
            elif dyn.dimension == "distance":
                if body.v <= 0:
                    raise OpenScenarioError(f"action {action.name!r}: a lane change by distance needs the entity "
                                            f"to move (speed {body.v:g} m/s)", action.where.file, action.where.line)
                self.T = dyn.value / body.v
            elif dyn.value <= 0:
                raise OpenScenarioError(f"action {action.name!r}: a lane change at a rate of 0 never happens",
                                        action.where.file, action.where.line)
            else:
                self.T = SHAPE_RATE[dyn.shape] * dy / dyn.value
        else:
            self.shape = p.shape
            if p.shape == "step" or dy < 1e-12:
                self.T = 0.0
            elif p.shape == "sinusoidal":
                self.T = math.pi * math.sqrt(dy / (2.0 * p.max_lateral_acc))
            else:
                self.T = math.sqrt(6.0 * dy / p.max_lateral_acc)

    def lateral(self, t: float) -> float:
        if self.T <= 0.0:
            return self.y1
        return self.y0 + (self.y1 - self.y0) * shape_value(self.shape, (t - self.t0) / self.T)

    def finished(self, t: float) -> bool:
        return t >= self.t0 + self.T - 1e-9


class TrajectoryRun(_Run):
    """A polyline followed by position: timed (each vertex reached at its time: the speed is
    each segment's length over its duration) or at the entity's own speed along the path."""

    def __init__(self, action, element, body: Body, t0: float, points: list, world, headings: list | None = None):
        super().__init__(action, element)
        p: M.FollowTrajectoryAction = action.payload
        self.points = points  # [(s, t)] in road coordinates, resolved when the action starts
        # the vertices' orientations, when every vertex gives one: the entity's heading between them (interpolated
        # along each segment); the direction of motion is the segment's either way
        self.headings = headings
        self._advances = None  # advances(), once asked
        seg = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(points, points[1:])]
        self.cum = [0.0]
        for d in seg:
            self.cum.append(self.cum[-1] + d)
        self.timed = p.timing is not None
        if self.timed:
            rel, scale, offset = p.timing
            self.times = [(t0 if rel else 0.0) + scale * tv + offset for tv, _ in p.vertices]
        self.along = 0.0  # [m] distance along the path (untimed)

    def _heading(self, k: int, f: float, course):
        """The heading at the share ``f`` of segment ``k`` (``course``: its direction)."""
        if self.headings is None:
            return course
        return self.headings[k] + f * (self.headings[k + 1] - self.headings[k])

    def _at_length(self, d: float):
        """``(s, t, course, h)`` at the distance ``d`` along the path (``course`` the segment's
        direction, ``h`` the heading; None: unchanged); at a vertex (within 1e-9 m) they are
        the arriving segment's."""
        k = 0
        while k < len(self.cum) - 2 and d > self.cum[k + 1] + 1e-9:
            k += 1
        a, b = self.points[k], self.points[k + 1]
        L = self.cum[k + 1] - self.cum[k]
        f = 0.0 if L <= 0 else min(max((d - self.cum[k]) / L, 0.0), 1.0)
        course = math.atan2(b[1] - a[1], b[0] - a[0]) if L > 0 else None
        return a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), course, self._heading(k, f, course)

    def at(self, t: float):
        """``(s, y, v, course, h)`` at time ``t`` (timed): before the first vertex's time at the
        first vertex, after the last at the last (speed 0 while waiting, the last segment's after)."""
        ts, pts = self.times, self.points
        if t <= ts[0]:
            return pts[0][0], pts[0][1], 0.0, None, self._heading(0, 0.0, None)
        k = 0
        while k < len(ts) - 2 and t > ts[k + 1]:
            k += 1
        a, b = pts[k], pts[k + 1]
        f = min((t - ts[k]) / (ts[k + 1] - ts[k]), 1.0)
        L = math.hypot(b[0] - a[0], b[1] - a[1])
        course = math.atan2(b[1] - a[1], b[0] - a[0]) if L > 0 else None
        return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), L / (ts[k + 1] - ts[k]), course,
                self._heading(k, f, course))

    def advances(self) -> bool:
        """Whether the vertices' ``s`` never decreases (a path :meth:`lateral_at` can follow)."""
        if self._advances is None:
            self._advances = all(b[0] >= a[0] for a, b in zip(self.points, self.points[1:]))
        return self._advances

    def lateral_at(self, s: float) -> float:
        """The path's lateral position at ``s`` along the road, for a vehicle whose longitudinal
        motion is driven from outside (linear between vertices; the end vertices' beyond them)."""
        pts = self.points
        k = 0
        while k < len(pts) - 2 and s > pts[k + 1][0] + 1e-9:
            k += 1
        a, b = pts[k], pts[k + 1]
        if b[0] <= a[0] or s >= b[0] - 1e-9:
            return b[1] if s >= a[0] else a[1]
        return a[1] + max(s - a[0], 0.0) / (b[0] - a[0]) * (b[1] - a[1])

    def finished(self, t: float) -> bool:
        if self.timed:
            return t >= self.times[-1] - 1e-9
        return self.along >= self.cum[-1] - 1e-9


class Element:
    """A storyboard element's state (OpenSCENARIO's state machine)."""

    def __init__(self, kind: str, name: str, node=None, parent=None):
        self.kind, self.name, self.node, self.parent = kind, name, node, parent
        self.state = "standby"
        self.transitions: set = set()  # happened in the last update (seen by conditions next step)
        self.pending: set = set()
        self.count = 0  # executions started
        self.children: list = []
        self.runs: list = []  # actions: their per-actor runs

    def go(self, state: str, transition: str) -> None:
        self.state = state
        self.pending.add(transition)


class _CondState:
    """A condition's edge and delay: ``update(raw, t)`` is its value at ``t``."""

    def __init__(self, cond: M.Condition):
        self.cond, self.last, self.history, self.delayed = cond, None, deque(), False

    def update(self, raw: bool, t: float) -> bool:
        e = self.cond.edge
        if e == "none":
            val = raw
        elif self.last is None:  # no edge at the first evaluation
            val = False
        elif e == "rising":
            val = raw and not self.last
        elif e == "falling":
            val = self.last and not raw
        else:
            val = raw != self.last
        self.last = raw
        if self.cond.delay <= 0:
            return val
        self.history.append((t, val))
        while self.history and self.history[0][0] <= t - self.cond.delay + 1e-9:
            self.delayed = self.history.popleft()[1]  # the value delay seconds ago
        return self.delayed


class World:
    """The entities and the storyboard of one scenario being run: :meth:`start`, then per step
    :meth:`update` (triggers and actions at the step's start), the ego's decision by the caller,
    and :meth:`move`."""

    def __init__(self, sc: M.OpenScenario):
        self.sc = sc
        self.bodies = {n: Body(e) for n, e in sc.entities.items()}
        self.t, self.k = 0.0, 0
        self.notes: list[str] = []
        self.ignored: list[str] = []
        self.ego = sc.ego
        self.ego_active = not _activates(sc)
        self.driven: set = set()  # entities a human-like driver drives (run_file's drivers=): moved by the caller
        self.travelled_at_start: dict = {}  # name -> travelled at the start of the step being moved
        self.activated_at = 0.0 if self.ego_active else None
        self.ended = None  # why the storyboard ended
        self.elements: dict = {}  # (kind, name) -> Element (the first of that name: references are by name)
        self.conds: dict = {}  # id(Condition) -> _CondState
        self.values: dict = {}  # id(Condition) -> bool this step
        self.triggered_by: dict = {}  # id(Trigger) -> entities that made it true (selectTriggeringEntities)
        self.stories = [self._tree(st) for st in sc.stories]

    # --- building
    def _el(self, kind, name, node, parent):
        el = Element(kind, name, node, parent)
        self.elements.setdefault((kind, name), el)
        if parent is not None:
            parent.children.append(el)
        return el

    def _tree(self, st: M.Story) -> Element:
        s = self._el("story", st.name, st, None)
        for act in st.acts:
            a = self._el("act", act.name, act, s)
            for g in act.groups:
                ge = self._el("maneuverGroup", g.name, g, a)
                for man in g.maneuvers:
                    me = self._el("maneuver", man.name, man, ge)
                    for ev in man.events:
                        ee = self._el("event", ev.name, ev, me)
                        for ac in ev.actions:
                            self._el("action", ac.name, ac, ee)
        return s

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    # --- positions
    def lane_of(self, body: Body) -> M.Lane | None:
        lid = self.sc.road.lane_at(body.t)
        return None if lid is None else self.sc.road.lanes[lid]

    def _driving_lanes(self):
        return sorted((ln for ln in self.sc.road.lanes.values() if ln.driving), key=lambda ln: ln.centre)

    def shifted_lane(self, body: Body, dlane: int, where: M.Where) -> M.Lane:
        lanes = self._driving_lanes()
        here = self.lane_of(body)
        if here is None or here not in lanes:
            raise OpenScenarioError(f"entity {body.ent.name!r} is on no driving lane (t = {body.t:.2f} m): a relative "
                                    f"lane cannot be counted from it", where.file, where.line)
        k = lanes.index(here) + dlane
        if not 0 <= k < len(lanes):
            raise OpenScenarioError(f"{dlane:+d} lanes from {body.ent.name!r}'s lane {here.id} is off the road's "
                                    f"driving lanes {[ln.id for ln in lanes]}", where.file, where.line)
        return lanes[k]

    def _lane(self, lane_id: int, where: M.Where) -> M.Lane:
        if lane_id not in self.sc.road.lanes:
            raise OpenScenarioError(f"lane {lane_id} is not a lane of the road (lanes {sorted(self.sc.road.lanes)})",
                                    where.file, where.line)
        return self.sc.road.lanes[lane_id]

    def _ref(self, name: str, where: M.Where) -> Body:
        if name not in self.bodies:
            raise OpenScenarioError(f"entity {name!r} is not declared (entities: {list(self.bodies)})",
                                    where.file, where.line)
        b = self.bodies[name]
        if not b.placed:
            raise OpenScenarioError(f"entity {name!r} is used as a reference before it has a position",
                                    where.file, where.line)
        return b

    def place(self, p: M.Position, ref_body: Body | None = None):
        """``(s, t, h)`` of a position now (``h`` None: keep the entity's heading)."""
        v, w, road = p.values, p.where, self.sc.road
        h = v.get("h")
        if p.kind == "LanePosition":
            ln = self._lane(v["lane"], w)
            s, t = v["s"], ln.centre + v["offset"]
        elif p.kind == "RelativeLanePosition":
            ref = self._ref(v["entity"], w)
            ln = self.shifted_lane(ref, v["dlane"], w)
            s, t = ref.s + v["ds"], ln.centre + v["offset"]
            if h is not None and v.get("h_relative", True):
                h = ref.h + h
        elif p.kind == "RoadPosition":
            s, t = v["s"], v["t"]
        elif p.kind == "RelativeRoadPosition":
            ref = self._ref(v["entity"], w)
            s, t = ref.s + v["ds"], ref.t + v["dt"]
        elif p.kind == "WorldPosition":
            if road.curved:
                raise OpenScenarioError("a WorldPosition on a curved road cannot be projected onto s here",
                                        w.file, w.line)
            c, sn = math.cos(road.heading), math.sin(road.heading)
            dx, dy = v["x"] - road.x0, v["y"] - road.y0
            s, t = c * dx + sn * dy, -sn * dx + c * dy
            if h is not None and not v.get("h_relative", False):
                h = h - road.heading
        elif p.kind == "RelativeWorldPosition":
            ref = self._ref(v["entity"], w)
            c, sn = math.cos(road.heading), math.sin(road.heading)
            s, t = ref.s + c * v["dx"] + sn * v["dy"], ref.t - sn * v["dx"] + c * v["dy"]
        else:  # RelativeObjectPosition: in the reference's own frame
            ref = self._ref(v["entity"], w)
            c, sn = math.cos(ref.h), math.sin(ref.h)
            s, t = ref.s + c * v["dx"] - sn * v["dy"], ref.t + sn * v["dx"] + c * v["dy"]
        return s, t, h

    # --- actions
    def start(self) -> None:
        """Apply the Init actions at t = 0 and start the stories. Init's actions all happen at
        t = 0; decided: the positions are applied first (in file order: a relative position may
        name an entity placed before it), then the trajectories (one places an entity that has
        no position at its first vertex, as esmini does), then the others in file order, so a
        speed written before its entity's position (as esmini's examples have it) is read."""
        order = {M.TeleportAction: 0, M.FollowTrajectoryAction: 1}
        for ent, action in sorted(self.sc.init, key=lambda ea: order.get(type(ea[1].payload), 2)):
            self._apply(action, None, [ent] if ent is not None else [])
        for b in self.bodies.values():
            if not b.placed:
                raise OpenScenarioError(f"entity {b.ent.name!r} is never given a position in Init",
                                        b.ent.where.file, b.ent.where.line)
        for s in self.stories:
            s.go("running", "startTransition")

    def _apply(self, action: M.Action, element: Element | None, actors: list) -> None:
        """Start ``action`` on ``actors`` now."""
        p = action.payload
        runs = []
        for name in actors:
            if name not in self.bodies:
                raise OpenScenarioError(f"action {action.name!r} names entity {name!r}, which is not declared",
                                        action.where.file, action.where.line)
            body = self.bodies[name]
            is_ego = name == self.ego
            if isinstance(p, M.ActivateController):
                if is_ego and p.longitudinal and not self.ego_active:
                    self.ego_active, self.activated_at = True, self.t
                    self._replace(body, "long", None)  # the controller takes over: the scripted motion stops
                elif not is_ego:
                    self.note(f"the controller of {name!r} is not run: the storyboard drives it")
                continue
            if isinstance(p, M.OutOfScope):
                continue
            # decided: a vehicle driven longitudinally from outside (the ego under test, a human-like driver)
            # keeps its scripted lateral motion -- lane changes, lane offsets and untimed paths, as its lateral
            # position over its position along the road -- as the environments script the ego's lane change
            timed = isinstance(p, M.FollowTrajectoryAction) and p.timing is not None
            lengthwise = action.domain in ("longitudinal", "position") or timed  # Init's actions: the initial state
            if is_ego and self.ego_active and element is not None and lengthwise:
                self.ignored.append(f"{action.where}: {type(p).__name__} {action.name!r} on the ego at "
                                    f"t = {self.t:.2f} s (the controller under test drives it)")
                continue
            if name in self.driven and (action.domain == "longitudinal" or timed):
                self.ignored.append(f"{action.where}: {type(p).__name__} {action.name!r} on {name!r} at "
                                    f"t = {self.t:.2f} s (a human-like driver drives it)")
                continue
            if isinstance(p, M.TeleportAction):
                s, t, h = self.place(p.position)
                body.s, body.t, body.placed = s, t, True
                if h is not None:
                    body.h = h
                continue
            if not body.placed and element is None and isinstance(p, M.FollowTrajectoryAction) and p.vertices:
                body.s, body.t, _h = self.place(p.vertices[0][1])  # Init: the trajectory's start is the position
                body.placed = True
            if not body.placed:
                raise OpenScenarioError(f"{type(p).__name__} {action.name!r} on {name!r} before the entity has a "
                                        f"position (Init gives none: a TeleportAction or a trajectory places it)",
                                        action.where.file, action.where.line)
            if isinstance(p, M.FollowTrajectoryAction):
                pts, hs = [], []
                for _tv, pos in p.vertices:
                    s, y, h = self.place(pos)
                    pts.append((s, y))
                    hs.append(h)
                run = TrajectoryRun(action, element, body, self.t, pts, self,
                                    None if any(h is None for h in hs) else hs)
                self._replace(body, "path", run)
                self._replace(body, "lat", None)
                if run.timed:
                    self._replace(body, "long", None)
                runs.append(run)
                continue
            if isinstance(p, M.SpeedAction):
                target = p.value
                if p.relative_to is not None:
                    r = self._ref(p.relative_to, action.where).v
                    target = r + p.value if p.value_type == "delta" else r * p.value
                if target < 0:
                    raise OpenScenarioError(f"action {action.name!r}: target speed {target:g} m/s < 0 (no "
                                            f"reversing here)", action.where.file, action.where.line)
                run = SpeedRun(action, element, body, self.t, target, self)
                self._replace(body, "long", run)
                if run.T <= 0.0:
                    body.v = run._target(body)
                    if run.finished(self.t):
                        run.done = True
                runs.append(run)
            elif isinstance(p, M.SpeedProfileAction):
                run = ProfileRun(action, element, body, self.t, self)
                self._replace(body, "long", run)
                k = 0
                while k < len(run.T) - 1 and run.T[k + 1] <= self.t + 1e-9:  # changes at once: the speed now
                    k += 1
                body.v = run.V[k]
                if run.finished(self.t):
                    run.done = True
                runs.append(run)
            elif isinstance(p, M.LongitudinalDistanceAction):
                self._ref(p.entity, action.where)
                run = DistanceRun(action, element, self)
                self._replace(body, "long", run)
                run.place(body)
                runs.append(run)
            elif isinstance(p, (M.LaneChangeAction, M.LaneOffsetAction)):
                if isinstance(p, M.LaneChangeAction):
                    if p.lane is not None:
                        ln = self._lane(p.lane, action.where)
                    else:
                        ln = self.shifted_lane(self._ref(p.relative_to, action.where), p.relative_lanes,
                                               action.where)
                    y1 = ln.centre + p.target_offset
                else:
                    here = self.lane_of(body)
                    if here is None:
                        raise OpenScenarioError(f"action {action.name!r}: {name!r} is on no lane for a lane "
                                                f"offset", action.where.file, action.where.line)
                    if p.relative_to is not None:  # the reference's offset in its lane, plus the value
                        ref = self._ref(p.relative_to, action.where)
                        rl = self.lane_of(ref)
                        y1 = here.centre + (ref.t - rl.centre if rl is not None else 0.0) + p.offset
                    else:
                        y1 = here.centre + p.offset
                run = LateralRun(action, element, body, self.t, y1, self)
                self._replace(body, "lat", run)
                if run.T <= 0.0:
                    body.t, run.done = y1, True
                runs.append(run)
        if element is not None:
            element.runs = runs

    def _replace(self, body: Body, slot: str, run: _Run | None) -> None:
        """Start ``run`` in ``slot`` (None: empty it); the running action there is stopped."""
        old = getattr(body, slot)
        if old is not None and not old.done:
            old.done, old.stopped = True, True
        setattr(body, slot, run)

    # --- conditions
    def _value(self, c: M.Condition) -> bool:
        x = c.test
        if isinstance(x, M.SimulationTime):  # t rounded: k dt is 0.6000000000000001 at k = 3, dt = 0.2
            return compare(x.rule, round(self.t, 9), x.value)
        if isinstance(x, M.ParameterValue):
            return x.holds
        if isinstance(x, M.StoryboardState):
            el = self.elements.get((x.element_type, x.ref))
            if el is None:
                raise OpenScenarioError(f"condition {c.name!r} refers to {x.element_type} {x.ref!r}, which the "
                                        f"storyboard does not have", c.where.file, c.where.line)
            if x.state.endswith("State"):
                return el.state == x.state[:-5]
            return x.state in el.transitions
        ok = [self._entity_value(x, self.bodies[n] if n in self.bodies else self._ref(n, c.where), c)
              for n in x.triggering]
        if x.rule == "any":
            self._last_triggering = [n for n, o in zip(x.triggering, ok) if o]
        return any(ok) if x.rule == "any" else all(ok)

    def _entity_value(self, x: M.EntityCondition, b: Body, c: M.Condition) -> bool:
        v = x.values
        k = x.kind
        if k == "SpeedCondition":
            return compare(v["rule"], b.v, v["value"])
        if k == "AccelerationCondition":
            return compare(v["rule"], b.a, v["value"])
        if k == "StandStillCondition":
            return b.still >= v["duration"] - 1e-9
        if k == "TraveledDistanceCondition":
            return b.travelled >= v["value"] - 1e-9
        if k in ("ReachPositionCondition", "DistanceCondition"):
            s, t, _ = self.place(v["position"])
            if k == "ReachPositionCondition":
                return math.hypot(s - b.s, t - b.t) <= v["tolerance"]
            if v.get("freespace"):
                r, f, R, L = b.box()
                ds, dtt = max(0.0, r - s, s - f), max(0.0, R - t, t - L)
            else:
                ds, dtt = s - b.s, t - b.t
            d = {"longitudinal": abs(ds), "lateral": abs(dtt)}.get(v["distance_type"], math.hypot(ds, dtt))
            return compare(v["rule"], d, v["value"])
        if k == "TimeToCollisionCondition" and "position" in v:
            s, _, _ = self.place(v["position"])
            d = s - (b.s + (b.ent.front if v["freespace"] else 0.0))
            ttc = d / b.v if d >= 0 and b.v > 0 else math.inf
            return compare(v["rule"], ttc, v["value"])
        o = self._ref(v["entity"], c.where)
        if k == "CollisionCondition":
            return overlap(b, o)
        if k == "RelativeSpeedCondition":
            return compare(v["rule"], b.v - o.v, v["value"])
        fs = v["freespace"]
        if k == "RelativeDistanceCondition":
            if v["distance_type"] == "longitudinal":
                d = abs(gap_along(b, o, fs))
            elif v["distance_type"] == "lateral":
                d = gap_across(b, o, fs)
            else:
                d = math.hypot(gap_along(b, o, fs), gap_across(b, o, fs))
            return compare(v["rule"], d, v["value"])
        if k == "TimeHeadwayCondition":
            d = gap_along(b, o, fs)
            thw = d / b.v if d >= 0 and b.v > 0 else math.inf
            return compare(v["rule"], thw, v["value"])
        # TimeToCollisionCondition to an entity: along the road, whichever is ahead
        d = gap_along(b, o, fs)
        closing = (b.v - o.v) if d >= 0 else (o.v - b.v)
        ttc = abs(d) / closing if closing > 0 else math.inf
        return compare(v["rule"], ttc, v["value"])

    def _trigger(self, trig: M.Trigger | None) -> bool:
        """Whether a start trigger fires now. Decided: a missing or an empty one (``<StartTrigger/>``,
        as esmini's examples write it) fires at once; stop triggers are asked only when they have
        a condition group (an empty stop trigger never fires)."""
        if trig is None or not trig.groups:
            return True
        out = False
        who: list = []
        for g in trig.groups:
            vals = [self.values[id(c)] for c in g]
            if all(vals):
                out = True
                for c in g:
                    who += self._who.get(id(c), [])
        self.triggered_by[id(trig)] = who
        return out

    def _evaluate_all(self) -> None:
        self._who = {}
        for trig in self._triggers():
            for g in trig.groups:
                for c in g:
                    if id(c) in self.values and id(c) in self._seen:
                        continue
                    st = self.conds.setdefault(id(c), _CondState(c))
                    self._last_triggering = []
                    raw = bool(self._value(c))
                    self._who[id(c)] = list(self._last_triggering)
                    self.values[id(c)] = st.update(raw, self.t)
                    self._seen.add(id(c))

    def _triggers(self):
        if self.sc.stop is not None:
            yield self.sc.stop
        for st in self.sc.stories:
            for act in st.acts:
                for trig in (act.start, act.stop):
                    if trig is not None:
                        yield trig
                for g in act.groups:
                    for man in g.maneuvers:
                        for ev in man.events:
                            if ev.start is not None:
                                yield ev.start

    # --- the storyboard's step
    def update(self) -> None:
        """Triggers and actions at time :attr:`t` (the step's start)."""
        for el in self.elements_all():
            el.transitions, el.pending = el.pending, set()
        self.values, self._seen = {}, set()
        self._evaluate_all()
        if self.ended is None and self.sc.stop is not None and self.sc.stop.groups and self._trigger(self.sc.stop):
            self.ended = "stop trigger"
            return
        for story in self.stories:
            if story.state != "running":
                continue
            for act in story.children:
                self._act(act)

    def elements_all(self):
        for s in self.stories:
            yield from _walk(s)

    def _act(self, act: Element) -> None:
        node: M.Act = act.node
        if act.state == "standby":
            if self._trigger(node.start):
                act.go("running", "startTransition")
                for g in act.children:
                    self._start_group(g)
            else:
                return
        if act.state != "running":
            return
        if node.stop is not None and node.stop.groups and self._trigger(node.stop):
            self._stop(act)
            return
        for g in act.children:
            if g.state != "running":
                continue
            for man in g.children:
                if man.state != "running":
                    continue
                for ev in man.children:
                    if ev.state == "standby" and self._trigger(ev.node.start):
                        self._start_event(ev, man, g)

    def _start_group(self, g: Element) -> None:
        g.go("running", "startTransition")
        g.count += 1
        for man in g.children:
            man.go("running", "startTransition")
            for ev in man.children:
                ev.state, ev.count = "standby", 0
                for a in ev.children:
                    a.state = "standby"

    def _start_event(self, ev: Element, man: Element, g: Element) -> None:
        prio = ev.node.priority
        others = [e for e in man.children if e is not ev and e.state == "running"]
        if prio == "skip" and others:
            ev.pending.add("skipTransition")
            return
        if prio == "override":
            for e in others:
                self._stop(e)
        ev.go("running", "startTransition")
        ev.count += 1
        gnode: M.ManeuverGroup = g.node
        actors = list(gnode.actors)
        if gnode.select_triggering:
            actors += [n for n in self.triggered_by.get(id(ev.node.start), []) if n not in actors]
        for a in ev.children:
            if not actors and a.node.domain not in ("none",):
                w = a.node.where
                raise OpenScenarioError(f"action {a.node.name!r} of event {ev.name!r} acts on no entity (its "
                                        f"maneuver group names no actor)", w.file, w.line)
            a.go("running", "startTransition")
            self._apply(a.node, a, actors)
            self._check_action(a)

    def _stop(self, el: Element) -> None:
        for c in _walk(el):
            if c.state == "running" or (c is el):
                for r in c.runs:
                    if not r.done:
                        r.done, r.stopped = True, True
                        for b in self.bodies.values():
                            if b.long is r:
                                b.long = None
                            if b.lat is r:
                                b.lat = None
                            if b.path is r:
                                b.path = None
                if c.state != "complete":
                    c.go("complete", "stopTransition")

    def _check_action(self, a: Element) -> None:
        if a.state == "running" and all(r.done for r in a.runs):
            a.go("complete", "stopTransition" if any(getattr(r, "stopped", False) for r in a.runs) else "endTransition")

    def _complete(self) -> None:
        """Completion after a move: actions, events, maneuvers, groups, acts, stories."""
        for story in self.stories:
            for act in story.children:
                if act.state != "running":
                    continue
                for g in act.children:
                    if g.state != "running":
                        continue
                    for man in g.children:
                        if man.state != "running":
                            continue
                        for ev in man.children:
                            if ev.state != "running":
                                continue
                            for a in ev.children:
                                self._check_action(a)
                            if all(a.state == "complete" for a in ev.children):
                                ev.go("complete", "endTransition")
                                if ev.count < ev.node.max_count:
                                    ev.state = "standby"
                        if all(ev.state == "complete" for ev in man.children):
                            man.go("complete", "endTransition")
                    if all(m.state == "complete" for m in g.children):
                        g.go("complete", "endTransition")
                        if g.count < g.node.max_count:
                            self._start_group(g)
                if all(g.state == "complete" for g in act.children):
                    act.go("complete", "endTransition")
            if story.state == "running" and all(a.state == "complete" for a in story.children):
                story.go("complete", "endTransition")

    # --- motion
    def move(self, dt: float, ego_state=None, driven: dict | None = None) -> None:
        """Move every entity over ``[t, t + dt]``; the ego from ``ego_state`` ``(s, v, a)`` at
        ``t + dt`` when its controller is active, and each of :attr:`driven` from ``driven[name]``
        (the same triple: their longitudinal motion; lateral actions still move them)."""
        t1 = (self.k + 1) * dt
        self.travelled_at_start = {n: b.travelled for n, b in self.bodies.items()}
        follows = lambda nb: isinstance(nb[1].long, SpeedRun) and nb[1].long.ref is not None  # noqa: E731
        for name, b in sorted(self.bodies.items(), key=follows):  # continuous followers after the others
            v0 = b.v
            if (name == self.ego and self.ego_active) or name in self.driven:
                s1, v1, a = ego_state if name == self.ego else driven[name]
                ds = s1 - b.s
                b.s, b.v, b.a = s1, v1, a
                path = b.path
                if path is not None and path.timed:  # started before the controller took over: it ends
                    path.done, path.stopped, b.path = True, True, None
                elif path is not None and not path.advances():
                    path.done, path.stopped, b.path = True, True, None
                    self.ignored.append(f"{path.action.where}: FollowTrajectoryAction {path.action.name!r} on "
                                        f"{name!r} at t = {self.t:.2f} s (its controller drives it along the road, "
                                        f"and the path turns back along it)")
                elif path is not None:
                    b.t = path.lateral_at(b.s)
                    if b.s >= path.points[-1][0] - 1e-9:
                        path.done, b.path = True, None
            else:
                run, path = b.long, b.path
                if isinstance(run, (SpeedRun, ProfileRun)) and not run.done or (
                        isinstance(run, SpeedRun) and run.ref is not None):
                    v1, ds = run.speed_and_distance(self.t, dt, b)
                else:
                    v1, ds = b.v, b.v * dt
                if path is not None:
                    if path.timed:  # the position from the trajectory
                        s1, y1, v1, course, h = path.at(t1)
                        ds = math.hypot(s1 - b.s, y1 - b.t)
                        b.s, b.t = s1, y1
                    else:  # along the trajectory at the entity's own speed
                        path.along += ds
                        b.s, b.t, course, h = path._at_length(path.along)
                    b.h = b.h if h is None else h
                    if course is not None:
                        b.course = None if path.headings is None else course
                else:
                    b.s += ds * math.cos(b.h)
                    b.t += ds * math.sin(b.h)
                b.a = (v1 - v0) / dt
                b.v = v1
                if isinstance(run, (SpeedRun, ProfileRun)) and not run.done and run.finished(t1):
                    run.done = True
                if path is not None and path.finished(t1):
                    path.done, b.path, b.course = True, None, None
            if b.lat is not None:
                b.t = b.lat.lateral(t1)
                if b.lat.finished(t1):
                    b.lat.done = True
                    b.lat = None
            b.travelled += abs(ds)
            b.still = b.still + dt if b.v <= 1e-6 and v0 <= 1e-6 else 0.0  # at rest over the whole step
        self.k += 1
        self.t = self.k * dt  # no drift: t is always a whole number of steps
        for b in self.bodies.values():  # the distance actions after the others have moved
            if isinstance(b.long, DistanceRun) and not b.long.done:
                b.long.place(b)
        self._complete()

    def all_complete(self) -> bool:
        return all(s.state == "complete" for s in self.stories)


def _walk(el: Element):
    yield el
    for c in el.children:
        yield from _walk(c)


def _activates(sc: M.OpenScenario) -> bool:
    """Whether the file activates the ego's longitudinal controller anywhere (else the
    controller under test drives from the start)."""
    for ent, a in sc.init:
        if ent == sc.ego and isinstance(a.payload, M.ActivateController) and a.payload.longitudinal:
            return True
    for st in sc.stories:
        for act in st.acts:
            for g in act.groups:
                if sc.ego not in g.actors and not g.select_triggering:
                    continue
                for man in g.maneuvers:
                    for ev in man.events:
                        for a in ev.actions:
                            if isinstance(a.payload, M.ActivateController) and a.payload.longitudinal:
                                return True
    return False


def lead_of(world: World, sensor_range: float, who: str | None = None):
    """The ego's target now, by the environments' rule (:mod:`acc_gym.simulation.single_lane`):
    the nearest entity whose front is ahead of the ego's front and whose contour overlaps the
    ego's lane corridor (one lane width centred on the ego), within ``sensor_range``:
    ``(name, gap, v, a)`` or None; ``gap`` from the ego's front bumper to the target's rear
    [m] (negative for one whose rear is not yet ahead of the ego's front: a collision, as the
    environments count it) and ``v``, ``a`` its speed and acceleration along the road.
    ``who``: another entity's target by the same rule (default the ego's)."""
    who = world.ego if who is None else who
    ego = world.bodies[who]
    lane = world.lane_of(ego)
    width = lane.width if lane is not None else 3.5
    _er, ef, _eR, _eL = ego.box()
    best = None
    for name, b in world.bodies.items():
        if name == who:
            continue
        r, f, R, L = b.box()
        if not (R < ego.t + 0.5 * width and L > ego.t - 0.5 * width) or f <= ef:
            continue
        gap = r - ef
        if gap > sensor_range:
            continue
        if best is None or gap < best[1]:
            c = math.cos(b.h if b.course is None else b.course)  # the speed along the road
            best = (name, gap, b.v * c, b.a * c)
    return best


def passed_through(before: tuple, after: tuple, ego_before: tuple, ego_after: tuple) -> bool:
    """Whether an entity with contours ``before`` and ``after`` (``Body.box()``) was entirely
    ahead of the ego and is entirely behind it one step later while their contours overlap
    laterally: a collision that happened between two steps."""
    ahead = before[0] >= ego_before[1]
    behind = after[1] <= ego_after[0]
    lateral = after[2] < ego_after[3] and ego_after[2] < after[3]
    return ahead and behind and lateral
