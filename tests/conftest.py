"""Shared test settings: the host's leaderboard keys and secrets from the environment of
whoever runs the tests must not change what the tests see."""

import pytest

HOST_VARIABLES = ("ACC_GYM_RESULTS_KEY", "ACC_GYM_RESULTS_KEY_FILE", "ACC_GYM_LEADERBOARD_SECRET")


@pytest.fixture(autouse=True)
def _no_host_keys(monkeypatch):
    for name in HOST_VARIABLES:
        monkeypatch.delenv(name, raising=False)
