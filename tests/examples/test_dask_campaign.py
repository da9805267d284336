"""examples/dask_campaign.py: a campaign on a one-worker Dask LocalCluster, summarised, then
resumed without running anything again, in quick mode."""

from __future__ import annotations

import json
import re

import pytest

pytest.importorskip("pyarrow", reason="campaigns need pyarrow (pip install '.[campaign]' or '.[test]')")
pytest.importorskip("distributed", reason="the example needs Dask distributed (pip install '.[dist]' or '.[test]')")


def test_a_quick_campaign_runs_on_dask_and_resumes_without_rerunning(run_example, tmp_path):
    out = tmp_path / "campaign"
    stdout = run_example("dask_campaign.py", "--quick", "--out", str(out)).stdout
    assert re.search(r"^Dask: 1 worker\(s\) at tcp://127\.0\.0\.1:\d+$", stdout, re.M), stdout
    m = re.search(r"campaign: acc on singlelane-v3 v3 \(test, root seed \d+\): (\d+) of (\d+) episodes, "
                  r".* \(complete\)", stdout)
    assert m and m[1] == m[2] and int(m[1]) >= 1, stdout
    # every chunk was written once, by the first call; the second ran nothing and agreed
    written = re.findall(r"^  chunk (\d+) written", stdout, re.M)
    assert written and len(written) == len(set(written))
    assert f"resumed: {m[1]} episodes, nothing re-run: True" in stdout
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert (out / "campaign.json").is_file() and summary["complete"] and summary["episodes"] == int(m[1])
    assert summary["controller"] == "acc" and 0.0 <= summary["mean_score"]["estimate"] <= 100.0
