"""OpenSCENARIO variation files as lists of concrete scenarios, and as campaigns."""

import json
import math

import numpy as np
import pytest

from acc_gym.scenarios.openscenario import OpenScenarioError
from acc_gym.scenarios.openscenario.bundle import alks_scenarios, alks_variation
from acc_gym.scenarios.openscenario.variation import read_variation

HEAD = """<?xml version="1.0"?>
<OpenSCENARIO>
  <FileHeader revMajor="1" revMinor="2" description="v" author="t" date="2024-01-01T00:00:00"/>
  <ParameterValueDistribution>
    <ScenarioFile filepath="{template}"/>
{body}
  </ParameterValueDistribution>
</OpenSCENARIO>
"""
TEMPLATE = str(alks_scenarios()["4.2.1"])  # Ego_InitSpeed_Ve0_kph in (0, 60], the target's offset >= 0


def _var(tmp_path, body, template=TEMPLATE):
    f = tmp_path / "v.xosc"
    f.write_text(HEAD.format(template=template, body=body))
    return f


def test_a_deterministic_variation_is_the_product_of_its_axes_last_fastest(tmp_path):
    v = read_variation(_var(tmp_path, """<Deterministic>
      <DeterministicSingleParameterDistribution parameterName="Ego_InitSpeed_Ve0_kph">
        <DistributionRange stepWidth="20"><Range lowerLimit="20" upperLimit="60"/></DistributionRange>
      </DeterministicSingleParameterDistribution>
      <DeterministicMultiParameterDistribution><ValueSetDistribution>
        <ParameterValueSet><ParameterAssignment parameterRef="TargetBlocking_Model" value="car"/>
          <ParameterAssignment parameterRef="TargetBlocking_Catalog" value="vehicle_catalog"/></ParameterValueSet>
        <ParameterValueSet><ParameterAssignment parameterRef="TargetBlocking_Model" value="pedestrian"/>
          <ParameterAssignment parameterRef="TargetBlocking_Catalog" value="pedestrian_catalog"/></ParameterValueSet>
      </ValueSetDistribution></DeterministicMultiParameterDistribution>
    </Deterministic>"""))
    assert v.kind == "deterministic" and len(v) == 6 and v.invalid == 0
    assert [(p["Ego_InitSpeed_Ve0_kph"], p["TargetBlocking_Model"]) for p in (v[i] for i in range(6))] == [
        (20.0, "car"), (20.0, "pedestrian"), (40.0, "car"), (40.0, "pedestrian"), (60.0, "car"), (60.0, "pedestrian")]


def test_combinations_that_break_the_templates_constraints_are_left_out_and_counted(tmp_path):
    v = read_variation(_var(tmp_path, """<Deterministic>
      <DeterministicSingleParameterDistribution parameterName="Ego_InitSpeed_Ve0_kph">
        <DistributionSet><Element value="0"/><Element value="30"/><Element value="60"/><Element value="90"/>
        </DistributionSet>
      </DeterministicSingleParameterDistribution>
    </Deterministic>"""))
    assert [p["Ego_InitSpeed_Ve0_kph"] for p in (v[i] for i in range(len(v)))] == ["30", "60"]
    assert v.invalid == 2 and "violates its constraint: greaterThan 0.0" in v.first_invalid


def test_a_stochastic_variation_draws_each_run_from_its_own_generator(tmp_path):
    body = """<Stochastic numberOfTestRuns="400" randomSeed="7">
      <StochasticDistribution parameterName="Ego_InitSpeed_Ve0_kph">
        <NormalDistribution expectedValue="40" variance="25"><Range lowerLimit="30" upperLimit="50"/></NormalDistribution>
      </StochasticDistribution>
      <StochasticDistribution parameterName="TargetBlocking_InitPosition_LongitudinalOffset_m">
        <UniformDistribution><Range lowerLimit="300" upperLimit="500"/></UniformDistribution>
      </StochasticDistribution>
      <StochasticDistribution parameterName="TargetBlocking_Model">
        <ProbabilityDistributionSet><Element value="pedestrian" weight="3"/><Element value="car" weight="1"/>
        </ProbabilityDistributionSet>
      </StochasticDistribution>
    </Stochastic>"""
    v = read_variation(_var(tmp_path, body))
    assert v.kind == "stochastic" and v.seed == 7
    # run i is a pure function of (randomSeed, i): drawn here by hand in the declared order
    rng = np.random.default_rng([7, 3])
    x = rng.normal(40, 5)
    while not 30 <= x <= 50:
        x = rng.normal(40, 5)
    assert v[3]["Ego_InitSpeed_Ve0_kph"] == x
    assert v[3]["TargetBlocking_InitPosition_LongitudinalOffset_m"] == rng.uniform(300, 500)
    speeds = np.array([v[i]["Ego_InitSpeed_Ve0_kph"] for i in range(len(v))])
    assert speeds.min() >= 30 and speeds.max() <= 50 and abs(speeds.mean() - 40) < 1.0
    peds = sum(v[i]["TargetBlocking_Model"] == "pedestrian" for i in range(len(v))) / len(v)
    assert abs(peds - 0.75) < 0.07
    assert read_variation(_var(tmp_path, body))[17] == v[17]


@pytest.mark.parametrize("body, match", [
    ("<Deterministic/><Stochastic numberOfTestRuns='1'/>", "exactly one of Deterministic and Stochastic"),
    ("""<Deterministic><DeterministicSingleParameterDistribution parameterName="x">
       <UserDefinedDistribution type="mine">1</UserDefinedDistribution>
       </DeterministicSingleParameterDistribution></Deterministic>""", "UserDefinedDistribution is not read"),
    ("""<Deterministic><DeterministicSingleParameterDistribution parameterName="Ego_InitSpeed_Ve0_kph">
       <DistributionRange stepWidth="0"><Range lowerLimit="1" upperLimit="2"/></DistributionRange>
       </DeterministicSingleParameterDistribution></Deterministic>""", "stepWidth must be > 0"),
])
def test_bad_variations_are_errors_naming_the_line(tmp_path, body, match):
    with pytest.raises(OpenScenarioError, match=match) as e:
        read_variation(_var(tmp_path, body))
    assert f"{tmp_path / 'v.xosc'}:" in str(e.value)


def test_the_bundles_variations_read():
    v = read_variation(alks_variation("4.4.1"))
    # 5 ego speeds x 5 models x 2 sides x 5 relative speeds x 7 trigger gaps x 6 lateral speeds x 5 rates
    assert len(v) + v.invalid == 5 * 5 * 2 * 5 * 7 * 6 * 5
    assert v.invalid > 0 and len(v) > 0


def _campaign(tmp_path, controller, **kw):
    pytest.importorskip("pyarrow", reason="campaigns need pyarrow (pip install '.[campaign]' or '.[test]')")
    from acc_gym.campaigns import run_campaign
    from acc_gym.campaigns.sweep import VariationSweep

    sweep = VariationSweep(_var(tmp_path, """<Deterministic>
      <DeterministicSingleParameterDistribution parameterName="Ego_InitSpeed_Ve0_kph">
        <DistributionSet><Element value="30"/><Element value="45"/><Element value="60"/></DistributionSet>
      </DeterministicSingleParameterDistribution></Deterministic>"""))
    return sweep, run_campaign(sweep, None, controller, tmp_path / f"out-{controller}", chunk_size=2, **kw)


def test_a_variation_campaign_runs_every_concrete_scenario_with_the_campaigns_outputs(tmp_path):
    sweep, s = _campaign(tmp_path, "constant")
    assert s["episodes"] == s["planned_episodes"] == 3 and s["complete"]
    assert s["collisions"]["count"] == 3 and s["preventable_collisions"] == 3  # the cc-driver stops for the target
    assert s["suite"] == "openscenario:alks_scenario_4_2_1_fully_blocking_target_template" and s["hours"] == 0.0
    from acc_gym.campaigns import load_campaign
    from acc_gym.scenarios.openscenario import read, run_file
    from acc_gym.evaluation.runner import load_controller

    rows = sorted(load_campaign(tmp_path / "out-constant").rows(), key=lambda r: r["index"])
    assert [r["scenario_id"].rsplit("#", 1)[1] for r in rows] == ["0", "1", "2"]
    sc = read(TEMPLATE, parameters=sweep.parameters(1))  # the row is the template run with its parameters
    r, _ = run_file(sc.path, load_controller("constant"), scenario=sc)
    assert math.isclose(rows[1]["min_gap"], r["min_gap"]) and math.isclose(rows[1]["duration"], r["duration"])


def test_a_variation_campaign_resumes_to_the_same_rows(tmp_path):
    pytest.importorskip("pyarrow", reason="campaigns need pyarrow (pip install '.[campaign]' or '.[test]')")
    from acc_gym.campaigns import load_campaign, run_campaign
    from acc_gym.campaigns.sweep import VariationSweep

    _, whole = _campaign(tmp_path, "acc")
    sweep = VariationSweep(tmp_path / "v.xosc")
    part = run_campaign(sweep, None, "acc", tmp_path / "resumed", chunk_size=2, max_chunks=1)
    assert not part["complete"] and part["episodes"] == 2
    done = run_campaign(sweep, None, "acc", tmp_path / "resumed", chunk_size=2)
    key = lambda r: r["index"]  # noqa: E731
    assert sorted(load_campaign(tmp_path / "resumed").rows(), key=key) == sorted(
        load_campaign(tmp_path / "out-acc").rows(), key=key)
    assert done["mean_score"] == whole["mean_score"]


def test_the_command_line_runs_a_bundle_variation(tmp_path, capsys):
    pytest.importorskip("pyarrow", reason="campaigns need pyarrow (pip install '.[campaign]' or '.[test]')")
    from acc_gym.cli import main

    assert main(["campaign", "--variation", "alks:4.6.2", "--controller", "acc", "--out", str(tmp_path / "c"),
                 "--workers", "1", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["episodes"] == 2 and s["collisions"]["count"] == 0
    with pytest.raises(SystemExit):
        main(["campaign", "--variation", "alks:4.6.2", "--hours", "1", "--controller", "acc", "--out", str(tmp_path)])
    assert "give no --suite or --hours" in capsys.readouterr().err
