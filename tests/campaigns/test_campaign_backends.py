"""The same campaign gives the same rows and the same summary on every backend and worker count."""

import pytest

from acc_gym.campaigns import load_campaign, run_campaign

from campaign_settings import CHUNK, CONTROLLER, HOURS, SUITE


def _same(reference, out, summary):
    ref_out, ref_summary, ref_campaign = reference
    campaign = load_campaign(out)
    assert campaign.complete and campaign.episodes == ref_campaign.episodes == 10
    assert campaign.rows() == ref_campaign.rows()  # every column of every row, bit for bit
    assert [r["index"] for r in campaign.rows()] == list(range(10))
    assert summary == ref_summary


def test_two_local_workers_match_one(reference, tmp_path):
    summary = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK, workers=2)
    _same(reference, tmp_path, summary)


def test_dask_local_cluster_matches_one_worker(reference, tmp_path):
    distributed = pytest.importorskip("distributed", reason="Dask distributed is not installed (pip install '.[dist]' or '.[test]')")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        # by address: run_campaign makes its own Client and closes it
        summary = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path / "by-address", chunk_size=CHUNK,
                               scheduler=cluster.scheduler_address)
        _same(reference, tmp_path / "by-address", summary)
        with distributed.Client(cluster) as client:  # a Client of ours: used, left open
            summary = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path / "by-client", chunk_size=CHUNK,
                                   scheduler=client)
            _same(reference, tmp_path / "by-client", summary)
            assert client.status == "running"


def test_summary_json_is_the_returned_summary(reference):
    from acc_gym.campaigns import load_summary

    out, summary, _ = reference
    assert load_summary(out) == summary


def test_ranking_of_controllers_is_the_same_on_every_backend(reference, tmp_path):
    """Two controllers ranked by their campaigns' mean score: one worker, a two-process pool and a
    Dask LocalCluster give the same order and the same numbers (the ranking is backend-free)."""
    distributed = pytest.importorskip("distributed", reason="Dask distributed is not installed (pip install '.[dist]' or '.[test]')")

    def ranking(**backend):
        out = {}
        for controller in ("acc", "constant"):
            summary = run_campaign(SUITE, HOURS, controller, tmp_path / f"{controller}-{len(list(tmp_path.iterdir()))}",
                                   chunk_size=CHUNK, **backend)
            out[controller] = summary
        order = sorted(out, key=lambda c: -_mean_score(out[c]))
        return order, out

    one = ranking(workers=1)
    pool = ranking(workers=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        dask = ranking(scheduler=cluster.scheduler_address)
    assert one == pool == dask
    assert one[0] == ["acc", "constant"]  # the linear ACC beats the constant-speed floor on NCAP
    assert _mean_score(one[1]["acc"]) > _mean_score(one[1]["constant"])


def _mean_score(summary: dict) -> float:
    value = summary["mean_score"]  # {"estimate", "low", "high", "n"}
    return value["estimate"]
