"""Process hygiene shared by the leaderboard and the campaigns (Linux; elsewhere best effort).

* :func:`die_with_parent`: a worker asks the kernel to SIGKILL it when its parent dies, so
  a killed campaign or leaderboard leaves no idle workers behind;
* :func:`become_subreaper`: orphaned descendants are reparented to this process instead
  of ``init``, so it can find and kill them (:func:`descendants`, :func:`kill_all`).
"""

from __future__ import annotations

import os
import signal
import time

PR_SET_PDEATHSIG = 1
PR_SET_CHILD_SUBREAPER = 36


def _prctl(option: int, value: int) -> bool:
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(option, value, 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        return False


def die_with_parent(parent_pid: int | None = None) -> None:
    """SIGKILL this process when its parent dies (a pool initializer: pass the parent's pid,
    so a parent that died before the call is noticed too)."""
    _prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL))
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)


def become_subreaper() -> bool:
    """Make this process a child subreaper (Linux): orphaned descendants come to it."""
    return _prctl(PR_SET_CHILD_SUBREAPER, 1)


def descendants(root: int | None = None) -> list[int]:
    """Every living descendant of ``root`` (this process by default), from ``/proc``."""
    root = os.getpid() if root is None else root
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as f:
                stat = f.read()
        except OSError:
            continue
        ppid = int(stat[stat.rindex(b")") + 2:].split()[1])
        children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [root]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def processes_of(uid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            st = os.stat(f"/proc/{entry}")
        except OSError:
            continue
        if st.st_uid == uid:
            out.append(int(entry))
    return out


def kill_all(uid: int | None, timeout: float = 5.0) -> None:
    """SIGKILL every descendant of this process (and, with ``uid``, every process of that
    user id), reap them, until none is left."""
    end = time.monotonic() + timeout
    while True:
        pids = set(descendants())
        if uid is not None:
            pids |= set(processes_of(uid))
        pids.discard(os.getpid())
        if not pids or time.monotonic() > end:
            return
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        while True:  # reap what we can (our children and the orphans reparented to us)
            try:
                pid, _ = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                break
            if pid == 0:
                break
        time.sleep(0.01)


# -- cgroups: memory and process count for a whole process tree -----------------------------------
def _cgroup_dirs() -> dict[str, str]:
    """This process's cgroup directory for each of ``memory`` and ``pids`` that is mounted and
    writable-looking: cgroup v1 hierarchies, or v2's unified one (key ``"v2"``)."""
    own: dict[str, str] = {}
    with open("/proc/self/cgroup") as f:
        for line in f:
            _, controllers, path = line.rstrip("\n").split(":", 2)
            for c in (controllers.split(",") if controllers else ["v2"]):
                own[c] = path
    out: dict[str, str] = {}
    with open("/proc/self/mountinfo") as f:
        for line in f:
            fields = line.split()
            sep = fields.index("-")
            root, point, fstype, options = fields[3], fields[4], fields[sep + 1], fields[sep + 3]
            if fstype == "cgroup":
                for c in ("memory", "pids"):
                    if c in options.split(",") and c in own:
                        rel = os.path.relpath(own[c], root) if own[c].startswith(root) else None
                        if rel is not None:
                            out[c] = os.path.normpath(os.path.join(point, rel))
            elif fstype == "cgroup2" and "v2" in own and own["v2"].startswith(root):
                out["v2"] = os.path.normpath(os.path.join(point, os.path.relpath(own["v2"], root)))
    return out


class Cgroups:
    """A fresh cgroup (or one per cgroup v1 hierarchy) capping a process tree's memory
    (``memory_bytes``, swap included where the kernel counts it) and number of processes and
    threads (``processes``). ``procs``: the ``cgroup.procs`` files a process joins;
    ``problem``: why there is none (then ``procs`` is empty and rlimits are all there is).
    Needs root; :meth:`remove` kills what is left in them and removes them."""

    def __init__(self, name: str, memory_bytes: int, processes: int):
        self.dirs: list[str] = []
        self.problem: str | None = None
        try:
            if os.geteuid() != 0:
                raise OSError("the runner is not root")
            found = _cgroup_dirs()
            if "memory" in found and "pids" in found:  # cgroup v1
                plan = [(found["memory"], {"memory.limit_in_bytes": memory_bytes}),
                        (found["pids"], {"pids.max": processes})]
                swap = {"memory.memsw.limit_in_bytes": memory_bytes}
            elif "v2" in found:
                ctl = open(os.path.join(found["v2"], "cgroup.controllers")).read().split()
                if not {"memory", "pids"} <= set(ctl):
                    raise OSError(f"cgroup v2 at {found['v2']} does not offer memory and pids (it has: "
                                  f"{' '.join(ctl) or 'none'})")
                plan = [(found["v2"], {"memory.max": memory_bytes, "memory.swap.max": 0, "pids.max": processes})]
                swap = {}
            else:
                raise OSError("no memory and pids cgroup is mounted")
            for parent, limits in plan:
                d = os.path.join(parent, name)
                os.mkdir(d)
                self.dirs.append(d)
                for key, value in limits.items():
                    with open(os.path.join(d, key), "w") as f:
                        f.write(str(int(value)))
                if "memory.limit_in_bytes" in limits:
                    for key, value in swap.items():  # absent without swap accounting
                        try:
                            with open(os.path.join(d, key), "w") as f:
                                f.write(str(int(value)))
                        except OSError:
                            pass
        except OSError as exc:
            self.problem = f"no cgroup for the controller ({exc.strerror or exc}): memory is capped per process"
            self.remove()
            self.dirs = []

    @property
    def procs(self) -> list[str]:
        return [os.path.join(d, "cgroup.procs") for d in self.dirs]

    def pids(self) -> set[int]:
        out: set[int] = set()
        for procs in self.procs:
            try:
                with open(procs) as f:
                    out |= {int(x) for x in f.read().split()}
            except OSError:
                pass
        return out

    def peak_memory(self) -> int | None:
        """The most memory the tree held [bytes] (None where the kernel does not say)."""
        for d in self.dirs:
            for key in ("memory.max_usage_in_bytes", "memory.peak"):
                try:
                    with open(os.path.join(d, key)) as f:
                        return int(f.read())
                except (OSError, ValueError):
                    continue
        return None

    def remove(self, timeout: float = 5.0) -> None:
        end = time.monotonic() + timeout
        while self.pids() and time.monotonic() < end:
            for pid in self.pids():
                try:
                    os.kill(pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
            time.sleep(0.01)
        for d in self.dirs:
            try:
                os.rmdir(d)
            except OSError:
                pass


# -- the controller's jail: namespaces, a private /tmp, cgroups, then the controller's user id -------
CLONE_NEWNS = 0x00020000
CLONE_NEWNET = 0x40000000
MS_RDONLY, MS_NOSUID, MS_NODEV, MS_REMOUNT, MS_BIND, MS_REC, MS_PRIVATE = 1, 2, 4, 32, 4096, 16384, 1 << 18
JAIL_FAILED = 121  # the jail's exit code when it could not build what it was asked for


def _libc():
    import ctypes

    return ctypes.CDLL(None, use_errno=True)


def _check(result: int, what: str) -> None:
    if result != 0:
        import ctypes

        err = ctypes.get_errno()
        raise OSError(err, f"{what}: {os.strerror(err)}")


def _mount(source, target, fstype, flags: int, data=None) -> None:
    enc = (lambda x: None if x is None else str(x).encode())
    _check(_libc().mount(enc(source), enc(target), enc(fstype), flags, enc(data)), f"mount {target}")


def private_tmp(tmp_bytes: int, rw: list[str], ro: list[str]) -> None:
    """In a new mount namespace: an empty tmpfs of ``tmp_bytes`` on ``/tmp`` and on ``/dev/shm``
    (gone with the namespace's last process), the directories ``rw`` and ``ro`` that live under
    ``/tmp`` bound back in (read-write, read-only)."""
    _check(_libc().unshare(CLONE_NEWNS), "unshare(CLONE_NEWNS)")
    _mount(None, "/", None, MS_REC | MS_PRIVATE)
    old_tmp = os.open("/tmp", os.O_PATH | os.O_DIRECTORY)
    _mount("tmpfs", "/tmp", "tmpfs", MS_NOSUID | MS_NODEV, f"size={int(tmp_bytes)},mode=1777")
    if os.path.isdir("/dev/shm"):
        _mount("tmpfs", "/dev/shm", "tmpfs", MS_NOSUID | MS_NODEV, f"size={int(tmp_bytes)},mode=1777")
    for path, writable in [(p, False) for p in ro] + [(p, True) for p in rw]:
        rel = os.path.relpath(path, "/tmp")
        os.makedirs(path, exist_ok=True)
        _mount(f"/proc/self/fd/{old_tmp}/{rel}", path, None, MS_BIND | MS_REC)
        if not writable:
            _mount(None, path, None, MS_BIND | MS_REMOUNT | MS_RDONLY | MS_NOSUID)
    os.close(old_tmp)


def jail(config: dict, argv: list[str]) -> None:
    """Build the controller's jail as ``config`` says, then exec ``argv`` in it (never returns).

    In order, while still root: join the cgroups (``cgroups``: their ``cgroup.procs`` files),
    a new network namespace (``network``: no interface but a loopback that is down, so not
    even 127.0.0.1 answers), a private ``/tmp`` and ``/dev/shm`` (``tmp_bytes``, ``rw``,
    ``ro``: :func:`private_tmp`); then the user id (``uid``: no supplementary groups), the
    resource limits (``rlimits``: name -> value), death with the parent. Whatever fails
    exits with :data:`JAIL_FAILED` and the reason on standard error."""
    import resource
    import sys

    try:
        for procs in config.get("cgroups", []):
            with open(procs, "w") as f:
                f.write(str(os.getpid()))
        if config.get("network") is False:
            _check(_libc().unshare(CLONE_NEWNET), "unshare(CLONE_NEWNET)")
        if config.get("tmp_bytes"):
            private_tmp(config["tmp_bytes"], config.get("rw", []), config.get("ro", []))
        if config.get("cwd"):
            os.chdir(config["cwd"])
        uid = config.get("uid")
        if uid is not None:
            os.setgroups([])
            os.setgid(uid)
            os.setuid(uid)
        for name, value in config.get("rlimits", {}).items():
            resource.setrlimit(getattr(resource, name), (value, value))
        _prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL))
        if os.getppid() != config.get("parent", os.getppid()):
            os._exit(1)
        os.execve(argv[0], argv, config.get("env", dict(os.environ)))
    except (OSError, ValueError) as exc:
        sys.stderr.write(f"acc-gym sandbox: cannot build the controller's jail: {exc}\n")
        sys.stderr.flush()
        os._exit(JAIL_FAILED)


if __name__ == "__main__":  # python -I acc_gym/_process.py CONFIG_JSON ARGV...: imports nothing but the stdlib
    import json
    import sys

    jail(json.loads(sys.argv[1]), sys.argv[2:])
