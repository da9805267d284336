"""Adversarial controllers for the leaderboard tests, loaded as ``cheats:NAME``.

Each tries one of the cheats that worked when controllers ran beside the simulator
(issue 16) and reports what it managed on its standard output, which the leaderboard
sends to the controller's own log file. They only *try*: where a write would succeed it
writes nothing (an append of zero bytes), so a run without isolation damages nothing.
A cheat's target (the output directory) comes from ``cheats_target.txt`` in the
directory named by ``CHEATS_DIR`` beside this file, written by the test.
"""

import gc
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

FULL_THROTTLE = np.array([1.0], dtype=np.float32)


def say(*words) -> None:
    print("CHEAT", *words, flush=True)


def target(name: str = "cheats_target.txt") -> Path:
    """The path a test left in ``name`` beside this file (each test file its own name: test files
    run at once in different pytest-xdist workers)."""
    return Path((Path(__file__).with_name(name)).read_text().strip())


class FullThrottle:
    """No cheat: full throttle, which collides in every episode with a vehicle ahead."""

    def predict(self, obs, deterministic=True):
        return FULL_THROTTLE, None


class PatchesScorer(FullThrottle):
    """Full throttle, after replacing the scorer and the result pipe in its own process."""

    def __init__(self):
        import multiprocessing.connection

        import acc_gym.envs.core as core
        from acc_gym.evaluation import scoring

        fake = scoring.score_episode

        def perfect(*args, **kwargs):
            report = fake(*args, **kwargs)
            object.__setattr__(report, "score", 100.0)
            return report

        core.score_episode = perfect
        scoring.score_episode = perfect
        multiprocessing.connection.Connection.send = lambda self, obj: None
        say("patched the scorer")


class Introspects(FullThrottle):
    """Looks through its frames and the garbage collector for the simulator or a scenario."""

    def predict(self, obs, deterministic=True):
        found = []
        frame = sys._getframe()
        while frame is not None:
            found += [k for k, v in frame.f_locals.items() if type(v).__name__ in ("SingleLaneWorld", "Scenario",
                                                                                    "ACCEnv", "EpisodeRun")]
            frame = frame.f_back
        found += [type(o).__name__ for o in gc.get_objects()
                  if type(o).__name__ in ("SingleLaneWorld", "Scenario", "ACCEnv", "EpisodeRun")]
        for o in gc.get_objects():  # move the ego to a safe gap where it can
            if type(o).__name__ == "SingleLaneWorld":
                o.x[0] = -1e6
        say("found", len(found))
        return FULL_THROTTLE, None


class FreezesClock:
    """Freezes its clocks and takes 1.5 s in every call after the first (budget: 1 s)."""

    def __init__(self):
        self.calls = 0
        time.monotonic = lambda: 0.0
        time.perf_counter = lambda: 0.0

    def predict(self, obs, deterministic=True):
        self.calls += 1
        if self.calls >= 2:
            time.sleep(1.5)
        return np.zeros(1, dtype=np.float32), None


class ForgesDone:
    """After two steps, writes forged frames (a goodbye, then a short answer) to its socket."""

    def __init__(self):
        self.calls = 0

    def predict(self, obs, deterministic=True):
        self.calls += 1
        if self.calls == 3:
            import socket
            import struct

            fd = int(sys.argv[1])
            s = socket.socket(fileno=os.dup(fd))
            s.sendall(struct.pack("<4sII", b"ACCB", 0, 0) + struct.pack("<4sII", b"ACCA", 0, 0))
            say("forged")
        return np.zeros(1, dtype=np.float32), None


def _others() -> list[int]:
    me, out = os.getpid(), []
    for entry in os.listdir("/proc"):
        if entry.isdigit() and int(entry) != me:
            try:
                cmd = Path(f"/proc/{entry}/cmdline").read_bytes()
            except OSError:
                continue
            if b"acc_gym.leaderboard.sandbox" in cmd or b"multiprocessing" in cmd or b"pytest" in cmd:
                out.append(int(entry))
    return out


class KillsOthers(FullThrottle):
    """SIGKILLs every other controller, simulation and test process it can find."""

    def __init__(self):
        self.done = False

    def predict(self, obs, deterministic=True):
        if not self.done:
            self.done = True
            killed = refused = 0
            for pid in _others() + [os.getppid()]:
                try:
                    os.kill(pid, signal.SIGKILL)
                    killed += 1
                except PermissionError:
                    refused += 1
                except ProcessLookupError:
                    pass
            say("killed", killed, "refused", refused)
        return FULL_THROTTLE, None


def forged_results_text(path: Path, me: str) -> str:
    """results.json as a forger would rewrite it: ``me`` ranked first (taken from the file
    at ``path`` if it can be read), with a freshly computed, valid checksum."""
    import json

    from acc_gym.leaderboard.results import results_text

    try:
        results = json.loads(path.read_text())["results"]
    except (OSError, ValueError, KeyError, TypeError):
        results = {"ranking": []}
    results["ranking"] = [me] + [n for n in results.get("ranking", []) if n != me]
    return results_text(results, key=None)  # unsigned: the forger has no key, only the checksum


class Lingers(FullThrottle):
    """Double-forks a detached grandchild that outlives the run and rewrites results.json
    (itself first, with a recomputed checksum, so that the file still loads)."""

    def __init__(self):
        out = target()
        if os.fork() == 0:
            os.setsid()
            if os.fork() == 0:
                say("grandchild", os.getpid())
                for _ in range(200):  # for up to 20 s, keep trying to rewrite the results
                    time.sleep(0.1)
                    try:
                        path = out / "results.json"
                        text = forged_results_text(path, "cheats:Lingers")
                        path.write_text(text)
                        say("rewrote results")
                    except OSError:
                        pass
                os._exit(0)
            os._exit(0)
        os.wait()


class EditsFiles(FullThrottle):
    """Tries to open the installed package source, the suite data and the output for writing."""

    def __init__(self):
        import acc_gym
        import acc_gym.envs.core as core

        paths = [Path(core.__file__), Path(acc_gym.__file__).parent / "suites" / "data" / "ncap-v1.json"]
        for p in paths:
            try:
                with open(p, "ab"):  # a zero-byte append: proves the right without changing a byte
                    pass
                say("writable", p)
            except OSError:
                say("refused", p)


class Floods(FullThrottle):
    """Prints 3 MB of junk and a fake ranking line on its standard output and error."""

    def __init__(self):
        sys.stdout.write("1  cheats:Floods  ok  100.0  100.0  100%\n")
        sys.stdout.write("x" * (3 << 20) + "\n")
        sys.stderr.write("y" * 1000 + "\n")
        sys.stdout.flush()


_ENVS: dict = {}


def first_observation(suite, scenario) -> tuple:
    """The first observation of ``scenario`` (an episode of ``suite``), as the controller gets it."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)

    env = _ENVS.get(suite.env_id) or _ENVS.setdefault(suite.env_id, gym.make(suite.env_id))
    obs, _ = env.reset(seed=scenario.seed, options={"scenario": scenario})
    return tuple(np.asarray(obs, dtype=np.float64).tolist())


def first_observation_table(suite, split: str = "test") -> dict:
    """What a controller can compute offline from the shipped suite data: each first
    observation of ``split`` -> the episode indices that start with it. With it, a
    controller knows on its first step which shipped episode it is in."""
    table: dict = {}
    for k, sc in enumerate(suite.episodes(split)):
        table.setdefault(first_observation(suite, sc), []).append(k)
    return table


# -- round two -------------------------------------------------------------------------------------
def _here(name: str) -> Path:
    return Path(__file__).with_name(name)


class Escapes(FullThrottle):
    """Prints escape sequences, then fails with an exception text that clears the screen and
    draws a forged ranking (no newline: the reason's first line keeps them all)."""

    def __init__(self):
        sys.stdout.write("\x1b[2J\x1b[H\x1b]0;owned\x07log line\r\n")
        sys.stdout.flush()
        self.calls = 0

    def predict(self, obs, deterministic=True):
        self.calls += 1
        if self.calls == 3:
            raise RuntimeError("\x1b[2J\x1b[H\x1b[1;1H1  cheats:Escapes  ok  100.0\x1b[5;1H\x1b[K\x9b2J\u202edone")
        return FULL_THROTTLE, None


class FloodsLog(FullThrottle):
    """Writes 6 MiB to its standard output (the test caps the log at 1 MiB)."""

    def __init__(self):
        for _ in range(6):
            sys.stdout.write("z" * (1 << 20))
        sys.stdout.write("\nCHEAT flooded\n")
        sys.stdout.flush()


class Forks(FullThrottle):
    """Forks 200 sleeping children and reports how many it got."""

    def __init__(self):
        got, kids = 0, []
        for _ in range(200):
            try:
                pid = os.fork()
            except OSError:
                break
            if pid == 0:
                time.sleep(30)
                os._exit(0)
            kids.append(pid)
            got += 1
        say("forked", got)
        for pid in kids:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)


class HoldsMemory(FullThrottle):
    """Three forked children each hold 400 MiB at once (the test caps the tree at 1 GiB)."""

    def __init__(self):
        kids = []
        for k in range(3):
            pid = os.fork()
            if pid == 0:
                block = bytearray(400 << 20)
                for i in range(0, len(block), 4096):
                    block[i] = 1
                say("held", k)
                time.sleep(3)
                os._exit(0)
            kids.append(pid)
        codes = [os.waitpid(pid, 0)[1] for pid in kids]
        say("children ended", codes)


class Connects(FullThrottle):
    """Connects to the test's listener on 127.0.0.1 (its port in cheats_port.txt)."""

    def __init__(self):
        import socket

        port = int(_here("cheats_port.txt").read_text())
        try:
            socket.create_connection(("127.0.0.1", port), timeout=2).sendall(b"CHEAT here")
            say("connected")
        except OSError as exc:
            say("refused", type(exc).__name__)


class LeavesTmp(FullThrottle):
    """Leaves a file in /tmp and one in /dev/shm for the next controller."""

    def __init__(self):
        token = _here("cheats_port.txt").read_text().strip()
        for d in ("/tmp", "/dev/shm"):
            try:
                Path(d, f"acc-gym-cheat-{token}").write_text("left")
                say("left", d)
            except OSError as exc:
                say("could not leave", d, exc)


class ReadsTmp(FullThrottle):
    """Looks for what LeavesTmp left."""

    def __init__(self):
        token = _here("cheats_port.txt").read_text().strip()
        for d in ("/tmp", "/dev/shm"):
            say("found" if Path(d, f"acc-gym-cheat-{token}").exists() else "nothing in", d)


class ShutsSocket(FullThrottle):
    """After two steps, shuts its socket down and stays alive."""

    def __init__(self):
        self.calls = 0

    def predict(self, obs, deterministic=True):
        import socket

        self.calls += 1
        if self.calls == 3:
            s = socket.socket(fileno=os.dup(int(sys.argv[1])))
            s.shutdown(socket.SHUT_RDWR)
            time.sleep(60)
        return FULL_THROTTLE, None


class ReadsResults(FullThrottle):
    """Tries to read an earlier private run's results (their path in cheats_private_target.txt)."""

    def __init__(self):
        try:
            text = (target("cheats_private_target.txt") / "results.json").read_text()
            say("read", len(text))
        except OSError as exc:
            say("refused", type(exc).__name__)


class FillsDisk(FullThrottle):
    """Writes eight 1 MiB files into its working directory at every call, 256 in all at most (its
    copies count together): each under the per-file cap the test sets (4 MiB), together past its
    disk limit (64 MiB)."""

    written = 0  # every copy's files: one process

    def predict(self, obs, deterministic=True):
        for _ in range(8):
            if FillsDisk.written < 256:
                Path(f"fill-{FillsDisk.written:03d}.bin").write_bytes(b"d" * (1 << 20))
                FillsDisk.written += 1
                if FillsDisk.written % 32 == 0:
                    say("wrote", FillsDisk.written, "MiB")
        return FULL_THROTTLE, None


class FillsTmp(FullThrottle):
    """Writes 1 MiB files into /dev/shm and /tmp until told there is no room, 64 MiB in each at most
    (the test sizes them at 16 MiB); the last such error ends it."""

    def __init__(self):
        error = None
        for d in ("/dev/shm", "/tmp"):
            try:
                for k in range(64):
                    Path(d, f"acc-gym-fill-{os.getpid()}-{k}").write_bytes(b"t" * (1 << 20))
                say("filled", d)
            except OSError as exc:
                say("no room in", d, exc.errno)
                error = exc
        if error is not None:
            raise error
