"""``acc-gym run FILE.xosc --controller NAME``: the JSON, the preventability, the trace and the errors."""

import csv
import json

import pytest

from acc_gym.cli import main
from acc_gym.scenarios.openscenario.bundle import alks_scenarios

KEYS = {"file", "controller", "collided", "preventable", "score", "min_gap", "min_ttc", "unsupported"}


def _json(capsys, *argv):
    assert main(["run", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_json_has_the_documented_keys_and_a_non_preventable_collision(capsys):
    out = _json(capsys, "alks:4.4.2", "--controller", "constant")
    assert KEYS <= set(out)
    assert out["collided"] and out["preventable"] is False  # the cc-driver collides too
    assert out["collision_with"] == "CutInVehicle" and out["min_gap"] < 0
    assert out["file"] == str(alks_scenarios()["4.4.2"]) and out["controller"] == "constant"


def test_a_preventable_collision_is_one_the_cc_driver_avoids(capsys):
    out = _json(capsys, "alks:4.4.1", "--controller", "constant")
    assert out["collided"] and out["preventable"] is True
    out = _json(capsys, "alks:4.4.1", "--controller", "acc")
    assert not out["collided"] and out["preventable"] is None and out["min_ttc"] > 1.0


def test_parameters_from_the_command_line_change_the_run(capsys):
    slow = _json(capsys, "alks:4.2.1", "--controller", "acc", "--param", "Ego_InitSpeed_Ve0_kph=30")
    fast = _json(capsys, "alks:4.2.1", "--controller", "acc")
    assert slow["min_ttc"] > fast["min_ttc"]


def test_the_trace_has_every_entity_at_every_step(tmp_path, capsys):
    path = tmp_path / "run.csv"
    out = _json(capsys, "alks:4.3.2", "--controller", "acc", "--trace", str(path))
    rows = list(csv.DictReader(path.open()))
    assert list(rows[0]) == ["t", "entity", "s", "y", "v", "a", "controlled"]
    assert {r["entity"] for r in rows} == {"Ego", "LeadVehicle"}
    steps = round(out["duration"] / 0.2) + 1
    assert len(rows) == 2 * steps
    ego = [r for r in rows if r["entity"] == "Ego"]
    assert [int(r["controlled"]) for r in ego[:16]] == [0] * 15 + [1]  # activated at t = 3 s (step 15)


def test_a_plot_is_written(tmp_path, capsys):
    path = tmp_path / "run.png"
    assert main(["run", "alks:4.4.1", "--controller", "acc", "--plot", str(path)]) == 0
    assert path.stat().st_size > 10_000
    assert "no collision" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["alks:4.4.2", "--param", "CutInVehicle_HeadwayDistanceTrigger_dx0_m=-3"],
     r"template.xosc:37: parameter 'CutInVehicle_HeadwayDistanceTrigger_dx0_m' = -3.0 violates its constraint"),
    (["alks:4.4.2", "--param", "Nope=1"], "'Nope' is assigned but not declared"),
    (["alks:4.4.2", "--param", "Nope"], "expected NAME=VALUE"),
    (["alks:7"], "not a scenario of the shipped ALKS bundle"),
    (["missing.xosc"], "missing.xosc: cannot read the file"),
    (["alks:4.4.2", "--ego", "Bob"], "--ego 'Bob' is not an entity"),
])
def test_bad_input_is_an_error_naming_it(argv, message, capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", *argv, "--controller", "acc"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    import re
    assert re.search(message, err), err


def test_an_element_the_reader_does_not_cover_is_named_with_its_line(tmp_path, capsys):
    f = tmp_path / "sync.xosc"
    text = (alks_scenarios()["4.1.1"]).read_text(encoding="utf-8-sig")
    at = text.index("<TeleportAction>")
    text = text[:at] + "<SynchronizeAction masterEntityRef=\"Ego\"/></PrivateAction><PrivateAction>" + text[at:]
    f.write_text(text.replace("./catalogs", str(alks_scenarios()["4.1.1"].parent / "catalogs")).replace(
        "./road_networks", str(alks_scenarios()["4.1.1"].parent / "road_networks")), encoding="utf-8")
    line = text[:at].count("\n") + 1
    with pytest.raises(SystemExit):
        main(["run", str(f), "--controller", "acc"])
    assert f"{f}:{line}: the private action <SynchronizeAction> is not read here" in capsys.readouterr().err


def test_iso_15622s_envelope_is_checked_on_the_controlled_drive(capsys):
    brake = _json(capsys, "alks:4.3.2", "--controller", "acc")["iso15622"]  # the lead brakes at 9.81 m/s^2
    decel = next(r for r in brake["requirements"] if r["name"] == "mean automatic deceleration over 2 s")
    assert brake["passed"] is False and decel["passed"] is False and decel["measured"] > decel["limit"]
    free = _json(capsys, "alks:4.1.1", "--controller", "acc")["iso15622"]  # nothing ahead: nothing to brake for
    assert free["passed"] is True
