"""Shared test settings: the host's leaderboard keys and secrets from the environment of
whoever runs the tests must not change what the tests see."""

import pytest

HOST_VARIABLES = ("ACC_GYM_RESULTS_KEY", "ACC_GYM_RESULTS_KEY_FILE", "ACC_GYM_LEADERBOARD_SECRET")


@pytest.fixture(autouse=True)
def _no_host_keys(monkeypatch):
    for name in HOST_VARIABLES:
        monkeypatch.delenv(name, raising=False)


def readable_dir(prefix: str):
    """A fresh directory every user may read (mode 0755 under the system's temporary directory),
    for tests that rank a module file through the leaderboard as root: pytest's own ``tmp_path``
    lies under a 0700 directory, where a controller's own user id could not read its module, so
    the leaderboard refuses it (it never runs a stranger's code as root unless asked)."""
    import tempfile
    from pathlib import Path

    d = Path(tempfile.mkdtemp(prefix=f"acc-gym-{prefix}-"))
    d.chmod(0o755)
    return d


@pytest.fixture
def readable_tmp():
    import shutil

    d = readable_dir("test")
    yield d
    shutil.rmtree(d, ignore_errors=True)


@pytest.fixture(scope="module")
def readable_module_tmp():
    """:func:`readable_tmp` shared by a module's tests."""
    import shutil

    d = readable_dir("module")
    yield d
    shutil.rmtree(d, ignore_errors=True)
