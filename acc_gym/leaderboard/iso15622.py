"""The leaderboard's ISO 15622 column: each controller's verdict on ISO 15622:2018's ACC envelope
over the ``iso15622-v1`` battery (:mod:`acc_gym.standards.battery`), measured through its sandbox.

After its suite episodes (and the string-stability column), the simulation process drives the
battery's 30 episodes (10 cases at seeds 0, 1, 2) with the controller's answers, builds the
drives and checks them (:func:`acc_gym.standards.battery.remote_iso15622_report`): the
controller only ever sees observation rows, as in its episodes; the verdict is made in the
simulation process and sent to the runner as the JSON-safe cell :func:`cell`. It is the verdict
``acc-gym conformance CONTROLLER --standard iso15622`` gives (the same drives, the same values).

The column is information beside the ranking: it changes no episode's points and no rank. A
controller's failure inside the battery (it raises, answers NaN, overruns a budget) is the
cell's -- ``{"failed_to_run": reason}`` -- and its episodes stand; a battery that exercises no
requirement has ``passed`` None ("not exercised"), never True.
"""

from __future__ import annotations

from acc_gym.standards.battery import ISO15622_V1, SEEDS

BATTERY = ISO15622_V1
HEADER = f"ISO 15622 ({BATTERY})"
#: the tables' short names of :mod:`acc_gym.standards.iso15622`'s requirements (the files keep the full ones)
SHORT_NAMES = {
    "mean automatic deceleration over 2 s": "deceleration",
    "mean jerk over 1 s": "jerk",
    "mean automatic acceleration over 2 s": "acceleration",
    "steady-state time gap": "time gap",
    "standstill gap behind a stopped target": "standstill gap",
    "no automatic go while the target stays stopped": "automatic go",
}
CELL_KEYS = ("name", "measured", "limit", "unit", "passed")


def cell(report) -> dict:
    """The compact, JSON-safe cell of an :class:`~acc_gym.standards.iso15622.Report`:
    ``{"passed": True | False | None, "failed": [names of the failed requirements], "requirements":
    [{"name", "measured", "limit", "unit", "passed"}, ...]}`` (numbers rounded to 1e-6, a non-finite
    one as None, as :meth:`~acc_gym.standards.iso15622.Requirement.to_dict` has them; where the worst
    case happened and the sources are left to ``acc-gym conformance``)."""
    reqs = [r.to_dict() for r in report.requirements]
    return {"passed": report.passed, "failed": [r["name"] for r in reqs if r["passed"] is False],
            "requirements": [{k: r[k] for k in CELL_KEYS} for r in reqs]}


def failed_cell(reason: str) -> dict:
    """The cell of a controller that failed inside the battery."""
    return {"failed_to_run": str(reason)}


def format_cell(value: dict | None) -> str:
    """A table cell: ``passes``, ``fails: <short names>``, ``not exercised``, ``failed`` (the
    controller failed in the battery) or ``-`` (not measured: the controller failed in its episodes)."""
    if not value:
        return "-"
    if "failed_to_run" in value:
        return "failed"
    if value.get("passed") is None:
        return "not exercised"
    if value["passed"]:
        return "passes"
    return "fails: " + ", ".join(SHORT_NAMES.get(n, n) for n in value.get("failed", []))


def settings(seeds=SEEDS) -> dict:
    """What the manifest records of the column (``settings.iso15622``)."""
    from acc_gym.standards.battery import BATTERIES
    from acc_gym.standards.iso15622 import STANDARD

    return {"standard": STANDARD, "battery": BATTERY, "seeds": list(seeds),
            "drives": len(BATTERIES[BATTERY]) * len(seeds),
            "rule": "passes when every requirement a drive exercises is within its limit; information only: "
                    "no effect on points or rank"}


def note(results: dict) -> str:
    """The tables' line on the column (from the manifest)."""
    st = results["manifest"]["settings"]["iso15622"]
    short = ", ".join(SHORT_NAMES.values())
    return (f"{HEADER}: {st['standard']}'s ACC envelope over the {st['battery']} battery ({st['drives']} drives, "
            f"seeds {', '.join(map(str, st['seeds']))}), driven by each controller in its sandbox; passes / fails: "
            f"the requirements outside their limits ({short}) / not exercised / failed: the controller failed in "
            f"the battery (acc-gym conformance --standard iso15622); not part of the points or the rank")
