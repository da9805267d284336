"""A controller's own process: what it may touch, and the code it runs.

The leaderboard ranks strangers' code, so the controller never runs where the
simulation, the scoring, the clocks or the output live. Its process is started fresh
(``python -m acc_gym.leaderboard.sandbox``, not forked from the runner) and holds only
its end of a socket; it receives observations and answers actions
(:mod:`acc_gym.leaderboard.protocol`). Each episode in flight has its own copy of the
controller, made before its first call and ``reset()`` at every episode start, and it
is called with that episode's single observation row, exactly as
:func:`acc_gym.evaluation.runner.run_episode` calls it -- so a controller's episodes
are the same bits here as under ``acc-gym evaluate``. (The string-stability column sends
one position's rows of every frequency under one slot: a vectorised controller's copy
answers them in one call, as ``acc-gym string-stability`` calls it, any other gets a
copy per row.)

What the process sandbox (``sandbox="process"``, the default) guarantees:

* **no shared memory** with the runner: the simulator, the scenario (the lead's future),
  the scores and the runner's clocks are in other processes; the controller sees the
  observation rows, episode-start flags, nothing else;
* its **own session** (``setsid``), a fresh temporary working directory (also ``HOME``
  and ``TMPDIR``), a **scrubbed environment** (only ``PATH``, ``PYTHONPATH`` -- the
  runner's ``sys.path``, so the same modules import --, thread counts of 1 and the
  temporary directories), standard input closed, standard output and error to its own
  log file (never the runner's output);
* **resource limits**: address space (``RLIMIT_AS``, 8 GiB), CPU time (the total budget
  plus a minute), open files (256); and, with its own user id, processes (64);
* when the runner is **root**, its **own unprivileged user id** (a different one for every
  controller of a run): it cannot write the installed package, the suite data, the
  output directory or another controller's files (root-owned), and it cannot signal
  (kill, stop, trace) the runner or a sibling controller;
* **nothing outlives it**: the simulation process that starts it is a child subreaper, so
  even a double-forked, ``setsid``'d grandchild is reparented to it and killed (with
  every other process of the controller's user id) before any result is reported.

What it does not guarantee: without root the controller runs as the runner's user,
so it *can* signal sibling processes and write wherever that user can (the manifest
says ``"uid_isolated": false``); it can read any file that user can read, and it has
the network. ``sandbox="bwrap"`` adds what a host needs for untrusted submissions:
bubblewrap's read-only root, a new PID namespace (nothing else visible, nothing to
signal), no network, a private ``/tmp``; it needs the ``bwrap`` program.
"""

from __future__ import annotations

import copy
import os
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path

import numpy as np

from acc_gym._process import become_subreaper, die_with_parent, kill_all, processes_of  # noqa: F401
from acc_gym.leaderboard import protocol

SANDBOXES = ("process", "bwrap")
ADDRESS_SPACE = 8 << 30  # [bytes] RLIMIT_AS
OPEN_FILES = 256
PROCESSES = 64  # RLIMIT_NPROC, applied with an own user id only (it counts per user)
CPU_MARGIN = 60.0  # [s] RLIMIT_CPU = total budget + this
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
    sock = socket.socket(fileno=fd)
    try:
        serve(sock, reference)
    finally:
        sock.close()
    return 0


# -- the trusted side ------------------------------------------------------------------------------
def _readable_by_others(path: str) -> bool:
    """Whether ``path`` and every directory above it are open to other users."""
    p = Path(path).resolve()
    try:
        if not (p.stat().st_mode & (0o004 if p.is_file() else 0o005)):
            return False
        return all(parent.stat().st_mode & 0o001 for parent in p.parents)
    except OSError:
        return False


def search_path() -> list[str]:
    """The runner's working directory, then its ``sys.path`` entries that exist (what the
    controller imports from: a module in the directory the leaderboard is run from comes
    first, as under ``python -m`` and :func:`acc_gym.evaluation.runner.import_from_cwd`)."""
    cwd = os.getcwd()
    paths = [os.path.abspath(p) for p in sys.path if p and os.path.exists(p)]  # the sandbox has another cwd
    return [cwd] + [p for p in paths if p != cwd]


def own_uid_possible(extra_paths=()) -> tuple[bool, str]:
    """Whether the controller can run as its own user id, and why not."""
    if os.geteuid() != 0:
        return False, "the runner is not root"
    needed = [sys.executable, *search_path(), *extra_paths]
    closed = [p for p in needed if not _readable_by_others(p)]
    if closed:
        return False, f"not readable by other users: {closed[0]}"
    return True, ""


CACHED_PACKAGES = ("acc_gym", "acc_gym_agents")  # whose compiled numba code a controller may reuse


def seed_numba_cache(cache_dir: str, uid: int | None) -> int:
    """Copy the installed packages' compiled numba code into a controller's own cache.

    A controller cannot write the installed package, so numba would not use the package's
    in-tree cache (its ``__pycache__`` must be writable) and would compile every kernel a
    controller touches again -- 15 s for the MPC controller, in every run. Numba reads a
    ``NUMBA_CACHE_DIR`` as ``<dir>/<source folder name>_<sha1 of its path>/``; the same
    index and code files go there (copies: the controller may rewrite its own, never the
    package's). Returns the number of files copied."""
    import hashlib
    import importlib.util

    copied = 0
    for name in CACHED_PACKAGES:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
        for root in (spec.submodule_search_locations or []) if spec is not None else []:
            for dirpath, _, filenames in os.walk(root):
                if os.path.basename(dirpath) != "__pycache__":
                    continue
                source_dir = os.path.dirname(os.path.abspath(dirpath))
                files = [f for f in filenames if f.endswith((".nbi", ".nbc"))]
                if not files:
                    continue
                target = os.path.join(cache_dir, os.path.basename(source_dir) + "_" +
                                      hashlib.sha1(source_dir.encode()).hexdigest())
                os.makedirs(target, exist_ok=True)
                for f in files:
                    shutil.copy2(os.path.join(dirpath, f), os.path.join(target, f))
                    copied += 1
                if uid is not None:
                    for path in [target, *(os.path.join(target, f) for f in files)]:
                        os.chown(path, uid, uid)
    return copied


def bwrap_available() -> str | None:
    return shutil.which("bwrap")


_BWRAP_PROBES: dict = {}


def bwrap_problem(uid: int | None = None) -> str | None:
    """Why ``sandbox="bwrap"`` cannot run here (``None`` when it can).

    Installed is not enough: a container may refuse the namespaces bubblewrap needs
    (Docker's default seccomp profile does). So this starts the interpreter inside a
    sandbox built as :class:`ControllerProcess` builds it, under the same user id the
    controllers get, once per id, and reports bwrap's own message when that fails.
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
            cmd = [exe, *_bwrap_flags(workdir), sys.executable, "-c", "pass"]
            kw = dict(user=uid, group=uid, extra_groups=[]) if uid is not None else {}
            try:
                done = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, timeout=60,
                                      cwd=workdir, **kw)
                problem = None if done.returncode == 0 else (
                    f"bwrap cannot start a sandbox here (exit {done.returncode}): "
                    f"{done.stderr.decode(errors='replace').strip()[:300] or 'no message'}")
            except (OSError, subprocess.SubprocessError) as exc:
                problem = f"bwrap cannot start a sandbox here: {exc}"
        finally:
            shutil.rmtree(workdir, ignore_errors=True)
    _BWRAP_PROBES[uid] = problem
    return problem


def _bwrap_flags(workdir: str) -> list[str]:
    """The sandbox: the file system read-only, a private /tmp, /dev and /proc, no network,
    no shared IPC or PID namespace, a new session, and death with its parent. What the
    controller needs from the host's /tmp -- an interpreter or virtual environment there,
    the directories it imports from -- is bound back in, read-only."""
    tmp = "/tmp"
    needed = {os.path.realpath(p) for p in (sys.prefix, sys.base_prefix, os.path.dirname(sys.executable),
                                            *search_path())}
    back = sorted(p for p in needed if (p == tmp or p.startswith(tmp + os.sep)) and os.path.isdir(p)
                  and p != tmp and not p.startswith(os.path.realpath(workdir)))
    keep = [p for p in back if not any(p != q and p.startswith(q + os.sep) for q in back)]  # outermost only
    flags = ["--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc", "--tmpfs", tmp]
    for p in keep:
        flags += ["--ro-bind", p, p]
    return flags + ["--bind", workdir, workdir, "--unshare-all", "--die-with-parent", "--new-session",
                    "--chdir", workdir]


class ControllerProcess:
    """The trusted side's handle on one controller's sandboxed process."""

    def __init__(self, reference: str, *, log_path, budget: float, uid: int | None, sandbox: str = "process"):
        if sandbox not in SANDBOXES:
            raise ValueError(f"unknown sandbox {sandbox!r}; use one of {list(SANDBOXES)}")
        self.reference, self.uid = reference, uid
        self.workdir = tempfile.mkdtemp(prefix="acc-gym-controller-")
        os.makedirs(os.path.join(self.workdir, "numba"))
        if uid is not None:
            for d in (self.workdir, os.path.join(self.workdir, "numba")):
                os.chown(d, uid, uid)
        seed_numba_cache(os.path.join(self.workdir, "numba"), uid)
        self.sock, theirs = socket.socketpair()
        env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": self.workdir, "TMPDIR": self.workdir,
               "PYTHONPATH": os.pathsep.join(search_path()), "NUMBA_CACHE_DIR": os.path.join(self.workdir, "numba"),
               "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
               "NUMBA_NUM_THREADS": "1", "LANG": "C.UTF-8", "PYTHONDONTWRITEBYTECODE": "1"}
        cmd = [sys.executable, "-m", "acc_gym.leaderboard.sandbox", str(theirs.fileno()), reference]
        if sandbox == "bwrap":
            cmd = self._bwrap(cmd, theirs.fileno())
        cpu = int(budget + CPU_MARGIN)

        def limits():  # in the child, before exec: the controller cannot raise them again
            die_with_parent()  # if the simulation process is killed, so is the controller
            resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
            resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))
            resource.setrlimit(resource.RLIMIT_NOFILE, (OPEN_FILES, OPEN_FILES))
            if uid is not None:
                resource.setrlimit(resource.RLIMIT_NPROC, (PROCESSES, PROCESSES))

        self.log = open(log_path, "ab")
        kw = dict(user=uid, group=uid, extra_groups=[]) if uid is not None else {}
        self.process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=self.log, stderr=self.log,
                                        cwd=self.workdir, env=env, pass_fds=(theirs.fileno(),),
                                        start_new_session=True, preexec_fn=limits, close_fds=True, **kw)
        theirs.close()

    def _bwrap(self, cmd: list[str], fd: int) -> list[str]:
        exe = bwrap_available()
        if exe is None:
            raise RuntimeError("sandbox 'bwrap' needs the bubblewrap program (apt-get install bubblewrap)")
        return [exe, *_bwrap_flags(self.workdir), *cmd]

    def close(self) -> None:
        """End the controller and everything it started; remove its working directory."""
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
        if self.process.poll() is None:  # pragma: no cover - killed above
            self.process.kill()
        self.process.wait()
        self.log.close()
        shutil.rmtree(self.workdir, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
