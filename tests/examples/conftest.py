"""Running an example script the way a user does: ``python examples/NAME.py --quick ...`` in a
fresh interpreter, from a scratch directory, its output returned (a failure shows both streams)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture
def run_example(readable_tmp):
    tmp_path = readable_tmp  # a scratch directory a controller's own user id may read (the leaderboard's examples)

    def run(name: str, *args: str, check: bool = True, timeout: float = 300.0) -> subprocess.CompletedProcess:
        proc = subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=tmp_path, capture_output=True,
                              text=True, timeout=timeout)
        if check:
            assert proc.returncode == 0, f"{name} {' '.join(args)} failed:\n{proc.stdout}\n{proc.stderr}"
        return proc

    return run
