"""Round two: a stranger's modules beside the controllers are never imported by a trusted process.

The directory the leaderboard runs from holds the submissions. Files there named like the
standard library's modules (``signal.py``, ``struct.py``, ...) were imported by the trusted
simulation process (multiprocessing's ``spawn`` runs ``-c``, which puts the working directory
first on ``sys.path``), outside any sandbox. Each file here writes a marker when imported;
none may be written, and a controller given as ``signal:X`` is refused with the clash named.
"""

import os
import sys
from pathlib import Path

import pytest

from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard.sandbox import check_reference

SHADOWS = ["signal", "struct", "selectors", "socket", "pickle", "_compat_pickle", "weakref", "threading",
           "subprocess", "locale", "_weakrefset"]

HONEST = '''
import numpy as np


class Law:
    """Holds the set speed's pedal at zero: an honest, dull controller."""

    def predict(self, obs, deterministic=True):
        return np.zeros(1, dtype=np.float32), None
'''


def _plant(where: Path, marker: Path) -> None:
    for name in SHADOWS:  # each records who imported it, then hands over to the real module
        (where / f"{name}.py").write_text(
            "import os as _os, sys as _sys\n"
            f"with open({str(marker)!r}, 'a') as _f:\n"
            f"    _f.write('{name} ' + str(_os.getpid()) + ' ' + ' '.join(_sys.argv)[:200] + '\\n')\n"
            f"_sys.path = [p for p in _sys.path if p not in ('', {str(where)!r})]\n"
            f"del _sys.modules[{name!r}]\n"
            f"from importlib import import_module as _im\n"
            f"_sys.modules[__name__] = _im({name!r})\n")
    (where / "mylaw.py").write_text(HONEST)


@pytest.fixture()
def submissions(tmp_path, monkeypatch):
    where = tmp_path / "submissions"
    where.mkdir()
    marker = tmp_path / "imported.txt"
    _plant(where, marker)
    monkeypatch.chdir(where)
    return where, marker


def test_no_trusted_process_imports_a_module_beside_the_controllers(submissions):
    where, marker = submissions
    r = run_leaderboard(["ncap-v1"], "test", ["acc", "mylaw:Law"], episodes=2, workers=2, string_stability=False,
                        iso15622=False, waves=False, robustness=False, budget=600, allow_root=True)
    by = {c["name"]: c for c in r["controllers"]}
    assert [by[n]["status"] for n in ("acc", "mylaw:Law")] == ["ok", "ok"], [c["reason"] for c in by.values()]
    assert len(by["mylaw:Law"]["episodes"]) == 2  # its module was found in the working directory
    assert not marker.exists(), marker.read_text()  # ... and nothing else there was imported, by anyone


@pytest.mark.parametrize("ref, words", [
    ("signal:X", "'signal' has the name of a standard-library module"),
    ("struct.sub:X", "'struct' has the name of a standard-library module"),
    ("numpy:X", "'numpy' .* has the name of a module already importable from"),
])
def test_a_controller_named_like_an_importable_module_is_refused(submissions, ref, words):
    where, marker = submissions
    (where / "numpy.py").write_text("raise SystemExit('imported')\n")
    with pytest.raises(ValueError, match=words):
        run_leaderboard(["ncap-v1"], "test", ["acc", ref], episodes=1, string_stability=False, iso15622=False, waves=False, robustness=False,
                        allow_root=True)
    assert not marker.exists()


def test_a_reference_with_control_characters_is_refused():
    with pytest.raises(ValueError, match="control characters"):
        check_reference("mylaw:Law\x1b[2J")


def test_the_controllers_own_directory_comes_after_everything_installed(submissions):
    from acc_gym.leaderboard.sandbox import controller_dirs, search_path, trusted_path

    where, _ = submissions
    assert str(where) not in trusted_path() and os.getcwd() not in trusted_path()
    assert search_path()[-1] == str(where) and controller_dirs() == [str(where)]
    assert "" not in trusted_path() and all(os.path.isabs(p) for p in trusted_path())
    assert sys.path  # untouched
