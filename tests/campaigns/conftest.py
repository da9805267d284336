"""Shared campaign fixtures: one small uninterrupted reference campaign run in this process."""

import pytest
from campaign_settings import CHUNK, CONTROLLER, HOURS, SUITE


@pytest.fixture(scope="session")
def reference(tmp_path_factory):
    """(out_dir, summary, campaign) of the reference: 1 worker, no interruption."""
    from acc_gym.campaigns import load_campaign, run_campaign

    out = tmp_path_factory.mktemp("reference")
    summary = run_campaign(SUITE, HOURS, CONTROLLER, out, chunk_size=CHUNK, workers=1)
    return out, summary, load_campaign(out)
