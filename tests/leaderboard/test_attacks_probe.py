"""Round two: the bwrap probe imports the installed package and loads a built-in controller.

A bwrap that cannot see the package (an editable install under /tmp, hidden by bwrap's own
/tmp) made every controller fail with "No module named 'acc_gym'" while the probe, which ran
``python -c pass``, passed. Here a stand-in bwrap starts the interpreter without its
site-packages (``-S``, and ``-E`` for the handed-over PYTHONPATH): the package does not import there, and the probe must say so.
"""

import sys
import tempfile
from pathlib import Path

import pytest

from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard import sandbox as sandbox_mod


def _fake_bwrap(body: str) -> str:
    bin_dir = Path(tempfile.mkdtemp(prefix="acc-gym-fake-bwrap-"))
    bin_dir.chmod(0o755)
    fake = bin_dir / "bwrap"
    fake.write_text(f"#!{sys.executable} -I\nimport os, sys\nargs = sys.argv[1:]\n{body}\n")
    fake.chmod(0o755)
    return str(fake)


def test_the_probe_fails_where_the_package_does_not_import(monkeypatch, tmp_path):
    # everything from the interpreter on, run without site-packages and without the PYTHONPATH the sandbox
    # hands over (-S -E): what a sandbox that cannot see them runs, editable install or not
    fake = _fake_bwrap(f"i = args.index({sys.executable!r})\nos.execv(args[i], [args[i], '-S', '-E', *args[i + 1:]])")
    monkeypatch.setattr(sandbox_mod, "bwrap_available", lambda: fake)
    monkeypatch.setattr(sandbox_mod, "_BWRAP_PROBES", {})
    problem = sandbox_mod.bwrap_problem(None)
    assert problem is not None and "No module named" in problem, problem
    with pytest.raises(RuntimeError, match="(?s)bwrap.*not usable.*No module named .acc_gym."):
        run_leaderboard(["ncap-v1"], "test", ["acc"], episodes=1, out=tmp_path / "b", sandbox="bwrap",
                        string_stability=False, waves=False, robustness=False)
    assert not (tmp_path / "b").exists()


def test_the_probe_passes_where_the_package_imports(monkeypatch):
    fake = _fake_bwrap(f"i = args.index({sys.executable!r})\nos.execv(args[i], args[i:])")
    monkeypatch.setattr(sandbox_mod, "bwrap_available", lambda: fake)
    monkeypatch.setattr(sandbox_mod, "_BWRAP_PROBES", {})
    assert sandbox_mod.bwrap_problem(None) is None
