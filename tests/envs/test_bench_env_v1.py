"""benchmarks/bench_env.py times the -v1 ids (issue 35): the keys env_v1_*, vector_env_v1_* and,
with --peers, sumo_ratio_v1 (the v1 IDM case over the same SUMO runs as sumo_ratio). Only the
keys and their arithmetic are checked here; speed is measured by the benchmark itself."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _bench(*args):
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_env.py"), "--json", "--repeats", "1",
                        "--workers", "1", *args], capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_bench_env_times_the_v1_cases():
    out = _bench("--steps", "60", "--vector-steps", "3", "--num-envs", "4", "--cases", "env_v1", "env_v1_idm")
    for case in ("env_v1", "env_v1_idm"):
        for key in (f"{case}_steps_per_s", f"vector_{case}_steps_per_s"):
            assert out[key] > 0 and len(out[key + "_runs"]) == 1
    assert out["cases"]["env_v1"] == {"id": "acc_gym/SingleLane-v1"}
    assert out["cases"]["env_v1_idm"] == {"id": "acc_gym/SingleLane-v1", "drivers": "idm"}


def test_bench_env_peers_reports_the_v1_ratio():
    pytest.importorskip("libsumo", reason="libsumo is not installed (pip install '.[bench]' or '.[test]'): no SUMO peer to time")
    out = _bench("--steps", "100", "--vector-steps", "2", "--num-envs", "4", "--cases", "env_v1", "--peers")
    assert out["env_v1_idm_steps_per_s"] > 0 and out["sumo_steps_per_s"] > 0  # env_v1_idm is added for the ratio
    assert out["sumo_ratio_v1"] == pytest.approx(out["env_v1_idm_steps_per_s"] / out["sumo_steps_per_s"])
    assert out["sumo_ratio"] == pytest.approx(out["env_idm_steps_per_s"] / out["sumo_steps_per_s"])
