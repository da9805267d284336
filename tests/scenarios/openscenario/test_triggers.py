"""OpenSCENARIO conditions against hand computation: the step at which each kind fires.

Every scenario runs on the default road (lanes 3.5 m wide: lane -1's centre at t = -1.75,
lane -k's at -(k - 1/2) 3.5) in steps of 0.2 s. The ego is kept on its scripted motion (its
controller is activated only at t = 1e6 s), so every entity moves kinematically and every
number below is worked out by hand from the initial positions, speeds and the bounding box
(centre x = 1.4, length 5, width 2: the front 3.9 m ahead of the reference point, the rear
1.1 m behind it, the sides 1 m either side). A responder entity ``Target`` (lane -5, 10 m/s,
out of everyone's way) gets a step SpeedAction to 30 m/s when the condition under test fires;
conditions are evaluated on the snapshot at a step's start and a step change shows in the
trace row of that step, so the first row where ``Target``'s speed is 30 is the firing step.
"""

from pathlib import Path

import numpy as np
import pytest

from acc_gym.evaluation.runner import load_controller
from acc_gym.scenarios.openscenario import run_file
from acc_gym.scenarios.openscenario.runtime import World
from acc_gym.scenarios.openscenario.reader import read

DT = 0.2


# --- a minimal OpenSCENARIO file, built from pieces
def vehicle(name, kind="Vehicle"):
    cat = {"Vehicle": 'vehicleCategory="car"', "MiscObject": 'miscObjectCategory="obstacle" mass="100"'}[kind]
    extra = ('<Performance maxSpeed="70" maxAcceleration="10" maxDeceleration="10"/>'
             '<Axles><FrontAxle maxSteering="0.5" wheelDiameter="0.6" trackWidth="1.8" positionX="2.8" '
             'positionZ="0.3"/><RearAxle maxSteering="0" wheelDiameter="0.6" trackWidth="1.8" positionX="0" '
             'positionZ="0.3"/></Axles>' if kind == "Vehicle" else "")
    return (f'<ScenarioObject name="{name}"><{kind} name="{name}_model" {cat}><ParameterDeclarations/>'
            f'<BoundingBox><Center x="1.4" y="0" z="0.75"/><Dimensions length="5" width="2" height="1.5"/>'
            f'</BoundingBox>{extra}<Properties/></{kind}></ScenarioObject>')


def lane_pos(lane, s, offset=0.0):
    return f'<LanePosition roadId="0" laneId="{lane}" s="{s}" offset="{offset}"/>'


def world_pos(x, y):
    return f'<WorldPosition x="{x}" y="{y}" z="0" h="0"/>'


def teleport(pos):
    return f"<PrivateAction><TeleportAction><Position>{pos}</Position></TeleportAction></PrivateAction>"


def speed(target, shape="step", dim="time", value=0.0, relative=None):
    tgt = (f'<AbsoluteTargetSpeed value="{target}"/>' if relative is None else
           f'<RelativeTargetSpeed entityRef="{relative}" value="{target}" speedTargetValueType="delta" '
           f'continuous="false"/>')
    return (f'<PrivateAction><LongitudinalAction><SpeedAction><SpeedActionDynamics dynamicsShape="{shape}" '
            f'value="{value}" dynamicsDimension="{dim}"/><SpeedActionTarget>{tgt}</SpeedActionTarget>'
            f'</SpeedAction></LongitudinalAction></PrivateAction>')


def lane_change(lane, shape="linear", dim="time", value=2.0):
    return (f'<PrivateAction><LateralAction><LaneChangeAction><LaneChangeActionDynamics dynamicsShape="{shape}" '
            f'value="{value}" dynamicsDimension="{dim}"/><LaneChangeTarget><AbsoluteTargetLane value="{lane}"/>'
            f'</LaneChangeTarget></LaneChangeAction></LateralAction></PrivateAction>')


def private(entity, *actions):
    return f'<Private entityRef="{entity}">{"".join(actions)}</Private>'


def cond(inner, name="c", delay=0, edge="none"):
    return f'<Condition name="{name}" delay="{delay}" conditionEdge="{edge}">{inner}</Condition>'


def sim_time(value, rule="greaterOrEqual"):
    return f'<ByValueCondition><SimulationTimeCondition value="{value}" rule="{rule}"/></ByValueCondition>'


def state(kind, ref, st):
    return (f'<ByValueCondition><StoryboardElementStateCondition storyboardElementType="{kind}" '
            f'storyboardElementRef="{ref}" state="{st}"/></ByValueCondition>')


def by_entity(entities, inner, rule="any"):
    refs = "".join(f'<EntityRef entityRef="{e}"/>' for e in entities)
    return (f'<ByEntityCondition><TriggeringEntities triggeringEntitiesRule="{rule}">{refs}</TriggeringEntities>'
            f'<EntityCondition>{inner}</EntityCondition></ByEntityCondition>')


def trigger(*groups):
    return "<StartTrigger>" + "".join(f"<ConditionGroup>{''.join(g)}</ConditionGroup>" for g in groups) + \
        "</StartTrigger>"


def event(name, actions, start, priority="override", count=1):
    acts = "".join(f'<Action name="{n}">{a}</Action>' for n, a in actions)
    return f'<Event name="{name}" priority="{priority}" maximumExecutionCount="{count}">{acts}{start}</Event>'


def group(name, actors, events, count=1):
    refs = "".join(f'<EntityRef entityRef="{e}"/>' for e in actors)
    return (f'<ManeuverGroup maximumExecutionCount="{count}" name="{name}"><Actors selectTriggeringEntities="false">'
            f'{refs}</Actors><Maneuver name="{name}_maneuver">{"".join(events)}</Maneuver></ManeuverGroup>')


ACTIVATE = '<PrivateAction><ActivateControllerAction longitudinal="true" lateral="false"/></PrivateAction>'


def write(tmp_path, init, groups=(), *, entities=None, params="", hold_ego=True, name="t.xosc"):
    """A scenario file: ``init`` Private elements, ``groups`` maneuver groups of one act that
    starts at t = 0; ``hold_ego``: the ego's controller is activated only at t = 1e6 s."""
    entities = entities if entities is not None else [vehicle(n) for n in ("Ego", "Lead", "Other", "Target")]
    groups = list(groups)
    if hold_ego:
        groups.append(group("EgoHold", ["Ego"], [event("activate", [("act", ACTIVATE)],
                                                      trigger([cond(sim_time(1e6))]))]))
    text = ('<?xml version="1.0" encoding="UTF-8"?>\n<OpenSCENARIO>\n'
            '<FileHeader revMajor="1" revMinor="2" date="2024-01-01T00:00:00" description="t" author="t"/>\n'
            f'<ParameterDeclarations>{params}</ParameterDeclarations>\n<CatalogLocations/>\n<RoadNetwork/>\n'
            f'<Entities>\n' + "\n".join(entities) + '\n</Entities>\n<Storyboard>\n<Init><Actions>\n'
            + "\n".join(init) + '\n</Actions></Init>\n<Story name="S"><Act name="A">\n' + "\n".join(groups)
            + f'\n{trigger([cond(sim_time(0))])}</Act></Story>\n<StopTrigger/>\n</Storyboard>\n</OpenSCENARIO>\n')
    p = Path(tmp_path) / name
    p.write_text(text)
    return p


# --- the standard setup
START = {"Ego": (-1, 0.0, 20.0), "Lead": (-1, 50.0, 10.0), "Other": (-3, 0.0, 10.0), "Target": (-5, 0.0, 10.0)}


def init_of(start=START):
    return [private(n, teleport(lane_pos(ln, s)), speed(v)) for n, (ln, s, v) in start.items()]


def respond(*groups, count=1, action=None):
    """Target's event: a step to 30 m/s (or ``action``) when the condition groups hold."""
    return group("Respond", ["Target"], [event("respond", [("go", action or speed(30))], trigger(*groups),
                                               count=count)])


def run(tmp_path, groups, start=START, duration=6.0, **kw):
    path = write(tmp_path, init_of(start), groups, **kw)
    result, tr = run_file(path, load_controller("constant"), duration=duration)
    return result, tr


def fired(tr, entity="Target", v0=10.0):
    """The first step at which ``entity``'s speed leaves ``v0`` (None: never)."""
    j = tr.names.index(entity)
    k = np.flatnonzero(np.abs(tr.v[:, j] - v0) > 1e-9)
    return int(k[0]) if len(k) else None


def fires_at(tmp_path, conditions, extra=(), start=START, duration=6.0, **kw):
    """``conditions``: a list of condition groups (lists of Condition XML)."""
    _, tr = run(tmp_path, [respond(*conditions), *extra], start, duration, **kw)
    return fired(tr), tr


# ---------------------------------------------------------------- value conditions
@pytest.mark.parametrize("value, rule, expected", [
    (1.1, "greaterThan", 6),  # t = 1.2 is the first step after 1.1 s
    (1.0, "greaterOrEqual", 5),  # t = 5 x 0.2 = 1.0 exactly
    (0.5, "lessThan", 0),  # true at once
    (0.6, "greaterThan", 4),  # t = 3 x 0.2 is 0.6, not after it (in floating point: 0.6000000000000001)
    (0.6, "equalTo", 3),
    (1.4, "equalTo", 7),  # 7 x 0.2 = 1.4000000000000001 in floating point
])
def test_simulation_time_condition(tmp_path, value, rule, expected):
    k, tr = fires_at(tmp_path, [[cond(sim_time(value, rule))]])
    assert k == expected
    assert tr.t[k] == pytest.approx(expected * DT)


def test_an_equal_simulation_time_holds_for_one_step(tmp_path):
    step_up = speed(1.0, relative="Target")  # +1 m/s at each execution, up to 5 times
    _, tr = run(tmp_path, [respond([cond(sim_time(0.6, "equalTo"))], count=5, action=step_up)], duration=2.0)
    assert list(tr.v[:6, tr.names.index("Target")]) == [10.0, 10.0, 10.0, 11.0, 11.0, 11.0]


# Other: a linear SpeedAction from 10 m/s by 1 s (to 15 m/s), started when t >= 1.0: at step 5.
# Its startTransition happens at step 5 and is seen at step 6; it ends at t = 2.0, after the
# move of step 9, so endTransition and completeState are seen at step 10.
OTHER_CHANGE = group("Change", ["Other"], [event("change", [("otherSpeed", speed(15, "linear", "time", 1.0))],
                                                 trigger([cond(sim_time(1.0))]))])


@pytest.mark.parametrize("kind, ref, st, expected", [
    ("action", "otherSpeed", "startTransition", 6),
    ("action", "otherSpeed", "runningState", 6),
    ("action", "otherSpeed", "endTransition", 10),
    ("action", "otherSpeed", "completeState", 10),
    ("event", "change", "startTransition", 6),
    ("event", "change", "endTransition", 10),
    ("event", "change", "completeState", 10),
])
def test_storyboard_element_state_condition(tmp_path, kind, ref, st, expected):
    k, tr = fires_at(tmp_path, [[cond(state(kind, ref, st))]], extra=[OTHER_CHANGE])
    assert k == expected
    j = tr.names.index("Other")
    assert tr.v[5, j] == 10.0 and tr.v[6, j] == pytest.approx(11.0) and tr.v[10, j] == pytest.approx(15.0)


@pytest.mark.parametrize("st, speeds", [
    # a transition holds for one step: the re-armed event fires once
    ("endTransition", {9: 10.0, 10: 11.0, 11: 11.0, 12: 11.0, 13: 11.0}),
    # a state holds on: the event fires again every step until its maximumExecutionCount (3)
    ("completeState", {9: 10.0, 10: 11.0, 11: 12.0, 12: 13.0, 13: 13.0}),
])
def test_a_transition_lasts_one_step_and_a_state_lasts(tmp_path, st, speeds):
    step_up = speed(1.0, relative="Target")  # +1 m/s at each execution
    _, tr = run(tmp_path, [respond([cond(state("action", "otherSpeed", st))], count=3, action=step_up),
                           OTHER_CHANGE])
    j = tr.names.index("Target")
    assert {k: round(float(tr.v[k, j]), 9) for k in speeds} == speeds


@pytest.mark.parametrize("value, fires", [("1", True), ("2", False)])
def test_parameter_condition(tmp_path, value, fires):
    params = '<ParameterDeclaration name="Go" parameterType="int" value="1"/>'
    p = f'<ByValueCondition><ParameterCondition parameterRef="Go" value="{value}" rule="equalTo"/></ByValueCondition>'
    k, _ = fires_at(tmp_path, [[cond(p), cond(sim_time(0.5))]], params=params)  # and t >= 0.5: step 3
    assert k == (3 if fires else None)


def test_parameter_condition_on_a_string(tmp_path):
    params = '<ParameterDeclaration name="Mode" parameterType="string" value="brake"/>'
    p = '<ByValueCondition><ParameterCondition parameterRef="Mode" value="brake" rule="equalTo"/></ByValueCondition>'
    assert fires_at(tmp_path, [[cond(p)]], params=params)[0] == 0


# ---------------------------------------------------------------- entity conditions
# Ego at s = 4k (20 m/s), Lead 50 m ahead at 10 m/s in the same lane: between the reference points
# 50 - 2k, between the contours (Ego's front 3.9 m ahead, Lead's rear 1.1 m behind) 45 - 2k.
def rel_distance(value, freespace, dtype="longitudinal", entity="Lead", rule="lessThan"):
    return (f'<RelativeDistanceCondition entityRef="{entity}" relativeDistanceType="{dtype}" value="{value}" '
            f'freespace="{str(freespace).lower()}" rule="{rule}" coordinateSystem="entity"/>')


@pytest.mark.parametrize("freespace, expected", [
    (False, 10),  # 50 - 2k < 30.5: k > 9.75
    (True, 8),  # 45 - 2k < 30.5: k > 7.25
])
def test_relative_distance_longitudinal(tmp_path, freespace, expected):
    k, tr = fires_at(tmp_path, [[cond(by_entity(["Ego"], rel_distance(30.5, freespace)))]])
    assert k == expected
    ie, il = tr.names.index("Ego"), tr.names.index("Lead")
    d = tr.s[k, il] - tr.s[k, ie] - (5.0 if freespace else 0.0)
    assert d < 30.5 <= d + 2.0  # the step before did not hold


# Other changes from lane -3 (t = -8.75) to lane -1 (t = -1.75) linearly in 4 s from t = 0:
# t_other = -8.75 + 1.75 t = -8.75 + 0.35 k; across to Ego's t = -1.75: 7 - 0.35 k between the
# reference points, 5 - 0.35 k between the contours (1 m half-width each).
OTHER_ACROSS = group("Across", ["Other"], [event("across", [("lc", lane_change(-1, "linear", "time", 4.0))],
                                                 trigger([cond(sim_time(0))]))])


@pytest.mark.parametrize("freespace, value, expected", [
    (False, 2.0, 15),  # 7 - 0.35 k < 2.0: k > 14.29
    (True, 1.7, 10),  # 5 - 0.35 k < 1.7: k > 9.43
])
def test_relative_distance_lateral(tmp_path, freespace, value, expected):
    k, tr = fires_at(tmp_path, [[cond(by_entity(["Ego"], rel_distance(value, freespace, "lateral", "Other")))]],
                     extra=[OTHER_ACROSS])
    assert k == expected
    jo = tr.names.index("Other")
    assert tr.y[k, jo] == pytest.approx(-8.75 + 0.35 * k)


def test_relative_distance_cartesian_is_euclidean(tmp_path):
    # cartesianDistance (1.0's name): Lead 50 m ahead in lane -2, 3.5 m across:
    # sqrt((50 - 2k)^2 + 3.5^2) < 30.2 -> 50 - 2k < 29.9965 -> k > 10.002 -> 11 (longitudinal alone: k > 9.9 -> 10)
    start = dict(START, Lead=(-2, 50.0, 10.0))
    k, _ = fires_at(tmp_path, [[cond(by_entity(["Ego"], rel_distance(30.2, False, "cartesianDistance")))]],
                    start=start)
    assert k == 11
    k, _ = fires_at(tmp_path, [[cond(by_entity(["Ego"], rel_distance(30.2, False, "longitudinal")))]],
                    start=start)
    assert k == 10


@pytest.mark.parametrize("freespace, expected", [
    (False, 6),  # (50 - 2k) / 20 < 1.93: 50 - 2k < 38.6, k > 5.7
    (True, 4),  # (45 - 2k) / 20 < 1.93: k > 3.2
])
def test_time_headway(tmp_path, freespace, expected):
    c = (f'<TimeHeadwayCondition entityRef="Lead" value="1.93" freespace="{str(freespace).lower()}" '
         f'rule="lessThan" coordinateSystem="entity" relativeDistanceType="longitudinal"/>')
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == expected


def ttc(target, value, freespace, rule="lessThan"):
    return (f'<TimeToCollisionCondition value="{value}" freespace="{str(freespace).lower()}" rule="{rule}" '
            f'coordinateSystem="entity" relativeDistanceType="longitudinal"><TimeToCollisionConditionTarget>'
            f'{target}</TimeToCollisionConditionTarget></TimeToCollisionCondition>')


@pytest.mark.parametrize("freespace, expected", [
    (False, 10),  # closing at 10 m/s: (50 - 2k) / 10 < 3.05, k > 9.75
    (True, 8),  # (45 - 2k) / 10 < 3.05, k > 7.25
])
def test_time_to_collision_with_an_entity(tmp_path, freespace, expected):
    c = ttc('<EntityRef entityRef="Lead"/>', 3.05, freespace)
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == expected


@pytest.mark.parametrize("freespace, expected", [
    (False, 13),  # to s = 100 at 20 m/s: (100 - 4k) / 20 < 2.55, k > 12.25
    (True, 12),  # from the front bumper: (96.1 - 4k) / 20 < 2.55, k > 11.275
])
def test_time_to_collision_with_a_position(tmp_path, freespace, expected):
    c = ttc(f"<Position>{world_pos(100, -1.75)}</Position>", 2.55, freespace)
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == expected


# Other speeds up linearly from 10 m/s at 2 m/s^2 from t = 0: v = 10 + 0.4 k (to 20 m/s at k = 25)
OTHER_SPEEDS_UP = group("Up", ["Other"], [event("up", [("up", speed(20, "linear", "rate", 2.0))],
                                                trigger([cond(sim_time(0))]))])


def speed_cond(value, rule="greaterThan"):
    return f'<SpeedCondition value="{value}" rule="{rule}" direction="longitudinal"/>'


def test_speed_condition(tmp_path):
    k, tr = fires_at(tmp_path, [[cond(by_entity(["Other"], speed_cond(13.1)))]], extra=[OTHER_SPEEDS_UP])
    assert k == 8  # 10 + 0.4 k > 13.1: k > 7.75
    assert tr.v[k, tr.names.index("Other")] == pytest.approx(13.2)


def test_relative_speed_condition(tmp_path):
    # the triggering entity's speed minus the reference's: (10 + 0.4 k) - 20 > -6.9: k > 7.75
    c = '<RelativeSpeedCondition entityRef="Ego" value="-6.9" rule="greaterThan"/>'
    assert fires_at(tmp_path, [[cond(by_entity(["Other"], c))]], extra=[OTHER_SPEEDS_UP])[0] == 8


def test_acceleration_condition(tmp_path):
    # Other speeds up at 2 m/s^2 from t = 1.0 (step 5): the acceleration over [1.0, 1.2] is seen at step 6
    late = group("Up", ["Other"], [event("up", [("up", speed(20, "linear", "rate", 2.0))],
                                         trigger([cond(sim_time(1.0))]))])
    c = '<AccelerationCondition value="1.0" rule="greaterThan"/>'
    k, tr = fires_at(tmp_path, [[cond(by_entity(["Other"], c))]], extra=[late])
    assert k == 6
    assert tr.a[5, tr.names.index("Other")] == 0.0 and tr.a[6, tr.names.index("Other")] == pytest.approx(2.0)


def test_reach_position_condition(tmp_path):
    # Ego's reference point at s = 4k within 2 m of s = 40.5: k = 10 (0.5 m; k = 9 is 4.5 m away)
    c = (f'<ReachPositionCondition tolerance="2.0"><Position>{world_pos(40.5, -1.75)}</Position>'
         '</ReachPositionCondition>')
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == 10


def test_traveled_distance_condition(tmp_path):
    c = '<TraveledDistanceCondition value="30.5"/>'  # 4k >= 30.5: k = 8
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == 8


def test_stand_still_condition(tmp_path):
    # Other brakes from 4 m/s at 2 m/s^2 from t = 0: at rest from t = 2.0 (k = 10); standing still
    # for 0.5 s first holds at t = 2.6 (k = 13: 0.6 s; at k = 12 it has stood for 0.4 s)
    start = dict(START, Other=(-3, 0.0, 4.0))
    brake = group("Brake", ["Other"], [event("brake", [("brake", speed(0, "linear", "rate", 2.0))],
                                             trigger([cond(sim_time(0))]))])
    c = '<StandStillCondition duration="0.5"/>'
    k, tr = fires_at(tmp_path, [[cond(by_entity(["Other"], c))]], extra=[brake], start=start)
    j = tr.names.index("Other")
    assert tr.v[9, j] == pytest.approx(0.4) and tr.v[10, j] == 0.0
    assert k == 13


@pytest.mark.parametrize("freespace, expected", [
    (False, 13),  # |60.5 - 4k| < 10: k > 12.625
    (True, 12),  # from Ego's contour (front at 4k + 3.9): 56.6 - 4k < 10: k > 11.65
])
def test_distance_condition(tmp_path, freespace, expected):
    c = (f'<DistanceCondition value="10" freespace="{str(freespace).lower()}" rule="lessThan" '
         f'relativeDistanceType="euclidianDistance" coordinateSystem="entity"><Position>{world_pos(60.5, -1.75)}'
         f'</Position></DistanceCondition>')
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == expected


def test_distance_condition_euclidean_across(tmp_path):
    # a point 4 m to the side of Ego's lane: sqrt((60.5 - 4k)^2 + 16) < 10 -> |60.5 - 4k| < 9.165 -> k > 12.83 -> 13;
    # with 8.5: |60.5 - 4k| < 7.5 -> k > 13.25 -> 14 (a longitudinal distance would give 13)
    c = (f'<DistanceCondition value="8.5" freespace="false" rule="lessThan" relativeDistanceType="euclidianDistance" '
         f'coordinateSystem="entity"><Position>{world_pos(60.5, -5.75)}</Position></DistanceCondition>')
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c))]])[0] == 14


def test_collision_condition(tmp_path):
    # an obstacle standing in Ego's lane at s = 30 (its rear at 28.9): Ego's front 4k + 3.9 > 28.9 at k = 7
    entities = [vehicle(n) for n in ("Ego", "Lead", "Other", "Target")] + [vehicle("Box", "MiscObject")]
    init = init_of(dict(START, Lead=(-2, 200.0, 10.0))) + [private("Box", teleport(lane_pos(-1, 30.0)))]
    c = '<CollisionCondition><EntityRef entityRef="Box"/></CollisionCondition>'
    path = write(tmp_path, init, [respond([cond(by_entity(["Ego"], c))])], entities=entities)
    result, tr = run_file(path, load_controller("constant"), duration=3.0)
    assert fired(tr) == 7
    assert result["collided"] and result["collision_with"] == "Box" and result["collision_t"] == pytest.approx(1.4)


# ---------------------------------------------------------------- delays, edges, groups, rules
def test_condition_delay(tmp_path):
    # t >= 0.5 holds from step 3 (t = 0.6); delayed 1 s: from t = 1.6 (step 8)
    assert fires_at(tmp_path, [[cond(sim_time(0.5), delay=1.0)]])[0] == 8


def test_condition_delay_of_an_entity_condition(tmp_path):
    # traveled 30.5 m at step 8 (t = 1.6); delayed 0.4 s: step 10
    c = '<TraveledDistanceCondition value="30.5"/>'
    assert fires_at(tmp_path, [[cond(by_entity(["Ego"], c), delay=0.4)]])[0] == 10


@pytest.mark.parametrize("rule, edge, expected", [
    ("greaterThan", "none", 8),  # false, then true from k = 8
    ("greaterThan", "rising", 8),
    ("lessThan", "none", 0),  # true at once
    ("lessThan", "rising", None),  # true from the first evaluation: never rises
    ("lessThan", "falling", 8),  # true until k = 7, false from 8
    ("lessThan", "risingOrFalling", 8),
])
def test_condition_edges(tmp_path, rule, edge, expected):
    c = cond(by_entity(["Other"], speed_cond(13.1, rule)), edge=edge)
    assert fires_at(tmp_path, [[c]], extra=[OTHER_SPEEDS_UP])[0] == expected


def test_a_rising_edge_fires_once_and_again_on_the_next_rise(tmp_path):
    # Other: up to 15 m/s by 1 m/s^2 from t = 0 (v = 10 + 0.2 k), then down to 10 from t = 6.0 by 1 m/s^2
    # (v = 15 - 0.2 (k - 30)); "speed > 12.1" rises at k = 11 and falls at k = 45 (15 - 0.2*15 = 12.0)
    updown = group("UpDown", ["Other"], [
        event("up", [("up", speed(15, "linear", "rate", 1.0))], trigger([cond(sim_time(0))]), priority="parallel"),
        event("down", [("down", speed(10, "linear", "rate", 1.0))], trigger([cond(sim_time(6.0))]),
              priority="parallel")])
    step_up = speed(1.0, relative="Target")
    for edge, expected in (("rising", {10: 10.0, 11: 11.0, 44: 11.0, 45: 11.0}),
                           ("falling", {44: 10.0, 45: 11.0, 46: 11.0}),
                           ("risingOrFalling", {10: 10.0, 11: 11.0, 44: 11.0, 45: 12.0, 46: 12.0})):
        c = cond(by_entity(["Other"], speed_cond(12.1)), edge=edge)
        _, tr = run(tmp_path, [respond([c], count=5, action=step_up), updown], duration=9.4)
        j = tr.names.index("Target")
        assert {k: round(float(tr.v[k, j]), 9) for k in expected} == expected, edge


def test_condition_groups_are_or_ed(tmp_path):
    assert fires_at(tmp_path, [[cond(sim_time(2.1))], [cond(sim_time(1.1))]])[0] == 6


def test_conditions_in_a_group_are_and_ed(tmp_path):
    travelled = cond(by_entity(["Ego"], '<TraveledDistanceCondition value="30.5"/>'))  # k = 8
    assert fires_at(tmp_path, [[cond(sim_time(0.5)), travelled]])[0] == 8  # t >= 0.5 from k = 3
    assert fires_at(tmp_path, [[cond(sim_time(2.1)), travelled]])[0] == 11  # t >= 2.1 from k = 11
    assert fires_at(tmp_path, [[cond(sim_time(2.1)), travelled], [cond(sim_time(3.1))]])[0] == 11


@pytest.mark.parametrize("rule, expected", [
    ("any", 0),  # Ego at 20 m/s > 15.1 at once
    ("all", 13),  # Other too: 10 + 0.4 k > 15.1 from k = 13
])
def test_triggering_entities_rule(tmp_path, rule, expected):
    c = cond(by_entity(["Ego", "Other"], speed_cond(15.1), rule=rule))
    assert fires_at(tmp_path, [[c]], extra=[OTHER_SPEEDS_UP])[0] == expected


def test_conditions_see_the_snapshot_at_the_steps_start(tmp_path):
    # two conditions on the same step: Target fires on Other's speed > 13.1 (k = 8); Other's own
    # speed-up is started by Target's speed (Target > 20) -- which is seen one step after Target's change
    other_on_target = group("Up", ["Other"], [event("up", [("up", speed(20, "step"))], trigger(
        [cond(by_entity(["Target"], speed_cond(20.0)))]))])
    k, tr = fires_at(tmp_path, [[cond(sim_time(1.0))]], extra=[other_on_target])
    assert k == 5
    assert fired(tr, "Other") == 6


def test_the_world_counts_steps_without_drift(tmp_path):
    path = write(tmp_path, init_of(), [respond([cond(sim_time(1e5))])])
    w = World(read(path))
    w.start()
    for _ in range(1000):
        w.update()
        w.move(DT)
    assert w.t == 1000 * DT and w.bodies["Ego"].s == pytest.approx(20.0 * 200.0, abs=1e-6)
