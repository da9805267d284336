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


def pytest_sessionstart(session):
    """Under pytest-xdist (the default ``-n auto``), in the controlling process: when the kernel
    cache is empty (a fresh install, as in CI) compile the package's kernels once, two parts side
    by side, before the workers start, instead of once in every worker (tests/kernel_warmup.py)."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return  # a worker, or a run without workers
    import kernel_warmup

    kernel_warmup.warm(processes=2)
