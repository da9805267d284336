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

**Chunk checksums.** ``chunk_sha256`` maps each finished chunk's file name to its sha256
(:data:`CHECKSUMS`). The manifest is rewritten (atomically, like every file) after each
chunk file is in place, so it records every chunk but the one a kill may have interrupted
between the two writes; such a chunk, valid by its own ``.sha256`` file and fingerprint, is
recorded on the next run. A chunk whose bytes, ``.sha256`` file and recorded sha256 do not
all agree is refused by name (:mod:`acc_gym.campaigns.store`). A manifest without the key (written before
it existed, with the ``.sha256`` files) is upgraded the same way on the next run.

**Older versions.** Campaigns written by acc-gym before it pinned the controller's code
(whose chunks have no checksums), or before the fingerprint left ``hours`` out, cannot be
checked by this version: they are refused with a message that says so and what to do
(start again in a new directory; the older acc-gym can still summarise them). The same holds
for format ``acc_gym.campaign/1`` (:data:`OLDER_FORMATS`): its chunk files lack the
``preventable`` column format ``/2`` added (:mod:`acc_gym.campaigns.episodes`). Decided: the
format is bumped rather than the column made optional, since the chunk schema is checked
exactly and a ``/1`` chunk holds no verdict to give; the format is pinned in the
fingerprint, so ``/1`` chunk files are refused as another campaign's even without their
manifest.
"""

from __future__ import annotations

import hashlib
import json
import platform
import re
from dataclasses import asdict, dataclass

from acc_gym.campaigns.errors import CampaignError

FORMAT = "acc_gym.campaign/2"  # /2: chunk files carry the UN R157 ``preventable`` column
OLDER_FORMATS = {"acc_gym.campaign/1": "have no UN R157 'preventable' column in their chunk files (format "
                                       "acc_gym.campaign/1; this version writes acc_gym.campaign/2)"}
PINNED = ("format", "suite", "suite_version", "suite_hash", "env_id", "split", "root_seed", "controller",
          "controller_code", "hours", "chunk_size", "acc_gym_version")
CHECKSUMS = "chunk_sha256"  # manifest key: chunk file name -> its sha256 (hex)
REQUIRED = (*PINNED, "fingerprint", "n_scenarios", "n_chunks", "planned_seconds")
# keys older acc-gym versions did not write (their campaigns cannot be checked by this one)
NEWER_KEYS = ("controller_code",)
_CHUNK_NAME = re.compile(r"^chunk-(\d{6})\.parquet$")
_SHA256 = re.compile(r"^[0-9a-f]{64}$")


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


def build_manifest(settings: Settings, n_scenarios: int, n_chunks: int, planned_seconds: float,
                   checksums: dict | None = None) -> dict:
    return {**asdict(settings), "fingerprint": settings.fingerprint, "n_scenarios": int(n_scenarios),
            "n_chunks": int(n_chunks), "planned_seconds": float(planned_seconds), "versions": versions(),
            CHECKSUMS: dict(sorted((checksums or {}).items()))}


def _legacy_fingerprint(manifest: dict) -> str | None:
    """The fingerprint acc-gym wrote before it left ``hours`` out (all of :data:`PINNED`)."""
    try:
        blob = json.dumps({k: manifest[k] for k in PINNED}, sort_keys=True)
    except (KeyError, TypeError, ValueError):
        return None
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def _older_version(path, manifest: dict, what: str) -> CampaignError:
    return CampaignError(
        f"{path} was written by an older version of acc-gym (acc_gym_version {manifest.get('acc_gym_version')!r} in "
        f"it), whose campaigns {what}; this version cannot check that directory's chunk files, so it neither resumes "
        f"nor summarises it. Run the campaign again with this version in a new, empty output directory (the old "
        f"directory is left as it is: the acc-gym version that wrote it can still summarise it)")


def check_checksums(manifest: dict, path) -> dict:
    """The manifest's chunk checksums (empty if it has none yet), after checking their shape."""
    recorded = manifest.get(CHECKSUMS, {})
    if not isinstance(recorded, dict):
        raise CampaignError(f"campaign manifest {path}: {CHECKSUMS} must map chunk file names to sha256 digests, "
                            f"got {type(recorded).__name__}")
    for name, digest in recorded.items():
        m = _CHUNK_NAME.match(name)
        if m is None or int(m.group(1)) >= manifest["n_chunks"]:
            raise CampaignError(f"campaign manifest {path}: {CHECKSUMS} names {name!r}, not a chunk file of this "
                                f"campaign ({manifest['n_chunks']} chunks)")
        if not isinstance(digest, str) or not _SHA256.match(digest):
            raise CampaignError(f"campaign manifest {path}: {CHECKSUMS}[{name!r}] is not a sha256 digest: {digest!r}")
    return dict(recorded)


def check_manifest(manifest: dict, path) -> Settings:
    """The settings a manifest read from ``path`` holds, after checking its shape."""
    if not isinstance(manifest, dict):
        raise CampaignError(f"{path} is not a campaign manifest (not a JSON object)")
    if manifest.get("format") in OLDER_FORMATS:
        raise _older_version(path, manifest, OLDER_FORMATS[manifest["format"]])
    if manifest.get("format") != FORMAT:
        raise CampaignError(f"{path} is not a campaign manifest of format {FORMAT!r} "
                            f"(format {manifest.get('format')!r})")
    missing = [k for k in REQUIRED if k not in manifest]
    if missing and set(missing) <= set(NEWER_KEYS):
        raise _older_version(path, manifest, "record no digest of the controller's code (no 'controller_code' in "
                                             "it) and no checksums of their chunk files")
    if missing:
        raise CampaignError(f"campaign manifest {path} is missing {missing}")
    settings = Settings(**{k: manifest[k] for k in PINNED})
    if settings.fingerprint != manifest["fingerprint"] and manifest["fingerprint"] == _legacy_fingerprint(manifest):
        raise _older_version(path, manifest, "fingerprint their settings with the hours included (their chunk files "
                                             "carry that fingerprint)")
    if settings.fingerprint != manifest["fingerprint"]:
        raise CampaignError(f"campaign manifest {path} was edited: its fingerprint {manifest['fingerprint']!r} does "
                            f"not match its settings ({settings.fingerprint!r})")
    for key in ("n_scenarios", "n_chunks"):
        if isinstance(manifest[key], bool) or not isinstance(manifest[key], int) or manifest[key] < 0:
            raise CampaignError(f"campaign manifest {path}: {key} must be a non-negative integer, got "
                                f"{manifest[key]!r}")
    check_checksums(manifest, path)
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
