"""Composed and through the processes, the same numbers to the last digit.

Every run of `seaway study table1` (paper-c1 ... paper-c5 flown by NMPC, EO-EMPC and CC-EMPC) and of
`seaway study lake` (the lake scenario, the same three controllers) is flown once composed (the
study's default: each stack's services as nodes of one study worker process, over the in-memory
bus) and once through the processes (``--processes``: a launcher and its processes on Zenoh). The
report metrics of each run's recording (``outcome.report_json``, as the study keeps them in
results.json) must be equal field for field, exactly: lockstep makes a run's numbers a function of
its inputs alone, whichever transport carried its messages, whichever stack flew it and as which
episode of its recording.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest
from seaway_lab.study import definitions as defs

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system


def study(name: str, out: Path, env: dict[str, str], *extra: str) -> dict[str, Any]:
    """results.json of ``seaway study NAME`` (two stacks, no figures)."""
    p = subprocess.run([str(BIN / "seaway"), "study", name, "--workers", "2", "--no-figures",
                        "--out", str(out), "--json", *extra], env=env, cwd=REPO, capture_output=True,
                       text=True, timeout=1500)
    # The lake's NMPC run is not completed by the truth (docs/results.md): the study exits 1 for
    # it, and its metrics are compared all the same.
    assert p.returncode in (0, 1) and (out / "results.json").is_file(), \
        p.stdout[-3000:] + p.stderr[-3000:]
    return json.loads((out / "results.json").read_text())


def table(doc: dict[str, Any]) -> dict[str, Any]:
    """The study's table without the wall times (they are the machine's, not the run's)."""
    return {row: {col: {k: v for k, v in cell.items() if k != "wall_s"} for col, cell in cols.items()}
            for row, cols in doc["results"].items()}


@pytest.mark.slow  # 18 runs twice: minutes
@pytest.mark.timeout(3000)
@pytest.mark.parametrize("name", ["table1", "lake"])
def test_composed_runs_give_the_numbers_of_the_processes_to_the_last_digit(
        name: str, tmp_path: Path, zenoh_env: dict[str, str]) -> None:
    composed = study(name, tmp_path / "composed", zenoh_env)
    processes = study(name, tmp_path / "processes", zenoh_env, "--processes")
    assert composed["executor"]["services"] == "composed"
    assert processes["executor"]["services"] == "processes"
    a = {r["key"]: r for r in composed["runs"]}
    b = {r["key"]: r for r in processes["runs"]}
    assert set(a) == set(b) == {s.key for s in defs.get_study(name).runs}
    for key in sorted(a):
        assert a[key]["report"] is not None, (key, a[key]["error"])
        assert b[key]["report"] is not None, (key, b[key]["error"])
        ma, mb = a[key]["report"]["metrics"], b[key]["report"]["metrics"]
        assert ma.keys() == mb.keys(), key
        differ = {k: (ma[k], mb[k]) for k in ma if ma[k] != mb[k]}
        assert not differ, f"{key}: composed vs processes: {differ}"
    # and so the table, its comparisons and the paper's relations
    assert table(composed) == table(processes)
    assert composed["comparison"] == processes["comparison"]
    assert composed["relations"] == processes["relations"]
    assert composed["failures"].keys() == processes["failures"].keys()
