"""A controller's own process: what it may touch, and the code it runs.

The leaderboard ranks strangers' code, so the controller never runs where the
simulation, the scoring, the clocks or the output live. Its process is started fresh
(``python -m acc_gym.leaderboard.sandbox``, not forked from the runner) and holds only
its end of a socket; it receives observations and answers actions
(:mod:`acc_gym.leaderboard.protocol`). Each episode in flight has its own copy of the
controller, made before its first call and ``reset()`` at every episode start, and it
is called with that episode's single observation row, exactly as
:func:`acc_gym.evaluation.runner.run_episode` calls it -- so a controller's episodes
are exactly the same here as under ``acc-gym evaluate``. (The string-stability column sends
one position's rows of every frequency under one slot: a vectorised controller's copy
answers them in one call, as ``acc-gym string-stability`` calls it, any other gets a
copy per row.)

What may run (:func:`vet`, before anything does): a ``module:attribute`` whose module is named
like a standard-library module, or like one importable from the installed path while a file of
that name sits in the working directory, is refused, naming the clash; a stranger's code
(anything but the package's own built-ins, :func:`is_builtin`) is refused as root without a
user id of its own unless the host allows it (``allow_root``; then every report carries a
warning), and on the private split it runs only under its own user id.

What the process sandbox (``sandbox="process"``, the default) guarantees:

* **no shared memory** with the runner: the simulator, the scenario (the lead's future),
  the scores and the runner's clocks are in other processes; the controller sees the
  observation rows, episode-start flags, nothing else;
* **nothing of the stranger's in a trusted process**: the simulations and the sandbox's
  start-up import only from :func:`trusted_path` (the runner's path without its working
  directory); the working directory, where ``module:attribute`` controllers are found, comes
  *last* on the controller's own path (:func:`controller_dirs`), so it shadows nothing;
* its **own session** (``setsid``), a fresh temporary working directory (also ``HOME``
  and ``TMPDIR``) that holds nothing of the host's, a **scrubbed environment**
  (:func:`controller_env`: the import path, thread counts of 1, the temporary directories),
  standard input closed, standard output and error through a pipe into its own log
  (:class:`LogSink`: at most ``log_bytes``, escape sequences and control characters removed);
  every text it sends (an error, a traceback) is cleaned the same way when received
  (:func:`acc_gym.leaderboard.protocol.clean_text`);
* **resource limits** (:class:`Limits`): address space, CPU time (the total budget plus a
  minute), open files (256), file size, the **disk** its working directory holds (measured by
  the trusted side every :data:`DISK_POLL_S`, :func:`disk_usage`: past ``disk_bytes`` its whole
  tree is killed and it fails, naming the limit); and, when the runner is root, a **cgroup** for its
  whole process tree (memory and number of processes, v1 or v2, where one can be made:
  :class:`acc_gym._process.Cgroups`), else, with its own user id, ``RLIMIT_NPROC``;
* when the runner is **root**, a **jail** built before the controller's code starts
  (:func:`acc_gym._process.jail`): its own network namespace (no network, not even
  127.0.0.1), a private ``/tmp`` and ``/dev/shm`` (tmpfs of ``tmp_bytes``, gone with it), and
  its **own unprivileged user id** where the interpreter is readable by others (a different
  one for every controller of a run): it cannot read the host's 0600 files (the private
  split's secret, the results key, a private run's results), write the installed package, the
  suite data or the output, nor signal (kill, stop, trace) the runner or a sibling;
* **nothing outlives it**: the simulation process that starts it is a child subreaper, so
  even a double-forked, ``setsid``'d grandchild is reparented to it and killed (with
  every other process of the controller's user id and of its cgroup) before any result is
  reported.

What it does not guarantee: without root the controller runs as the runner's user, with
the runner's network and ``/tmp``, so it *can* signal sibling processes and read and write
wherever that user can (the manifest says ``"uid_isolated": false`` and why, and its
``network`` and ``tmp``). ``sandbox="bwrap"`` adds bubblewrap's read-only root and a new PID
namespace (nothing else visible, nothing to signal); it needs the ``bwrap`` program.
"""

from __future__ import annotations

import copy
import os
import re
import resource
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acc_gym._process import become_subreaper, die_with_parent, kill_all, processes_of  # noqa: F401
from acc_gym.leaderboard import protocol

SANDBOXES = ("process", "bwrap")
ADDRESS_SPACE = 8 << 30  # [bytes] RLIMIT_AS
OPEN_FILES = 256
PROCESSES = 64  # RLIMIT_NPROC, applied with an own user id only (it counts per user)
CPU_MARGIN = 60.0  # [s] RLIMIT_CPU = total budget + this
LOG_BYTES = 8 << 20  # [bytes] of a controller's standard output and error kept in its log
DISK_BYTES = 1 << 30  # [bytes] its working directory may hold (numba's cache copy included)
DISK_POLL_S = 0.2  # [s] how often the trusted side measures it
ENTRY_BYTES = 4096  # [bytes] the least a file or directory counts for (an empty one still takes an inode)
CONTROLLER_PATH_ENV = "ACC_GYM_CONTROLLER_PATH"
_SERIAL = __import__("itertools").count()  # the controller's own directories, appended to its sys.path
UID_BASE = 1_900_000_000  # own user ids: UID_BASE + 100 * (runner pid % 1e6) + controller index


# -- the controller's side -------------------------------------------------------------------------
def _answer(controller, obs_row: np.ndarray, reference: str) -> float:
    from acc_gym.evaluation.runner import _action, as_action

    return float(as_action(_action(controller, obs_row.astype(np.float32)), reference)[0])


def _answer_rows(controller, rows: np.ndarray, reference: str) -> np.ndarray:
    """A vectorised controller's answer to ``rows`` ``(n, d)`` in one call, checked as
    :func:`acc_gym.evaluation.runner.as_action` checks one (shape, finite), clipped, float32."""
    from acc_gym.evaluation.runner import _action

    raw = np.asarray(_action(controller, rows.astype(np.float32)))
    if raw.dtype.kind not in "fiu" or raw.size != rows.shape[0]:
        raise ValueError(f"controller {reference!r} answered {rows.shape[0]} observations with an array of shape "
                         f"{raw.shape} ({raw.dtype}); expected {rows.shape[0]} numbers")
    values = raw.astype(np.float64).reshape(-1)
    if not np.all(np.isfinite(values)):
        raise ValueError(f"controller {reference!r} returned an action that is not finite: "
                         f"{values[~np.isfinite(values)][0]!r}")
    return np.clip(values, -1.0, 1.0).astype(np.float32)


def serve(sock: socket.socket, reference: str) -> None:
    """Load the controller, say hello, then answer batches until goodbye."""
    where = "loading the controller"
    try:
        from acc_gym.evaluation.runner import load_controller

        pristine = load_controller(reference)
        vectorised = bool(getattr(pristine, "vectorised", False))
        copies: dict = {}

        def fresh():  # a copy made before any call: every slot starts from the same state
            try:
                return copy.deepcopy(pristine)
            except Exception:  # noqa: BLE001  (not copyable: load it again)
                return load_controller(reference)

        def copy_for(key, start: bool):
            """The copy answering ``key``'s rows: made on first use, ``reset()`` at an episode start."""
            if key not in copies:
                copies[key] = fresh()
            if start and hasattr(copies[key], "reset"):
                copies[key].reset()
            return copies[key]

        from acc_gym.evaluation.runner import declared_time_gap

        protocol.send_hello(sock, declared_time_gap(pristine))
        step = 0
        while True:
            batch = protocol.recv_observations(sock)
            if batch is None:
                return
            obs, starts, slots = batch
            where = f"step batch {step}"
            actions = np.empty(obs.shape[0])
            groups: dict[int, list[int]] = {}
            for i, slot in enumerate(slots):
                groups.setdefault(int(slot), []).append(i)
            for slot, rows in groups.items():
                # one row per slot (every episode's path): that slot's copy answers it. Several rows
                # under one slot (a string-stability column position): one call with all of them when
                # the controller is vectorised, else a copy per row (the same copy each step)
                if len(rows) > 1 and vectorised:
                    actions[rows] = _answer_rows(copy_for(slot, starts[rows].any()), obs[rows], reference)
                    continue
                for k, i in enumerate(rows):
                    key = slot if len(rows) == 1 else (slot, k)
                    actions[i] = _answer(copy_for(key, starts[i]), obs[i], reference)
            protocol.send_actions(sock, actions)
            step += 1
    except protocol.Closed:
        return
    except BaseException as exc:  # noqa: BLE001  (whatever the controller does wrong is a result)
        try:
            first = str(exc).splitlines()[0] if str(exc) else ""
            protocol.send_error(sock, f"{type(exc).__name__}: {first} (in {where})\n{traceback.format_exc()}")
        except protocol.Closed:
            pass


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    fd, reference = int(argv[0]), argv[1]
    for p in os.environ.get(CONTROLLER_PATH_ENV, "").split(os.pathsep):  # after everything installed
        if p and p not in sys.path:
            sys.path.append(p)
    sock = socket.socket(fileno=fd)
    try:
        serve(sock, reference)
    finally:
        sock.close()
    return 0


# -- the trusted side ------------------------------------------------------------------------------
def _closed_to_others(path: str) -> str | None:
    """Why other users cannot read ``path`` (the file, or a directory above it they cannot
    enter, with its mode), or ``None`` when they can."""
    p = Path(path).resolve()
    try:
        for parent in reversed(p.parents):
            if not parent.stat().st_mode & 0o001:
                return f"{parent} is mode {parent.stat().st_mode & 0o7777:04o}"
        if not (p.stat().st_mode & (0o004 if p.is_file() else 0o005)):
            return f"{p} is mode {p.stat().st_mode & 0o7777:04o}"
    except OSError as exc:
        return f"{p}: {exc.strerror or exc}"
    return None


def trusted_path() -> list[str]:
    """The runner's ``sys.path`` entries that exist, absolute, without the working directory
    (nor ``""``, which means it): what the trusted processes -- the simulations, the sandbox's
    own start-up -- import from. A module beside the controllers (a ``signal.py``) is never
    imported by them."""
    cwd = os.path.realpath(os.getcwd())
    mine = {os.path.realpath(p) for p in controller_dirs()}
    out = []
    for p in sys.path:
        if not p or not os.path.exists(p):
            continue
        p = os.path.abspath(p)
        if os.path.realpath(p) != cwd and os.path.realpath(p) not in mine and p not in out:
            out.append(p)
    return out


def controller_dirs() -> list[str]:
    """Where a ``module:attribute`` controller is looked up besides :func:`trusted_path`: the
    directory the leaderboard is run from (in a simulation process, which runs elsewhere, the
    runner's: :data:`CONTROLLER_PATH_ENV`, set for it by
    :func:`acc_gym.leaderboard.isolation.trusted_start`). It comes *last* on the controller's
    path, so a file there never shadows a module the package, numpy or the standard library imports."""
    given = os.environ.get(CONTROLLER_PATH_ENV)
    if given is not None:
        return [p for p in given.split(os.pathsep) if p]
    return [os.path.abspath(os.getcwd())]


def search_path() -> list[str]:
    """The controller's import path, in order: :func:`trusted_path`, then :func:`controller_dirs`."""
    trusted = trusted_path()
    return trusted + [p for p in controller_dirs() if p not in trusted]


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def check_reference(reference: str) -> None:
    """``ValueError`` for a reference that must not run: one with control characters (it would
    be printed), or a ``module:attribute`` whose top-level module is named like a
    standard-library module or like one already importable from the trusted path while a file
    of that name sits in :func:`controller_dirs` (which one runs would depend on the path's
    order; the trusted processes must never import the stranger's): the clash is named."""
    if _CONTROL.search(reference):
        raise ValueError(f"controller reference {reference!r} contains control characters")
    if ":" not in reference or os.path.exists(reference):
        return
    from acc_gym.leaderboard.provenance import module_location

    top = reference.split(":", 1)[0].split(".")[0]
    if top in sys.stdlib_module_names or top in sys.builtin_module_names:
        raise ValueError(f"controller {reference!r}: its module {top!r} has the name of a standard-library module "
                         f"({top}); rename the controller's module")
    mine = module_location(top, controller_dirs(), meta_path=False)
    if mine is None:
        return
    theirs = module_location(top, trusted_path())
    if theirs is not None and theirs != mine:
        raise ValueError(f"controller {reference!r}: its module {top!r} ({mine}) has the name of a module already "
                         f"importable from {theirs}; rename the controller's module")


def host_only(root) -> None:
    """``root`` and everything under it readable by the runner's user only (directories 0700,
    files 0600): a private run's results and logs, which name the secret's episodes."""
    os.chmod(root, 0o700)
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            os.chmod(os.path.join(dirpath, d), 0o700)
        for f in filenames:
            os.chmod(os.path.join(dirpath, f), 0o600)


BUILTIN_DISTRIBUTIONS = ("acc-gym", "acc_gym")


def is_builtin(reference: str) -> bool:
    """Whether ``reference`` names a controller shipped in this package (an entry point of the
    ``acc-gym`` distribution): the package's own code, not a stranger's."""
    from acc_gym import controllers

    if ":" in reference or os.path.exists(reference) or reference in controllers._REGISTERED:
        return False
    eps = controllers._entry_points(controllers.GROUP).get(reference) or []
    dist = getattr(eps[0], "dist", None) if len(eps) == 1 else None
    return dist is not None and dist.name in BUILTIN_DISTRIBUTIONS


def how_to_isolate(why: str) -> str:
    """What a host does to give every controller its own user id."""
    if why.startswith("not readable by other users"):
        return ("run with an interpreter other users can read: a system Python (/usr/bin/python3) or a virtual "
                "environment outside a private home directory (python -m venv /opt/acc-gym-venv; every directory "
                "above it with o+rx)")
    return "run the leaderboard as root (each controller then gets a user id of its own)"


def vet(refs: list[str], possible: bool, why: str, allow_root: bool = False, private: bool = False) -> str | None:
    """What may run, checked before anything does; returns the warning the reports carry (or None).

    * every reference passes :func:`check_reference` (``ValueError`` naming the clash);
    * a stranger's code (anything but :func:`is_builtin`: a ``module:attribute``, a saved
      model, another package's entry point) does not run as root without a user id of its own
      (``possible``; ``why`` not) unless ``allow_root``: ``RuntimeError`` with the reason and
      how to get one; with ``allow_root``, the warning;
    * on the private split (``private``) a stranger's code runs only under its own user id:
      under the host's, it could read the secret and the results key however they are kept
      (``RuntimeError``, ``allow_root`` or not).
    """
    for ref in refs:
        check_reference(ref)
    if possible:
        return None
    strangers = [r for r in refs if not is_builtin(r)]
    if not strangers:
        return None
    which = repr(strangers[0]) + (f" and {len(strangers) - 1} more" if len(strangers) > 1 else "")
    if private:
        raise RuntimeError(f"refusing to run {which} on the private split without a user id of its own ({why}): "
                           f"under the host's it could read the secret and the results key. To isolate it: "
                           f"{how_to_isolate(why)}")
    if os.geteuid() != 0:
        return None
    if not allow_root:
        raise RuntimeError(f"refusing to run {which} as root without a user id of its own ({why}): it could read "
                           f"and write everything root can. To isolate it: {how_to_isolate(why)}; or pass "
                           f"--allow-root to run it as root anyway")
    return (f"WARNING: controllers ran as root without a user id of their own ({why}; --allow-root): "
            f"{', '.join(strangers)} could read and write everything root can, so these results are not "
            f"trustworthy. To isolate them: {how_to_isolate(why)}")


def own_uid_possible(extra_paths=()) -> tuple[bool, str]:
    """Whether the controller can run as its own user id, and why not."""
    if os.geteuid() != 0:
        return False, "the runner is not root"
    for p in [sys.executable, *search_path(), *extra_paths]:
        closed = _closed_to_others(p)
        if closed is not None:
            return False, f"not readable by other users: {p} ({closed})"
    return True, ""


CACHED_PACKAGES = ("acc_gym", "acc_gym_agents")  # whose compiled numba code a controller may reuse


def _cache_files(folder: str) -> list[str]:
    """The numba index and code files directly in ``folder`` (regular files only: a link is not followed)."""
    try:
        with os.scandir(folder) as it:
            return sorted(e.name for e in it if e.name.endswith((".nbi", ".nbc")) and e.is_file(follow_symlinks=False))
    except OSError:
        return []


def seed_numba_cache(cache_dir: str, uid: int | None, user_cache: str | None = None) -> int:
    """Copy the installed packages' compiled numba code into a controller's own cache.

    A controller cannot write the installed package, so numba would not use the package's
    in-tree cache (its ``__pycache__`` must be writable) and would compile every kernel a
    controller touches again -- 15 s for the MPC controller, in every run. Numba reads a
    ``NUMBA_CACHE_DIR`` as ``<dir>/<source folder name>_<sha1 of its path>/``; the same
    index and code files go there (copies: the controller may rewrite its own, never the
    package's). Where the runner keeps its compiled code is numba's choice: the package's
    ``__pycache__`` folders, or, when ``NUMBA_CACHE_DIR`` is set (``user_cache``, default: the
    environment's), that directory in the layout above; both are read (never written), the
    user's cache last, as numba prefers it, and only the package's folders of it (not what
    else the user compiled). Returns the number of files copied."""
    import hashlib
    import importlib.util

    if user_cache is None:
        user_cache = os.environ.get("NUMBA_CACHE_DIR") or None
    copied = 0
    for name in CACHED_PACKAGES:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
        for root in (spec.submodule_search_locations or []) if spec is not None else []:
            for dirpath, dirnames, _ in os.walk(root):
                dirnames[:] = [d for d in dirnames if d != "__pycache__"]
                source_dir = os.path.abspath(dirpath)
                folder = os.path.basename(source_dir) + "_" + hashlib.sha1(source_dir.encode()).hexdigest()
                sources = [os.path.join(source_dir, "__pycache__")]
                if user_cache:
                    sources.append(os.path.join(user_cache, folder))
                target = os.path.join(cache_dir, folder)
                for source in sources:
                    files = _cache_files(source)
                    if not files:
                        continue
                    os.makedirs(target, exist_ok=True)
                    for f in files:
                        shutil.copyfile(os.path.join(source, f), os.path.join(target, f))
                        shutil.copystat(os.path.join(source, f), os.path.join(target, f))
                        copied += 1
                    if uid is not None:
                        for path in [target, *(os.path.join(target, f) for f in files)]:
                            os.chown(path, uid, uid)
    return copied


def bwrap_available() -> str | None:
    return shutil.which("bwrap")


_BWRAP_PROBES: dict = {}
PROBE = ("import acc_gym.leaderboard.sandbox\n"
         "from acc_gym.evaluation.runner import load_controller\n"
         "load_controller('constant')")


def bwrap_problem(uid: int | None = None) -> str | None:
    """Why ``sandbox="bwrap"`` cannot run here (``None`` when it can).

    Installed is not enough: a container may refuse the namespaces bubblewrap needs
    (Docker's default seccomp profile does), and a package the sandbox cannot see (an
    editable install under ``/tmp``) fails only at import. So this starts the interpreter
    inside a sandbox built as :class:`ControllerProcess` builds it, under the same user id
    the controllers get, once per id, and has it import the package and load a built-in
    controller (:data:`PROBE`); it reports bwrap's own message, or the import's, when that fails.
    """
    if uid in _BWRAP_PROBES:
        return _BWRAP_PROBES[uid]
    exe = bwrap_available()
    if exe is None:
        problem = "bubblewrap (bwrap) is not installed: apt-get install bubblewrap"
    else:
        workdir = tempfile.mkdtemp(prefix="acc-gym-bwrap-probe-")
        try:
            if uid is not None:  # the controller's working directory is its own
                os.chown(workdir, uid, uid)
            cmd = [exe, *_bwrap_flags(workdir, Limits().tmp_bytes), sys.executable, "-P", "-c", PROBE]
            kw = dict(user=uid, group=uid, extra_groups=[]) if uid is not None else {}
            try:
                done = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, timeout=120,
                                      cwd=workdir, env=controller_env(workdir), **kw)
                problem = None if done.returncode == 0 else (
                    f"bwrap cannot start a sandbox here (exit {done.returncode}): "
                    f"{done.stderr.decode(errors='replace').strip()[-600:] or 'no message'}")
            except (OSError, subprocess.SubprocessError) as exc:
                problem = f"bwrap cannot start a sandbox here: {exc}"
        finally:
            shutil.rmtree(workdir, ignore_errors=True)
    _BWRAP_PROBES[uid] = problem
    return problem


def package_dirs() -> list[str]:
    """The directories the package and its agents are imported from (an editable install's
    source tree is not on ``sys.path``: its finder maps the name to it)."""
    import importlib.util

    out = []
    for name in CACHED_PACKAGES:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            continue
        for loc in (spec.submodule_search_locations or []) if spec is not None else []:
            out.append(os.path.dirname(os.path.abspath(loc)))
    return out


def controller_env(workdir: str) -> dict:
    """The controller's whole environment: nothing of the runner's but the import path."""
    return {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": workdir, "TMPDIR": workdir,
            "PYTHONPATH": os.pathsep.join(trusted_path()), CONTROLLER_PATH_ENV: os.pathsep.join(controller_dirs()),
            "NUMBA_CACHE_DIR": os.path.join(workdir, "numba"), "OMP_NUM_THREADS": "1",
            "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "LANG": "C.UTF-8",
            "PYTHONDONTWRITEBYTECODE": "1"}


def _under_tmp(workdir: str) -> list[str]:
    """What the controller needs from the host's /tmp -- an interpreter or virtual environment
    there, the directories it imports from -- outermost directories only, its own
    ``workdir`` left out."""
    tmp = "/tmp"
    needed = {os.path.realpath(p) for p in (sys.prefix, sys.base_prefix, os.path.dirname(sys.executable),
                                            *search_path(), *package_dirs())}
    back = sorted(p for p in needed if p.startswith(tmp + os.sep) and os.path.isdir(p)
                  and not p.startswith(os.path.realpath(workdir)))
    return [p for p in back if not any(p != q and p.startswith(q + os.sep) for q in back)]


_BWRAP_SIZE: dict = {}


def _bwrap_sizes_tmpfs(exe: str) -> bool:
    """Whether this bwrap has ``--size`` (0.5 and later)."""
    if exe not in _BWRAP_SIZE:
        try:
            text = subprocess.run([exe, "--help"], capture_output=True, timeout=10).stdout.decode(errors="replace")
        except (OSError, subprocess.SubprocessError):
            text = ""
        _BWRAP_SIZE[exe] = "--size" in text
    return _BWRAP_SIZE[exe]


def _bwrap_flags(workdir: str, tmp_bytes: int | None = None) -> list[str]:
    """The sandbox: the file system read-only, a private /tmp and /dev/shm (each a tmpfs of
    ``tmp_bytes`` where bwrap can size it; bwrap's own /dev/shm is a folder of its unsized /dev),
    /dev and /proc, no network, no shared IPC or PID namespace, a new session, and
    death with its parent; what the controller needs from the host's /tmp (:func:`_under_tmp`)
    is bound back in, read-only."""
    exe = bwrap_available()
    size = ["--size", str(int(tmp_bytes))] if tmp_bytes and exe and _bwrap_sizes_tmpfs(exe) else []
    flags = ["--ro-bind", "/", "/", "--dev", "/dev", *size, "--tmpfs", "/dev/shm", "--proc", "/proc", *size,
             "--tmpfs", "/tmp"]
    for p in _under_tmp(workdir):
        flags += ["--ro-bind", p, p]
    return flags + ["--bind", workdir, workdir, "--unshare-all", "--die-with-parent", "--new-session",
                    "--chdir", workdir]


def disk_usage(root: str, stop_above: int | None = None) -> int:
    """What the directory tree ``root`` holds [bytes]: every file's, directory's and link's
    allocated blocks (``st_blocks``, so a sparse file counts what it takes; links are not
    followed), each counted as at least :data:`ENTRY_BYTES` (an empty file still takes an
    inode); counting stops once past ``stop_above``. An entry that vanishes while it is
    counted is skipped; a directory that cannot be read is an ``OSError``."""
    total, todo = 0, [root]
    while todo:
        try:
            it = os.scandir(todo.pop())
        except (FileNotFoundError, NotADirectoryError):
            continue
        with it:
            for entry in it:
                try:
                    st = entry.stat(follow_symlinks=False)
                except FileNotFoundError:
                    continue
                total += max(st.st_blocks * 512, ENTRY_BYTES)
                if stat.S_ISDIR(st.st_mode):
                    todo.append(entry.path)
        if stop_above is not None and total > stop_above:
            break
    return total


@dataclass(frozen=True)
class Limits:
    """What one controller may use (each a flag of ``acc-gym leaderboard``).

    * ``log_bytes``: its standard output and error kept in its log; the rest is dropped, with a note;
    * ``memory_bytes``: its whole process tree's memory where the runner is root and a memory
      cgroup can be made (v1 or v2), else each process's address space (``RLIMIT_AS``);
    * ``processes``: processes and threads of its tree (a pids cgroup as root, else with an own
      user id ``RLIMIT_NPROC``; without either, none);
    * ``tmp_bytes``: its private ``/tmp`` and ``/dev/shm`` (tmpfs, in RAM) as root and under bwrap;
    * ``file_bytes``: any one file it writes (``RLIMIT_FSIZE``: its working directory's files too);
    * ``disk_bytes``: everything its working directory holds (:func:`disk_usage`, measured every
      :data:`DISK_POLL_S` by the trusted side, under either sandbox: past it the controller's
      tree is killed and it fails with the reason, :meth:`ControllerProcess.disk_problem`).

    Wall time is the total budget; CPU time the budget plus :data:`CPU_MARGIN`."""

    log_bytes: int = LOG_BYTES
    memory_bytes: int = ADDRESS_SPACE
    processes: int = PROCESSES
    tmp_bytes: int = 256 << 20
    file_bytes: int = 1 << 30
    disk_bytes: int = DISK_BYTES

    def __post_init__(self):
        for name in ("log_bytes", "memory_bytes", "processes", "tmp_bytes", "file_bytes", "disk_bytes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise ValueError(f"limit {name} must be a positive integer, got {value!r}")


@dataclass(frozen=True)
class Sandbox:
    """A sandbox kind (:data:`SANDBOXES`) with its :class:`Limits`."""

    kind: str = "process"
    limits: Limits = Limits()

    def __post_init__(self):
        if self.kind not in SANDBOXES:
            raise ValueError(f"unknown sandbox {self.kind!r}; use one of {list(SANDBOXES)}")


def as_sandbox(sandbox) -> Sandbox:
    return sandbox if isinstance(sandbox, Sandbox) else Sandbox(sandbox)


def containment(sandbox) -> dict:
    """What the manifest says about the controllers' network, /tmp, memory and process limits
    here (a cgroup is tried, then removed)."""
    from acc_gym._process import Cgroups

    sb = as_sandbox(sandbox)
    root = os.geteuid() == 0
    probe = Cgroups(f"acc-gym-probe-{os.getpid()}", sb.limits.memory_bytes, sb.limits.processes)
    probe.remove()
    if sb.kind == "bwrap":
        network, tmp = "none (bwrap --unshare-all)", "private (bwrap tmpfs on /tmp and /dev/shm)"
    elif root:
        network, tmp = "none (own network namespace)", "private tmpfs on /tmp and /dev/shm"
    else:
        network, tmp = "shared: the runner is not root", "shared: the runner is not root"
    return {"network": network, "tmp": tmp,
            "memory": "whole process tree (cgroup)" if probe.problem is None else probe.problem,
            "limits": {"log_bytes": sb.limits.log_bytes, "memory_bytes": sb.limits.memory_bytes,
                       "processes": sb.limits.processes, "tmp_bytes": sb.limits.tmp_bytes,
                       "file_bytes": sb.limits.file_bytes, "disk_bytes": sb.limits.disk_bytes}}


class LogSink(threading.Thread):
    """Copies a controller's standard output and error (the read end of their pipe) into its
    log file, at most ``limit`` bytes of it (counting what the file already holds: a
    controller started again appends), reading and dropping the rest so that the controller
    never blocks on a full pipe. :meth:`finish`: once every writer has gone, the file is
    rewritten through :func:`~acc_gym.leaderboard.protocol.clean_text` (no escape sequence or
    control character reaches a terminal that shows it) with a note of what was dropped."""

    def __init__(self, fd: int, path, limit: int):
        super().__init__(name="acc-gym-log", daemon=True)
        self.fd, self.path, self.limit = fd, str(path), int(limit)
        self.kept = os.path.getsize(self.path) if os.path.exists(self.path) else 0
        self.dropped = 0

    def run(self) -> None:
        with open(self.path, "ab") as f:
            while True:
                try:
                    chunk = os.read(self.fd, 1 << 16)
                except OSError:
                    break
                if not chunk:
                    break
                keep = chunk[:max(0, self.limit - self.kept)]
                if keep:
                    f.write(keep)
                    f.flush()
                self.kept += len(keep)
                self.dropped += len(chunk) - len(keep)
        os.close(self.fd)

    def finish(self, timeout: float = 10.0) -> None:
        self.join(timeout)
        with open(self.path, "rb") as f:
            text = protocol.clean_text(f.read().decode("utf-8", "replace"))
        if self.dropped:
            text += (f"\n[acc-gym: log truncated at {self.limit} bytes; {self.dropped} more bytes of the "
                     f"controller's output were dropped]\n")
        with open(self.path, "w", encoding="utf-8") as f:
            f.write(text)


class ControllerProcess:
    """The trusted side's handle on one controller's sandboxed process."""

    def __init__(self, reference: str, *, log_path, budget: float, uid: int | None, sandbox="process"):
        import json

        from acc_gym import _process
        from acc_gym._process import Cgroups

        sb = as_sandbox(sandbox)
        lim = sb.limits
        self.reference, self.uid = reference, uid
        self.disk_bytes = lim.disk_bytes
        self.stopped: str | None = None  # why the trusted side killed it (:meth:`stop`)
        self.workdir = tempfile.mkdtemp(prefix="acc-gym-controller-")
        os.makedirs(os.path.join(self.workdir, "numba"))
        if uid is not None:
            for d in (self.workdir, os.path.join(self.workdir, "numba")):
                os.chown(d, uid, uid)
        seed_numba_cache(os.path.join(self.workdir, "numba"), uid)
        self.sock, theirs = socket.socketpair()
        env = controller_env(self.workdir)
        cmd = [sys.executable, "-P", "-m", "acc_gym.leaderboard.sandbox", str(theirs.fileno()), reference]
        if sb.kind == "bwrap":
            cmd = self._bwrap(cmd, lim.tmp_bytes)
        cpu = int(budget + CPU_MARGIN)
        self.cgroups = None
        if os.geteuid() == 0:
            self.cgroups = Cgroups(f"acc-gym-{os.getpid()}-{next(_SERIAL)}", lim.memory_bytes, lim.processes)
        # with a memory cgroup the tree's memory is capped there, and each process keeps the address
        # space an interpreter with numba and torch reserves; without one, each process's is the cap
        space = max(lim.memory_bytes, ADDRESS_SPACE) if self.cgroups and self.cgroups.procs else lim.memory_bytes
        rlimits = {"RLIMIT_AS": space, "RLIMIT_CPU": cpu, "RLIMIT_NOFILE": OPEN_FILES,
                   "RLIMIT_FSIZE": lim.file_bytes, **({"RLIMIT_NPROC": lim.processes} if uid is not None else {})}
        read_end, write_end = os.pipe()
        self.log = LogSink(read_end, log_path, lim.log_bytes)
        kw: dict = {}
        if os.geteuid() == 0:  # the jail: cgroups, namespaces, a private /tmp, then the user id
            config = {"cgroups": self.cgroups.procs, "uid": uid, "rlimits": rlimits, "parent": os.getpid(),
                      "cwd": self.workdir}
            if sb.kind == "process":
                config.update(network=False, tmp_bytes=lim.tmp_bytes, rw=[self.workdir],
                              ro=_under_tmp(self.workdir))
            cmd = [sys.executable, "-I", os.path.abspath(_process.__file__), json.dumps(config), *cmd]
        else:
            def limits():  # in the child, before exec: the controller cannot raise them again
                die_with_parent()  # if the simulation process is killed, so is the controller
                for name, value in rlimits.items():
                    resource.setrlimit(getattr(resource, name), (value, value + 5 if name == "RLIMIT_CPU" else value))

            kw = dict(preexec_fn=limits, **(dict(user=uid, group=uid, extra_groups=[]) if uid is not None else {}))
        try:
            self.process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=write_end, stderr=write_end,
                                            cwd=self.workdir, env=env, pass_fds=(theirs.fileno(),),
                                            start_new_session=True, close_fds=True, **kw)
        finally:
            os.close(write_end)
            theirs.close()
        self.log.start()
        self._watching = threading.Event()
        self._watch = threading.Thread(target=self._watch_disk, name="acc-gym-disk", daemon=True)
        self._watch.start()

    def disk_problem(self) -> str | None:
        """Why the controller must stop for its working directory (``None``: within the disk limit)."""
        try:
            used = disk_usage(self.workdir, self.disk_bytes)
        except OSError as exc:
            return (f"killed: its working directory could not be measured against the disk limit of "
                    f"{self.disk_bytes / 2**20:g} MiB ({type(exc).__name__}: {exc.strerror or 'unreadable'})")
        if used > self.disk_bytes:
            return (f"killed: its working directory held more than the disk limit of {self.disk_bytes / 2**20:g} MiB "
                    f"(--disk-limit)")
        return None

    def _watch_disk(self) -> None:
        while not self._watching.wait(DISK_POLL_S):
            problem = self.disk_problem()
            if problem is not None:
                self.stop(problem)
                return

    def stop(self, reason: str) -> None:
        """Kill the controller's tree now (its process and descendants, its user id's processes,
        its cgroup's) and end the socket, so the simulation's wait ends at once; ``stopped`` says why."""
        from acc_gym._process import descendants

        if self.stopped is None:
            self.stopped = reason
        pids = set(self.cgroups.pids()) if self.cgroups is not None else set()
        if self.process.returncode is None:
            pids |= {self.process.pid, *descendants(self.process.pid)}
        if self.uid is not None:
            pids |= set(processes_of(self.uid))
        pids.discard(os.getpid())
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def _bwrap(self, cmd: list[str], tmp_bytes: int) -> list[str]:
        exe = bwrap_available()
        if exe is None:
            raise RuntimeError("sandbox 'bwrap' needs the bubblewrap program (apt-get install bubblewrap)")
        return [exe, *_bwrap_flags(self.workdir, tmp_bytes), *cmd]

    def close(self) -> None:
        """End the controller and everything it started; remove its working directory."""
        self._watching.set()
        self._watch.join()
        try:
            protocol.send_frame(self.sock, protocol.BYE)
        except (protocol.Closed, OSError):
            pass
        self.sock.close()
        try:
            self.process.wait(timeout=2.0)
        except subprocess.TimeoutExpired:
            pass
        kill_all(self.uid)
        if self.cgroups is not None:
            self.cgroups.remove()
        if self.process.poll() is None:  # pragma: no cover - killed above
            self.process.kill()
        self.process.wait()
        self.log.finish()
        shutil.rmtree(self.workdir, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
