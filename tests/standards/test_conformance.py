"""acc-gym conformance: the JSON object scripts read, the files, bad input named."""

import json

import pytest

from acc_gym.cli import main


def test_json_object_and_files(capsys, tmp_path):
    out = tmp_path / "conf"
    assert main(["conformance", "acc", "--standard", "iso15622", "--seeds", "0", "--json", "--out", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["controller"] == "acc" and set(d["standards"]) == {"iso15622"}
    iso = d["standards"]["iso15622"]
    assert iso["battery"] == "iso15622-v1" and iso["seeds"] == [0]
    names = [r["name"] for r in iso["requirements"]]
    assert "mean jerk over 1 s" in names and "steady-state time gap" in names
    for r in iso["requirements"]:
        assert {"name", "measured", "limit", "unit", "passed", "where"} <= set(r)
    # the linear ACC brakes harder than an ACC may at the end of paper 003's 120 km/h test, and jerks at cut-ins
    assert iso["passed"] is False
    assert next(r for r in iso["requirements"] if r["name"].startswith("mean jerk"))["passed"] is False
    for name in ("conformance.json", "conformance.md", "conformance.html", "envelope.png"):
        assert (out / name).stat().st_size > 100
    assert json.loads((out / "conformance.json").read_text())["standards"]["iso15622"]["passed"] is False
    assert "data:image/png;base64," in (out / "conformance.html").read_text()


def test_unknown_standard_is_named(capsys):
    with pytest.raises(SystemExit):
        main(["conformance", "acc", "--standard", "iso26262"])
    assert "iso26262" in capsys.readouterr().err


def test_the_failing_drives_are_written_as_openscenario_and_replay(tmp_path):
    pytest.importorskip("scenariogeneration", reason="scenariogeneration is not installed (pip install '.[osc]' or '.[test]'): nothing writes OpenSCENARIO")
    import numpy as np

    from acc_gym.evaluation.runner import load_controller
    from acc_gym.scenarios.openscenario import run_file
    from acc_gym.scenarios.openscenario.writer import REAR_AXLE, file_stem
    from acc_gym.standards.conformance import conformance, write_reports

    result = conformance("acc", ["iso15622"], (0,))
    iso = result["standards"]["iso15622"]
    failed = {d for r in iso["requirements"] if r["passed"] is False for d in iso["drives"] if r["where"].startswith(d)}
    assert failed  # the linear ACC's jerk at cut-ins (test_json_object_and_files)
    fails = result["_failures"]
    assert {f["label"] for f in fails} == {f"iso15622-{label}" for label in failed | set(iso["collisions"])}
    paths = write_reports(result, tmp_path)
    written = sorted((tmp_path / "failures").glob("*.xosc"))
    assert paths["failures"] == str(tmp_path / "failures") and len(written) == len(fails)
    assert "_failures" not in json.loads((tmp_path / "conformance.json").read_text())
    # each file replays its drive: the ego's positions to 1e-6 m
    f = fails[0]
    path = tmp_path / "failures" / f"{file_stem(f['label'])}.xosc"
    assert path in written
    _, back = run_file(path, load_controller("acc"))
    x = back.s[:, back.names.index("Ego")] + (1 - REAR_AXLE) * f["trace"].lengths[0, 0]
    x0 = f["trace"].x[:, 0, 0]
    np.testing.assert_allclose(x - x[0], x0 - x0[0], atol=1e-6)


def test_r157_keeps_the_collisions_when_asked_and_only_then():
    from acc_gym.standards.r157 import r157_cases

    kept = r157_cases("constant", families=("lead deceleration",), keep_failures=True)
    assert len(kept["_failures"]) == sum(c["controller_collides"] for c in kept["cases"]) > 0
    assert all(f["label"].startswith("r157-lead deceleration-") for f in kept["_failures"])
    for f in kept["_failures"]:  # the recorded drive is the colliding one
        assert f["trace"].collided[0, 0]
    plain = r157_cases("constant", families=("lead deceleration",))
    assert "_failures" not in plain and plain["cases"] == kept["cases"]
