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
