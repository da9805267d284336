"""Every code block of the README runs.

* The ```python blocks run in order in one namespace, as a reader pastes them into one
  session; the block that starts ``# mycontroller.py`` is written to that file instead (the
  bash blocks import it).
* Every line of the ```bash blocks runs as a command from a scratch directory holding
  ``mycontroller.py``, with three kinds of documented changes (:data:`QUICK`, :data:`SKIP`):
  ``pip install ... &&`` prefixes are dropped (the package is installed; ``.ci/run`` runs the
  quick start's install itself); the long runs get quick flags appended (fewer episodes,
  training steps, controllers) -- only appended, checked below; and the test command itself
  (``python -m pytest``) is not run from inside the tests.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
LB_QUICK = " --episodes 1 --no-string-stability --no-iso15622 --no-waves --no-robustness"
# command as written in the README (comment stripped) -> what is appended to run it quickly
QUICK = {
    "acc-gym leaderboard": LB_QUICK + " --controllers acc constant",
    "acc-gym evaluate mycontroller:Gap --env acc_gym/CarFollowing-v1 --episodes 20": None,  # replaced: 2 episodes
    "acc-gym leaderboard --controllers acc mycontroller:Gap": LB_QUICK,
    "acc-gym train ppo --env acc_gym/CarFollowing-v1 --seed 0 --out runs/ppo":
        " --timesteps 256 --eval-freq 128 --eval-episodes 1 --no-progress",
    "acc-gym evaluate runs/ppo --env acc_gym/SingleLane-v1 --episodes 300": None,
    # the README's leaderboard line with a relative run directory and a module file, as printed
    # but with 2 episodes and the columns off (they have their own tests; waves alone took 2 min)
    "acc-gym leaderboard --suite ncap-v2 --controllers acc mycontroller:Gap runs/ppo --episodes 10":
        " --episodes 2 --no-string-stability --no-iso15622 --no-waves --no-robustness",
    "acc-gym ring follower-stopper --length 260 --duration 300 --json": None,
    "acc-gym string-stability acc --time-gap 0.6 --plot ss.png": " --frequencies 0.02 0.1",
    "acc-gym string-stability mycontroller:Gap --vehicles 20 --json": " --frequencies 0.02 0.1",
    "acc-gym string-stability acc --penetration 0.25 --drivers naturalistic": " --frequencies 0.02 0.1",
    "python benchmarks/conformance.py": " --controllers acc",
    "acc-gym string-stability acc --time-gap 1.0 --actuator-delay 1.0": " --frequencies 0.02 0.1",
    "acc-gym evaluate acc --env acc_gym/SingleLane-v1 --episodes 20 --sensors typical --actuators typical": None,
    "acc-gym run alks:4.4.2 --controller acc --plot cutin.png": None,
    "python benchmarks/openscenario_bundle.py --table": " --controllers acc constant",
    "acc-gym robustness ppo --plot robustness.png": " --episodes 3 --lags 0 0.5 --delays 0.5 --noise 1 "
                                                   "--no-string-stability",
}
REPLACED = {  # a count in the README lowered for the quick run
    "acc-gym evaluate mycontroller:Gap --env acc_gym/CarFollowing-v1 --episodes 20":
        "acc-gym evaluate mycontroller:Gap --env acc_gym/CarFollowing-v1 --episodes 2",
    "acc-gym evaluate runs/ppo --env acc_gym/SingleLane-v1 --episodes 300":
        "acc-gym evaluate runs/ppo --env acc_gym/SingleLane-v1 --episodes 2",
}
SKIP = {"python -m pytest": "the test run itself (.ci/run runs it)"}


def blocks(kind: str) -> list[str]:
    text = README.read_text(encoding="utf-8")
    return re.findall(rf"^```{kind}\n(.*?)^```", text, flags=re.S | re.M)


def commands() -> list[str]:
    out = []
    for block in blocks("bash"):
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            line = re.sub(r"^pip install \S+ && ", "", line)
            if line and not line.startswith("pip install"):
                out.append(line)
    return out


def test_the_readme_has_the_blocks_this_test_knows():
    known = set(QUICK) | set(SKIP) | {c for c in commands() if c.endswith("--help") or "conformance acc" in c}
    assert set(commands()) <= known, f"a README command this test does not know: {set(commands()) - known}"
    for cmd, quick in QUICK.items():
        assert cmd in commands(), f"{cmd!r} is no longer in the README: update QUICK"
    for cmd, quick in REPLACED.items():  # only the count (the last word) lowered, flags appended
        n = len(cmd.split())
        assert quick.split()[:n - 1] == cmd.split()[:-1] and int(quick.split()[n - 1]) < int(cmd.split()[-1])


@pytest.fixture(scope="module")
def workdir(readable_module_tmp):
    d = readable_module_tmp  # readable by a controller's own user id: the leaderboard lines run as printed
    module = [b for b in blocks("python") if b.startswith("# mycontroller.py")]
    assert len(module) == 1
    (d / "mycontroller.py").write_text(module[0], encoding="utf-8")
    return d


def test_the_python_blocks_run_in_order(workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    monkeypatch.syspath_prepend(str(workdir))
    ns: dict = {"__name__": "readme"}
    pre = "import numpy as np\nfrom acc_gym.drivers import IDM\nrng = np.random.default_rng(0)\n"
    exec(compile(pre, "README preamble", "exec"), ns)  # what the earlier blocks of a session define
    for k, block in enumerate(blocks("python")):
        if block.startswith("# mycontroller.py"):
            continue
        exec(compile(block, f"README python block {k}", "exec"), ns)
    # what the blocks claim, checked
    assert ns["tr"].gap[:, 1].min() > 0
    assert len(ns["scenarios"].list_scenarios()) == 111
    assert ns["list_suites"]() == ["carfollowing-v1", "malicious-v3", "ncap-v1", "ncap-v2", "singlelane-v3"]
    assert 0.0 <= ns["report"].score <= 100.0


@pytest.mark.parametrize("cmd", commands())
def test_each_bash_line_runs(cmd, workdir):
    if cmd in SKIP:
        pytest.skip(SKIP[cmd])
    line = REPLACED.get(cmd, cmd + (QUICK.get(cmd) or ""))
    argv = shlex.split(line)
    if argv[0] == "python":
        argv = [sys.executable, str(ROOT / argv[1]), *argv[2:]]
    else:
        argv = [sys.executable, "-m", "acc_gym", *argv[1:]]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(workdir), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run(argv, cwd=workdir, capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, f"{line}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    assert proc.stdout.strip()
