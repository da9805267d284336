"""Versioned benchmark suites: fixed, seeded scenario lists with a public dev split and a
test split, for tuning a controller on one and ranking it on the other.

    from acc_gym.suites import get_suite, list_suites
    list_suites()                        # ['carfollowing-v1', 'malicious-v3', 'ncap-v1', 'ncap-v2', 'singlelane-v3']
    s = get_suite("singlelane-v3")
    s.episodes("dev")                    # the fixed list (about one hour of paper 004's traffic)
    s.scenario(1234, "test")             # the unbounded stream, a pure function of (index, split)
    s.hash("test")                       # what a leaderboard records to say what it ran

=================  ==============================================  ====================  ==================
suite              what                                            episodes per split    env_id
=================  ==============================================  ====================  ==================
carfollowing-v1    paper 003's test at 60 / 90 / 120 km/h,          15 (5 lead drivers    CarFollowing-v0
                   each seed another human-like lead                 per speed)
singlelane-v3      paper 004's 22 configurations by occurrence      ~1 simulated hour     SingleLane-v0
                   rate, typical human-like MPC drivers              (~275 scenarios)
ncap-v1            the 24 CCRs / CCRm / CCRb tests with test-track  48 (each test twice)  NCAP-v0
                   deviations of speed and distance
ncap-v2            Euro NCAP 2026's car-to-car points (ACC         57 (each point once)  SingleLane-v0
                   performance and frontal collisions, up to
                   130 km/h; cut-in, cut-out, 1 s / 4 m/s^2 CCRb)
malicious-v3       malicious MPC drivers in cut-in and braking      36 (4 per config.)    SingleLane-v0
                   configurations, plus the hard CCRb tests
=================  ==============================================  ====================  ==================

See :mod:`acc_gym.suites.generators` for what each suite's stream draws, and
:mod:`acc_gym.suites.suite` for splits, root seeds and hashes.

**Decision: the definitions ship as data.** Each suite's definition (root seeds, and per
split the episodes as ``(id, params, seed, drivers)`` plus a digest of the built
scenarios) is materialised in ``acc_gym/suites/data/<name>.json`` (package data), and
:meth:`Suite.episodes` reads it from there; the generator code is still what
:meth:`Suite.scenario` / :meth:`Suite.stream` run. Why data: a published suite must not
move when code moves -- a refactor of a generator, a new scenario id in a family, or a
changed registry order would otherwise silently redefine ``-v1``. With the data file the
definition is reviewable and diffable, its hash is fixed at release, and the tests
regenerate it from the code and check that content and hash agree (and that the episodes
still build to the recorded content digest), so any drift is a failing test, not a
silent change. Each file stores ``sha256`` of its definition; a file edited by hand or
damaged is refused by name.

**Pinned.** A file's own ``sha256`` only catches damage: whoever edits a parameter can
recompute it. So each released suite's definition hash is also compiled into the
package, in :data:`PINNED`, and :func:`get_suite` refuses a file whose definition hashes
to anything else, naming the file -- an edited data file (by a user, or by a controller
on a machine where controllers can write the installation) is an error, not a silently
different benchmark. To make a new version, add a suite with a new name, run
``python -m acc_gym.suites.generate NAME`` (it writes the file atomically and prints the
hash) and add that hash to :data:`PINNED`; a released entry never changes.

**Retired suites** (:data:`RETIRED`): singlelane-v1, malicious-v1, singlelane-v2 and
malicious-v2. Their episodes' content digests include the surrounding MPC drivers' sampled
parameters, and the current driver model samples the distance weight differently
(:mod:`acc_gym.drivers.population`), so their episodes no longer build to what they
recorded. They were not re-pinned in place: the same (id, params, seed) lists under new
seeds are ``singlelane-v3`` / ``malicious-v3``, and results on the retired suites are not
comparable with results on those. carfollowing-v1 and ncap-v1 hold no sampled MPC driver.
Asking for a retired suite names its successor; ``CHANGELOG.md`` says when each was retired.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

from acc_gym.suites import generators
from acc_gym.suites.suite import (
    SPLITS,
    Suite,
    canonical_json,
    definition_hash,
    derive_root_seed,
)

DATA_DIR = Path(__file__).with_name("data")
FILE_FORMAT = "acc_gym.suite/1"
# sha256 of each released suite's definition (all splits): the data files must hash to these
PINNED = {
    "carfollowing-v1": "96e543fba1374302c1df0b3826134bcd504e7de67cc55bf5e0691058f750164c",
    "malicious-v3": "bc432ec9ec1c1c13874b340a5611d3cc9de3ab0812bcd0c3ae6d699172ce6cda",
    "ncap-v1": "4c807fa8938850c3a408e05b6d2086de63d1fbeb262c1271af48867ec8346d89",
    "ncap-v2": "4d91ec702f856b94fcabb893dc34d93ba152dce7fa04d2701099ad0faa2bc0ce",
    "singlelane-v3": "32cfc23340c76fbca1f5b5a4abba66ee80fc7534c074b93f8f7f2ca48cae1009",
}
# Retired suites: name -> (the release that retired it, its successor, why)
RETIRED = {
    "singlelane-v1": ("0.5.0", "singlelane-v3", "driver model 3 samples the surrounding drivers differently"),
    "malicious-v1": ("0.5.0", "malicious-v3", "driver model 3 samples the surrounding drivers differently"),
    "singlelane-v2": ("0.7.0", "singlelane-v3", "driver model 5 samples the surrounding drivers' distance weight "
                                                "differently"),
    "malicious-v2": ("0.7.0", "malicious-v3", "driver model 5 samples the surrounding drivers' distance weight "
                                              "differently"),
}


def _templates() -> dict[str, Suite]:
    """Every suite's code (its definition not yet loaded)."""
    return {s.name: s for s in (
        Suite("carfollowing-v1", 1, "carfollowing", "acc_gym/CarFollowing-v0", generators.carfollowing, count=15,
              description="paper 003's car-following test at 60, 90 and 120 km/h, five lead drivers each"),
        Suite("malicious-v3", 3, "malicious", "acc_gym/SingleLane-v0", generators.malicious, count=36,
              description="malicious MPC drivers cutting in and braking hard, and the 6 m/s^2 CCRb tests"),
        Suite("ncap-v1", 1, "ncap", "acc_gym/NCAP-v0", generators.ncap, count=48,
              description="the Euro NCAP-style CCRs / CCRm / CCRb catalogue, each test twice with test-track "
                          "deviations"),
        Suite("ncap-v2", 2, "ncap", "acc_gym/SingleLane-v0", generators.ncap2026, count=57,
              description="Euro NCAP 2026's car-to-car points: ACC performance (CCRs, CCRm, CCRb, cut-in, cut-out) "
                          "and the frontal-collision CCRs / CCRm / CCRb, with test-track deviations"),
        Suite("singlelane-v3", 3, "singlelane", "acc_gym/SingleLane-v0", generators.singlelane, hours=1.0,
              description="one hour of paper 004's single-lane traffic, configurations by occurrence rate"),
    )}


def list_suites() -> list[str]:
    """The suite names, sorted."""
    return sorted(_templates())


def data_path(name: str) -> Path:
    return DATA_DIR / f"{name}.json"


def read_definition(path) -> dict:
    """A shipped definition file's definition, its stored sha256 checked."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"suite file {str(path)!r} is not valid JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FILE_FORMAT or set(doc) != {"format", "sha256", "definition"}:
        raise ValueError(f"suite file {str(path)!r} is not an {FILE_FORMAT} file")
    if definition_hash(doc["definition"]) != doc["sha256"]:
        raise ValueError(f"suite file {str(path)!r}: its definition does not match its sha256 (edited by hand or "
                         f"damaged); regenerate it with: python -m acc_gym.suites.generate")
    return doc["definition"]


def file_text(definition: dict) -> str:
    """The text of a definition file (one episode per line, so that diffs are readable)."""
    head = {k: v for k, v in definition.items() if k != "episodes"}
    lines = ['{"format": ' + json.dumps(FILE_FORMAT) + ',',
             ' "sha256": ' + json.dumps(definition_hash(definition)) + ',',
             ' "definition": {']
    for key in sorted(head):
        lines.append(f'  {json.dumps(key)}: {canonical_json(head[key])},')
    lines.append('  "episodes": {')
    for n, sp in enumerate(SPLITS):
        eps = definition["episodes"][sp]
        lines.append(f'   {json.dumps(sp)}: [')
        lines.extend("    " + canonical_json(e) + ("," if k < len(eps) - 1 else "") for k, e in enumerate(eps))
        lines.append("   ]" + ("," if n < len(SPLITS) - 1 else ""))
    lines += ["  }", " }", "}", ""]
    return "\n".join(lines)


@cache
def _load(name: str) -> Suite:
    template = _templates()[name]
    path = data_path(name)
    if not path.exists():
        raise ValueError(f"suite {name!r}: its definition file {str(path)!r} is missing (regenerate it with: "
                         f"python -m acc_gym.suites.generate {name})")
    definition = read_definition(path)
    pinned = PINNED.get(name)
    actual = definition_hash(definition)
    if pinned is None:
        raise ValueError(f"suite {name!r} has no pinned hash: add {name!r}: {actual!r} to "
                         f"acc_gym.suites.PINNED once its definition file {str(path)!r} is final")
    if actual != pinned:
        raise ValueError(f"suite file {str(path)!r} is not the released {name}: its definition hashes to "
                         f"{actual[:12]}..., the package pins {pinned[:12]}... (edited after release? reinstall "
                         f"acc-gym, or make a new suite version with a new name)")
    return Suite.from_dict(definition, template)


def get_suite(name: str) -> Suite:
    """The suite ``name`` (its definition read from the shipped data file)."""
    if isinstance(name, str) and name in RETIRED:
        release, successor, why = RETIRED[name]
        raise ValueError(f"suite {name!r} was retired in acc-gym {release} ({why}; its episodes no longer build to "
                         f"what it recorded): use {successor!r}, or an acc-gym release before {release}")
    if not isinstance(name, str) or name not in _templates():
        raise ValueError(f"unknown suite {name!r}; known: {list_suites()}")
    return _load(name)


def template(name: str) -> Suite:
    """The suite ``name`` with its definition generated from the code (not the data file)."""
    if name not in _templates():
        raise ValueError(f"unknown suite {name!r}; known: {list_suites()}")
    return _templates()[name]


__all__ = ["PINNED", "RETIRED", "SPLITS", "Suite", "data_path", "definition_hash", "derive_root_seed", "get_suite", "list_suites",
           "read_definition", "template"]
