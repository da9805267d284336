"""The -v0 ids give the episodes they gave before the -v1 ids came (issue 33): stored
reference episodes (``data/v0_reference.json``, written by ``make_v0_reference.py`` with
acc-gym 0.7.0's driver model 5, before the v1 work) replayed step for step: the same
number of steps and end, every 25th observation and reward, the return and the score.

Tolerances as the suites' (``acc_gym.reproducibility``): trajectories are reproducible to
a tolerance across machines (BLAS, libm), not to the bit."""

import json
from pathlib import Path

import numpy as np
import pytest

from acc_gym.reproducibility import SCORE_TOLERANCE

HERE = Path(__file__).parent
REFERENCE = json.loads((HERE / "data" / "v0_reference.json").read_text())["episodes"]


def _replay():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_v0_reference", HERE / "make_v0_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("ref", REFERENCE, ids=lambda r: f"{r['env_id'].split('/')[1]}-{r['seed']}-{r['driver']}")
def test_a_v0_episode_is_what_it_was(ref):
    got = _replay().episode(ref["env_id"], ref["seed"], ref["driver"])
    assert (got["scenario"], got["steps"], got["terminated"]) == (ref["scenario"], ref["steps"], ref["terminated"])
    np.testing.assert_allclose(np.array(got["obs"]), np.array(ref["obs"]), rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(got["rewards"], ref["rewards"], rtol=1e-6, atol=1e-6)
    assert got["return"] == pytest.approx(ref["return"], rel=1e-6, abs=1e-6)
    assert got["score"] == pytest.approx(ref["score"], abs=SCORE_TOLERANCE)


def test_the_reference_covers_every_v0_id_both_ways():
    assert {r["env_id"] for r in REFERENCE} == {"acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v0",
                                               "acc_gym/NCAP-v0", "acc_gym/StopAndGo-v0"}
    assert {r["driver"] for r in REFERENCE} == {"acc", "wobble"} and all(r["steps"] > 10 for r in REFERENCE)
