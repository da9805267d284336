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
