"""Each extra of pyproject.toml installs what its documented commands import.

The default run checks it statically: the third-party top-level modules imported by the
code an extra's commands run (parsed with ``ast``) must each come from a distribution the
core dependencies or that extra list by name (a module that only arrives as another
package's dependency -- PyYAML through mkdocs -- is the defect this catches). The slow test
checks it for real: a fresh virtual environment per extra, ``pip install "REPO[extra]"``,
and the command that extra's documentation shows, so a missing dependency fails it
(``python -m pytest -m slow tests/test_extras.py -n 0``)."""

from __future__ import annotations

import ast
import functools
import json
import os
import re
import subprocess
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]

# the code each extra's commands run (beyond the core's): files, or folders of them
EXTRA_CODE = {
    "rl": ["agents/rl"],  # acc-gym train, and the saved runs acc-gym evaluate opens
    "ncap": ["acc_gym/standards/ncap.py"],  # acc-gym conformance --standard ncap
    "campaign": ["acc_gym/campaigns"],  # acc-gym campaign (pyarrow)
    "dist": ["acc_gym/campaigns"],  # acc-gym campaign --scheduler (dask.distributed)
    "docs": ["docs/_ext", "examples/record_video.py"],  # mkdocs build --strict (the docstring extension), the docs video
    "osc": ["acc_gym/scenarios/openscenario/check.py", "acc_gym/commands/validate.py",  # acc-gym validate
            "acc_gym/scenarios/openscenario/writer.py", "acc_gym/commands/export.py"],  # acc-gym export
    "bench": ["benchmarks/bench_env.py", "benchmarks/sumo_peer.py"],  # bench_env.py --peers
}
# modules a file imports for another extra's feature: (extra, file) -> {module: the extra that has it}
ELSEWHERE = {
    ("campaign", "acc_gym/campaigns/errors.py"): {"distributed": "dist"},  # the --scheduler message
    ("dist", "acc_gym/campaigns/errors.py"): {"pyarrow": "campaign"},
    ("dist", "acc_gym/campaigns/manifest.py"): {"pyarrow": "campaign"},  # a cluster's campaign writes Parquet too
    ("dist", "acc_gym/campaigns/summary.py"): {"pyarrow": "campaign"},
    ("bench", "benchmarks/bench_env.py"): {"torch": "rl", "stable_baselines3": "rl"},  # --policy, not --peers
}
LOCAL = {"acc_gym", "acc_gym_agents", "sumo_peer", "__future__"}  # this repository's own modules
# distributions of modules this test's environment may not have installed (bench's peer)
KNOWN = {"cacc_sim": "cavsandbox"}


def _name(requirement: str) -> str:
    """A requirement's distribution name, normalised (PEP 503)."""
    return re.sub(r"[-_.]+", "-", re.match(r"[A-Za-z0-9][A-Za-z0-9._-]*", requirement).group()).lower()


def _files(paths: list[str]) -> list[Path]:
    out = []
    for p in paths:
        path = REPO / p
        out.extend(sorted(path.rglob("*.py")) if path.is_dir() else [path])
    return out


def third_party_imports(path: Path) -> set[str]:
    """The top-level names of the absolute imports in ``path`` that are neither the standard
    library's nor this repository's."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return {n for n in names if n not in sys.stdlib_module_names and n not in LOCAL}


@functools.cache
def _packages() -> dict:
    return metadata.packages_distributions()


def _distributions(module: str) -> set[str]:
    found = _packages().get(module) or ([KNOWN[module]] if module in KNOWN else [])
    return {_name(d) for d in found}


def test_extras_are_the_ones_pyproject_lists():
    assert set(EXTRA_CODE) == set(PYPROJECT["optional-dependencies"]) - {"test", "all"}


@pytest.mark.parametrize("extra", sorted(EXTRA_CODE))
def test_each_extra_lists_what_its_code_imports(extra):
    core = {_name(r) for r in PYPROJECT["dependencies"]}
    listed = {_name(r) for r in PYPROJECT["optional-dependencies"][extra]}
    missing = []
    for path in _files(EXTRA_CODE[extra]):
        rel = str(path.relative_to(REPO))
        elsewhere = ELSEWHERE.get((extra, rel), {})
        for module in sorted(third_party_imports(path)):
            if module in elsewhere:
                continue
            dists = _distributions(module)
            assert dists, f"{rel} imports {module!r}, which no installed distribution provides: add it to KNOWN"
            if not dists & (core | listed):
                missing.append(f"{rel} imports {module!r} ({' or '.join(sorted(dists))})")
    assert not missing, f"the {extra!r} extra does not list: " + "; ".join(missing)


def test_the_static_check_sees_a_missing_dependency(tmp_path):
    """What the check above rests on: PyYAML's module maps to its distribution, which the rl
    extra must name (it did not: mkdocs brought it into the test environment)."""
    (tmp_path / "m.py").write_text("import yaml\nfrom acc_gym import cli\nimport json\n")
    assert third_party_imports(tmp_path / "m.py") == {"yaml"}
    assert _distributions("yaml") == {"pyyaml"}
    assert "pyyaml" in {_name(r) for r in PYPROJECT["optional-dependencies"]["rl"]}
    assert "rich" in {_name(r) for r in PYPROJECT["dependencies"]}  # the progress bars


# ---------------------------------------------------------------- for real: a fresh venv per extra
TORCH = "torch==2.13.0"  # the CPU build CI installs first (never a looser spec: pip would fetch a CUDA one)
COMMANDS = {  # what each extra's documentation shows, made small; run in a scratch directory
    "core": [["acc-gym", "demo", "--plot", "demo.png"]],
    "rl": [["acc-gym", "train", "ppo", "--env", "acc_gym/CarFollowing-v1", "--timesteps", "256", "--num-envs", "2",
            "--eval-episodes", "1", "--seed", "0", "--out", "run", "--no-progress"],
           ["acc-gym", "evaluate", "run", "--env", "acc_gym/CarFollowing-v1", "--episodes", "1"]],
    "ncap": [["acc-gym", "conformance", "acc", "--standard", "ncap", "--json"]],
    "osc": [["acc-gym", "validate", "alks:4.4.2", "--json"],
            ["acc-gym", "export", "ncap/ccrs/30", "--controller", "acc", "--out", "exported", "--json"]],
    "docs": [["mkdocs", "build", "--strict", "-f", str(REPO / "mkdocs.yml"), "-d", "{tmp}/site"]],
    "bench": [["python", str(REPO / "benchmarks" / "bench_env.py"), "--peers", "--steps", "50", "--vector-steps", "5",
               "--num-envs", "4", "--repeats", "1", "--cases", "env_idm", "--workers", "1", "--json"]],
}


def _run(cmd, cwd, env, timeout=1800):
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{' '.join(cmd)} exited {r.returncode}:\n{r.stdout[-2000:]}\n{r.stderr[-4000:]}"
    return r


@pytest.mark.slow
@pytest.mark.parametrize("extra", sorted(COMMANDS))
def test_a_fresh_install_of_each_extra_runs_its_documented_command(extra, tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    bin_dir = venv / "bin"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["VIRTUAL_ENV"] = str(venv)
    pip = [str(bin_dir / "python"), "-m", "pip", "install", "--quiet"]
    if extra == "rl":
        _run([*pip, TORCH], tmp_path, env)
    _run([*pip, str(REPO) if extra == "core" else f"{REPO}[{extra}]"], tmp_path, env)
    work = tmp_path / "work"
    work.mkdir()
    for cmd in COMMANDS[extra]:
        cmd = [str(bin_dir / "python") if c == "python" else c.replace("{tmp}", str(tmp_path)) for c in cmd]
        last = _run(cmd, work, env)
    if extra == "core":
        assert (work / "demo.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    if extra == "rl":
        assert (work / "run" / "model.zip").is_file() and (work / "run" / "manifest.json").is_file()
    if extra == "docs":
        assert (tmp_path / "site" / "index.html").is_file()
    if extra == "bench":  # both peers ran: SUMO (libsumo) and cavsandbox
        out = json.loads(last.stdout)
        assert out["sumo_steps_per_s"] > 0 and out["column_ratio_cavsandbox"] is not None, out
    if extra == "osc":  # an export passes ASAM's checker (the validate command before it: the shipped bundle)
        assert json.loads(last.stdout)["checked"] is True
    if extra == "ncap":  # scored by Euro NCAP's calculator, not just driven
        assert json.loads(last.stdout)["standards"]["ncap"]["score_percent"] is not None
