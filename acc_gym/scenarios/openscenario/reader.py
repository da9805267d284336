"""Read the longitudinal content of an ASAM OpenSCENARIO XML file (1.0-1.3).

:func:`read` returns an :class:`~acc_gym.scenarios.openscenario.model.OpenScenario`: its
parameters (declarations, ``$name`` and ``${...}``, constraints checked:
:mod:`~acc_gym.scenarios.openscenario.expressions`), entities with their catalogs'
dimensions (catalogs by directory: vehicles, pedestrians, misc objects, controllers), the
Init actions, the storyboard (stories, acts, maneuver groups, maneuvers, events with their
priorities, actions, start and stop triggers) and the road (a straight OpenDRIVE road's
lanes).

What is read (decided here; ``docs/openscenario.md`` has the table):

* actions: SpeedAction (step, linear, cubic, sinusoidal dynamics by time, distance or rate;
  absolute and relative targets, continuous or not), SpeedProfileAction (followingMode
  position), LongitudinalDistanceAction without
  dynamic constraints, LaneChangeAction (absolute or relative target lane, target lane
  offset), LaneOffsetAction, TeleportAction, ActivateControllerAction;
* conditions: SimulationTime, StoryboardElementState, Parameter (the parameters do not
  change here, so it is decided when read), and by entity RelativeDistance, TimeHeadway,
  TimeToCollision, Speed, RelativeSpeed, ReachPosition, TraveledDistance, StandStill,
  Acceleration, Distance, Collision; condition delays and edges; condition groups;
* positions: lane, relative lane, road, relative road, world, relative world and relative
  object positions, with an optional orientation's heading.

Left out and listed in :attr:`OpenScenario.out_of_scope` (they do not change the
longitudinal motion): lights and appearance, weather and environment, visibility, the
road's curvature and elevation (a curved road is projected onto its ``s`` coordinate),
controllers assigned or overridden (the storyboard drives every entity but the ego).
Any other element that would change the motion -- a trajectory, a route, a synchronise
action, a user-defined action or condition, a variable or parameter changed while running
-- is an :class:`~acc_gym.scenarios.openscenario._xml.OpenScenarioError` naming the
element, the file and the line: nothing that changes the motion is dropped silently.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from acc_gym.scenarios.openscenario import model as M
from acc_gym.scenarios.openscenario._xml import Node, OpenScenarioError, parse
from acc_gym.scenarios.openscenario.expressions import Scope, compare, convert, declare, resolve

DEFAULT_LANE_WIDTH = 3.5  # [m] lanes of a file without a readable OpenDRIVE road
SHAPES = ("step", "linear", "cubic", "sinusoidal")
DIMENSIONS = ("time", "distance", "rate")
PRIORITIES = {"override": "override", "overwrite": "override", "skip": "skip", "parallel": "parallel"}
EDGES = ("none", "rising", "falling", "risingOrFalling")
STATES = ("startTransition", "endTransition", "stopTransition", "skipTransition", "completeState",
          "runningState", "standbyState")
ELEMENT_TYPES = ("story", "act", "maneuverGroup", "maneuver", "event", "action")
ENTITY_CONDITIONS = ("RelativeDistanceCondition", "TimeHeadwayCondition", "TimeToCollisionCondition",
                     "SpeedCondition", "RelativeSpeedCondition", "ReachPositionCondition",
                     "TraveledDistanceCondition", "StandStillCondition", "AccelerationCondition",
                     "DistanceCondition", "CollisionCondition")
# elements that change nothing longitudinal: left out, listed in the result
OUT_OF_SCOPE_ACTIONS = {"VisibilityAction": "visibility", "AppearanceAction": "lights and appearance",
                        "LightStateAction": "lights", "AnimationAction": "animation",
                        "EnvironmentAction": "weather and environment", "InfrastructureAction": "traffic signals",
                        "AssignControllerAction": "assigned controllers (the storyboard drives the others)",
                        "OverrideControllerValueAction": "controller overrides (pedals, gear, steering)"}
POSITIONS = ("LanePosition", "RelativeLanePosition", "RoadPosition", "RelativeRoadPosition", "WorldPosition",
             "RelativeWorldPosition", "RelativeObjectPosition")


class _Reader:
    def __init__(self, path: Path, parameters: dict | None):
        self.path = path
        self.root = parse(path)
        if self.root.tag != "OpenSCENARIO":
            raise self.root.error(f"the root element is <{self.root.tag}>, not <OpenSCENARIO>")
        header = self.root.find("FileHeader")
        if header is None:
            raise self.root.error("no <FileHeader>")
        try:
            self.version = (int(header.attrib.get("revMajor", "1")), int(header.attrib.get("revMinor", "0")))
        except ValueError:
            raise header.error(f"revMajor/revMinor must be integers, got {header.attrib!r}") from None
        if self.version[0] != 1 or not 0 <= self.version[1] <= 3:
            raise header.error(f"OpenSCENARIO {self.version[0]}.{self.version[1]} is not read here (1.0-1.3 are)")
        self.description = header.attrib.get("description", "")
        if self.root.find("ParameterValueDistribution") is not None:
            raise self.root.error("this is a variation file (ParameterValueDistribution), not a scenario: "
                                  "run the scenario it names")
        self.scope = declare(self.root.find("ParameterDeclarations"), Scope(), parameters)
        self.out: list[str] = []
        self.catalogs: dict = {}  # catalog name -> {entry name: (Node, directory)}
        self._catalog_dirs()

    # --- attribute access
    def get(self, node: Node, name: str, scope: Scope, ptype: str = "double", default=...):
        if name not in node.attrib:
            if default is ...:
                raise node.error(f"<{node.tag}> needs the attribute {name!r}")
            return default
        raw = resolve(node.attrib[name], scope, node)
        return convert(raw, ptype, f"<{node.tag}> {name}", node)

    def where(self, node: Node) -> M.Where:
        return M.Where(node.file, node.line)

    def note(self, what: str) -> None:
        if what not in self.out:
            self.out.append(what)

    # --- catalogs
    def _catalog_dirs(self) -> None:
        loc = self.root.find("CatalogLocations")
        if loc is None:
            return
        for c in loc.children:
            d = c.find("Directory")
            if d is None:
                raise c.error(f"<{c.tag}> needs a <Directory>")
            rel = str(self.get(d, "path", self.scope, "string"))
            folder = (self.path.parent / rel).resolve()
            if not folder.is_dir():
                continue  # a catalog folder the file names but does not ship: an error only if an entry is used
            for f in sorted(folder.glob("*.xosc")):
                root = parse(f)
                cat = root.find("Catalog")
                if cat is None:
                    continue
                name = cat.attrib.get("name", f.stem)
                entries = self.catalogs.setdefault(name, {})
                for e in cat.children:
                    if "name" in e.attrib:
                        entries[e.attrib["name"]] = e

    def catalog_entry(self, ref: Node, scope: Scope):
        cat = str(self.get(ref, "catalogName", scope, "string"))
        entry = str(self.get(ref, "entryName", scope, "string"))
        if cat not in self.catalogs:
            raise ref.error(f"catalog {cat!r} not found in the CatalogLocations' directories "
                            f"(found: {sorted(self.catalogs) or 'none'})")
        if entry not in self.catalogs[cat]:
            raise ref.error(f"catalog {cat!r} has no entry {entry!r} (it has {sorted(self.catalogs[cat])})")
        node = self.catalogs[cat][entry]
        assigned = {}
        pa = ref.find("ParameterAssignments")
        if pa is not None:
            for a in pa.findall("ParameterAssignment"):
                ref_name = str(a.attrib.get("parameterRef", "")).lstrip("$")
                assigned[ref_name] = resolve(a.attrib.get("value", ""), scope, a)
        try:
            escope = declare(node.find("ParameterDeclarations"), self.scope, assigned)
        except OpenScenarioError as exc:
            raise ref.error(f"catalog entry {cat}/{entry}: {exc}") from None
        return node, escope

    # --- entities
    def entities(self) -> dict:
        ents = self.root.find("Entities")
        if ents is None:
            raise self.root.error("no <Entities>")
        out = {}
        for so in ents.children:
            if so.tag == "EntitySelection":
                self.note("entity selections")
                continue
            if so.tag != "ScenarioObject":
                raise so.error(f"<{so.tag}> in <Entities> is not read here")
            name = str(self.get(so, "name", self.scope, "string"))
            obj, scope = None, self.scope
            for c in so.children:
                if c.tag == "CatalogReference":
                    obj, scope = self.catalog_entry(c, self.scope)
                elif c.tag in ("Vehicle", "Pedestrian", "MiscObject"):
                    obj = c
                elif c.tag == "ExternalObjectReference":
                    raise c.error("external object references are not read here")
            if obj is None:
                raise so.error(f"entity {name!r} has no Vehicle, Pedestrian, MiscObject or catalog reference")
            out[name] = self._entity(name, obj, scope, so)
        if not out:
            raise ents.error("the file declares no entity")
        return out

    def _entity(self, name: str, obj: Node, scope: Scope, so: Node) -> M.Entity:
        kinds = {"Vehicle": ("vehicle", "vehicleCategory"), "Pedestrian": ("pedestrian", "pedestrianCategory"),
                 "MiscObject": ("misc", "miscObjectCategory")}
        if obj.tag not in kinds:
            raise obj.error(f"entity {name!r}: a catalog entry <{obj.tag}> is not a Vehicle, Pedestrian or MiscObject")
        kind, cat_attr = kinds[obj.tag]
        category = str(self.get(obj, cat_attr, scope, "string", default=kind))
        bb = obj.find("BoundingBox")
        if bb is None:
            raise obj.error(f"entity {name!r} has no BoundingBox")
        centre, dims = bb.find("Center"), bb.find("Dimensions")
        if centre is None or dims is None:
            raise bb.error(f"entity {name!r}: a BoundingBox needs Center and Dimensions")
        length = self.get(dims, "length", scope)
        width = self.get(dims, "width", scope)
        if not (length > 0 and width > 0):
            raise dims.error(f"entity {name!r}: length and width must be > 0, got {length!r} and {width!r}")
        perf = obj.find("Performance")
        ms = ma = md = None
        if perf is not None:
            ms = self.get(perf, "maxSpeed", scope, default=None)
            ma = self.get(perf, "maxAcceleration", scope, default=None)
            md = self.get(perf, "maxDeceleration", scope, default=None)
        props = {}
        oc = so.find("ObjectController")
        ctrl = None if oc is None else oc.find("Controller")  # an inline one (a catalog's: its properties unread)
        if ctrl is not None and ctrl.find("Properties") is not None:
            for pr in ctrl.find("Properties").findall("Property"):
                props[str(self.get(pr, "name", self.scope, "string"))] = str(self.get(pr, "value", self.scope,
                                                                                      "string"))
        return M.Entity(name=name, category=category, kind=kind, length=length, width=width,
                        center_x=self.get(centre, "x", scope, default=0.0),
                        center_y=self.get(centre, "y", scope, default=0.0), max_speed=ms, max_acceleration=ma,
                        max_deceleration=md, has_controller=oc is not None, where=self.where(so),
                        controller_properties=props)

    # --- road
    def road(self) -> M.Road:
        rn = self.root.find("RoadNetwork")
        logic = rn.find("LogicFile") if rn is not None else None
        if logic is None:
            self.note(f"no OpenDRIVE road: a straight road with lanes {DEFAULT_LANE_WIDTH:g} m wide")
            return _default_road()
        rel = str(self.get(logic, "filepath", self.scope, "string"))
        path = (self.path.parent / rel).resolve()
        if not path.is_file():
            self.note(f"OpenDRIVE file {rel} not found: a straight road with lanes {DEFAULT_LANE_WIDTH:g} m wide")
            return _default_road()
        return read_opendrive(path, self.note)

    # --- positions
    def position(self, node: Node, scope: Scope) -> M.Position:
        p = node.only("position") if node.tag == "Position" else node
        kind = p.tag
        if kind not in POSITIONS:
            raise p.error(f"<{kind}> is not read here (positions read: {', '.join(POSITIONS)})")
        g = lambda a, t="double", d=...: self.get(p, a, scope, t, d)  # noqa: E731
        v: dict = {}
        if kind == "LanePosition":
            v = dict(road=g("roadId", "string"), lane=g("laneId", "int"), s=g("s"), offset=g("offset", d=0.0))
        elif kind == "RelativeLanePosition":
            v = dict(entity=g("entityRef", "string"), dlane=g("dLane", "int"), ds=g("ds", d=None),
                     ds_lane=g("dsLane", d=None), offset=g("offset", d=0.0))
            if v["ds"] is None and v["ds_lane"] is None:
                raise p.error("a RelativeLanePosition needs ds or dsLane")
            if v["ds"] is None:
                v["ds"] = v["ds_lane"]
        elif kind == "RoadPosition":
            v = dict(road=g("roadId", "string"), s=g("s"), t=g("t"))
        elif kind == "RelativeRoadPosition":
            v = dict(entity=g("entityRef", "string"), ds=g("ds"), dt=g("dt"))
        elif kind == "WorldPosition":
            v = dict(x=g("x"), y=g("y"), h=g("h", d=None))
        elif kind in ("RelativeWorldPosition", "RelativeObjectPosition"):
            v = dict(entity=g("entityRef", "string"), dx=g("dx"), dy=g("dy"))
        o = p.find("Orientation")
        if o is not None:
            v["h"] = self.get(o, "h", scope, default=0.0)
            v["h_relative"] = str(self.get(o, "type", scope, "string", default="relative")) == "relative"
        return M.Position(kind, v, self.where(p))

    # --- actions
    def dynamics(self, d: Node | None, scope: Scope, owner: Node) -> M.Dynamics:
        if d is None:
            raise owner.error(f"<{owner.tag}> needs its dynamics")
        shape = str(self.get(d, "dynamicsShape", scope, "string"))
        dim = str(self.get(d, "dynamicsDimension", scope, "string"))
        value = self.get(d, "value", scope)
        if shape not in SHAPES:
            raise d.error(f"dynamicsShape {shape!r} is not one of {SHAPES}")
        if dim not in DIMENSIONS:
            raise d.error(f"dynamicsDimension {dim!r} is not one of {DIMENSIONS}")
        if value < 0 and dim == "rate":  # decided: the target gives the direction (esmini's examples write -4)
            self.note(f"{d.file}:{d.line}: a negative rate ({value:g}) read as its magnitude (the standard's range "
                      f"is [0, inf[)")
            value = -value
        if value < 0:
            raise d.error(f"a transition's value must be >= 0 (the standard's range is [0, inf[), got {value!r}")
        if shape != "step" and dim != "rate" and value == 0:
            shape = "step"  # decided: a transition over no time or distance is a step (esmini reads it so)
        if d.attrib.get("followingMode") not in (None, "position"):
            raise d.error(f"followingMode {d.attrib['followingMode']!r} is not read here (only 'position')")
        return M.Dynamics(shape, dim, value)

    def action(self, node: Node, scope: Scope, name: str = "") -> M.Action:
        """A PrivateAction or GlobalAction element (or an Action's child)."""
        w = self.where(node)
        if node.tag == "GlobalAction":
            c = node.only("global action")
            if c.tag in OUT_OF_SCOPE_ACTIONS:
                self.note(OUT_OF_SCOPE_ACTIONS[c.tag])
                return M.Action(name, M.OutOfScope(OUT_OF_SCOPE_ACTIONS[c.tag]), "none", w)
            raise c.error(f"the global action <{c.tag}> is not read here (it may change the scenario's motion)")
        if node.tag == "UserDefinedAction":
            raise node.error("a UserDefinedAction is not read here (its effect is unknown)")
        if node.tag != "PrivateAction":
            raise node.error(f"<{node.tag}> is not an action read here")
        c = node.only("private action")
        if c.tag == "LongitudinalAction":
            a = c.only("longitudinal action")
            if a.tag == "SpeedAction":
                return M.Action(name, self.speed_action(a, scope), "longitudinal", w)
            if a.tag == "LongitudinalDistanceAction":
                if a.find("DynamicConstraints") is not None:
                    raise a.find("DynamicConstraints").error(
                        "a LongitudinalDistanceAction with DynamicConstraints is not read here (without them the "
                        "entity is kept at the distance)")
                dist = self.get(a, "distance", scope, default=None)
                gap = self.get(a, "timeGap", scope, default=None)
                if (dist is None) == (gap is None):
                    raise a.error("a LongitudinalDistanceAction needs exactly one of distance and timeGap")
                return M.Action(name, M.LongitudinalDistanceAction(
                    entity=str(self.get(a, "entityRef", scope, "string")), distance=dist, time_gap=gap,
                    freespace=bool(self.get(a, "freespace", scope, "boolean")),
                    continuous=bool(self.get(a, "continuous", scope, "boolean")),
                    displacement=str(self.get(a, "displacement", scope, "string", default="trailingReferencedEntity"))),
                    "longitudinal", w)
            if a.tag == "SpeedProfileAction":
                return M.Action(name, self.speed_profile(a, scope), "longitudinal", w)
            raise a.error(f"the longitudinal action <{a.tag}> is not read here")
        if c.tag == "LateralAction":
            a = c.only("lateral action")
            if a.tag == "LaneChangeAction":
                tgt = a.find("LaneChangeTarget")
                if tgt is None:
                    raise a.error("a LaneChangeAction needs a LaneChangeTarget")
                t = tgt.only("lane change target")
                off = self.get(a, "targetLaneOffset", scope, default=0.0)
                dyn = self.dynamics(a.find("LaneChangeActionDynamics"), scope, a)
                if t.tag == "AbsoluteTargetLane":
                    return M.Action(name, M.LaneChangeAction(dyn, int(self.get(t, "value", scope, "int")), None, 0,
                                                             off), "lane", w)
                if t.tag == "RelativeTargetLane":
                    return M.Action(name, M.LaneChangeAction(dyn, None, str(self.get(t, "entityRef", scope, "string")),
                                                             int(self.get(t, "value", scope, "int")), off), "lane", w)
                raise t.error(f"<{t.tag}> is not a lane change target read here")
            if a.tag == "LaneOffsetAction":
                dyn = a.find("LaneOffsetActionDynamics")
                shape = "step" if dyn is None else str(self.get(dyn, "dynamicsShape", scope, "string"))
                if shape not in SHAPES:
                    raise dyn.error(f"dynamicsShape {shape!r} is not one of {SHAPES}")
                acc = None if dyn is None else self.get(dyn, "maxLateralAcc", scope, default=None)
                if shape != "step" and not (acc is not None and acc > 0):
                    raise (dyn or a).error(f"a {shape} lane offset needs maxLateralAcc > 0")
                if shape == "linear":
                    raise dyn.error("a linear lane offset has no finite lateral acceleration; use cubic or sinusoidal")
                tgt = a.find("LaneOffsetTarget")
                if tgt is None:
                    raise a.error("a LaneOffsetAction needs a LaneOffsetTarget")
                t = tgt.only("lane offset target")
                rel = str(self.get(t, "entityRef", scope, "string")) if t.tag == "RelativeTargetLaneOffset" else None
                if t.tag not in ("AbsoluteTargetLaneOffset", "RelativeTargetLaneOffset"):
                    raise t.error(f"<{t.tag}> is not a lane offset target read here")
                return M.Action(name, M.LaneOffsetAction(shape, acc, self.get(t, "value", scope), rel,
                                                         bool(self.get(a, "continuous", scope, "boolean",
                                                                       default=False))), "lane", w)
            raise a.error(f"the lateral action <{a.tag}> is not read here")
        if c.tag == "TeleportAction":
            return M.Action(name, M.TeleportAction(self.position(c.only("position"), scope)), "position", w)
        if c.tag == "RoutingAction":
            a = c.only("routing action")
            if a.tag != "FollowTrajectoryAction":
                raise a.error(f"the routing action <{a.tag}> is not read here (routes need the road network's "
                              f"junctions; FollowTrajectoryAction is read)")
            return M.Action(name, self.trajectory_action(a, scope), "trajectory", w)
        if c.tag == "ControllerAction" or c.tag == "ActivateControllerAction":
            acts = [c] if c.tag == "ActivateControllerAction" else c.children
            act = None
            for x in acts:
                if x.tag == "ActivateControllerAction":
                    act = x
                elif x.tag in OUT_OF_SCOPE_ACTIONS:
                    self.note(OUT_OF_SCOPE_ACTIONS[x.tag])
                else:
                    raise x.error(f"the controller action <{x.tag}> is not read here")
            if act is None:
                return M.Action(name, M.OutOfScope("controller actions"), "none", w)
            return M.Action(name, M.ActivateController(
                bool(self.get(act, "longitudinal", scope, "boolean", default=True)),
                bool(self.get(act, "lateral", scope, "boolean", default=True))), "controller", w)
        if c.tag in OUT_OF_SCOPE_ACTIONS:
            self.note(OUT_OF_SCOPE_ACTIONS[c.tag])
            return M.Action(name, M.OutOfScope(OUT_OF_SCOPE_ACTIONS[c.tag]), "none", w)
        raise c.error(f"the private action <{c.tag}> is not read here (it may change the motion)")

    def trajectory_action(self, a: Node, scope: Scope) -> M.FollowTrajectoryAction:
        """FollowTrajectoryAction: an inline trajectory (1.0's ``Trajectory`` child or 1.1+'s
        ``TrajectoryRef``) or a catalog reference, a polyline shape, ``followingMode`` position."""
        ref = a.find("TrajectoryRef")
        holder = ref if ref is not None else a
        traj, tscope = holder.find("Trajectory"), scope
        cref = holder.find("CatalogReference")
        if traj is None and cref is not None:
            traj, tscope = self.catalog_entry(cref, scope)
            if traj.tag != "Trajectory":
                raise cref.error(f"the catalog entry is <{traj.tag}>, not a <Trajectory>")
        elif traj is not None:
            tscope = declare(traj.find("ParameterDeclarations"), scope)
        if traj is None:
            raise a.error("a FollowTrajectoryAction needs a Trajectory (inline or by catalog reference)")
        shape = traj.find("Shape")
        if shape is None:
            raise traj.error("a Trajectory needs a Shape")
        poly = shape.only("trajectory shape")
        if poly.tag != "Polyline":
            raise poly.error(f"a <{poly.tag}> trajectory shape is not read here (Polyline is)")
        verts = []
        for v in poly.findall("Vertex"):
            tv = self.get(v, "time", tscope, default=None)
            p = v.find("Position")
            if p is None:
                raise v.error("a Vertex needs a Position")
            verts.append((tv, self.position(p, tscope)))
        if len(verts) < 2:
            raise poly.error(f"a Polyline needs at least 2 vertices, it has {len(verts)}")
        mode = a.find("TrajectoryFollowingMode")
        if mode is not None and str(self.get(mode, "followingMode", scope, "string")) != "position":
            raise mode.error(f"followingMode {mode.attrib.get('followingMode')!r} is not read here (position is: "
                             f"the entity is placed on the trajectory, as the default controller does)")
        timing = None
        tr = a.find("TimeReference")
        if tr is not None and tr.find("Timing") is not None:
            tm = tr.find("Timing")
            dom = str(self.get(tm, "domainAbsoluteRelative", scope, "string"))
            if dom not in ("absolute", "relative"):
                raise tm.error(f"domainAbsoluteRelative {dom!r} is not absolute or relative")
            timing = (dom == "relative", self.get(tm, "scale", scope), self.get(tm, "offset", scope))
            if not timing[1] > 0:
                raise tm.error(f"Timing scale must be > 0, got {timing[1]!r}")
            times = [tv for tv, _ in verts]
            if any(tv is None for tv in times):
                raise poly.error("a timed trajectory needs a time on every Vertex")
            if any(b <= c for c, b in zip(times, times[1:])):
                raise poly.error(f"the vertices' times must increase, got {times}")
        return M.FollowTrajectoryAction(str(traj.attrib.get("name", "")), tuple(verts), timing)

    def speed_action(self, a: Node, scope: Scope) -> M.SpeedAction:
        dyn = self.dynamics(a.find("SpeedActionDynamics"), scope, a)
        tgt = a.find("SpeedActionTarget")
        if tgt is None:
            raise a.error("a SpeedAction needs a SpeedActionTarget")
        t = tgt.only("speed target")
        if t.tag == "AbsoluteTargetSpeed":
            value = self.get(t, "value", scope)
            if value < 0:
                raise t.error(f"a target speed must be >= 0 (no reversing here), got {value!r}")
            return M.SpeedAction(dyn, value)
        if t.tag == "RelativeTargetSpeed":
            vt = str(self.get(t, "speedTargetValueType", scope, "string", default="delta"))
            if vt not in ("delta", "factor"):
                raise t.error(f"speedTargetValueType {vt!r} is not delta or factor")
            return M.SpeedAction(dyn, self.get(t, "value", scope), str(self.get(t, "entityRef", scope, "string")), vt,
                                 bool(self.get(t, "continuous", scope, "boolean", default=False)))
        raise t.error(f"<{t.tag}> is not a speed target read here")

    def speed_profile(self, a: Node, scope: Scope) -> M.SpeedProfileAction:
        """SpeedProfileAction (1.2+), ``followingMode`` position: the speed linear in time
        between entries (see :class:`~acc_gym.scenarios.openscenario.runtime.ProfileRun`)."""
        mode = str(self.get(a, "followingMode", scope, "string"))
        if mode != "position":
            raise a.error(f"SpeedProfileAction followingMode {mode!r} is not read here (position is: the speeds "
                          f"reached at the entries' times; 'follow' smooths them by a controller's jerk limits)")
        ma = md = None
        dc = a.find("DynamicConstraints")
        if dc is not None:
            ma = self.get(dc, "maxAcceleration", scope, default=None)
            md = self.get(dc, "maxDeceleration", scope, default=None)
            for what, x in (("maxAcceleration", ma), ("maxDeceleration", md)):
                if x is not None and not x > 0:
                    raise dc.error(f"DynamicConstraints {what} must be > 0, got {x!r}")
        rel = self.get(a, "entityRef", scope, "string", default=None)
        entries = []
        for e in a.findall("SpeedProfileEntry"):
            tv = self.get(e, "time", scope, default=None)
            v = self.get(e, "speed", scope)
            if tv is not None and tv < 0:
                raise e.error(f"a SpeedProfileEntry's time must be >= 0 (a duration from the previous entry), "
                              f"got {tv!r}")
            if rel is None and v < 0:
                raise e.error(f"a SpeedProfileEntry's speed must be >= 0 (no reversing here), got {v!r}")
            if tv is None and (ma is None or md is None):
                raise e.error("a SpeedProfileEntry without a time needs DynamicConstraints with maxAcceleration "
                              "and maxDeceleration (it is reached at those limits)")
            entries.append((tv, v))
        if not entries:
            raise a.error("a SpeedProfileAction needs at least one SpeedProfileEntry")
        return M.SpeedProfileAction(tuple(entries), None if rel is None else str(rel), ma, md)

    # --- conditions
    def trigger(self, node: Node | None, scope: Scope) -> M.Trigger | None:
        if node is None:
            return None
        groups = []
        for g in node.findall("ConditionGroup"):
            conds = tuple(self.condition(c, scope) for c in g.findall("Condition"))
            if conds:
                groups.append(conds)
        return M.Trigger(tuple(groups))

    def condition(self, c: Node, scope: Scope) -> M.Condition:
        name = str(self.get(c, "name", scope, "string", default=""))
        delay = self.get(c, "delay", scope, default=0.0)
        if delay < 0:
            raise c.error(f"condition {name!r}: delay must be >= 0, got {delay!r}")
        edge = str(self.get(c, "conditionEdge", scope, "string", default="none"))
        if edge not in EDGES:
            raise c.error(f"condition {name!r}: conditionEdge {edge!r} is not one of {EDGES}")
        body = c.only("condition")
        if body.tag == "ByValueCondition":
            v = body.only("value condition")
            if v.tag == "SimulationTimeCondition":
                rule = str(self.get(v, "rule", scope, "string"))
                compare(rule, 0, 0, v)
                test = M.SimulationTime(self.get(v, "value", scope), rule)
            elif v.tag == "StoryboardElementStateCondition":
                et = str(self.get(v, "storyboardElementType", scope, "string"))
                st = str(self.get(v, "state", scope, "string"))
                if et not in ELEMENT_TYPES:
                    raise v.error(f"storyboardElementType {et!r} is not one of {ELEMENT_TYPES}")
                if st not in STATES:
                    raise v.error(f"state {st!r} is not one of {STATES}")
                test = M.StoryboardState(et, str(self.get(v, "storyboardElementRef", scope, "string")), st)
            elif v.tag == "ParameterCondition":
                ref = str(v.attrib.get("parameterRef", "")).lstrip("$")
                try:
                    val = scope.lookup(ref)
                except KeyError:
                    raise v.error(f"ParameterCondition: parameter {ref!r} is not declared") from None
                other = resolve(v.attrib.get("value", ""), scope, v)
                if isinstance(val, (int, float)) and not isinstance(val, bool):
                    other = convert(other, "double", "ParameterCondition value", v)
                else:
                    val, other = str(val), str(other)
                test = M.ParameterValue(compare(str(self.get(v, "rule", scope, "string")), val, other, v))
            else:
                raise v.error(f"the value condition <{v.tag}> is not read here")
        elif body.tag == "ByEntityCondition":
            te = body.find("TriggeringEntities")
            ec = body.find("EntityCondition")
            if te is None or ec is None:
                raise body.error("a ByEntityCondition needs TriggeringEntities and an EntityCondition")
            rule = str(self.get(te, "triggeringEntitiesRule", scope, "string", default="any"))
            if rule not in ("any", "all"):
                raise te.error(f"triggeringEntitiesRule {rule!r} is not any or all")
            ents = tuple(str(self.get(e, "entityRef", scope, "string")) for e in te.findall("EntityRef"))
            if not ents:
                raise te.error("TriggeringEntities names no entity")
            test = self.entity_condition(ec.only("entity condition"), scope, ents, rule)
        else:
            raise body.error(f"<{body.tag}> is not a condition read here")
        return M.Condition(name, delay, edge, test, self.where(c))

    def entity_condition(self, e: Node, scope: Scope, ents: tuple, rule: str) -> M.EntityCondition:
        if e.tag not in ENTITY_CONDITIONS:
            raise e.error(f"the entity condition <{e.tag}> is not read here (read: {', '.join(ENTITY_CONDITIONS)})")
        g = lambda a, t="double", d=...: self.get(e, a, scope, t, d)  # noqa: E731
        v: dict = {}
        if e.tag not in ("ReachPositionCondition", "TraveledDistanceCondition", "StandStillCondition",
                         "CollisionCondition"):
            v["rule"] = str(g("rule", "string"))
            compare(v["rule"], 0, 0, e)
            v["value"] = g("value")
        if e.tag in ("RelativeDistanceCondition", "TimeHeadwayCondition", "RelativeSpeedCondition"):
            v["entity"] = str(g("entityRef", "string"))
        if e.tag in ("RelativeDistanceCondition", "TimeHeadwayCondition", "TimeToCollisionCondition",
                     "DistanceCondition"):
            v["freespace"] = bool(g("freespace", "boolean", False))
            dtype = str(g("relativeDistanceType", "string", "longitudinal" if e.tag != "DistanceCondition"
                          else "euclidianDistance"))
            if dtype == "cartesianDistance":
                dtype = "euclidianDistance"
            if dtype not in ("longitudinal", "lateral", "euclidianDistance"):
                raise e.error(f"relativeDistanceType {dtype!r} is not read here")
            v["distance_type"] = dtype
            cs = str(g("coordinateSystem", "string", "entity"))
            if cs not in ("entity", "road", "lane"):
                raise e.error(f"coordinateSystem {cs!r} is not read here (entity, road and lane are the same on a "
                              f"straight road)")
        if e.tag == "TimeToCollisionCondition":
            tgt = e.find("TimeToCollisionConditionTarget")
            if tgt is None:
                raise e.error("a TimeToCollisionCondition needs a TimeToCollisionConditionTarget")
            t = tgt.only("target")
            if t.tag == "EntityRef":
                v["entity"] = str(self.get(t, "entityRef", scope, "string"))
            else:
                v["position"] = self.position(t, scope)
        if e.tag in ("ReachPositionCondition", "DistanceCondition"):
            p = e.find("Position")
            if p is None:
                raise e.error(f"a {e.tag} needs a Position")
            v["position"] = self.position(p, scope)
            if e.tag == "ReachPositionCondition":
                v["tolerance"] = g("tolerance")
        if e.tag == "TraveledDistanceCondition":
            v["value"] = g("value")
        if e.tag == "StandStillCondition":
            v["duration"] = g("duration")
        if e.tag == "CollisionCondition":
            t = e.only("collision target")
            if t.tag != "EntityRef":
                raise t.error("a CollisionCondition by type is not read here (name the entity)")
            v["entity"] = str(self.get(t, "entityRef", scope, "string"))
        if e.tag in ("SpeedCondition", "AccelerationCondition") and e.attrib.get("direction") not in (
                None, "longitudinal"):
            raise e.error(f"{e.tag} direction {e.attrib['direction']!r} is not read here")
        return M.EntityCondition(ents, rule, e.tag, v)

    # --- storyboard
    def actions_of_private(self, priv: Node, scope: Scope) -> list:
        ent = str(self.get(priv, "entityRef", scope, "string"))
        return [(ent, self.action(a, scope)) for a in priv.findall("PrivateAction")]

    def init(self, sb: Node) -> tuple:
        init = sb.find("Init")
        out = []
        if init is None:
            return ()
        acts = init.find("Actions")
        if acts is None:
            return ()
        for c in acts.children:
            if c.tag == "Private":
                out += self.actions_of_private(c, self.scope)
            elif c.tag == "GlobalAction":
                out.append((None, self.action(c, self.scope)))
            elif c.tag == "UserDefinedAction":
                raise c.error("a UserDefinedAction is not read here (its effect is unknown)")
        return tuple(out)

    def stories(self, sb: Node) -> tuple:
        stories = []
        for st in sb.findall("Story"):
            sscope = declare(st.find("ParameterDeclarations"), self.scope)
            acts = []
            for act in st.findall("Act"):
                groups = []
                for mg in act.findall("ManeuverGroup"):
                    actors = mg.find("Actors")
                    names = tuple(str(self.get(e, "entityRef", sscope, "string"))
                                  for e in (actors.findall("EntityRef") if actors is not None else []))
                    sel = bool(self.get(actors, "selectTriggeringEntities", sscope, "boolean", False)) \
                        if actors is not None else False
                    mans = []
                    for man in mg.children:
                        if man.tag == "CatalogReference":
                            node, mscope = self.catalog_entry(man, sscope)
                            mans.append(self.maneuver(node, mscope))
                        elif man.tag == "Maneuver":
                            mans.append(self.maneuver(man, declare(man.find("ParameterDeclarations"), sscope)))
                    groups.append(M.ManeuverGroup(str(self.get(mg, "name", sscope, "string")),
                                                  int(self.get(mg, "maximumExecutionCount", sscope, "unsignedInt",
                                                               1)), names, sel, tuple(mans)))
                acts.append(M.Act(str(self.get(act, "name", sscope, "string")), tuple(groups),
                                  self.trigger(act.find("StartTrigger"), sscope),
                                  self.trigger(act.find("StopTrigger"), sscope)))
            stories.append(M.Story(str(self.get(st, "name", sscope, "string", "")), tuple(acts)))
        return tuple(stories)

    def maneuver(self, man: Node, scope: Scope) -> M.Maneuver:
        if man.tag != "Maneuver":
            raise man.error(f"a maneuver catalog entry is <{man.tag}>, not <Maneuver>")
        events = []
        for ev in man.findall("Event"):
            pr = str(self.get(ev, "priority", scope, "string", "override"))
            if pr not in PRIORITIES:
                raise ev.error(f"event priority {pr!r} is not one of {sorted(PRIORITIES)}")
            acts = []
            for a in ev.findall("Action"):
                aname = str(self.get(a, "name", scope, "string", ""))
                acts.append(self.action(a.only("action"), scope, aname))
            events.append(M.Event(str(self.get(ev, "name", scope, "string")), PRIORITIES[pr],
                                  int(self.get(ev, "maximumExecutionCount", scope, "unsignedInt", 1)), tuple(acts),
                                  self.trigger(ev.find("StartTrigger"), scope), self.where(ev)))
        return M.Maneuver(str(self.get(man, "name", scope, "string")), tuple(events))


def _default_road() -> M.Road:
    w = DEFAULT_LANE_WIDTH
    lanes = {}
    for k in range(1, 7):
        lanes[-k] = M.Lane(-k, -(k - 0.5) * w, w, True)
        lanes[k] = M.Lane(k, (k - 0.5) * w, w, True)
    return M.Road(lanes)


def read_opendrive(path: Path, note) -> M.Road:
    """The first road of an OpenDRIVE file: lane centres and widths of its first lane section
    (constant widths; a width that varies along the road is an error), its reference line's
    start and heading. Arcs and spirals in the plan view are noted (the road is projected onto
    its ``s`` coordinate)."""
    root = parse(path)
    road = root.find("road")
    if road is None:
        raise root.error("the OpenDRIVE file has no <road>")
    if len(root.findall("road")) > 1:
        note("OpenDRIVE roads beyond the first (the scenario is placed on the first)")
    pv = road.find("planView")
    geos = pv.findall("geometry") if pv is not None else []
    if not geos:
        raise road.error("the road has no plan view geometry")
    g0 = geos[0]
    if any(g.find("line") is None for g in geos):
        note("road curvature (the road is projected onto its s coordinate)")
        curved = True
    else:
        curved = len({g.attrib.get("hdg") for g in geos}) > 1
        if curved:
            note("road curvature (the road is projected onto its s coordinate)")
    if road.find("elevationProfile") is not None and road.find("elevationProfile").children:
        note("road elevation")
    lanes_node = road.find("lanes")
    sections = lanes_node.findall("laneSection") if lanes_node is not None else []
    if not sections:
        raise road.error("the road has no lane section")
    lanes: dict = {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        part = sections[0].find(side)
        if part is None:
            continue
        items = []
        for ln in part.findall("lane"):
            w = ln.find("width")
            if w is None:
                raise ln.error("a lane needs a <width>")
            coef = [float(w.attrib.get(k, "0")) for k in "abcd"]
            if any(abs(c) > 1e-12 for c in coef[1:]) or len(ln.findall("width")) > 1:
                raise w.error("a lane width that varies along the road is not read here")
            items.append((abs(int(ln.attrib["id"])), int(ln.attrib["id"]), coef[0], ln.attrib.get("type", "")))
        edge = 0.0
        for _, lid, width, typ in sorted(items):
            lanes[lid] = M.Lane(lid, sign * (edge + 0.5 * width), width, typ == "driving")
            edge += width
    if len(sections) > 1:
        note("lane sections beyond the first (the first's lanes are used along the whole road)")
    return M.Road(lanes, x0=float(g0.attrib.get("x", 0.0)), y0=float(g0.attrib.get("y", 0.0)),
                  heading=float(g0.attrib.get("hdg", 0.0)), length=float(road.attrib.get("length", math.inf)),
                  source=os.fspath(path), curved=curved)


def read(path, *, parameters: dict | None = None, ego: str | None = None) -> M.OpenScenario:
    """Read the OpenSCENARIO file ``path``. ``parameters``: values for the file's declared
    parameters (name -> value or text), as a variation would set them. ``ego``: the entity
    under test (default: the one named ``Ego``, else the first)."""
    path = Path(path)
    r = _Reader(path, parameters)
    entities = r.entities()
    if ego is None:
        ego = "Ego" if "Ego" in entities else next(iter(entities))
    elif ego not in entities:
        raise OpenScenarioError(f"--ego {ego!r} is not an entity of the file (entities: {list(entities)})", str(path))
    sb = r.root.find("Storyboard")
    if sb is None:
        raise r.root.error("no <Storyboard>")
    road = r.road()
    init = r.init(sb)
    stories = r.stories(sb)
    stop = r.trigger(sb.find("StopTrigger"), r.scope)
    for ent, _a in init:
        if ent is not None and ent not in entities:
            raise OpenScenarioError(f"Init names entity {ent!r}, which is not declared", str(path))
    return M.OpenScenario(path=str(path), version=r.version, description=r.description,
                          parameters={k: r.scope.values[k] for k in r.scope.values}, entities=entities, init=init,
                          stories=stories, stop=stop, road=road, ego=ego, out_of_scope=tuple(r.out))
