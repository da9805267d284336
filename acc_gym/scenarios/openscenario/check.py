"""Check an OpenSCENARIO file with ASAM's own checker.

:func:`check` runs ASAM's quality checker bundle for OpenSCENARIO XML
(``asam-qc-openscenarioxml`` on PyPI, MPL-2.0; the ``osc`` extra installs it) on one file, in
this process, and returns what it found as a :class:`CheckReport`. The bundle validates the
file against the XML schema of the version its ``FileHeader`` declares (it ships the
schemas of 1.0 to 1.3) and then checks ASAM's rules (references resolve, names are unique
on a level, parameters are declared, operators are allowed, ...). A rule newer than the
file's version is skipped by the bundle, and so is every rule after a failed schema check;
the report lists both.

Decided here: the bundle's own log lines (it configures Python's root logger at INFO when
imported) are silenced while it runs; a file passes when the bundle reports no issue and its
schema check completed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

INSTALL_HINT = "pip install 'acc-gym[osc]'"


@dataclass(frozen=True)
class Issue:
    """One finding of the checker: its rule, level (1 error, 2 warning, 3 information, as ASAM's
    result format numbers them), message and where (``line`` in the file when it knows)."""

    rule: str
    level: int
    message: str
    line: int | None = None
    xpath: str | None = None

    def __str__(self) -> str:
        where = f"line {self.line}: " if self.line is not None else (f"{self.xpath}: " if self.xpath else "")
        return f"{where}{self.message} [{self.rule}]"


@dataclass(frozen=True)
class CheckReport:
    """The checker's result for one file: ``passed``, the ``issues``, the rules it ``skipped``
    (rule id -> the bundle's reason) and how many rules it ``completed``."""

    file: str
    passed: bool
    issues: tuple = ()
    skipped: dict = field(default_factory=dict)
    completed: int = 0

    def to_dict(self) -> dict:
        return {"file": self.file, "passed": self.passed, "completed": self.completed,
                "issues": [{"rule": i.rule, "level": i.level, "message": i.message, "line": i.line,
                            "xpath": i.xpath} for i in self.issues],
                "skipped": dict(self.skipped)}


def available() -> bool:
    """Whether ASAM's checker bundle is installed."""
    try:
        import qc_openscenario.main  # noqa: F401
    except ImportError:
        return False
    return True


def check(path) -> CheckReport:
    """Run ASAM's OpenSCENARIO checker bundle on ``path``; raises ``FileNotFoundError`` for a
    missing file and ``ImportError`` (naming the extra) without the bundle."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such OpenSCENARIO file: {path}")
    try:
        from qc_baselib import Configuration, Result, StatusType
        from qc_openscenario import constants, main
    except ImportError as exc:
        raise ImportError(f"checking OpenSCENARIO files needs ASAM's checker bundle: {INSTALL_HINT} ({exc})") from None
    config = Configuration()
    config.set_config_param("InputFile", str(path))
    result = Result()
    result.register_checker_bundle(name=constants.BUNDLE_NAME, description="OpenScenario checker bundle",
                                   version=constants.BUNDLE_VERSION, summary="")
    result.set_result_version(version=constants.BUNDLE_VERSION)
    before = logging.root.manager.disable
    logging.disable(logging.CRITICAL)  # the bundle logs every check (at INFO, a failure at ERROR)
    try:
        main.run_checks(config, result)
    finally:
        logging.disable(before)
    issues, skipped, completed, schema_ok = [], {}, 0, False
    for checker_id in result.get_checker_ids(constants.BUNDLE_NAME):
        res = result.get_checker_result(constants.BUNDLE_NAME, checker_id)
        rules = [r.rule_uid for r in (res.addressed_rule or [])] or [checker_id]
        if res.status == StatusType.SKIPPED:
            for rule in rules:
                skipped[rule] = res.summary or "skipped"
            continue
        if res.status == StatusType.ERROR:
            issues.append(Issue(rules[0], 1, f"the checker failed: {res.summary}"))
            continue
        completed += 1
        if checker_id.endswith("valid_schema"):
            schema_ok = True
        for issue in res.issues or ():
            lines = [fl.row for loc in issue.locations for fl in (loc.file_location or [])]
            xpaths = [xl.xpath for loc in issue.locations for xl in (loc.xml_location or [])]
            detail = "; ".join(loc.description for loc in issue.locations if loc.description)
            message = issue.description + (f": {detail}" if detail else "")
            issues.append(Issue(issue.rule_uid, int(issue.level), message, lines[0] if lines else None,
                                xpaths[0] if xpaths else None))
    return CheckReport(str(path), schema_ok and not issues, tuple(issues), skipped, completed)
