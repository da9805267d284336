"""OpenSCENARIO actions against hand computation: transitions, targets, positions, priorities,
the conflict rule, the ego under test and the reader's errors.

The scenarios run on the default road (lanes 3.5 m wide: lane -1's centre at t = -1.75, lane -2's
at -5.25, lane -3's at -8.75, lane 1's at +1.75) or on a tiny OpenDRIVE road written next to
them, in steps of 0.2 s. Vehicles have the bounding box centre x = 1.4, length 5, width 2 (front
3.9 m ahead of the reference point, rear 1.1 m behind it). Unless a test says otherwise the ego
keeps its scripted motion (its controller is activated only at t = 1e6 s). The actions under
test start at t = 1.0 s (step 5): ``tau = t - 1`` is the time since.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from acc_gym.evaluation.runner import load_controller
from acc_gym.scenarios.openscenario import OpenScenarioError, read, run_file

DT = 0.2
K0 = 5  # the step at which the actions under test start (t = 1.0)


# --- a minimal OpenSCENARIO file, built from pieces
def vehicle(name):
    return (f'<ScenarioObject name="{name}"><Vehicle name="{name}_model" vehicleCategory="car">'
            f'<ParameterDeclarations/><BoundingBox><Center x="1.4" y="0" z="0.75"/>'
            f'<Dimensions length="5" width="2" height="1.5"/></BoundingBox>'
            f'<Performance maxSpeed="70" maxAcceleration="10" maxDeceleration="10"/>'
            f'<Axles><FrontAxle maxSteering="0.5" wheelDiameter="0.6" trackWidth="1.8" positionX="2.8" '
            f'positionZ="0.3"/><RearAxle maxSteering="0" wheelDiameter="0.6" trackWidth="1.8" positionX="0" '
            f'positionZ="0.3"/></Axles><Properties/></Vehicle></ScenarioObject>')


def lane_pos(lane, s, offset=0.0):
    return f'<LanePosition roadId="0" laneId="{lane}" s="{s}" offset="{offset}"/>'


def teleport(pos):
    return f"<PrivateAction><TeleportAction><Position>{pos}</Position></TeleportAction></PrivateAction>"


def speed(target, shape="step", dim="time", value=0.0, relative=None, vtype="delta", continuous=False):
    tgt = (f'<AbsoluteTargetSpeed value="{target}"/>' if relative is None else
           f'<RelativeTargetSpeed entityRef="{relative}" value="{target}" speedTargetValueType="{vtype}" '
           f'continuous="{str(continuous).lower()}"/>')
    return (f'<PrivateAction><LongitudinalAction><SpeedAction><SpeedActionDynamics dynamicsShape="{shape}" '
            f'value="{value}" dynamicsDimension="{dim}"/><SpeedActionTarget>{tgt}</SpeedActionTarget>'
            f'</SpeedAction></LongitudinalAction></PrivateAction>')


def distance_action(entity, distance=None, time_gap=None, freespace=False, continuous=False,
                    displacement="trailingReferencedEntity"):
    what = f'distance="{distance}"' if distance is not None else f'timeGap="{time_gap}"'
    return (f'<PrivateAction><LongitudinalAction><LongitudinalDistanceAction entityRef="{entity}" {what} '
            f'freespace="{str(freespace).lower()}" continuous="{str(continuous).lower()}" '
            f'displacement="{displacement}" coordinateSystem="entity"/></LongitudinalAction></PrivateAction>')


def lane_change(target, shape="sinusoidal", dim="time", value=3.0, offset=0.0):
    return (f'<PrivateAction><LateralAction><LaneChangeAction targetLaneOffset="{offset}">'
            f'<LaneChangeActionDynamics dynamicsShape="{shape}" value="{value}" dynamicsDimension="{dim}"/>'
            f'<LaneChangeTarget>{target}</LaneChangeTarget></LaneChangeAction></LateralAction></PrivateAction>')


def absolute_lane(lane):
    return f'<AbsoluteTargetLane value="{lane}"/>'


def relative_lane(entity, value):
    return f'<RelativeTargetLane entityRef="{entity}" value="{value}"/>'


def lane_offset(offset, acc, shape="sinusoidal"):
    return (f'<PrivateAction><LateralAction><LaneOffsetAction continuous="false">'
            f'<LaneOffsetActionDynamics maxLateralAcc="{acc}" dynamicsShape="{shape}"/><LaneOffsetTarget>'
            f'<AbsoluteTargetLaneOffset value="{offset}"/></LaneOffsetTarget></LaneOffsetAction></LateralAction>'
            f'</PrivateAction>')


def private(entity, *actions):
    return f'<Private entityRef="{entity}">{"".join(actions)}</Private>'


def cond(inner, name="c"):
    return f'<Condition name="{name}" delay="0" conditionEdge="none">{inner}</Condition>'


def sim_time(value):
    return f'<ByValueCondition><SimulationTimeCondition value="{value}" rule="greaterOrEqual"/></ByValueCondition>'


def state(kind, ref, st):
    return (f'<ByValueCondition><StoryboardElementStateCondition storyboardElementType="{kind}" '
            f'storyboardElementRef="{ref}" state="{st}"/></ByValueCondition>')


def trigger(*conditions):
    return f"<StartTrigger><ConditionGroup>{''.join(conditions)}</ConditionGroup></StartTrigger>"


def at(t):
    return trigger(cond(sim_time(t)))


def event(name, actions, start, priority="override", count=1):
    acts = "".join(f'<Action name="{n}">{a}</Action>' for n, a in actions)
    return f'<Event name="{name}" priority="{priority}" maximumExecutionCount="{count}">{acts}{start}</Event>'


def group(name, actors, events, count=1):
    refs = "".join(f'<EntityRef entityRef="{e}"/>' for e in actors)
    return (f'<ManeuverGroup maximumExecutionCount="{count}" name="{name}"><Actors selectTriggeringEntities="false">'
            f'{refs}</Actors><Maneuver name="{name}_maneuver">{"".join(events)}</Maneuver></ManeuverGroup>')


ACTIVATE = '<PrivateAction><ActivateControllerAction longitudinal="true" lateral="false"/></PrivateAction>'


def write(tmp_path, init, groups=(), *, names=("Ego", "Target", "Ref", "Other"), road="", rev=(1, 2),
          hold_ego=True, name="t.xosc"):
    groups = list(groups)
    if hold_ego:
        groups.append(group("EgoHold", ["Ego"], [event("activate", [("activate", ACTIVATE)], at(1e6))]))
    text = ('<?xml version="1.0" encoding="UTF-8"?>\n<OpenSCENARIO>\n'
            f'<FileHeader revMajor="{rev[0]}" revMinor="{rev[1]}" date="2024-01-01T00:00:00" description="t" '
            f'author="t"/>\n<ParameterDeclarations/>\n<CatalogLocations/>\n<RoadNetwork>{road}</RoadNetwork>\n'
            '<Entities>\n' + "\n".join(vehicle(n) for n in names) + '\n</Entities>\n<Storyboard>\n<Init><Actions>\n'
            + "\n".join(init) + '\n</Actions></Init>\n<Story name="S"><Act name="A">\n' + "\n".join(groups)
            + f'\n{at(0)}</Act></Story>\n<StopTrigger/>\n</Storyboard>\n</OpenSCENARIO>\n')
    p = Path(tmp_path) / name
    p.write_text(text)
    return p


# Ego in lane -1 at s = 0, Target in lane -2 at s = 20, Ref in lane -3 at s = 0, Other in lane -4: all at 10 m/s
START = {"Ego": (-1, 0.0, 10.0), "Target": (-2, 20.0, 10.0), "Ref": (-3, 0.0, 10.0), "Other": (-4, 0.0, 10.0)}


def init_of(start=START):
    return [private(n, teleport(lane_pos(ln, s)), speed(v)) for n, (ln, s, v) in start.items()]


def run(tmp_path, groups, start=START, duration=8.0, controller="constant", **kw):
    path = write(tmp_path, init_of(start), groups, **kw)
    return run_file(path, load_controller(controller), duration=duration)


def on_target(*actions, t=1.0, priority="override"):
    """One event on Target at ``t`` with the ``actions`` (name, xml)."""
    return group("G", ["Target"], [event("E", list(actions), at(t), priority=priority)])


def column(tr, entity, what="v"):
    return getattr(tr, what)[:, tr.names.index(entity)]


def tau_of(tr):
    return tr.t - 1.0


# ---------------------------------------------------------------- SpeedAction
def test_linear_by_rate_is_v0_plus_rate_t_and_ends_at_the_target(tmp_path):
    _, tr = run(tmp_path, [on_target(("a", speed(20, "linear", "rate", 2.0)))])  # 10 -> 20 at 2 m/s^2: 5 s
    v, s, a, tau = column(tr, "Target"), column(tr, "Target", "s"), column(tr, "Target", "a"), tau_of(tr)
    during = (tau >= 0) & (tau <= 5.0 + 1e-9)
    np.testing.assert_allclose(v[during], 10.0 + 2.0 * tau[during], atol=1e-9)
    np.testing.assert_allclose(s[during], 30.0 + 10.0 * tau[during] + tau[during] ** 2, atol=1e-9)
    assert np.all(v[tau < 0] == 10.0) and np.all(v[tau >= 5.0 - 1e-9] == pytest.approx(20.0, abs=1e-12))
    np.testing.assert_allclose(a[K0 + 1:K0 + 26], 2.0, atol=1e-9)
    assert a[K0 + 26] == pytest.approx(0.0, abs=1e-9)
    after = tau > 5.0
    np.testing.assert_allclose(s[after], 30.0 + 75.0 + 20.0 * (tau[after] - 5.0), atol=1e-9)


def test_a_transition_ending_inside_a_step_is_integrated_exactly(tmp_path):
    # 10 -> 20 at 3 m/s^2: T = 10/3 s, ends between the steps at tau = 3.2 and 3.4
    _, tr = run(tmp_path, [on_target(("a", speed(20, "linear", "rate", 3.0)))])
    v, s, tau = column(tr, "Target"), column(tr, "Target", "s"), tau_of(tr)
    T = 10.0 / 3.0
    expect_v = np.where(tau < 0, 10.0, np.where(tau < T, 10.0 + 3.0 * tau, 20.0))
    x = np.clip(tau, 0.0, T)
    expect_s = np.where(tau < 0, 20.0 + 10.0 * tr.t, 30.0 + 10.0 * x + 1.5 * x ** 2 + 20.0 * np.clip(tau - T, 0, None))
    np.testing.assert_allclose(v, expect_v, atol=1e-9)
    np.testing.assert_allclose(s, expect_s, atol=1e-9)


def test_linear_by_time(tmp_path):
    _, tr = run(tmp_path, [on_target(("a", speed(20, "linear", "time", 4.0)))])
    v, tau = column(tr, "Target"), tau_of(tr)
    np.testing.assert_allclose(v, np.where(tau < 0, 10.0, 10.0 + 2.5 * np.clip(tau, 0.0, 4.0)), atol=1e-9)


@pytest.mark.parametrize("shape", ["linear", "cubic", "sinusoidal"])
def test_by_distance_covers_the_distance_during_the_transition(tmp_path, shape):
    # 10 -> 20 over 60 m: T = 2 x 60 / 30 = 4 s, from step 5 to step 25
    _, tr = run(tmp_path, [on_target(("a", speed(20, shape, "distance", 60.0)))])
    v, s = column(tr, "Target"), column(tr, "Target", "s")
    assert s[K0 + 20] - s[K0] == pytest.approx(60.0, abs=1e-9)
    assert v[K0 + 19] < 20.0 - 1e-6 and v[K0 + 20] == pytest.approx(20.0, abs=1e-12)


SHAPES = {"cubic": lambda x: 3 * x * x - 2 * x ** 3, "sinusoidal": lambda x: 0.5 * (1 - np.cos(np.pi * x))}


@pytest.mark.parametrize("shape, rate, T", [
    ("cubic", 2.0, 6.0),  # T = 3/2 x 8 / 2
    ("sinusoidal", math.pi / 2 * 8 / 6.4, 6.4),  # T = pi/2 x 8 / rate
])
def test_cubic_and_sinusoidal_by_rate_peak_at_the_rate(tmp_path, shape, rate, T):
    _, tr = run(tmp_path, [on_target(("a", speed(18, shape, "rate", rate)))], duration=8.4)  # 10 -> 18
    v, tau = column(tr, "Target"), tau_of(tr)
    x = np.clip(tau / T, 0.0, 1.0)
    np.testing.assert_allclose(v, 10.0 + 8.0 * SHAPES[shape](x), atol=1e-9)
    mid = K0 + round(T / 2 / DT)
    assert tr.t[mid] == pytest.approx(1.0 + T / 2)
    assert v[mid] == pytest.approx(14.0, abs=1e-9)  # half the change at half the time
    assert v[K0 + round(T / DT)] == pytest.approx(18.0, abs=1e-9) and v[K0 + round(T / DT) - 1] < 18.0 - 1e-6
    central = (v[2:] - v[:-2]) / (2 * DT)  # the rate of change; its peak at mid-time is the value
    assert central.max() == pytest.approx(rate, abs=5e-3)
    assert int(np.argmax(central)) + 1 == mid


def test_step(tmp_path):
    _, tr = run(tmp_path, [on_target(("a", speed(25)))])
    v, s = column(tr, "Target"), column(tr, "Target", "s")
    assert np.all(v[:K0] == 10.0) and np.all(v[K0:] == 25.0)
    assert s[K0 + 1] - s[K0] == pytest.approx(5.0) and s[K0] - s[K0 - 1] == pytest.approx(2.0)


@pytest.mark.parametrize("vtype, value, target", [("delta", 3.0, 15.0), ("factor", 1.5, 18.0)])
def test_relative_target_speed_is_taken_when_the_action_starts(tmp_path, vtype, value, target):
    # Ref at 12 m/s; Target to Ref's speed +3 (x 1.5) in 2 s; Ref then speeds up to 20 at t = 4: not followed
    start = dict(START, Ref=(-3, 0.0, 12.0))
    ref_up = group("RefUp", ["Ref"], [event("up", [("up", speed(20))], at(4.0))])
    _, tr = run(tmp_path, [on_target(("a", speed(value, "linear", "time", 2.0, relative="Ref", vtype=vtype))), ref_up],
                start=start)
    v, tau = column(tr, "Target"), tau_of(tr)
    np.testing.assert_allclose(v, 10.0 + (target - 10.0) * np.clip(tau / 2.0, 0.0, 1.0), atol=1e-9)
    assert column(tr, "Ref")[-1] == 20.0 and v[-1] == pytest.approx(target)


@pytest.mark.parametrize("names", [("Ego", "Target", "Ref", "Other"), ("Ego", "Ref", "Target", "Other")])
def test_continuous_relative_speed_follows_the_reference(tmp_path, names):
    # Target to Ref + 3 m/s in 1 s (steps 5-10), continuous; Ref speeds up at 1 m/s^2 from t = 3 (step 15)
    # to 17 m/s: Target's speed is Ref's + 3 at every step from 10, its position the integral of it
    ref_up = group("RefUp", ["Ref"], [event("up", [("up", speed(17, "linear", "rate", 1.0))], at(3.0))])
    act = ("a", speed(3.0, "linear", "time", 1.0, relative="Ref", continuous=True))
    _, tr = run(tmp_path, [on_target(act), ref_up], names=names, duration=11.0)
    v, vr = column(tr, "Target"), column(tr, "Ref")
    s, sr = column(tr, "Target", "s"), column(tr, "Ref", "s")
    np.testing.assert_allclose(v[K0:K0 + 6], 10.0 + 3.0 * np.arange(6) / 5.0, atol=1e-9)  # 10 -> 13 in 1 s
    np.testing.assert_allclose(v[K0 + 5:], vr[K0 + 5:] + 3.0, atol=1e-9)
    assert vr[-1] == pytest.approx(17.0)
    # from step 10 on, Target moves as Ref does plus 3 m/s x 0.2 s each step
    np.testing.assert_allclose(np.diff(s[K0 + 5:]), np.diff(sr[K0 + 5:]) + 0.6, atol=1e-9)


def test_continuous_factor_by_a_step_follows_the_reference_at_once(tmp_path):
    ref_up = group("RefUp", ["Ref"], [event("up", [("up", speed(17, "linear", "rate", 1.0))], at(3.0))])
    act = ("a", speed(1.5, relative="Ref", vtype="factor", continuous=True))
    _, tr = run(tmp_path, [on_target(act), ref_up], duration=11.0)
    v, vr = column(tr, "Target"), column(tr, "Ref")
    s, sr = column(tr, "Target", "s"), column(tr, "Ref", "s")
    assert v[K0 - 1] == 10.0
    np.testing.assert_allclose(v[K0:], 1.5 * vr[K0:], atol=1e-9)
    np.testing.assert_allclose(np.diff(s[K0:]), 1.5 * np.diff(sr[K0:]), atol=1e-9)
    assert v[-1] == pytest.approx(25.5)


# ---------------------------------------------------------------- SpeedProfileAction
def profile(*entries, relative=None, follow=False, max_acc=None, max_dec=None):
    """A SpeedProfileAction of ``entries`` ``(time or None, speed)``."""
    dc = "" if max_acc is None else (f'<DynamicConstraints maxAcceleration="{max_acc}" '
                                     f'maxDeceleration="{max_dec}"/>')
    es = "".join(f'<SpeedProfileEntry speed="{v}"' + ("" if t is None else f' time="{t}"') + "/>" for t, v in entries)
    ref = "" if relative is None else f' entityRef="{relative}"'
    mode = "follow" if follow else "position"
    return (f'<PrivateAction><LongitudinalAction><SpeedProfileAction{ref} followingMode="{mode}">\n{dc}{es}'
            f'</SpeedProfileAction></LongitudinalAction></PrivateAction>')


def piecewise_linear(T, V, t):
    """Hand computation: speed (the value reached at t) and distance since T[0] of the speed
    linear between the vertices (T, V), held after the last."""
    v, d = V[0], 0.0
    for Ta, Tb, va, vb in zip(T, T[1:], V, V[1:]):
        if t <= Ta:
            break
        if Tb == Ta:
            v = vb
            continue
        te = min(t, Tb)
        ve = va + (vb - va) * (te - Ta) / (Tb - Ta)
        d += 0.5 * (va + ve) * (te - Ta)
        v = ve
    if t > T[-1]:
        d += V[-1] * (t - T[-1])
    return v, d


@pytest.mark.parametrize("entries, T, V, kw", [
    # 10 -> 16 over 1.3 s (ends off the 0.2 s grid), a change at once to 12, held 2 s, to 0 in 1 s
    (((1.3, 16), (0.0, 12), (2.0, 12), (1.0, 0)), (1.0, 2.3, 2.3, 4.3, 5.3), (10, 16, 12, 12, 0), {}),
    # speeds relative to Ref's (10 m/s) when the action starts
    (((1.0, -4), (2.0, 5)), (1.0, 2.0, 4.0), (10, 6, 15), dict(relative="Ref")),
    # entries without times at the constraints' limits: 10 -> 16 at 2 m/s^2 (3 s), -> 8 at 4 m/s^2 (2 s)
    (((None, 16), (None, 8)), (1.0, 4.0, 6.0), (10, 16, 8), dict(max_acc=2.0, max_dec=4.0)),
    # an entry asking 12 m/s^2 where 2 are allowed takes the 3 s the limit needs
    (((0.5, 16),), (1.0, 4.0), (10, 16), dict(max_acc=2.0, max_dec=4.0)),
])
def test_speed_profile_is_linear_between_entries_and_integrated_exactly(tmp_path, entries, T, V, kw):
    result, tr = run(tmp_path, [on_target(("p", profile(*entries, **kw)))])
    v, s = column(tr, "Target"), column(tr, "Target", "s")
    for k, t in enumerate(tr.t):
        if t < 1.0:
            assert v[k] == 10.0 and s[k] == pytest.approx(20.0 + 10.0 * t, abs=1e-9)
            continue
        vh, dh = piecewise_linear(T, V, t)
        assert v[k] == pytest.approx(vh, abs=1e-9), t
        assert s[k] == pytest.approx(30.0 + dh, abs=1e-9), t
    assert any("beyond the dynamic constraints" in n for n in result["notes"]) == (entries == ((0.5, 16),))


def test_speed_profile_starting_with_a_time_of_zero_sets_the_speed_at_once(tmp_path):
    _, tr = run(tmp_path, [on_target(("p", profile((0.0, 4), (1.0, 4))))])
    v, s = column(tr, "Target"), column(tr, "Target", "s")
    assert v[K0 - 1] == 10.0 and v[K0] == 4.0 and np.all(v[K0:] == 4.0)
    np.testing.assert_allclose(s[K0:], 30.0 + 4.0 * tau_of(tr)[K0:], atol=1e-9)


@pytest.mark.parametrize("entries, kw, msg", [
    (((1.0, 5),), dict(follow=True), "followingMode 'follow'"),
    (((None, 5),), {}, "without a time needs DynamicConstraints"),
    (((-1.0, 5),), {}, "time must be >= 0"),
])
def test_speed_profiles_the_reader_refuses(tmp_path, entries, kw, msg):
    path = write(tmp_path, init_of(), [on_target(("p", profile(*entries, **kw)))])
    with pytest.raises(OpenScenarioError, match=msg) as e:
        read(path)
    text = path.read_text()
    tag = "SpeedProfileAction" if "follow" in msg else "SpeedProfileEntry"
    assert e.value.line == text[:text.index(f"<{tag}")].count("\n") + 1


# ---------------------------------------------------------------- LongitudinalDistanceAction
# Ref ahead in lane -2 at s = 100, 15 m/s; Target in lane -2 at s = 20, 10 m/s; placed at step 5
DIST_START = dict(START, Ref=(-2, 100.0, 15.0))


@pytest.mark.parametrize("kw, gap", [
    (dict(distance=30.0), 30.0),  # between the reference points
    (dict(distance=30.0, freespace=True), 30.0 + 5.0),  # between the contours: 3.9 + 1.1 more
    (dict(time_gap=2.0), 30.0),  # 2 s at the follower's speed, Ref's 15 m/s once placed
    (dict(time_gap=2.0, freespace=True), 35.0),
])
def test_longitudinal_distance_places_the_target_behind_its_reference(tmp_path, kw, gap):
    _, tr = run(tmp_path, [on_target(("d", distance_action("Ref", **kw)))], start=DIST_START, duration=3.0)
    s, sr, v = column(tr, "Target", "s"), column(tr, "Ref", "s"), column(tr, "Target")
    assert s[K0 - 1] == pytest.approx(20.0 + 10.0 * 0.8)
    np.testing.assert_allclose(sr[K0:] - s[K0:], gap, atol=1e-9)  # placed at once and kept (both at 15 m/s)
    assert sr[K0] == pytest.approx(115.0) and np.all(v[K0:] == 15.0)
    if "time_gap" in kw:  # the time headway once placed is the time gap
        free = sr[K0] - s[K0] - (5.0 if kw.get("freespace") else 0.0)
        assert free / v[K0] == pytest.approx(2.0)


def test_longitudinal_distance_leading(tmp_path):
    _, tr = run(tmp_path, [on_target(("d", distance_action("Ref", distance=12.0, freespace=True,
                                                          displacement="leadingReferencedEntity")))],
                start=DIST_START, duration=2.0)
    s, sr = column(tr, "Target", "s"), column(tr, "Ref", "s")
    np.testing.assert_allclose(s[K0:] - sr[K0:], 12.0 + 5.0, atol=1e-9)  # Target's rear 12 m ahead of Ref's front


def test_continuous_longitudinal_distance_keeps_the_distance_while_the_reference_brakes(tmp_path):
    ref_brake = group("RefBrake", ["Ref"], [event("brake", [("brake", speed(5, "linear", "rate", 2.0))], at(2.0))])
    _, tr = run(tmp_path, [on_target(("d", distance_action("Ref", distance=30.0, continuous=True))), ref_brake],
                start=DIST_START, duration=8.0)
    s, sr, v, vr = column(tr, "Target", "s"), column(tr, "Ref", "s"), column(tr, "Target"), column(tr, "Ref")
    np.testing.assert_allclose(sr[K0:] - s[K0:], 30.0, atol=1e-9)
    np.testing.assert_allclose(v[K0:], vr[K0:], atol=1e-12)
    assert vr[-1] == pytest.approx(5.0)


# ---------------------------------------------------------------- LaneChangeAction
def test_lane_change_absolute_sinusoidal_by_rate(tmp_path):
    # lane -2 (t = -5.25) to lane -3 (t = -8.75): 3.5 m at a peak lateral speed of 1 m/s: T = pi/2 x 3.5 s
    _, tr = run(tmp_path, [on_target(("lc", lane_change(absolute_lane(-3), "sinusoidal", "rate", 1.0)))],
                duration=8.0)
    y, tau = column(tr, "Target", "y"), tau_of(tr)
    T = math.pi / 2 * 3.5
    np.testing.assert_allclose(y, -5.25 - 3.5 * SHAPES["sinusoidal"](np.clip(tau / T, 0, 1)), atol=1e-9)
    assert y[-1] == -8.75
    assert int(np.flatnonzero(y == -8.75)[0]) == math.ceil((1.0 + T) / DT)  # ends at t = 1 + 5.498: step 33
    lat = (y[:-2] - y[2:]) / (2 * DT)
    assert lat.max() == pytest.approx(1.0, abs=5e-3)


def test_lane_change_by_time(tmp_path):
    _, tr = run(tmp_path, [on_target(("lc", lane_change(absolute_lane(-1), "linear", "time", 2.0)))], duration=4.0)
    y = column(tr, "Target", "y")
    np.testing.assert_allclose(y[K0:K0 + 11], -5.25 + 3.5 * np.arange(11) / 10, atol=1e-9)
    assert np.all(y[K0 + 10:] == -1.75) and np.all(y[:K0 + 1] == -5.25)


def test_lane_change_by_distance(tmp_path):
    # 40 m at 10 m/s: T = 4 s, from step 5 to step 25
    _, tr = run(tmp_path, [on_target(("lc", lane_change(absolute_lane(-3), "cubic", "distance", 40.0)))])
    y, s = column(tr, "Target", "y"), column(tr, "Target", "s")
    end = int(np.flatnonzero(y == -8.75)[0])
    assert end == K0 + 20 and s[end] - s[K0] == pytest.approx(40.0)
    assert y[K0 + 10] == pytest.approx(-5.25 - 1.75, abs=1e-9)  # half way at half the distance


@pytest.mark.parametrize("value, offset, y1", [
    (-1, 0.0, -5.25),  # one to the right of Ego's lane -1: lane -2, where Target already is (no move)
    (1, 0.0, 1.75),  # one to the left of lane -1 is lane 1, across the reference line (no lane 0)
    (-2, 0.5, -8.75 + 0.5),  # two to the right, with a target lane offset
])
def test_lane_change_relative_target_lane(tmp_path, value, offset, y1):
    lc = lane_change(relative_lane("Ego", value), "linear", "time", 2.0, offset=offset)
    _, tr = run(tmp_path, [on_target(("lc", lc))], duration=4.0)
    y = column(tr, "Target", "y")
    assert y[-1] == pytest.approx(y1, abs=1e-12)
    np.testing.assert_allclose(y[K0:K0 + 11], -5.25 + (y1 + 5.25) * np.arange(11) / 10, atol=1e-9)


@pytest.mark.parametrize("shape, T", [
    ("sinusoidal", math.pi * math.sqrt(1.0 / (2 * 0.5))),  # pi sqrt(|dy| / (2 a)) = pi
    ("cubic", math.sqrt(6 * 1.0 / 0.5)),  # sqrt(6 |dy| / a)
])
def test_lane_offset_peaks_at_its_max_lateral_acceleration(tmp_path, shape, T):
    _, tr = run(tmp_path, [on_target(("lo", lane_offset(1.0, 0.5, shape)))], duration=6.0)
    y, tau = column(tr, "Target", "y"), tau_of(tr)
    np.testing.assert_allclose(y, -5.25 + SHAPES[shape](np.clip(tau / T, 0, 1)), atol=1e-9)
    assert y[-1] == pytest.approx(-4.25, abs=1e-12)
    if shape == "sinusoidal":  # its lateral acceleration 0.5 cos(tau): the peak at the start and the end
        inside = (tau > 0.5 * DT) & (tau < T - 0.5 * DT)
        acc = (y[2:] - 2 * y[1:-1] + y[:-2]) / DT ** 2
        assert np.abs(acc[inside[1:-1]]).max() == pytest.approx(0.5 * math.cos(0.2), abs=2e-3)


# ---------------------------------------------------------------- TeleportAction
XODR = """<?xml version="1.0" encoding="UTF-8"?>
<OpenDRIVE><header revMajor="1" revMinor="6" name="r"/>
<road name="r" length="1000" id="0" junction="-1">
<planView><geometry s="0" x="{x0}" y="{y0}" hdg="{hdg}" length="1000"><line/></geometry></planView>
<lanes><laneSection s="0">
<left><lane id="1" type="median" level="false"><width sOffset="0" a="1.0" b="0" c="0" d="0"/></lane>
<lane id="2" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></left>
<center><lane id="0" type="none" level="false"/></center>
<right><lane id="-1" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
<lane id="-2" type="driving" level="false"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
<lane id="-3" type="shoulder" level="false"><width sOffset="0" a="2.0" b="0" c="0" d="0"/></lane></right>
</laneSection></lanes></road></OpenDRIVE>
"""


XODR_START = dict(START, Other=(-2, 200.0, 10.0))  # the road below has no lane -4


def road(tmp_path, x0=0.0, y0=0.0, hdg=0.0):
    (Path(tmp_path) / "road.xodr").write_text(XODR.format(x0=x0, y0=y0, hdg=hdg))
    return '<LogicFile filepath="road.xodr"/><SceneGraphFile filepath=""/>'


@pytest.mark.parametrize("pos, s5, y5, xodr", [
    (lane_pos(-2, 30.0, 0.5), 30.0, -5.25 + 0.5, None),
    # dLane counts driving lanes: one to the left of Ego's lane -1 skips the median (lane 1, t = 0.5)
    ('<RelativeLanePosition entityRef="Ego" dLane="1" ds="10" offset="0"/>', 20.0, 1.0 + 1.75, {}),
    ('<RelativeLanePosition entityRef="Ego" dLane="-1" dsLane="5" offset="0.25"/>', 15.0, -5.25 + 0.25, {}),
    ('<RoadPosition roadId="0" s="40" t="-3"/>', 40.0, -3.0, None),
    ('<RelativeRoadPosition entityRef="Ego" ds="15" dt="-3.5"/>', 25.0, -5.25, None),
    ('<WorldPosition x="130" y="46" z="0" h="0"/>', 30.0, -4.0, dict(x0=100.0, y0=50.0)),
    # a road heading north from (100, 50): s along y, t = -(x - 100)
    ('<WorldPosition x="97" y="80" z="0" h="1.5707963267948966"/>', 30.0, 3.0,
     dict(x0=100.0, y0=50.0, hdg=1.5707963267948966)),
])
def test_teleport(tmp_path, pos, s5, y5, xodr):
    rn = road(tmp_path, **xodr) if xodr is not None else ""
    _, tr = run(tmp_path, [on_target(("tp", teleport(pos)))], road=rn, duration=2.0,
                start=START if xodr is None else XODR_START)
    s, y = column(tr, "Target", "s"), column(tr, "Target", "y")
    assert s[K0] == pytest.approx(s5, abs=1e-9) and y[K0] == pytest.approx(y5, abs=1e-9)  # Ego at s = 10 then
    np.testing.assert_allclose(s[K0:], s5 + 2.0 * np.arange(len(s) - K0), atol=1e-9)  # on along the road
    np.testing.assert_allclose(y[K0:], y5, atol=1e-9)


def test_the_road_lanes_of_an_opendrive_file(tmp_path):
    sc = read(write(tmp_path, init_of(XODR_START), road=road(tmp_path)))
    centres = {k: ln.centre for k, ln in sc.road.lanes.items()}
    assert centres == {1: 0.5, 2: 2.75, -1: -1.75, -2: -5.25, -3: -8.0}
    assert [k for k, ln in sc.road.lanes.items() if not ln.driving] in ([1, -3], [-3, 1])


def test_a_relative_lane_off_the_driving_lanes_is_an_error(tmp_path):
    pos = '<RelativeLanePosition entityRef="Ego" dLane="-2" ds="10" offset="0"/>'  # beyond lane -2: a shoulder
    path = write(tmp_path, init_of(XODR_START), [on_target(("tp", teleport(pos)))], road=road(tmp_path))
    with pytest.raises(OpenScenarioError, match="off the road's driving lanes"):
        run_file(path, load_controller("constant"), duration=2.0)


# ---------------------------------------------------------------- priorities and execution counts
def two_events(priority, rev=(1, 2)):
    """Target: E1 a lane change from lane -2 to -3 in 2 s from t = 0 (steps 0-10), E2 (``priority``)
    a step to 30 m/s from t >= 1; Other (watching E1 and E2) steps to 20 / Ref to 20 on their transitions."""
    e1 = event("E1", [("lc", lane_change(absolute_lane(-3), "linear", "time", 2.0))], at(0), priority="parallel")
    e2 = event("E2", [("fast", speed(30))], at(1.0), priority=priority)
    watch_stop = group("W1", ["Other"], [event("w1", [("w1", speed(20))], trigger(cond(state("event", "E1",
                                                                                                "stopTransition"))))])
    watch_skip = group("W2", ["Ref"], [event("w2", [("w2", speed(20))], trigger(cond(state("event", "E2",
                                                                                              "skipTransition"))))])
    return [group("G", ["Target"], [e1, e2]), watch_stop, watch_skip]


def first_change(x, v0=10.0):
    k = np.flatnonzero(np.abs(x - v0) > 1e-9)
    return int(k[0]) if len(k) else None


@pytest.mark.parametrize("priority, rev", [("override", (1, 2)), ("overwrite", (1, 0))])
def test_override_stops_the_running_event(tmp_path, priority, rev):
    _, tr = run(tmp_path, two_events(priority), duration=4.0, rev=rev)
    y, v = column(tr, "Target", "y"), column(tr, "Target")
    assert first_change(v) == K0 and v[-1] == 30.0
    assert y[K0] == pytest.approx(-7.0) and np.all(y[K0:] == y[K0])  # half way when stopped: it stays there
    assert first_change(column(tr, "Other")) == K0 + 1  # E1's stopTransition, seen a step later
    assert first_change(column(tr, "Ref")) is None


def test_skip_is_not_started_while_another_event_runs(tmp_path):
    _, tr = run(tmp_path, two_events("skip"), duration=4.0)
    y, v = column(tr, "Target", "y"), column(tr, "Target")
    assert first_change(v) == 10  # E1 ends at t = 2.0; E2's trigger still holds then
    assert y[10] == -8.75
    assert first_change(column(tr, "Ref")) == K0 + 1  # E2's skipTransition at step 5
    assert first_change(column(tr, "Other")) is None


def test_parallel_runs_beside_the_others(tmp_path):
    _, tr = run(tmp_path, two_events("parallel"), duration=4.0)
    y, v = column(tr, "Target", "y"), column(tr, "Target")
    assert first_change(v) == K0 and y[10] == -8.75
    np.testing.assert_allclose(y[:11], -5.25 - 3.5 * np.arange(11) / 10, atol=1e-9)
    assert first_change(column(tr, "Other")) is None and first_change(column(tr, "Ref")) is None


def test_maximum_execution_count_of_an_event(tmp_path):
    plus_one = speed(1.0, relative="Target")
    g = group("G", ["Target"], [event("E", [("up", plus_one)], at(1.0), count=3)])
    _, tr = run(tmp_path, [g], duration=3.0)
    v = column(tr, "Target")
    assert list(v[K0 - 1:K0 + 5]) == [10.0, 11.0, 12.0, 13.0, 13.0, 13.0]


def test_maximum_execution_count_of_a_maneuver_group(tmp_path):
    plus_one = speed(1.0, relative="Target")
    g = group("G", ["Target"], [event("E", [("up", plus_one)], at(1.0), count=1)], count=2)
    _, tr = run(tmp_path, [g], duration=3.0)
    assert list(column(tr, "Target")[K0 - 1:K0 + 4]) == [10.0, 11.0, 12.0, 12.0, 12.0]


# ---------------------------------------------------------------- conflicting actions
def test_a_new_speed_action_stops_the_running_one(tmp_path):
    first = group("G1", ["Target"], [event("E1", [("first", speed(20, "linear", "time", 4.0))], at(0))])
    second = group("G2", ["Target"], [event("E2", [("second", speed(5))], at(1.0))])
    w_stop = group("W1", ["Other"], [event("w1", [("w1", speed(20))],
                                           trigger(cond(state("action", "first", "stopTransition"))))])
    w_end = group("W2", ["Ref"], [event("w2", [("w2", speed(20))],
                                        trigger(cond(state("action", "first", "endTransition"))))])
    w_done = group("W3", ["Ego"], [event("w3", [("w3", speed(20))],
                                         trigger(cond(state("action", "first", "completeState"))))])
    _, tr = run(tmp_path, [first, second, w_stop, w_end, w_done], duration=6.0)
    v = column(tr, "Target")
    np.testing.assert_allclose(v[:K0], 10.0 + 2.5 * tr.t[:K0], atol=1e-9)
    assert np.all(v[K0:] == 5.0)  # the first no longer pulls it up to 20
    assert first_change(column(tr, "Other")) == K0 + 1  # stopped at step 5: seen at step 6
    assert first_change(column(tr, "Ego")) == K0 + 1  # and complete from then on
    assert first_change(column(tr, "Ref")) is None  # it never ended by itself


def test_a_lateral_action_does_not_stop_a_longitudinal_one(tmp_path):
    first = group("G1", ["Target"], [event("E1", [("first", speed(20, "linear", "time", 4.0))], at(0))])
    second = group("G2", ["Target"], [event("E2", [("lc", lane_change(absolute_lane(-1), "linear", "time", 1.0))],
                                             at(1.0))])
    _, tr = run(tmp_path, [first, second], duration=6.0)
    np.testing.assert_allclose(column(tr, "Target"), 10.0 + 2.5 * np.clip(tr.t, 0, 4.0), atol=1e-9)
    assert column(tr, "Target", "y")[-1] == -1.75


# ---------------------------------------------------------------- the ego under test
def test_the_ego_follows_its_script_until_its_controller_is_activated(tmp_path):
    ego = group("EgoG", ["Ego"], [
        event("speedup", [("speedup", speed(30, "linear", "rate", 1.0))], at(0), priority="parallel"),
        event("activate", [("activate", ACTIVATE)], at(2.0), priority="parallel"),
        event("late", [("late", speed(5))], at(3.0), priority="parallel")])
    # the scripted speed-up still running at the activation is stopped there (seen at step 11)
    watch = group("W", ["Other"], [event("w", [("w", speed(20))],
                                         trigger(cond(state("action", "speedup", "stopTransition"))))])
    start = dict(START, Ego=(-1, 0.0, 20.0))
    result, tr = run(tmp_path, [ego, watch], start=start, duration=8.0, hold_ego=False)
    v, c = column(tr, "Ego"), tr.controlled
    np.testing.assert_allclose(v[:11], 20.0 + 0.2 * np.arange(11), atol=1e-9)  # scripted: +1 m/s^2
    assert not c[:10].any() and c[10:].all()
    assert result["activated_at"] == pytest.approx(2.0)
    # the controller (constant: the set speed, the speed at activation) drives: no 30 m/s, no 5 m/s
    np.testing.assert_allclose(v[10:], 22.0, atol=0.3)
    assert len(result["ignored"]) == 1 and "'late'" in result["ignored"][0] and "t = 3.00 s" in result["ignored"][0]
    assert first_change(column(tr, "Other")) == 11


def test_without_an_activation_the_controller_drives_from_the_start(tmp_path):
    ego = group("EgoG", ["Ego"], [event("brake", [("brake", speed(0, "linear", "rate", 5.0))], at(1.0))])
    result, tr = run(tmp_path, [ego], duration=3.0, hold_ego=False)
    assert tr.controlled.all() and result["activated_at"] == 0.0
    assert len(result["ignored"]) == 1 and "'brake'" in result["ignored"][0]
    np.testing.assert_allclose(column(tr, "Ego"), 10.0, atol=0.3)  # never braked to 0


# ---------------------------------------------------------------- what the reader refuses
def refused(tmp_path, element, groups=None, init=None):
    path = write(tmp_path, init if init is not None else init_of(), groups or [])
    text = path.read_text()
    line = text[:text.index(f"<{element}")].count("\n") + 1
    with pytest.raises(OpenScenarioError) as e:
        read(path)
    msg = str(e.value)
    assert element in msg and f"{path}:{line}:" in msg, msg
    assert e.value.line == line


def test_an_assign_route_action_is_refused(tmp_path):
    route = ('<PrivateAction><RoutingAction>\n<AssignRouteAction><Route name="r" closed="false"><Waypoint '
             f'routeStrategy="shortest"><Position>{lane_pos(-1, 0)}</Position></Waypoint><Waypoint '
             f'routeStrategy="shortest"><Position>{lane_pos(-1, 100)}</Position></Waypoint></Route>'
             '</AssignRouteAction></RoutingAction></PrivateAction>')
    refused(tmp_path, "AssignRouteAction", [on_target(("route", route))])


def test_a_clothoid_trajectory_is_refused(tmp_path):
    traj = ('<PrivateAction><RoutingAction><FollowTrajectoryAction><TrajectoryRef><Trajectory name="tr" '
            'closed="false"><Shape>\n<Clothoid curvature="0" curvatureDot="0" length="10"><Position>'
            f'{lane_pos(-2, 0)}</Position></Clothoid></Shape></Trajectory></TrajectoryRef><TimeReference><None/>'
            '</TimeReference><TrajectoryFollowingMode followingMode="position"/></FollowTrajectoryAction>'
            '</RoutingAction></PrivateAction>')
    refused(tmp_path, "Clothoid", [on_target(("traj", traj))])


def test_a_synchronize_action_is_refused(tmp_path):
    sync = ('<PrivateAction>\n<SynchronizeAction masterEntityRef="Ego"><TargetPositionMaster>'
            f'{lane_pos(-1, 100)}</TargetPositionMaster><TargetPosition>{lane_pos(-2, 100)}</TargetPosition>'
            '</SynchronizeAction></PrivateAction>')
    refused(tmp_path, "SynchronizeAction", [on_target(("sync", sync))])


def test_a_user_defined_action_is_refused(tmp_path):
    refused(tmp_path, "UserDefinedAction", [on_target(("user", '\n<UserDefinedAction><CustomCommandAction '
                                                                'type="brake">now</CustomCommandAction>'
                                                                '</UserDefinedAction>'))])


def test_a_parameter_set_action_is_refused(tmp_path):
    act = '<GlobalAction><ParameterAction parameterRef="x">\n<SetAction value="1"/></ParameterAction></GlobalAction>'
    path = write(tmp_path, init_of(), [on_target(("p", act))])
    with pytest.raises(OpenScenarioError, match="ParameterAction"):
        read(path)


def test_an_end_of_road_condition_is_refused(tmp_path):
    c = ('<ByEntityCondition><TriggeringEntities triggeringEntitiesRule="any"><EntityRef entityRef="Target"/>'
         '</TriggeringEntities><EntityCondition>\n<EndOfRoadCondition duration="0"/></EntityCondition>'
         '</ByEntityCondition>')
    g = group("G", ["Target"], [event("E", [("a", speed(0))], trigger(cond(c)))])
    refused(tmp_path, "EndOfRoadCondition", [g])


def test_a_user_defined_value_condition_is_refused(tmp_path):
    c = '<ByValueCondition>\n<UserDefinedValueCondition name="x" value="1" rule="equalTo"/></ByValueCondition>'
    g = group("G", ["Target"], [event("E", [("a", speed(0))], trigger(cond(c)))])
    refused(tmp_path, "UserDefinedValueCondition", [g])


def test_a_document_type_declaration_is_refused(tmp_path):
    path = write(tmp_path, init_of())
    text = path.read_text().replace('<OpenSCENARIO>', '<!DOCTYPE OpenSCENARIO [<!ENTITY a "aaaa">]>\n<OpenSCENARIO>', 1)
    path.write_text(text)
    with pytest.raises(OpenScenarioError, match=r"DOCTYPE") as e:
        read(path)
    assert e.value.line == 2 and str(path) in str(e.value)


def test_an_unknown_version_is_refused(tmp_path):
    with pytest.raises(OpenScenarioError, match=r"OpenSCENARIO 2\.0 is not read here"):
        read(write(tmp_path, init_of(), rev=(2, 0)))
    assert read(write(tmp_path, init_of(), rev=(1, 0))).version == (1, 0)
