"""ASAM's checker on OpenSCENARIO files (``acc-gym validate``): the shipped bundle passes, a
schema violation fails with its line, a broken reference fails by ASAM's rule, exit codes."""

import json
from pathlib import Path

import pytest

pytest.importorskip("qc_openscenario", reason="ASAM's checker bundle is in the osc extra: pip install 'acc-gym[osc]'")

from acc_gym.cli import main  # noqa: E402
from acc_gym.scenarios.openscenario.bundle import ALKS_DIR, alks_scenarios  # noqa: E402
from acc_gym.scenarios.openscenario.check import check  # noqa: E402

TEMPLATE = alks_scenarios()["4.1.1"]


def _edited(tmp_path, old, new, count=1) -> Path:
    text = TEMPLATE.read_text()
    assert old in text
    path = tmp_path / "edited.xosc"
    path.write_text(text.replace(old, new, count))
    return path


@pytest.mark.parametrize("path", sorted(Path(ALKS_DIR).rglob("*.xosc")), ids=lambda p: p.name)
def test_every_file_of_the_shipped_bundle_passes(path):
    report = check(path)
    assert report.passed, [str(i) for i in report.issues]
    assert report.completed >= 5 and not report.issues


def test_an_element_the_schema_does_not_allow_fails_with_its_line(tmp_path):
    path = _edited(tmp_path, "<Init>", "<Init>\n<Bogus/>")
    line = path.read_text().splitlines().index("<Bogus/>") + 1
    report = check(path)
    assert not report.passed
    (issue,) = report.issues
    assert issue.rule.endswith("xml.valid_schema") and issue.line == line and "Bogus" in issue.message
    assert report.skipped  # ASAM's rules are not run on a file that is not schema-valid


def test_a_reference_to_no_entity_fails_by_asams_rule(tmp_path):
    text = TEMPLATE.read_text()
    n = text.count('entityRef="Ego"')
    assert n >= 2
    path = _edited(tmp_path, 'entityRef="Ego"', 'entityRef="Nobody"', n)
    report = check(path)
    assert not report.passed
    assert any("resolvable_entity_references" in i.rule for i in report.issues), [str(i) for i in report.issues]


def test_the_command_exits_by_the_result(tmp_path, capsys):
    assert main(["validate", "alks:4.4.2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["passed"] is True
    bad = _edited(tmp_path, "<Init>", "<Init>\n<Bogus/>")
    assert main(["validate", "alks:4.4.2", str(bad)]) == 1
    out = capsys.readouterr().out
    assert f"{bad}:line" in out and "FAILED" in out
    assert main(["validate", str(tmp_path / "missing.xosc")]) == 2
    assert "missing.xosc" in capsys.readouterr().out
