"""A campaign's settings and its ``campaign.json`` manifest.

The manifest pins everything the results depend on: the suite (name, version, hash of
the split), the split, the root seed, the controller reference and a digest of its code
(the files its reference loads, :func:`acc_gym.leaderboard.provenance.code_digest`: an
edited ``mymod.py`` between an interrupted run and its resume is refused, not mixed in),
the environment id, the
hours asked for, the chunk size, and this package's version; plus what planning found
(number of scenarios and chunks, simulated seconds) and, for the record only, the
versions of Python, numpy, gymnasium and pyarrow.

A restart into a directory that already holds a manifest must have the same settings
(:data:`PINNED`); any difference raises :class:`CampaignError` naming each field, so
results of different campaigns are never mixed -- except more ``hours``, which extend the
campaign (:func:`acc_gym.campaigns.campaign.run_campaign`): the fingerprint leaves hours
out, since a shorter campaign's scenarios are a prefix of a longer one's. The ``fingerprint`` (a hash of the pinned
fields) is also written into every chunk file and into ``summary.json``, so a file
copied in from another campaign is refused too.
"""

from __future__ import annotations

import hashlib
import json
import platform
from dataclasses import asdict, dataclass

from acc_gym.campaigns.errors import CampaignError

FORMAT = "acc_gym.campaign/1"
PINNED = ("format", "suite", "suite_version", "suite_hash", "env_id", "split", "root_seed", "controller",
          "controller_code", "hours", "chunk_size", "acc_gym_version")


@dataclass(frozen=True)
class Settings:
    """The pinned settings of a campaign (see :data:`PINNED`)."""

    suite: str
    suite_version: str
    suite_hash: str
    env_id: str
    split: str
    root_seed: int
    controller: str
    controller_code: str  # sha256 of the controller's files (acc_gym.leaderboard.provenance.code_digest)
    hours: float
    chunk_size: int
    acc_gym_version: str
    format: str = FORMAT

    @property
    def fingerprint(self) -> str:
        """A hash of the pinned settings except ``hours``: a campaign extended to more hours
        keeps its chunks (its scenarios are a prefix of the longer plan's)."""
        blob = json.dumps({k: getattr(self, k) for k in PINNED if k != "hours"}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()[:20]


def versions() -> dict:
    """Versions of what the results may depend on (recorded, not compared)."""
    import gymnasium
    import numpy

    import acc_gym

    out = {"python": platform.python_version(), "acc_gym": acc_gym.__version__, "numpy": numpy.__version__,
           "gymnasium": gymnasium.__version__}
    try:
        import pyarrow

        out["pyarrow"] = pyarrow.__version__
    except ImportError:  # pragma: no cover
        pass
    return out


def build_manifest(settings: Settings, n_scenarios: int, n_chunks: int, planned_seconds: float) -> dict:
    return {**asdict(settings), "fingerprint": settings.fingerprint, "n_scenarios": int(n_scenarios),
            "n_chunks": int(n_chunks), "planned_seconds": float(planned_seconds), "versions": versions()}


def check_manifest(manifest: dict, path) -> Settings:
    """The settings a manifest read from ``path`` holds, after checking its shape."""
    if not isinstance(manifest, dict):
        raise CampaignError(f"{path} is not a campaign manifest (not a JSON object)")
    if manifest.get("format") != FORMAT:
        raise CampaignError(f"{path} is not a campaign manifest of format {FORMAT!r} "
                            f"(format {manifest.get('format')!r})")
    missing = [k for k in (*PINNED, "fingerprint", "n_scenarios", "n_chunks", "planned_seconds")
               if k not in manifest]
    if missing:
        raise CampaignError(f"campaign manifest {path} is missing {missing}")
    settings = Settings(**{k: manifest[k] for k in PINNED})
    if settings.fingerprint != manifest["fingerprint"]:
        raise CampaignError(f"campaign manifest {path} was edited: its fingerprint {manifest['fingerprint']!r} does "
                            f"not match its settings ({settings.fingerprint!r})")
    return settings


def compare(existing: Settings, wanted: Settings, path) -> None:
    """Raise :class:`CampaignError` naming every pinned field that differs."""
    diffs = [f"{k}: {getattr(existing, k)!r} there, {getattr(wanted, k)!r} now" for k in PINNED
             if getattr(existing, k) != getattr(wanted, k) and k != "controller_code"]
    if existing.controller_code != wanted.controller_code and existing.controller == wanted.controller:
        diffs.append(f"the code of controller {wanted.controller!r} changed since the campaign started (sha256 "
                     f"{existing.controller_code[:16]}... there, {wanted.controller_code[:16]}... now): its rows would "
                     f"mix two controllers")
    if diffs:
        raise CampaignError(f"{path} belongs to a campaign with other settings ({'; '.join(diffs)}); "
                            f"use another output directory, or the same settings to resume it")
