"""Run, resume and load a Monte Carlo campaign.

:func:`run_campaign` plans the campaign (:mod:`~acc_gym.campaigns.plan`), writes or checks
its manifest (:mod:`~acc_gym.campaigns.manifest`), skips every chunk whose file already
exists and validates (:mod:`~acc_gym.campaigns.store`), runs the rest on a backend
(:mod:`~acc_gym.campaigns.backends`), writes each chunk's file as soon as it arrives, and
finally writes ``summary.json`` (:mod:`~acc_gym.campaigns.summary`). A campaign stopped at
any point (killed, Ctrl-C, ``max_chunks``) and run again with the same settings finishes
the missing chunks only: each episode is stored exactly once, and the results are the
same as an uninterrupted run's.

**A lost manifest.** If ``campaign.json`` is missing, or no longer reads as JSON
(truncated, overwritten), while chunk files remain, a run with the campaign's settings
rebuilds it: every chunk file is checked against the settings asked for -- its own
``.sha256`` file, the fingerprint and chunk number it carries, its rows -- and, only if
all of them verify, they are adopted (recorded in the new manifest) and the missing
chunks run; the summary is then the same as an uninterrupted run's. A chunk file that does
not verify (other settings, damage) stops the run naming it, before anything is written,
and nothing is deleted: run again with the settings it was written with, or move it away.
A damaged manifest is kept as ``campaign.json.damaged``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from acc_gym.campaigns import store
from acc_gym.campaigns.episodes import ChunkTask
from acc_gym.campaigns.errors import CampaignError, require_distributed, require_pyarrow
from acc_gym.campaigns.manifest import CHECKSUMS, Settings, build_manifest, check_manifest, compare
from acc_gym.campaigns.plan import (Chunk, check_hours, check_positive_int, check_root_seed, check_split, chunks,
                                    plan_length, resolve_suite)

DEFAULT_CHUNK_SIZE = 20
_CHUNK_FILE = re.compile(r"^chunk-(\d{6})\.parquet$")
_CHECKSUM_FILE = re.compile(r"^chunk-(\d{6})\.sha256$")


@dataclass(frozen=True)
class Campaign:
    """A campaign directory's manifest and the rows of its finished chunks (sorted by scenario index)."""

    out_dir: Path
    manifest: dict
    settings: Settings
    table: object  # pyarrow.Table
    chunks_done: tuple  # chunk numbers with a valid file
    checksums: dict = field(default_factory=dict)  # chunk file name -> sha256, of each valid chunk file

    @property
    def unrecorded(self) -> dict:
        """Valid chunk files whose sha256 the manifest does not record yet (name -> sha256)."""
        recorded = self.manifest.get(CHECKSUMS, {})
        return {name: digest for name, digest in self.checksums.items() if name not in recorded}

    @property
    def complete(self) -> bool:
        return len(self.chunks_done) == self.manifest["n_chunks"]

    @property
    def episodes(self) -> int:
        return self.table.num_rows

    def rows(self) -> list[dict]:
        return self.table.to_pylist()

    def missing_chunks(self) -> list[Chunk]:
        done = set(self.chunks_done)
        return [c for c in self.all_chunks() if c.number not in done]

    def all_chunks(self) -> list[Chunk]:
        return chunks(self.manifest["n_scenarios"], self.manifest["chunk_size"])


def _read_manifest(out_dir: Path) -> tuple[dict, Settings]:
    path = out_dir / store.MANIFEST
    manifest = store.read_json(path, "campaign manifest")
    return manifest, check_manifest(manifest, path)


def _check_chunk_files(out_dir: Path, n_chunks: int) -> None:
    folder = out_dir / store.CHUNK_DIR
    if not folder.is_dir():
        return
    for p in sorted(folder.iterdir()):
        if p.name.startswith(".") and p.name.endswith(".tmp"):
            continue
        if _CHECKSUM_FILE.match(p.name) and int(p.name[6:12]) < n_chunks:
            continue
        m = _CHUNK_FILE.match(p.name)
        if m is None or int(m.group(1)) >= n_chunks:
            raise CampaignError(f"{p} is not a chunk file of this campaign ({n_chunks} chunks: chunk-000000.parquet "
                                f".. chunk-{n_chunks - 1:06d}.parquet); move it away")


def _has_chunk_files(out_dir: Path) -> bool:
    folder = out_dir / store.CHUNK_DIR
    return folder.is_dir() and any(folder.glob("chunk-*"))


def load_campaign(out_dir) -> Campaign:
    """A campaign directory's manifest and validated results so far (see :mod:`acc_gym.campaigns.store`)."""
    require_pyarrow()
    out_dir = Path(out_dir)
    if not (out_dir / store.MANIFEST).is_file():
        if _has_chunk_files(out_dir):
            raise CampaignError(f"{out_dir} holds chunk files but no {store.MANIFEST}; to rebuild it, "
                                f"{store.MANIFEST_ADVICE}")
        raise CampaignError(f"{out_dir} holds no campaign ({store.MANIFEST} not found)")
    manifest, settings = _read_manifest(out_dir)
    return _load(out_dir, manifest, settings)


def _load(out_dir: Path, manifest: dict, settings: Settings) -> Campaign:
    """The campaign of ``manifest`` with every chunk file there validated."""
    pa, _ = require_pyarrow()
    _check_chunk_files(out_dir, manifest["n_chunks"])
    recorded = manifest.get(CHECKSUMS, {})
    tables, done, checksums = [], [], {}
    for chunk in chunks(manifest["n_scenarios"], manifest["chunk_size"]):
        if store.chunk_exists(out_dir, chunk):
            name = store.chunk_path(out_dir, chunk.number).name
            tables.append(store.read_chunk(out_dir, chunk, settings.fingerprint, recorded.get(name)))
            done.append(chunk.number)
            checksums[name] = store.read_checksum(out_dir, chunk.number)
    table = pa.concat_tables(tables) if tables else store.schema().empty_table()
    return Campaign(out_dir, manifest, settings, table, tuple(done), checksums)


def _record(out_dir: Path, manifest: dict, checksums: dict) -> dict:
    """The manifest with ``checksums`` (chunk file name -> sha256) recorded, written atomically."""
    manifest = {**manifest, CHECKSUMS: dict(sorted({**manifest.get(CHECKSUMS, {}), **checksums}.items()))}
    store.write_json(out_dir / store.MANIFEST, manifest)
    return manifest


def _rebuild(out_dir: Path, settings: Settings, suite_obj, damaged: CampaignError | None) -> dict:
    """A new manifest for ``settings`` when ``campaign.json`` is missing (``damaged`` None) or unreadable,
    adopting every chunk file there -- each must verify against ``settings`` (checksum, fingerprint, chunk
    number, rows) -- and written only once all do; a damaged manifest is kept beside it."""
    path = out_dir / store.MANIFEST
    n, seconds = plan_length(suite_obj, settings.split, settings.root_seed, settings.hours)
    manifest = build_manifest(settings, n, len(chunks(n, settings.chunk_size)), seconds)
    try:
        found = _load(out_dir, manifest, settings)
    except CampaignError as exc:
        state = "is missing" if damaged is None else "is damaged"
        raise CampaignError(f"{path} {state}, and it cannot be rebuilt from the chunk files with the settings asked "
                            f"for: {str(exc).replace(store.DELETE_HINT, '')}. If the chunk files were written with "
                            f"other settings (suite, split, root seed, controller or its code, chunk size, hours, "
                            f"acc-gym version), run again with those; if that file is damaged or foreign, move it "
                            f"away (or delete it) to run its chunk again. Nothing was written or deleted") from None
    manifest[CHECKSUMS] = dict(sorted(found.checksums.items()))
    if damaged is not None:
        os.replace(path, path.with_name(store.MANIFEST + ".damaged"))
    store.write_json(path, manifest)
    return manifest


def _extend(out_dir: Path, manifest: dict, existing: Settings, settings: Settings, suite_obj) -> dict:
    """Grow a campaign to ``settings.hours``: the scenarios of the shorter plan are a prefix of
    the longer one's (the same stream, indices in order), so its full chunks stay; a partial
    last chunk is deleted first (it runs again with its new scenarios), then the manifest is
    rewritten. Asking for fewer hours than the campaign holds is refused."""
    path = out_dir / store.MANIFEST
    if settings.hours < existing.hours:
        raise CampaignError(f"{path} holds a campaign of {existing.hours:g} h; asking for {settings.hours:g} h "
                            f"would drop episodes (summarise it as it is, or use another output directory)")
    n, seconds = plan_length(suite_obj, settings.split, settings.root_seed, settings.hours)
    old_n, size = int(manifest["n_scenarios"]), settings.chunk_size
    if n < old_n:  # cannot happen for one stream; refuse rather than mix
        raise CampaignError(f"{path}: {settings.hours:g} h plan {n} scenarios, fewer than the {old_n} there")
    checksums = dict(manifest.get(CHECKSUMS, {}))
    if old_n % size:
        partial = old_n // size
        for p in (store.chunk_path(out_dir, partial), store.checksum_path(out_dir, partial)):
            p.unlink(missing_ok=True)
        checksums.pop(store.chunk_path(out_dir, partial).name, None)
    new = build_manifest(settings, n, len(chunks(n, size)), seconds, checksums)
    store.write_json(path, new)
    return new


def _controller_ref(controller) -> str:
    """Check the controller loads here (fail before planning) and return its reference; a saved model's path
    is made absolute so that workers started elsewhere find it."""
    if not isinstance(controller, str) or not controller:
        raise CampaignError(f"controller must be a reference string (a built-in name, 'module:attribute' or a "
                            f"saved model path), got {controller!r}")
    from acc_gym.evaluation.runner import load_controller

    try:
        load_controller(controller)
    except (ValueError, TypeError) as exc:
        raise CampaignError(str(exc)) from None
    if ":" not in controller and Path(controller).exists():
        return str(Path(controller).resolve())
    return controller


def run_campaign(suite, hours: float | None, controller: str, out_dir, *, split: str = "test", root_seed: int | None = None,
                 workers: int = 1, scheduler=None, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 max_chunks: int | None = None, confidence: float = 0.95, on_chunk=None,
                 on_start=None) -> dict:
    """Run (or resume) a campaign of ``hours`` of ``suite``'s traffic with ``controller``; return its summary.

    ``suite``: a registered name (``"singlelane-v3"``), a suite object, or an OpenSCENARIO variation
    (:class:`acc_gym.campaigns.sweep.VariationSweep`, with ``hours=None``: every concrete scenario
    of it); ``split``: ``"dev"`` or
    ``"test"``; ``root_seed``: default the split's own (see :mod:`acc_gym.campaigns.plan`);
    ``workers``: local processes (1: this process), or the ``LocalCluster`` size with
    ``scheduler="local"``; ``scheduler``: a Dask scheduler address, ``"local"`` or a
    ``distributed.Client`` (see :mod:`acc_gym.campaigns.backends`); ``chunk_size``:
    scenarios per task and per file; ``max_chunks``: run at most that many missing chunks
    now (the rest on a later call); ``on_chunk(number, done, total)``: called after each
    chunk file is written; ``on_start(done, total)``: once before the first chunk runs (the
    chunks already there, and all of them). Results go to ``out_dir``.
    """
    require_pyarrow()
    sweep = hasattr(suite, "n_points")  # an OpenSCENARIO variation: all its scenarios, no hours (campaigns.sweep)
    if sweep and hours is not None:
        raise CampaignError("a variation's campaign runs every concrete scenario of it: hours do not apply")
    hours = 0.0 if sweep else check_hours(hours)
    chunk_size = check_positive_int("chunk size", chunk_size)
    workers = check_positive_int("workers", workers)
    if max_chunks is not None:
        max_chunks = check_positive_int("max_chunks", max_chunks)
    if not 0.0 < confidence < 1.0:
        raise CampaignError(f"confidence must be in (0, 1), got {confidence!r}")
    if scheduler is not None:
        distributed = require_distributed()
        if not (isinstance(scheduler, distributed.Client) or (isinstance(scheduler, str) and scheduler)):
            raise CampaignError(f"scheduler must be a Dask scheduler address, 'local' or a distributed.Client, "
                                f"got {scheduler!r}")
    split = check_split(split)
    suite_obj = resolve_suite(suite)
    root = suite_obj.root_seed(split) if root_seed is None else check_root_seed(root_seed)
    controller = _controller_ref(controller)
    import acc_gym

    from acc_gym.leaderboard.provenance import code_digest

    code = code_digest(controller)
    settings = Settings(suite=str(suite_obj.name), suite_version=str(suite_obj.version),
                        suite_hash=str(suite_obj.hash(split)), env_id=str(suite_obj.env_id), split=split,
                        root_seed=int(root), controller=controller,
                        controller_code=code["sha256"] or f"unlocated: {code.get('why')}", hours=hours,
                        chunk_size=chunk_size, acc_gym_version=acc_gym.__version__)
    out_dir = Path(out_dir)
    manifest_path = out_dir / store.MANIFEST
    damaged = None
    if manifest_path.is_file():
        try:
            manifest, existing = _read_manifest(out_dir)
        except store.UnreadableFileError as exc:  # truncated, overwritten: rebuilt from the chunk files below
            damaged = exc
    if manifest_path.is_file() and damaged is None:
        if existing.hours != settings.hours and replace(existing, hours=settings.hours) == settings:
            manifest = _extend(out_dir, manifest, existing, settings, suite_obj)
        else:
            compare(existing, settings, manifest_path)
    elif damaged is not None or _has_chunk_files(out_dir):
        manifest = _rebuild(out_dir, settings, suite_obj, damaged)
    else:
        n, seconds = plan_length(suite_obj, split, settings.root_seed, hours)
        manifest = build_manifest(settings, n, len(chunks(n, chunk_size)), seconds)
        store.write_json(manifest_path, manifest)
    store.remove_stray_temps(out_dir)
    done = load_campaign(out_dir)  # validates every chunk file already there
    if done.unrecorded:  # written by a run killed before it recorded them, or before manifests recorded checksums
        manifest = _record(out_dir, manifest, done.unrecorded)
    todo = done.missing_chunks()
    if max_chunks is not None:
        todo = todo[:max_chunks]
    # workers resolve a suite given by name themselves (no pickling of suite objects to remote workers)
    task_suite = suite if isinstance(suite, str) else suite_obj
    tasks = [ChunkTask(task_suite, split, settings.root_seed, controller, settings.env_id, c) for c in todo]
    from acc_gym.campaigns.backends import execute

    n_done, total = len(done.chunks_done), manifest["n_chunks"]
    if on_start is not None:
        on_start(n_done, total)
    results = execute(tasks, workers=workers, scheduler=scheduler, fingerprint=settings.fingerprint)
    try:
        for task, rows in results:
            digest = store.write_chunk(out_dir, task.chunk, rows, settings.fingerprint)
            manifest = _record(out_dir, manifest, {store.chunk_path(out_dir, task.chunk.number).name: digest})
            n_done += 1
            if on_chunk is not None:
                on_chunk(task.chunk.number, n_done, total)
    finally:
        results.close()
    from acc_gym.campaigns.summary import summarise_campaign

    summary = summarise_campaign(load_campaign(out_dir), confidence)
    store.write_json_if_changed(out_dir / store.SUMMARY, summary)  # a finished, read-only campaign still summarises
    return summary
