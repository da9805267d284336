"""What the reader makes of an OpenSCENARIO file: frozen records of the longitudinal content.

Units as OpenSCENARIO's: metres, seconds, m/s, m/s^2, radians. Positions are kept as read
(:class:`Position`) and placed on the road when the scenario starts
(:mod:`acc_gym.scenarios.openscenario.runtime`), since relative positions depend on where
their reference entity is then. Every record keeps the ``file`` and ``line`` it was read
from (``where``), so that the runtime's messages can name them too.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Where:
    file: str
    line: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}"


@dataclass(frozen=True)
class Entity:
    """A ScenarioObject: its bounding box relative to its reference point (OpenSCENARIO's: for
    a vehicle the rear axle's centre) and its performance limits."""

    name: str
    category: str  # vehicleCategory / pedestrianCategory / miscObjectCategory ("car", "pedestrian", "obstacle", ...)
    kind: str  # "vehicle", "pedestrian" or "misc"
    length: float  # [m]
    width: float  # [m]
    center_x: float  # [m] bounding-box centre ahead of the reference point
    center_y: float  # [m] bounding-box centre left of the reference point
    max_speed: float | None  # [m/s] Performance (vehicles)
    max_acceleration: float | None  # [m/s^2]
    max_deceleration: float | None  # [m/s^2]
    has_controller: bool  # an ObjectController is declared
    where: Where
    controller_properties: dict = field(default_factory=dict)  # its Controller's Properties (name -> text)

    @property
    def front(self) -> float:
        """[m] the front bumper ahead of the reference point."""
        return self.center_x + 0.5 * self.length

    @property
    def rear(self) -> float:
        """[m] the rear bumper ahead of the reference point (usually negative: behind it)."""
        return self.center_x - 0.5 * self.length


@dataclass(frozen=True)
class Position:
    """A Position element: ``kind`` its XML name; ``values`` its resolved attributes
    (``road``, ``lane``, ``s``, ``offset``, ``t``, ``x``, ``y``, ``entity``, ``dlane``, ``ds``,
    ``dx``, ``dy``, ``h`` (the orientation's heading), ``h_relative``)."""

    kind: str
    values: dict
    where: Where


@dataclass(frozen=True)
class Dynamics:
    """A transition: ``shape`` step|linear|cubic|sinusoidal, ``dimension`` time|distance|rate, ``value``."""

    shape: str
    dimension: str
    value: float


@dataclass(frozen=True)
class SpeedAction:
    dynamics: Dynamics
    value: float  # [m/s] absolute target, or the relative target's value
    relative_to: str | None = None  # RelativeTargetSpeed's entityRef
    value_type: str = "delta"  # "delta" or "factor"
    continuous: bool = False


@dataclass(frozen=True)
class SpeedProfileAction:
    """A speed profile followed by position: ``entries`` of ``(time, speed)``, each ``time``
    the duration [s] from the previous entry (the first: from the action's start; None: at
    the dynamic constraints' limit), each ``speed`` [m/s] absolute or, with ``relative_to``,
    added to that entity's speed when the action starts."""

    entries: tuple
    relative_to: str | None = None
    max_acceleration: float | None = None  # [m/s^2] DynamicConstraints
    max_deceleration: float | None = None  # [m/s^2]


@dataclass(frozen=True)
class LongitudinalDistanceAction:
    entity: str
    distance: float | None  # [m]
    time_gap: float | None  # [s]
    freespace: bool
    continuous: bool
    displacement: str  # trailingReferencedEntity | leadingReferencedEntity | any


@dataclass(frozen=True)
class LaneChangeAction:
    dynamics: Dynamics
    lane: int | None  # AbsoluteTargetLane's lane id
    relative_to: str | None  # RelativeTargetLane's entityRef
    relative_lanes: int  # its value (lanes to the left: +)
    target_offset: float  # [m] targetLaneOffset


@dataclass(frozen=True)
class LaneOffsetAction:
    shape: str
    max_lateral_acc: float | None  # [m/s^2]
    offset: float  # [m]
    relative_to: str | None
    continuous: bool


@dataclass(frozen=True)
class FollowTrajectoryAction:
    """A polyline trajectory: ``vertices`` of ``(time or None, Position)``; ``timing`` None (the
    path followed at the entity's own speed) or ``(relative, scale, offset)`` (a vertex's time
    ``tv`` is reached at ``scale tv + offset``, from the action's start when relative)."""

    name: str
    vertices: tuple
    timing: tuple | None


@dataclass(frozen=True)
class TeleportAction:
    position: Position


@dataclass(frozen=True)
class ActivateController:
    longitudinal: bool
    lateral: bool


@dataclass(frozen=True)
class OutOfScope:
    """An element the reader leaves out because it does not change longitudinal motion
    (lights, weather, visibility, ...): listed in every result that meets it."""

    what: str


@dataclass(frozen=True)
class Action:
    name: str
    payload: object  # one of the action records above
    domain: str  # "longitudinal", "lane" (lane change / lane offset), "position", "controller", "none"
    where: Where


# --- conditions
@dataclass(frozen=True)
class SimulationTime:
    value: float
    rule: str


@dataclass(frozen=True)
class StoryboardState:
    element_type: str
    ref: str
    state: str


@dataclass(frozen=True)
class ParameterValue:
    holds: bool  # evaluated when read: parameters do not change while a scenario runs here


@dataclass(frozen=True)
class EntityCondition:
    """A ByEntityCondition: ``kind`` its EntityCondition's XML name, ``values`` its resolved
    attributes (``entity``, ``value``, ``rule``, ``freespace``, ``distance_type``,
    ``position``, ``tolerance``, ``duration``)."""

    triggering: tuple  # entity names
    rule: str  # "any" or "all"
    kind: str
    values: dict


@dataclass(frozen=True)
class Condition:
    name: str
    delay: float  # [s]
    edge: str  # none | rising | falling | risingOrFalling
    test: object  # SimulationTime | StoryboardState | ParameterValue | EntityCondition
    where: Where


@dataclass(frozen=True)
class Trigger:
    groups: tuple  # of tuples of Condition: any group whose conditions all hold


# --- storyboard
@dataclass(frozen=True)
class Event:
    name: str
    priority: str  # override (overwrite) | skip | parallel
    max_count: int
    actions: tuple  # of Action
    start: Trigger | None
    where: Where


@dataclass(frozen=True)
class Maneuver:
    name: str
    events: tuple


@dataclass(frozen=True)
class ManeuverGroup:
    name: str
    max_count: int
    actors: tuple  # entity names
    select_triggering: bool
    maneuvers: tuple


@dataclass(frozen=True)
class Act:
    name: str
    groups: tuple
    start: Trigger | None
    stop: Trigger | None


@dataclass(frozen=True)
class Story:
    name: str
    acts: tuple


@dataclass(frozen=True)
class Lane:
    id: int
    centre: float  # [m] lateral offset of the lane's centre from the reference line (left +)
    width: float  # [m]
    driving: bool


@dataclass(frozen=True)
class Road:
    """A straight road from the OpenDRIVE file (or the default): its lanes at ``s = 0`` and its
    reference line's start and heading in world coordinates."""

    lanes: dict  # lane id -> Lane
    x0: float = 0.0
    y0: float = 0.0
    heading: float = 0.0  # [rad]
    length: float = float("inf")
    source: str | None = None  # the .xodr file, None: the default road
    curved: bool = False  # its plan view has arcs or spirals (projected onto s: out of scope)

    def lane_at(self, t: float) -> int | None:
        """The lane whose band holds the lateral offset ``t``."""
        for lane in self.lanes.values():
            if abs(t - lane.centre) <= 0.5 * lane.width + 1e-9:
                return lane.id
        return None


@dataclass(frozen=True)
class OpenScenario:
    """One OpenSCENARIO file, read."""

    path: str
    version: tuple  # (revMajor, revMinor)
    description: str
    parameters: dict  # the file's parameters after overrides: name -> value
    entities: dict  # name -> Entity (in file order)
    init: tuple  # of (entity name, Action)
    stories: tuple
    stop: Trigger | None
    road: Road
    ego: str
    out_of_scope: tuple = field(default_factory=tuple)  # what the file has that the reader leaves out
