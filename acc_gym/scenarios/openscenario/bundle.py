"""The shipped OpenSCENARIO bundle: BMW AG's UN R157 (ALKS) Annex 5 scenarios (MPL-2.0,
unmodified, ``alks/NOTICE.md``), pinned by ``alks/SHA256SUMS``."""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

ALKS_DIR = Path(__file__).parent / "alks"
CONCRETE = ALKS_DIR / "logical_scenarios" / "concrete_scenarios"
PREFIX = "alks:"


def alks_scenarios() -> dict[str, Path]:
    """The bundle's concrete scenarios by Annex 5 number (``"4.4.2"`` -> its template file)."""
    out = {}
    for f in sorted(CONCRETE.glob("alks_scenario_*_template.xosc")):
        parts = f.name[len("alks_scenario_"):].split("_")
        out[".".join(parts[:3])] = f
    return out


def alks_variation(number: str) -> Path | None:
    """The variation file (ParameterValueDistribution) of scenario ``number``, if any."""
    src = alks_scenarios().get(number)
    if src is None:
        return None
    var = ALKS_DIR / "logical_scenarios" / src.name.replace("_template.xosc", "_variation.xosc")
    return var if var.is_file() else None


def resolve(ref: str) -> Path:
    """A scenario reference as a path: ``alks:4.4.2`` (a bundle scenario) or a file's path."""
    if ref.startswith(PREFIX):
        found = alks_scenarios().get(ref[len(PREFIX):])
        if found is None:
            raise ValueError(f"{ref!r} is not a scenario of the shipped ALKS bundle; it has "
                             f"{', '.join(PREFIX + k for k in alks_scenarios())}")
        return found
    return Path(ref)


def verify() -> list[str]:
    """The bundle's files whose SHA-256 differs from its pin (empty: as shipped)."""
    bad = []
    for line in (ALKS_DIR / "SHA256SUMS").read_text().splitlines():
        digest, name = line.split(maxsplit=1)
        p = ALKS_DIR / name
        if not p.is_file() or hashlib.sha256(p.read_bytes()).hexdigest() != digest:
            bad.append(name)
    return bad


# --- alks-v1: the bundle as a suite (the leaderboard's R157 column, acc_gym.leaderboard.alks)
SUITE = "alks-v1"
VARIATIONS_PER_SCENARIO = 2  # concrete scenarios taken from each variation file, beside the defaults
# sha256 of alks-v1's definition (suite_definition()): the selection and the bundle's pins; released, never changed
SUITE_HASH = "d1696937d812eb84280105a75026270f19b79dd60414305543c813c277997f2c"


def suite_entries() -> list[dict]:
    """alks-v1's episodes: for each of the bundle's concrete scenarios (Annex 5 order), the
    template at its default parameters, then :data:`VARIATIONS_PER_SCENARIO` concrete
    scenarios of its variation file, evenly spread over its valid combinations (indices
    ``floor((j + 1/2) n / K)``: deterministic, the whole range covered; an index taken
    already gives way to the next). Each entry: ``{"scenario", "index",
    "parameters"}`` (``index`` None: the defaults). Made once per process (reading the
    variations takes seconds: 4.4.1 alone has 52,500 combinations to check)."""
    return [dict(e, parameters=dict(e["parameters"])) for e in _suite_entries()]


@functools.cache
def _suite_entries() -> tuple:
    from acc_gym.scenarios.openscenario.variation import read_variation

    out = []
    for number in alks_scenarios():
        out.append({"scenario": number, "index": None, "parameters": {}})
        var = alks_variation(number)
        if var is None:
            continue
        v = read_variation(var)
        n = len(v)
        taken: set = set()
        for j in range(min(VARIATIONS_PER_SCENARIO, n)):
            k = int((j + 0.5) * n / VARIATIONS_PER_SCENARIO)
            while k in taken:
                k += 1
            if k >= n:
                break
            taken.add(k)
            out.append({"scenario": number, "index": k, "parameters": {p: str(x) for p, x in v[k].items()}})
    return tuple(out)


def suite_definition() -> dict:
    """What alks-v1's hash covers: its episodes and the bundle's SHA256SUMS (every file's pin)."""
    return {"suite": SUITE, "episodes": suite_entries(), "sha256sums": (ALKS_DIR / "SHA256SUMS").read_text()}


def suite_hash() -> str:
    """sha256 of the canonical JSON of :func:`suite_definition`."""
    import json

    text = json.dumps(suite_definition(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()
