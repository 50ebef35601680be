"""`seaway study --dask`: a run submitted to a Dask cluster on loopback starts its stack on the worker,
composed in one process (``seaway launch --composed``, the study's default).

One short run (condition #1 with NMPC: ~34 s of simulated time, a few seconds of wall) on a
``distributed.LocalCluster`` with one worker process; its metrics are those the report command prints
for the run's recording.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from seaway_lab.study.execute import report_args

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system


@pytest.mark.timeout(600)
def test_one_run_on_a_local_dask_cluster(tmp_path: Path, zenoh_env: dict[str, str]) -> None:
    distributed = pytest.importorskip("distributed")
    out = tmp_path / "study"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        p = subprocess.run([str(BIN / "seaway"), "study", "table1", "--rows", "#1", "--columns", "nmpc",
                            "--dask", cluster.scheduler_address, "--out", str(out), "--json"],
                           env=zenoh_env, cwd=REPO, capture_output=True, text=True, timeout=500)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    doc = json.loads(p.stdout)
    assert doc["executor"]["kind"] == "dask" and doc["executor"]["services"] == "composed"
    assert doc["executor"]["address"].startswith("tcp://127.0.0.1:")
    assert doc["workers"] == 1 and doc["failures"] == {}
    nm = doc["results"]["#1"]["nmpc"]
    assert nm["completed"]
    assert nm["paper"]["energy_j"] == 2328.4
    assert abs(nm["diff_pct"]["energy_j"]) < 10 and abs(nm["diff_pct"]["travel_time_s"]) < 10, nm

    run_dir = out / "runs" / "paper-c1-nmpc"
    assert (run_dir / "recording.mcap").is_file() and (run_dir / "launch.log").is_file()
    # the run's numbers are the report command's for its recording
    rep = subprocess.run([str(BIN / "seaway"), "report", *report_args(run_dir), "--json", "--no-plots",
                          "--out", str(tmp_path / "report")], capture_output=True, text=True, timeout=120,
                         check=True)
    metrics = json.loads(rep.stdout)["metrics"]
    for k in ("energy_j", "travel_time_s", "avg_cross_track_m"):
        assert nm[k] == metrics[k]
    run = json.loads((out / "results.json").read_text())["runs"][0]
    assert run["ok"] and run["timing"]["startup_s"] > 0
    assert "--composed" in run["command"] and run["port"] is None  # one process, no network
    assert run["cpu_s"]["composed"] > 0
