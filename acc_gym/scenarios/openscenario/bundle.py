"""The shipped OpenSCENARIO bundle: BMW AG's UN R157 (ALKS) Annex 5 scenarios (MPL-2.0,
unmodified, ``alks/NOTICE.md``), pinned by ``alks/SHA256SUMS``."""

from __future__ import annotations

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
