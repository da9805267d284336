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
