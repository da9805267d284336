"""A killed campaign leaves no process behind; Ctrl-C ends it with one line, not a traceback."""

import os
import signal
import subprocess
import sys
import time

import pytest

from acc_gym._process import descendants

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and prctl (Linux)")

# 12 hours: about a minute uninterrupted on 2 cores (3 hours took 16 s, so on a loaded machine the
# campaign could end before the signal; the tests interrupt it within seconds of its workers starting)
COMMAND = [sys.executable, "-c", "import sys; from acc_gym.cli import main; sys.exit(main(sys.argv[1:]))",
           "campaign", "--suite", "singlelane-v3", "--hours", "12", "--controller", "acc", "--workers", "2"]


def _as_from_a_terminal():
    """The campaign starts as from an interactive shell: SIGINT at its default action and not
    blocked, whatever the test process inherited. (Under pytest-xdist a fresh-clone CI run's
    campaign ran to its end after the SIGINT, exit 0, twice; a child inherits an ignored or
    blocked SIGINT through exec, and ignoring Ctrl-C is then the right behaviour.)"""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def sigint_state(pid: int) -> str:
    """The SigBlk / SigIgn / SigCgt lines of /proc/<pid>/status (for a failure's message)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return " ".join(line.strip() for line in f if line.startswith(("SigBlk", "SigIgn", "SigCgt")))
    except OSError:
        return "gone"


def start(tmp_path):
    proc = subprocess.Popen([*COMMAND, "--out", str(tmp_path / "c")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=tmp_path, preexec_fn=_as_from_a_terminal)
    end = time.monotonic() + 120
    while time.monotonic() < end:  # until both pool workers run chunks
        workers = [p for p in descendants(proc.pid) if b"spawn_main" in _cmdline(p)]
        if len(workers) >= 2 and (tmp_path / "c" / "campaign.json").exists():
            time.sleep(2.0)
            return proc, descendants(proc.pid)
        time.sleep(0.2)
    proc.kill()
    pytest.fail("the campaign's workers did not start")


def _cmdline(pid: int) -> bytes:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read()
    except OSError:
        return b""


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_sigkill_leaves_no_worker_behind(tmp_path):
    proc, children = start(tmp_path)
    assert len(children) >= 3  # two workers and the resource tracker at least
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    end = time.monotonic() + 15
    while time.monotonic() < end and any(alive(p) for p in children):
        time.sleep(0.2)
    left = [p for p in children if alive(p)]
    for p in left:  # do not leak them from the test either
        os.kill(p, signal.SIGKILL)
    assert not left, [_cmdline(p)[:80] for p in left]


def test_ctrl_c_ends_with_one_line(tmp_path):
    proc, children = start(tmp_path)
    state = sigint_state(proc.pid)
    proc.send_signal(signal.SIGINT)  # as Ctrl-C to the campaign process
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (state, err[-2000:])
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "acc-gym: interrupted"
    end = time.monotonic() + 15
    while time.monotonic() < end and any(alive(p) for p in children):
        time.sleep(0.2)
    assert not [p for p in children if alive(p)]
