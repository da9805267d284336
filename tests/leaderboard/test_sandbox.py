"""The controller sandbox's own pieces: the compiled-code cache it starts with."""

import os

import numpy as np
import pytest
from numba.core.caching import UserProvidedCacheLocator

from acc_gym.envs import _kernel
from acc_gym.leaderboard.sandbox import seed_numba_cache


def test_a_controller_starts_with_the_packages_compiled_kernels(tmp_path):
    """Numba reads NUMBA_CACHE_DIR at <dir>/<folder>_<sha1 of its path>: the package's own
    cache files must be there, so that a controller (which cannot write the package) does not
    compile every kernel again."""
    out = np.empty(1)
    _kernel.action_to_accel(np.array([0.5]), 3.0, 8.0, out)  # compiled, and cached in the package if it can be
    assert out[0] == 1.5
    source_dir = os.path.dirname(os.path.abspath(_kernel.__file__))
    in_tree = os.path.join(source_dir, "__pycache__")
    cached = sorted(f for f in os.listdir(in_tree) if f.endswith((".nbi", ".nbc"))) if os.path.isdir(in_tree) else []
    if not cached:
        pytest.skip(f"numba keeps no cache in {in_tree} (the installation is not writable): nothing to seed")
    n = seed_numba_cache(str(tmp_path), None)
    target = tmp_path / UserProvidedCacheLocator.get_suitable_cache_subpath(_kernel.__file__)
    assert n >= len(cached) and sorted(os.listdir(target)) == cached
    for f in cached:
        assert (target / f).read_bytes() == open(os.path.join(in_tree, f), "rb").read()


def test_a_user_numba_cache_dir_seeds_the_controllers_cache_and_stays_untouched(tmp_path, monkeypatch):
    """With NUMBA_CACHE_DIR set, numba keeps the runner's compiled code there, not in the package:
    the controller's cache is seeded from it (read only; the user's copy wins over the package's)."""
    import subprocess
    import sys

    user = tmp_path / "user-cache"
    code = ("import numpy as np\nfrom acc_gym.envs import _kernel\nout = np.empty(1)\n"
            "_kernel.action_to_accel(np.array([0.5]), 3.0, 8.0, out)\nassert out[0] == 1.5\n")
    subprocess.run([sys.executable, "-c", code], check=True, env={**os.environ, "NUMBA_CACHE_DIR": str(user)})
    folder = user / UserProvidedCacheLocator.get_suitable_cache_subpath(_kernel.__file__)
    assert any(f.endswith(".nbi") for f in os.listdir(folder)) and any(f.endswith(".nbc") for f in os.listdir(folder))
    (folder / "_kernel.only_the_users-1.py.nbi").write_bytes(b"an entry the package's own cache lacks")
    compiled = sorted(os.listdir(folder))
    (user / "elsewhere_0123").mkdir()  # what else the user compiled is not the controller's
    (user / "elsewhere_0123" / "other.nbi").write_bytes(b"not the package's")
    before = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in user.rglob("*") if p.is_file()}

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(user))
    ctl = tmp_path / "controller-cache"
    n = seed_numba_cache(str(ctl), None)
    target = ctl / folder.name
    assert n >= len(compiled) and set(compiled) <= set(os.listdir(target))
    for f in compiled:
        assert (target / f).read_bytes() == (folder / f).read_bytes()
    assert not (ctl / "elsewhere_0123").exists()
    assert {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in user.rglob("*") if p.is_file()} == before

