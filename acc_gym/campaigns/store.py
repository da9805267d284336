"""A campaign's files: ``campaign.json``, ``chunks/chunk-NNNNNN.parquet``, ``summary.json``.

**Atomic writes.** Every file is written to a temporary file in the same directory
(``.NAME.PID.RANDOM.tmp``), flushed to disk, then moved over its name with
``os.replace``: a reader (or a resumed campaign) sees either the whole file or none. A
campaign killed mid-write leaves at most a stray temporary file, which is ignored and
removed when the campaign resumes. One campaign process per directory.

**Checksums.** Each chunk's sha256 is written to ``chunk-NNNNNN.sha256`` beside it
*before* the chunk file itself is moved into place (both atomically), and checked on
every read: a flipped bit inside a Parquet page -- which Parquet itself may read without
complaint, as a different number -- is refused naming the file. A crash between the two
writes leaves a checksum without its chunk, and the chunk simply runs again. Once the
chunk file is in place, its sha256 is also recorded in ``campaign.json``
(:data:`acc_gym.campaigns.manifest.CHECKSUMS`, the manifest rewritten atomically), and a
chunk whose ``.sha256`` file disagrees with that record -- the pair replaced after the
campaign recorded it -- is refused by name too. The ``.sha256`` file is what lets a
chunk be verified when ``campaign.json`` itself is lost (see
:func:`acc_gym.campaigns.campaign.run_campaign`).

**Validation.** A chunk file counts only if its checksum matches, it reads as Parquet, has exactly the
expected schema (:data:`acc_gym.campaigns.episodes.COLUMNS`), carries the campaign's
fingerprint and chunk number in its metadata, holds one row for each of the chunk's
scenario indices, in order, and its checksum is the one the manifest records (if it records one). Since writes
are atomic, a file failing these checks was
damaged or put there by something else: it raises :class:`CampaignError` naming the file
(and saying to delete it to run that chunk again) instead of being re-run silently or,
worse, read as empty. The same holds for ``summary.json``. A ``campaign.json`` that no
longer reads as JSON raises :class:`UnreadableFileError`; running the campaign again with
its settings rebuilds it from the chunk files that verify.
"""

from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path

from acc_gym._io import atomic_write as _atomic_write
from acc_gym.campaigns.episodes import COLUMN_NAMES, COLUMNS
from acc_gym.campaigns.errors import CampaignError, require_pyarrow
from acc_gym.campaigns.plan import Chunk

MANIFEST = "campaign.json"
SUMMARY = "summary.json"
CHUNK_DIR = "chunks"
META_FINGERPRINT = b"acc_gym.campaign.fingerprint"
META_CHUNK = b"acc_gym.campaign.chunk"


class UnreadableFileError(CampaignError):
    """A JSON file of the campaign (``campaign.json``, ``summary.json``) is not readable JSON
    (truncated, overwritten, not an object): its content is lost, unlike one that reads but
    does not check out."""


def chunk_path(out_dir, number: int) -> Path:
    return Path(out_dir) / CHUNK_DIR / f"chunk-{number:06d}.parquet"


def checksum_path(out_dir, number: int) -> Path:
    return Path(out_dir) / CHUNK_DIR / f"chunk-{number:06d}.sha256"


def atomic_write(path, write) -> None:
    """Call ``write(file)`` on a temporary file next to ``path``, fsync, then ``os.replace`` it onto ``path``
    (:func:`acc_gym._io.atomic_write`; temporary files match ``.*.tmp``)."""
    _atomic_write(path, write)


def write_json(path, obj) -> None:
    text = (json.dumps(obj, indent=1, allow_nan=False) + "\n").encode()
    try:
        atomic_write(path, lambda f: f.write(text))
    except OSError as exc:
        raise CampaignError(f"could not write {path}: {exc.strerror or exc} (errno {exc.errno}); the chunk files "
                            f"written so far are kept, run the campaign again once there is room") from None


def write_json_if_changed(path, obj) -> bool:
    """Write ``obj`` unless ``path`` already holds it (a finished campaign in a read-only
    directory can still be summarised); True if it wrote."""
    path = Path(path)
    try:
        if path.is_file() and json.loads(path.read_text()) == json.loads(json.dumps(obj, allow_nan=False)):
            return False
    except (json.JSONDecodeError, UnicodeDecodeError, OSError):
        pass
    write_json(path, obj)
    return True


# what to do about a damaged file: the summary is derived from the chunks; the manifest is rebuilt from the
# settings asked for, keeping the chunk files that verify against them (each carries its checksum and fingerprint)
MANIFEST_ADVICE = ("run the campaign again with the settings it was started with: the manifest is rebuilt from "
                   "them, every chunk file whose checksum and fingerprint verify is kept, and any that does not is "
                   "refused by name, nothing deleted (or restore the manifest from a copy)")
_ADVICE = {"campaign summary": "delete it (the next run or summarise_campaign rewrites it from the chunk files)",
           "campaign manifest": MANIFEST_ADVICE}


def read_json(path, what: str) -> dict:
    path = Path(path)
    advice = _ADVICE.get(what, "delete the whole directory")
    try:
        obj = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UnreadableFileError(f"{what} {path} is corrupted or truncated ({exc}); {advice}") from None
    if not isinstance(obj, dict):
        raise UnreadableFileError(f"{what} {path} is corrupted: not a JSON object; {advice}")
    return obj


def remove_stray_temps(out_dir) -> list[Path]:
    """Delete temporary files a killed campaign left behind; return them."""
    out = []
    for folder in (Path(out_dir), Path(out_dir) / CHUNK_DIR):
        if folder.is_dir():
            for p in folder.glob(".*.tmp"):
                p.unlink(missing_ok=True)
                out.append(p)
    return out


def schema():
    pa, _ = require_pyarrow()
    return pa.schema([pa.field(name, getattr(pa, kind)(), nullable=nullable) for name, kind, nullable, _ in COLUMNS])


def write_chunk(out_dir, chunk: Chunk, rows: list[dict], fingerprint: str) -> str:
    """Write a chunk's rows to its Parquet file (atomically), its sha256 first to its ``.sha256``
    file; refuse rows that do not match the chunk. Returns the sha256 (for the manifest)."""
    pa, pq = require_pyarrow()
    got = [r["index"] for r in rows]
    if got != list(chunk.indices):
        raise CampaignError(f"chunk {chunk.number}: a worker returned rows for indices {got}, "
                            f"expected {list(chunk.indices)}")
    sch = schema().with_metadata({META_FINGERPRINT: fingerprint.encode(), META_CHUNK: str(chunk.number).encode()})
    table = pa.Table.from_pylist(rows, schema=sch)
    buf = io.BytesIO()
    pq.write_table(table, buf)
    data = buf.getvalue()
    digest = sha256(data)
    path = chunk_path(out_dir, chunk.number)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        atomic_write(checksum_path(out_dir, chunk.number), lambda f: f.write((digest + "\n").encode()))
        atomic_write(path, lambda f: f.write(data))
    except OSError as exc:  # a full disk, a read-only directory: name the file, keep what was written
        raise CampaignError(f"could not write chunk file {path}: {exc.strerror or exc} (errno {exc.errno}); the "
                            f"chunk files written so far are kept, run the campaign again to finish") from None
    return digest


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


DELETE_HINT = "; delete it to run that chunk again"  # what to do about a chunk file that does not validate


def read_checksum(out_dir, number: int) -> str:
    """The sha256 in chunk ``number``'s ``.sha256`` file (refused by name if missing or unreadable)."""
    path = checksum_path(out_dir, number)
    try:
        return path.read_text().strip()
    except (FileNotFoundError, UnicodeDecodeError):
        raise CampaignError(f"chunk file {chunk_path(out_dir, number)} has no checksum ({path.name} is missing or "
                            f"unreadable){DELETE_HINT}") from None


def read_chunk(out_dir, chunk: Chunk, fingerprint: str, in_manifest: str | None = None):
    """The chunk's rows as an Arrow table, after validating the file (see the module docstring);
    ``in_manifest``: the sha256 the manifest records for it (None: none recorded yet)."""
    pa, pq = require_pyarrow()
    path = chunk_path(out_dir, chunk.number)
    hint = DELETE_HINT
    data = path.read_bytes()  # FileNotFoundError: not run yet
    recorded = read_checksum(out_dir, chunk.number)
    if sha256(data) != recorded:
        raise CampaignError(f"chunk file {path} is damaged: its sha256 {sha256(data)[:16]}... is not the one recorded "
                            f"when it was written ({recorded[:16]}...){hint}")
    try:
        table = pq.read_table(io.BytesIO(data))
    except FileNotFoundError:
        raise
    except (pa.ArrowException, OSError) as exc:
        raise CampaignError(f"chunk file {path} is corrupted or truncated ({exc}){hint}") from None
    meta = table.schema.metadata or {}
    if meta.get(META_FINGERPRINT) != fingerprint.encode():
        raise CampaignError(f"chunk file {path} belongs to another campaign (fingerprint "
                            f"{meta.get(META_FINGERPRINT, b'none').decode()!r}, expected {fingerprint!r}){hint}")
    if meta.get(META_CHUNK) != str(chunk.number).encode():
        raise CampaignError(f"chunk file {path} holds chunk {meta.get(META_CHUNK, b'none').decode()}, "
                            f"not {chunk.number}{hint}")
    table = table.replace_schema_metadata(None)
    if not table.schema.equals(schema()):
        raise CampaignError(f"chunk file {path} has columns {table.schema.names}, expected {list(COLUMN_NAMES)}{hint}")
    if table.column("index").to_pylist() != list(chunk.indices):
        raise CampaignError(f"chunk file {path} holds {table.num_rows} rows, not one for each of scenarios "
                            f"{chunk.start}..{chunk.stop - 1}{hint}")
    if in_manifest is not None and in_manifest != recorded:
        raise CampaignError(f"chunk file {path} and its {checksum_path(out_dir, chunk.number).name} agree (sha256 "
                            f"{recorded[:16]}...), but {MANIFEST} records {in_manifest[:16]}... for it: the pair was "
                            f"replaced after the campaign recorded the chunk{hint} (and its .sha256 file)")
    return table


def chunk_exists(out_dir, chunk: Chunk) -> bool:
    return chunk_path(out_dir, chunk.number).is_file()
