"""`seaway study table1`, condition #1, end to end in lockstep: composed (the default) and through the
real processes (``--processes``).

Three runs (NMPC, EO-EMPC, CC-EMPC) on two stacks; then the paper's relations
(shared/reproduction.md): CC-EMPC costs at most +0.5 % of EO-EMPC's energy and has the lower mean
cross-track error; NMPC is the fastest and the most expensive. Composed, each stack is a study worker
process of its own (``seaway_lab.study.worker``) composing the launcher and the services as nodes;
through the processes, each stack is a launcher and its processes on a rendezvous port of its own.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system

SERVICES = ("sim", "estimator", "controller", "recorder")


def condition_1(out: Path, env: dict[str, str], *extra: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """``seaway study table1 --rows '#1'`` on two stacks: (what --json printed, results.json)."""
    p = subprocess.run([str(BIN / "seaway"), "study", "table1", "--rows", "#1", "--workers", "2",
                        "--out", str(out), "--json", *extra], env=env, cwd=REPO, capture_output=True,
                       text=True, timeout=800)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    doc = json.loads(p.stdout)
    saved = json.loads((out / "results.json").read_text())
    assert saved["results"] == doc["results"]
    return doc, saved


def assert_the_papers_relations(doc: dict[str, Any]) -> None:
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
    assert doc["timing"]["runs"] == 3 and doc["wall_s"] > 0


def assert_the_files(out: Path, saved: dict[str, Any]) -> set[Path]:
    """The study's files, and each stack's folder with its recording (a run per episode)."""
    for name in ("results.md", "results.csv", "results.json", "series.json",
                 "figures/trajectory-paper-c1.png", "figures/thrusts-paper-c1.png"):
        assert (out / name).is_file(), name
    folders = {Path(r["run_dir"]) for r in saved["runs"]}
    assert folders == {out / "runs" / f"stack-{n}" for n in (1, 2)}  # two workers, two stacks
    for folder in folders:
        assert (folder / "recording.mcap").is_file()
        # the launcher was told --no-report: the study reads the recording itself
        assert not (folder / "report").exists(), folder
        episodes = sorted(r["episode"] for r in saved["runs"] if Path(r["run_dir"]) == folder)
        assert episodes == list(range(len(episodes))), (folder, episodes)
    return folders


@pytest.mark.timeout(300)
def test_condition_1_composed_shows_the_papers_relations(tmp_path: Path,
                                                         zenoh_env: dict[str, str]) -> None:
    out = tmp_path / "study"
    doc, saved = condition_1(out, zenoh_env)
    assert_the_papers_relations(doc)
    assert doc["executor"]["services"] == "composed" and doc["executor"]["stacks"] == "shared"
    for folder in assert_the_files(out, saved):
        # the launcher ran as a node: its output (readiness, the missions) in launch.log, each
        # service's log in its own file, not mixed into the worker's
        launch = (folder / "launch.log").read_text()
        assert "composed: every service a node of this process" in launch
        assert "all ready in" in launch and "stopped in" in launch
        for service in SERVICES:
            log = (folder / "logs" / f"{service}.log").read_text()
            assert f"{service} ready on vessel" in log, (folder, service, log[-2000:])
        worker = (folder / "worker.log").read_text()
        assert "ready on vessel" not in worker and "all ready in" not in worker, worker[-2000:]
    for r in saved["runs"]:
        assert r["port"] is None  # no network
        assert "--composed" in r["command"] and "--processes" not in r["command"]
        assert r["cpu_s"]["composed"] > 0 and "controller" not in r["cpu_s"]
        assert r["timing"]["mission_s"] > 0
    first = [r for r in saved["runs"] if r["episode"] == 0]
    assert all(r["timing"]["startup_s"] > 0 for r in first)  # each stack's start-up, its first run's
    # two stacks on a machine of two or more CPUs: each worker process on CPUs of its own
    if len(os.sched_getaffinity(0)) >= 2:
        groups = doc["executor"]["cpus"]
        assert groups is not None and len(set(groups)) == 2, groups


@pytest.mark.timeout(900)
# Three paper missions through the processes, about 60 s; the composed test above is the default's.
@pytest.mark.slow
def test_condition_1_through_the_processes_shows_the_papers_relations(
        tmp_path: Path, zenoh_env: dict[str, str]) -> None:
    out = tmp_path / "study"
    doc, saved = condition_1(out, zenoh_env, "--processes")
    assert_the_papers_relations(doc)
    assert doc["executor"]["services"] == "processes"
    assert_the_files(out, saved)
    ports = {r["port"] for r in saved["runs"]}
    assert len(ports) == 2  # a rendezvous port per stack
    assert not any("--composed" in r["command"] for r in saved["runs"])
    # two stacks on a machine of two or more CPUs: each on CPUs of its own (seaway.runtime.cpus)
    if len(os.sched_getaffinity(0)) >= 2:
        groups = doc["executor"]["cpus"]
        assert groups is not None and len(set(groups)) == 2, groups
        pinned = {c[c.index("--cpus") + 1] for c in (r["command"] for r in saved["runs"])}
        assert pinned == set(groups)  # each stack's launcher told its own
