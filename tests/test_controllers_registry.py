"""Controllers by name (acc_gym.controllers): the core owns the registry and imports nothing
from the agents package; third-party distributions register controllers by entry point."""

import ast
import json
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import pytest

from acc_gym import controllers
from acc_gym.evaluation.runner import load_controller

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-c", "import sys; from acc_gym.cli import main; sys.exit(main(sys.argv[1:]))"]
BUILTINS = ["acc", "cacc", "cc-driver", "constant", "follower-stopper", "fsm-driver", "fuzzy", "gipps", "gm", "idm",
            "mp-cacc", "mpc", "pi-saturation", "ppo", "ppo-acc"]


def imported_top_levels(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_the_core_imports_nothing_from_the_agents_package():
    files = sorted((ROOT / "acc_gym").rglob("*.py"))
    assert len(files) > 40
    offenders = {str(f.relative_to(ROOT)): sorted(imported_top_levels(f) & {"agents", "acc_gym_agents"})
                 for f in files}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_every_package_folder_is_installed_and_agents_as_acc_gym_agents():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert cfg["package-dir"] == {"acc_gym_agents": "agents"}
    expected = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "acc_gym").rglob("__init__.py")}
    expected |= {".".join(("acc_gym_agents",) + p.parent.relative_to(ROOT / "agents").parts)
                 for p in (ROOT / "agents").rglob("__init__.py")}
    assert set(cfg["packages"]) == expected
    assert "agents" not in cfg["packages"]


def test_builtins_and_the_shipped_policy_are_registered_entry_points():
    names = controllers.registered_controllers()
    assert list(names) == sorted(BUILTINS) and all("entry point acc_gym_agents." in o for o in names.values())
    for name in BUILTINS:
        c = load_controller(name)
        assert hasattr(c, "predict")
    with pytest.raises(ValueError, match=r"unknown controller 'nope'.*'acc'.*acc-gym controllers"):
        load_controller("nope")


def test_register_controller_in_process():
    class Still:
        def predict(self, obs, deterministic=True):
            return [-1.0], None

    controllers.register_controller("still-test", Still)
    try:
        assert isinstance(load_controller("still-test"), Still)
        assert "still-test" in controllers.registered_controllers()
        with pytest.raises(ValueError, match="registered already"):
            controllers.register_controller("still-test", Still)
    finally:
        controllers.unregister_controller("still-test")
    assert "still-test" not in controllers.registered_controllers()
    for bad in ("", "a:b", " x"):
        with pytest.raises(ValueError, match="controller name"):
            controllers.register_controller(bad, Still)
    with pytest.raises(TypeError, match="callable"):
        controllers.register_controller("x", 3)
    controllers.register_controller("not-a-controller", lambda: object())
    try:
        with pytest.raises(ValueError, match="no predict"):
            load_controller("not-a-controller")
    finally:
        controllers.unregister_controller("not-a-controller")


@pytest.fixture
def readable_tmpdir():
    """A temporary directory other users may read (the leaderboard's sandboxed controller may
    run as another user, so pytest's 0o700 tmp_path will not do), removed afterwards."""
    d = Path(tempfile.mkdtemp(prefix="acc-gym-registry-"))
    os.chmod(d, 0o755)
    yield d
    shutil.rmtree(d, ignore_errors=True)


def throwaway_distribution(root: Path, dist: str = "third_party_acc", name: str = "third-acc",
                           target: str = "third_party_acc:Gentle") -> None:
    (root / "third_party_acc.py").write_text(
        "import numpy as np\n\n"
        "class Gentle:\n"
        "    def predict(self, obs, deterministic=True):\n"
        "        return np.array([-0.05], dtype=np.float32), None\n")
    info = root / f"{dist}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist.replace('_', '-')}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[acc_gym.controllers]\n{name} = {target}\n")
    for p in [root, *root.rglob("*")]:
        os.chmod(p, 0o755 if p.is_dir() else 0o644)


def run_cli(args, pythonpath: Path, cwd: Path):
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    return subprocess.run([*CLI, *args], capture_output=True, text=True, env=env, cwd=cwd, timeout=600)


def test_a_third_party_distribution_registers_a_controller_by_entry_point(readable_tmpdir):
    root = readable_tmpdir
    throwaway_distribution(root)
    listed = run_cli(["controllers"], root, root)
    assert listed.returncode == 0, listed.stderr
    line = next(x for x in listed.stdout.splitlines() if x.startswith("third-acc"))
    assert "third_party_acc:Gentle" in line and "third-party-acc 0.1" in line
    assert "acc " in listed.stdout  # the built-ins are still there
    ev = run_cli(["evaluate", "third-acc", "--env", "acc_gym/NCAP-v0", "--episodes", "1", "--json"], root, root)
    assert ev.returncode == 0, ev.stderr
    assert json.loads(ev.stdout)["episodes"] == 1
    lb = run_cli(["leaderboard", "--allow-root", "--suite", "ncap-v1", "--controllers", "third-acc", "acc",
                  "--episodes", "2", "--no-string-stability", "--no-iso15622", "--no-waves", "--no-robustness", "--json", "--out", str(root / "board")], root, root)
    assert lb.returncode == 0, lb.stderr
    ranking = {r["controller"]: r for r in json.loads(lb.stdout.splitlines()[-1])["ranking"]}
    assert ranking["third-acc"]["status"] == "ok" and ranking["acc"]["status"] == "ok"


def test_two_distributions_with_one_name_are_an_error_naming_both(readable_tmpdir):
    root = readable_tmpdir
    throwaway_distribution(root)
    throwaway_distribution(root, dist="other_acc", target="third_party_acc:Other")
    ev = run_cli(["evaluate", "third-acc", "--env", "acc_gym/NCAP-v0", "--episodes", "1"], root, root)
    assert ev.returncode != 0
    assert "registered twice" in ev.stderr and "third-party-acc" in ev.stderr and "other-acc" in ev.stderr


def test_a_foreign_agents_module_first_on_the_path_changes_nothing(readable_tmpdir):
    root = readable_tmpdir
    (root / "agents").mkdir()
    (root / "agents" / "__init__.py").write_text("raise ImportError('a foreign agents package, not acc_gym's')\n")
    for p in [root, *root.rglob("*")]:
        os.chmod(p, 0o755 if p.is_dir() else 0o644)
    ev = run_cli(["evaluate", "acc", "--env", "acc_gym/NCAP-v0", "--episodes", "1", "--json"], root, root)
    assert ev.returncode == 0, ev.stderr
    lb = run_cli(["leaderboard", "--suite", "ncap-v1", "--controllers", "acc", "ppo-acc", "--episodes", "2",
                  "--no-string-stability", "--no-iso15622", "--no-waves", "--no-robustness", "--json", "--out", str(root / "board")], root, root)
    assert lb.returncode == 0, lb.stderr
    assert all(r["status"] == "ok" for r in json.loads(lb.stdout.splitlines()[-1])["ranking"])
    tr = run_cli(["train", "--help"], root, root)
    assert tr.returncode == 0 and "--timesteps" in tr.stdout  # acc-gym train, a plugin of the agents package
