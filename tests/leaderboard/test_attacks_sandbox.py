"""Round two's attacks on the sandbox, each a small controller (cheats.py), each gaining nothing.

One leaderboard run, one controller at a time (LeavesTmp runs before ReadsTmp), with small
limits: a 1 MiB log, a 1 GiB memory tree, 32 processes, a 16 MiB /tmp, 4 MiB per file and 64 MiB
in the working directory (FillsDisk writes past it in 1 MiB files). The network, /tmp and cgroup attacks
need the runner to be root (the jail that builds namespaces and cgroups runs as root); they
are skipped, with the reason, elsewhere.
"""

import ast
import os
import socket
from pathlib import Path

import pytest

from acc_gym._process import Cgroups
from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard.sandbox import Limits, own_uid_possible

HERE = Path(__file__).resolve().parent
ROOT = os.geteuid() == 0
_probe = Cgroups(f"acc-gym-test-probe-{os.getpid()}", 1 << 30, 32)
_probe.remove()
CGROUP_PROBLEM = "the runner is not root" if not ROOT else _probe.problem
needs_root = pytest.mark.skipif(not ROOT, reason="namespaces and a private /tmp are built by the jail, as root")
needs_cgroup = pytest.mark.skipif(CGROUP_PROBLEM is not None, reason=f"no cgroup here: {CGROUP_PROBLEM}")
CHEATS = ["cheats:LeavesTmp", "cheats:ReadsTmp", "cheats:Escapes", "cheats:FloodsLog", "cheats:Forks",
          "cheats:HoldsMemory", "cheats:Connects", "cheats:ShutsSocket", "cheats:FillsDisk"] + \
         (["cheats:FillsTmp"] if ROOT else [])  # without root its /tmp is the host's: it would fill that
ESC = b"\x1b"


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(4)
    listener.settimeout(0.0)
    port_file = HERE / "cheats_port.txt"
    port_file.write_text(str(listener.getsockname()[1]))  # LeavesTmp/ReadsTmp name their file after it too
    out = tmp_path_factory.mktemp("attacks") / "board"
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.syspath_prepend(str(HERE))
            r = run_leaderboard(["ncap-v1"], "test", ["acc", *CHEATS], episodes=2, workers=1, step_budget=1.0,
                                budget=300, out=out, string_stability=False, iso15622=False, waves=False, robustness=False, allow_root=True,
                                limits=Limits(log_bytes=1 << 20, memory_bytes=1 << 30, processes=32, tmp_bytes=16 << 20,
                                              file_bytes=4 << 20, disk_bytes=64 << 20))
        connections = 0
        while True:
            try:
                listener.accept()[0].close()
                connections += 1
            except (BlockingIOError, OSError):
                break
    finally:
        listener.close()
        port_file.unlink()
    yield {"r": r, "out": out, "connections": connections}


def by_name(r):
    return {c["name"]: c for c in r["controllers"]}


def log(board, name) -> str:
    return (board["out"] / by_name(board["r"])[name]["log"]).read_text(errors="replace")


def test_escape_sequences_reach_no_terminal_and_no_file(board, capfd):
    c = by_name(board["r"])["cheats:Escapes"]
    assert c["status"] == "failed" and "RuntimeError: 1  cheats:Escapes  ok  100.0" in c["reason"]
    assert "\x1b" not in c["reason"] and "\x9b" not in c["reason"] and "\u202e" not in c["reason"]
    assert "\x1b" not in (c["traceback"] or "")
    for f in board["out"].rglob("*"):
        if f.is_file():
            assert ESC not in f.read_bytes() and b"\xc2\x9b" not in f.read_bytes(), f
    assert "log line" in log(board, "cheats:Escapes")
    from acc_gym.leaderboard.results import text_table

    assert "\x1b" not in text_table(board["r"])
    assert "\x1b" not in capfd.readouterr().out


def test_a_log_flood_is_truncated_with_a_note(board):
    text = log(board, "cheats:FloodsLog")
    assert len(text.encode()) < (1 << 20) + 1000
    assert "log truncated at 1048576 bytes" in text and "CHEAT flooded" not in text
    assert by_name(board["r"])["cheats:FloodsLog"]["status"] == "ok"  # truncated, not killed


@needs_cgroup
def test_the_process_count_is_capped(board):
    line = next(x for x in log(board, "cheats:Forks").splitlines() if x.startswith("CHEAT forked"))
    assert int(line.split()[-1]) < 32


@needs_cgroup
def test_memory_is_capped_for_the_whole_tree(board):
    text = log(board, "cheats:HoldsMemory")
    # 3 x 400 MiB do not fit in the tree's 1 GiB at once: a child is stopped before it holds its
    # block, or killed after (the kernel's OOM killer may pick one that already said so while the
    # last one allocates), or the controller itself is killed (no "children ended" line)
    ended = [line for line in text.splitlines() if line.startswith("CHEAT children ended")]
    statuses = ast.literal_eval(ended[0].split("ended", 1)[1].strip()) if ended else None
    killed = statuses is None and by_name(board["r"])["cheats:HoldsMemory"]["status"] != "ok"
    assert text.count("CHEAT held") < 3 or killed or (statuses is not None and any(statuses)), text[-2000:]


@needs_root
def test_the_controller_has_no_network(board):
    assert "CHEAT refused" in log(board, "cheats:Connects") and "CHEAT connected" not in log(board, "cheats:Connects")
    assert board["connections"] == 0
    assert board["r"]["manifest"]["sandbox"]["network"].startswith("none")


@needs_root
def test_a_file_left_in_tmp_is_seen_by_no_one_after(board):
    assert log(board, "cheats:LeavesTmp").count("CHEAT left") == 2  # it could write its private /tmp
    text = log(board, "cheats:ReadsTmp")
    assert text.count("CHEAT nothing in") == 2 and "CHEAT found" not in text
    assert not [p for d in ("/tmp", "/dev/shm") for p in Path(d).glob("acc-gym-cheat-*")]


def test_a_controller_that_shuts_its_socket_and_lives_is_blamed(board):
    c = by_name(board["r"])["cheats:ShutsSocket"]
    assert c["status"] == "failed"
    assert "the controller closed its connection and kept running" in c["reason"], c["reason"]
    assert "simulation" not in c["reason"]


def test_the_honest_controller_ranks_first_and_the_limits_are_recorded(board):
    r = board["r"]
    assert r["ranking"][0] == "acc" and by_name(r)["acc"]["status"] == "ok"
    assert r["manifest"]["sandbox"]["limits"]["log_bytes"] == 1 << 20
    if ROOT and not own_uid_possible()[0]:
        assert "WARNING: controllers ran as root" in r["manifest"]["sandbox"]["warning"]


def test_a_working_directory_past_the_disk_limit_fails_naming_it(board):
    c = by_name(board["r"])["cheats:FillsDisk"]
    assert c["status"] == "failed", c
    assert "killed: its working directory held more than the disk limit of 64 MiB (--disk-limit)" in c["reason"]
    assert c["rank"] is None and c["summary"] is None  # gains nothing
    assert "CHEAT wrote" in log(board, "cheats:FillsDisk")  # in files under the 4 MiB per-file cap
    assert board["r"]["manifest"]["sandbox"]["limits"]["disk_bytes"] == 64 << 20


@needs_root
def test_the_private_tmp_and_dev_shm_are_sized_and_filling_them_fails_cleanly(board):
    c = by_name(board["r"])["cheats:FillsTmp"]
    assert c["status"] == "failed" and "OSError: [Errno 28] No space left on device" in c["reason"], c["reason"]
    text = log(board, "cheats:FillsTmp")
    assert "CHEAT no room in /dev/shm 28" in text and "CHEAT no room in /tmp 28" in text and "filled" not in text
    assert not [p for d in ("/tmp", "/dev/shm") for p in Path(d).glob("acc-gym-fill-*")]
