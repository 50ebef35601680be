"""`seaway study table1`, condition #1, end to end through the real processes in lockstep.

Three runs (NMPC, EO-EMPC, CC-EMPC) on two stacks, each on its own rendezvous port; then the
paper's relations (shared/reproduction.md): CC-EMPC costs at most +0.5 % of EO-EMPC's energy and has
the lower mean cross-track error; NMPC is the fastest and the most expensive.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system


@pytest.mark.timeout(900)
# Three paper missions, about 60 s; test_study_dask runs one of a study's runs end to end by default.
@pytest.mark.slow
def test_condition_1_shows_the_papers_relations(tmp_path: Path, zenoh_env: dict[str, str]) -> None:
    out = tmp_path / "study"
    p = subprocess.run([str(BIN / "seaway"), "study", "table1", "--rows", "#1", "--workers", "2",
                        "--out", str(out), "--json"], env=zenoh_env, cwd=REPO, capture_output=True,
                       text=True, timeout=800)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    doc = json.loads(p.stdout)
    assert doc["study"] == "table1" and doc["failures"] == {}
    c1 = doc["results"]["#1"]
    assert set(c1) == {"nmpc", "eo-empc", "cc-empc"}
    cc, eo, nm = c1["cc-empc"], c1["eo-empc"], c1["nmpc"]
    assert all(x["completed"] for x in (cc, eo, nm))

    assert cc["energy_j"] <= 1.005 * eo["energy_j"], (cc, eo)
    assert cc["avg_cross_track_m"] < eo["avg_cross_track_m"], (cc, eo)
    assert nm["travel_time_s"] < min(cc["travel_time_s"], eo["travel_time_s"]), (nm, cc, eo)
    assert nm["energy_j"] > max(cc["energy_j"], eo["energy_j"]), (nm, cc, eo)
    assert doc["relations"]["#1"]["holds"] is True
    # energy and time of the economic controllers within 5 % of Table I (shared/reproduction.md)
    for x in (cc, eo):
        assert abs(x["diff_pct"]["energy_j"]) < 5.0 and abs(x["diff_pct"]["travel_time_s"]) < 5.0, x

    # the files, and each stack's folder with its recording (a run per episode)
    for name in ("results.md", "results.csv", "results.json", "series.json",
                 "figures/trajectory-paper-c1.png", "figures/thrusts-paper-c1.png"):
        assert (out / name).is_file(), name
    saved = json.loads((out / "results.json").read_text())
    assert saved["results"] == doc["results"]
    folders = {r["run_dir"] for r in saved["runs"]}
    assert folders == {str(out / "runs" / f"stack-{n}") for n in (1, 2)}  # two workers, two stacks
    for folder in map(Path, folders):
        assert (folder / "recording.mcap").is_file()
        # the launcher was told --no-report: the study reads the recording itself
        assert not (folder / "report").exists(), folder
    ports = {r["port"] for r in saved["runs"]}
    assert len(ports) == 2  # a rendezvous port per stack
    # two stacks on a machine of two or more CPUs: each on CPUs of its own (seaway.runtime.cpus)
    if len(os.sched_getaffinity(0)) >= 2:
        groups = doc["executor"]["cpus"]
        assert groups is not None and len(set(groups)) == 2, groups
        pinned = {c[c.index("--cpus") + 1] for c in (r["command"] for r in saved["runs"])}
        assert pinned == set(groups)  # each stack's launcher told its own
    assert doc["timing"]["runs"] == 3 and doc["wall_s"] > 0
