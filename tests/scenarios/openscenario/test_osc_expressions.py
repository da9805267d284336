"""OpenSCENARIO parameters: ``$name``, ``${...}`` expressions and value constraints, against hand values."""

import math

import pytest

from acc_gym.scenarios.openscenario import OpenScenarioError, read
from acc_gym.scenarios.openscenario._xml import parse_bytes
from acc_gym.scenarios.openscenario.expressions import Scope, declare, evaluate, resolve


@pytest.mark.parametrize("text, value", [
    ("1 + 2 * 3", 7.0),
    ("(1 + 2) * 3", 9.0),
    ("-$a * 2", -5.0),
    ("$a / 2 - $b", 1.25 - 3.0),
    ("7 % 3", 1.0),
    ("-7 % 3", -1.0),  # the sign of the dividend, as C's fmod
    ("pow(2, 10)", 1024.0),
    ("sqrt(16) + round(2.5) + round(-2.5) + floor(-1.5) + ceil(1.2)", 4.0 + 3.0 - 3.0 - 2.0 + 2.0),
    ("1.5e1 + .5", 15.5),
    ("$a >= 2.5", True),
    ("$a > 2.5 or $b == 3", True),
    ("not $a > 2.5 and $b != 3", False),
    ("true and not false", True),
    ("($b + 1) * ($a - 0.5) / 4", 2.0),
])
def test_expression_values_match_hand_computation(text, value):
    assert evaluate(text, Scope({"a": 2.5, "b": 3})) == value


@pytest.mark.parametrize("text, match", [
    ("1 / 0", "division by zero"),
    ("$missing + 1", r"uses \$missing, which is not declared"),
    ("exp(1)", "not one of OpenSCENARIO's functions"),
    ("pow(2)", "takes 2 argument"),
    ("sqrt(-1)", "undefined"),
    ("1 +", "unexpected"),
    ("2 $a", "unexpected"),
    ("__import__('os')", "cannot read"),
    ("__import__(1)", "not one of OpenSCENARIO's functions"),
    ("1 ; 2", "cannot read"),
])
def test_bad_expressions_are_errors_naming_the_text(text, match):
    node = parse_bytes(b"<X>\n<Y/></X>", "f.xosc").children[0]
    with pytest.raises(OpenScenarioError, match=match) as e:
        evaluate(text, Scope({"a": 1.0}), node)
    assert str(e.value).startswith("f.xosc:2: ")


def test_references_resolve_and_literals_stay_text():
    s = Scope({"v": 12.5, "name": "car"})
    assert resolve("$v", s) == 12.5
    assert resolve("${$v * 3.6}", s) == pytest.approx(45.0)
    assert resolve("car", s) == "car"
    assert resolve("$name", s) == "car"
    with pytest.raises(OpenScenarioError, match=r"parameter \$w is not declared"):
        resolve("$w", s)


DECLS = b"""<ParameterDeclarations>
  <ParameterDeclaration name="v_kph" parameterType="double" value="60"/>
  <ParameterDeclaration name="v" parameterType="double" value="${$v_kph / 3.6}"/>
  <ParameterDeclaration name="lane" parameterType="int" value="-1">
    <ConstraintGroup><ValueConstraint rule="equalTo" value="1"/></ConstraintGroup>
    <ConstraintGroup><ValueConstraint rule="equalTo" value="-1"/></ConstraintGroup>
  </ParameterDeclaration>
  <ParameterDeclaration name="dv" parameterType="double" value="-20">
    <ConstraintGroup>
      <ValueConstraint rule="lessThan" value="0"/>
      <ValueConstraint rule="greaterThan" value="${-$v_kph}"/>
    </ConstraintGroup>
  </ParameterDeclaration>
  <ParameterDeclaration name="n" parameterType="unsignedInt" value="${2.6 * 2}"/>
  <ParameterDeclaration name="on" parameterType="boolean" value="true"/>
  <ParameterDeclaration name="rng" parameterType="double" value="0.5">
    <ConstraintGroup><Range lowerLimit="0" upperLimit="1"/></ConstraintGroup>
  </ParameterDeclaration>
</ParameterDeclarations>"""


def test_declarations_reference_earlier_ones_and_convert_to_their_types():
    s = declare(parse_bytes(DECLS, "p.xosc"), Scope())
    assert s.values["v"] == pytest.approx(60 / 3.6)
    assert s.values["lane"] == -1 and isinstance(s.values["lane"], int)
    assert s.values["n"] == 5  # 5.2 rounded
    assert s.values["on"] is True


@pytest.mark.parametrize("overrides, match, line", [
    ({"lane": "2"}, r"parameter 'lane' = 2 violates its constraint: equalTo 1 \(and every other of its 2", 5),
    ({"dv": "-70"}, r"parameter 'dv' = -70.0 violates its constraint: greaterThan -60.0", 11),
    ({"dv": "5"}, r"parameter 'dv' = 5.0 violates its constraint: lessThan 0.0", 10),
    ({"rng": "1.5"}, r"parameter 'rng' = 1.5 violates its constraint: in \[0.0, 1.0\]", 17),
    ({"nope": "1"}, r"parameter 'nope' is assigned but not declared", 1),
    ({"n": "-3"}, r"must be a non-negative integer", 14),
    ({"on": "maybe"}, r"must be true or false", 15),
])
def test_overrides_are_checked_against_constraints_naming_the_line(overrides, match, line):
    with pytest.raises(OpenScenarioError, match=match) as e:
        declare(parse_bytes(DECLS, "p.xosc"), Scope(), overrides)
    assert f"p.xosc:{line}:" in str(e.value)


def test_an_override_changes_what_depends_on_it():
    s = declare(parse_bytes(DECLS, "p.xosc"), Scope(), {"v_kph": "36"})
    assert s.values["v"] == pytest.approx(10.0)
    s = declare(parse_bytes(DECLS, "p.xosc"), Scope(), {"dv": "-50", "v_kph": "72"})
    assert s.values["dv"] == -50.0


def test_a_file_read_with_parameters_uses_them(tmp_path):
    f = tmp_path / "s.xosc"
    f.write_text("""<?xml version="1.0"?>
<OpenSCENARIO>
  <FileHeader revMajor="1" revMinor="2" description="t" author="x" date="2024-01-01T00:00:00"/>
  <ParameterDeclarations>
    <ParameterDeclaration name="speed" parameterType="double" value="10"/>
  </ParameterDeclarations>
  <CatalogLocations/>
  <RoadNetwork/>
  <Entities>
    <ScenarioObject name="Ego">
      <Vehicle name="c" vehicleCategory="car">
        <BoundingBox><Center x="1.4" y="0" z="0.9"/><Dimensions width="2" length="5" height="1.5"/></BoundingBox>
      </Vehicle>
    </ScenarioObject>
  </Entities>
  <Storyboard>
    <Init><Actions><Private entityRef="Ego">
      <PrivateAction><TeleportAction><Position><LanePosition roadId="0" laneId="-1" s="0" offset="0"/></Position>
      </TeleportAction></PrivateAction>
      <PrivateAction><LongitudinalAction><SpeedAction>
        <SpeedActionDynamics dynamicsShape="step" dynamicsDimension="time" value="0"/>
        <SpeedActionTarget><AbsoluteTargetSpeed value="${$speed * 2}"/></SpeedActionTarget>
      </SpeedAction></LongitudinalAction></PrivateAction>
    </Private></Actions></Init>
    <StopTrigger/>
  </Storyboard>
</OpenSCENARIO>
""")
    assert read(f).init[1][1].payload.value == 20.0
    assert read(f, parameters={"speed": "4.5"}).init[1][1].payload.value == 9.0
    assert math.isclose(read(f, parameters={"speed": 3}).parameters["speed"], 3.0)
