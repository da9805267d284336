"""What a leaderboard row ran: a digest of each controller's code, found without running it.

A results row names a controller by reference (``acc``, ``mypkg.law:Law``, ``runs/ppo``);
the same reference can mean other code tomorrow. :func:`code_digest` records what it
meant today: the sha256 over the files the reference loads from, located the way the
controller's own process will import them (the runner's ``sys.path``, then its working
directory) but **without importing anything**: :class:`importlib.machinery.PathFinder`
reads directories, it does not execute a module (nor does a top-level
:func:`importlib.util.find_spec`, the fallback for editable installs), so a hostile module
gets no chance to run in the trusted process.

What is hashed (decided here):

* ``module:attribute`` -- the top-level module's files: a package's whole directory (every
  regular file under it, by relative path, ``__pycache__`` and ``*.pyc`` left out, so
  weights and data files count), or a single module's file -- that file only: the data a
  single-file module reads beside it is not covered (its directory is usually the host's
  working directory, holding anything); ship data inside a package to have it pinned;
* a registered name -- the same for the module its entry point (or
  :func:`acc_gym.controllers.register_controller` factory) lives in: for the built-ins
  that is the installed ``acc_gym_agents`` package, shipped policy included;
* a saved model's path -- the directory's files (or the one file).

The digest is ``sha256`` over ``relative path NUL sha256(content) LF`` lines in sorted
order, so it depends on names and contents, not on timestamps or the order a file system
lists them. It pins the controller's own code, not what that code imports from elsewhere
(numpy, torch, acc_gym: their versions are in the manifest).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
from importlib import machinery
from pathlib import Path

SKIPPED_DIRS = {"__pycache__", ".git"}


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def files_digest(root: Path) -> tuple[str, int]:
    """``(sha256, number of files)`` of a file or of every regular file under a directory."""
    root = Path(root)
    if root.is_file():
        items = [(root.name, root)]
    else:
        items = []
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = sorted(d for d in dirnames if d not in SKIPPED_DIRS)
            for name in filenames:
                p = Path(dirpath) / name
                if name.endswith(".pyc") or not p.is_file():
                    continue
                items.append((p.relative_to(root).as_posix(), p))
    h = hashlib.sha256()
    for rel, p in sorted(items):
        h.update(rel.encode("utf-8", "surrogateescape") + b"\0" + _file_sha256(p).encode("ascii") + b"\n")
    return h.hexdigest(), len(items)


def module_location(module: str, search: list[str], meta_path: bool = True) -> Path | None:
    """The file or package directory the top-level module of ``module`` would import from
    (``None`` if it is not found on ``search`` -- nor, with ``meta_path``, by an installed
    finder -- or is built into the interpreter)."""
    top = module.split(".")[0]
    spec = machinery.PathFinder.find_spec(top, search)
    if spec is None and meta_path:  # an editable install's finder (sys.meta_path): a top-level lookup imports nothing
        try:
            spec = importlib.util.find_spec(top)
        except (ImportError, ValueError):
            spec = None
    if spec is None:
        return None
    if spec.submodule_search_locations:  # a package (a namespace package: its first portion)
        return Path(list(spec.submodule_search_locations)[0])
    if spec.origin and os.path.isfile(spec.origin):
        return Path(spec.origin)
    return None


def _module_of_name(name: str) -> str | None:
    from acc_gym import controllers

    if name in controllers._REGISTERED:
        return getattr(controllers._REGISTERED[name][0], "__module__", None)
    eps = controllers._entry_points(controllers.GROUP).get(name)
    return eps[0].module if eps else None


def code_digest(reference: str, search: list[str] | None = None) -> dict:
    """``{"kind", "path", "files", "sha256"}`` for a controller reference (``sha256`` is None,
    with ``why``, where the code cannot be located without running it)."""
    from acc_gym.leaderboard.sandbox import search_path

    search = search_path() if search is None else search
    module = None
    if os.path.exists(reference):
        kind, where = "files", Path(reference).resolve()
    else:
        module = reference.split(":", 1)[0] if ":" in reference else _module_of_name(reference)
        kind = "module"
        where = module_location(module, search) if module else None
    if where is None:
        return {"kind": kind, "module": module, "path": None, "files": 0, "sha256": None,
                "why": f"cannot locate the code of {reference!r} without running it"}
    digest, n = files_digest(where)
    out = {"kind": kind, "path": str(where), "files": n, "sha256": digest}
    if module is not None:
        out["module"] = module.split(".")[0]
    return out
