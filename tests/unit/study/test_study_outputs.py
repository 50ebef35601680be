"""`seaway study`: the files and figures of a study, from synthetic runs (no stack started)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from seaway_lab.study import cli
from seaway_lab.study import definitions as defs
from seaway_lab.study.execute import RunOutcome

WPS = [[0.0, 0.0], [8.0, 0.0], [5.13, 8.57]]


def outcome(spec: defs.RunSpec, out: Path, energy: float, ok: bool = True) -> RunOutcome:
    n = 50
    t = [i * 0.1 for i in range(n)]
    series = {"t_s": t, "x_m": [8.0 * i / n for i in range(n)], "y_m": [0.1 * math.sin(i) for i in range(n)],
              "thrust_source": "sim/truth", "thrust_t_s": t, "thrust_port_n": [1.0] * n,
              "thrust_starboard_n": [0.9] * n, "waypoints_m": WPS, "coa_radius_m": 1.0}
    report = {"metrics": {"energy_j": energy, "avg_cross_track_m": 0.2, "travel_time_s": 300.0,
                          "completed": ok}, "mission": {"waypoints_m": WPS}}
    return RunOutcome(spec, str(out / "runs" / spec.key), ok=ok, error="" if ok else "launcher exited 1",
                      port=20001, command=["seaway", "launch"], returncode=0 if ok else 1, report=report,
                      series=series, timing={"wall_s": 10.0, "startup_s": 3.0}, cpu_s={"sim": 1.0})


def test_a_study_writes_its_tables_and_figures_and_redraws_them(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture) -> None:
    study = defs.only(defs.get_study("table1"), ["#1", "#2"])
    outs = {s.key: outcome(s, tmp_path, 300.0 + i, ok=s.key != "paper-c2-nmpc")
            for i, s in enumerate(study.runs)}
    doc, _ = cli.write_outputs(study, tmp_path, outs, 12.5, 2, {"kind": "local"}, "t0", {"cores": 2})
    for name in ("results.md", "results.csv", "results.json", "series.json"):
        assert (tmp_path / name).is_file(), name
    assert sorted(doc["figures"]) == ["figures/thrusts-paper-c1.png", "figures/trajectories.png",
                                      "figures/trajectory-paper-c1.png", "figures/trajectory-paper-c2.png"]
    assert all((tmp_path / f).stat().st_size > 5000 for f in doc["figures"])
    assert "paper-c2-nmpc" not in json.loads((tmp_path / "series.json").read_text())  # a failed run
    assert doc["failures"] == {"paper-c2-nmpc": "launcher exited 1"}
    assert doc["results"]["#1"]["cc-empc"]["energy_j"] == 302.0
    assert "![thrusts-paper-c1](figures/thrusts-paper-c1.png)" in (tmp_path / "results.md").read_text()

    assert cli.main(["--redraw", str(tmp_path), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["results"] == doc["results"] and again["wall_s"] == 12.5
    assert "runs" not in again  # --json prints the document without the per-run details


def test_the_tw_sweep_figure(tmp_path: Path) -> None:
    study = defs.get_study("tw-sweep")
    outs = {s.key: outcome(s, tmp_path, 100.0 * (s.task_power_w or 1.0)) for s in study.runs}
    doc, _ = cli.write_outputs(study, tmp_path, outs, 1.0, 2, {"kind": "local"}, "t0", {"cores": 2})
    assert "figures/tw-sweep.png" in doc["figures"]
    assert doc["results"]["0.49"]["cc-empc"]["paper"]["energy_j"] == 332.0


def test_bad_arguments() -> None:
    assert cli.main(["table9"]) == 2
    assert cli.main(["table1", "--rows", "#9"]) == 2
    for bad in (["--workers", "0"], ["--timeout-s", "nan"]):  # refused by argparse, exit 2
        with pytest.raises(SystemExit) as exit_:
            cli.main(["table1", *bad])
        assert exit_.value.code == 2, bad
    assert cli.main([]) == 2
    assert cli.main(["--list"]) == 0


def test_pinning_that_cannot_be_done_is_refused_before_anything_is_made(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from seaway.runtime import cpus

    monkeypatch.setattr(cpus, "allowed", lambda: frozenset({0, 1}))
    out = tmp_path / "study"
    assert cli.main(["table1", "--workers", "3", "--pin", "--out", str(out)]) == 2
    assert "3 stack(s) at once cannot each have CPUs of their own" in capsys.readouterr().err
    assert cli.main(["table1", "--pin", "--dask", "tcp://127.0.0.1:9", "--out", str(out)]) == 2
    assert "a Dask cluster's workers place their own stacks" in capsys.readouterr().err
    assert not out.exists()


def test_a_study_into_the_folder_of_an_earlier_one_is_refused_and_nothing_is_touched(
        tmp_path: Path, capsys, monkeypatch) -> None:
    # A second study into the same --out read the first one's recordings beside its own (a stack
    # reads every recording in its folder): its Table I came out scrambled. Refused before any
    # stack starts.
    started: list[object] = []
    monkeypatch.setattr(cli, "run_study", lambda *a, **k: started.append(a))
    out = tmp_path / "study"
    old = out / "runs" / "stack-1" / "recording.mcap"
    old.parent.mkdir(parents=True)
    old.write_bytes(b"an earlier study's recording")
    assert cli.main(["table1", "--out", str(out), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert f"{out} already holds the runs of an earlier study ({out / 'runs'}: stack-1)" in err
    assert "Give another --out" in err and f"--redraw {out}" in err
    assert started == [] and old.read_bytes() == b"an earlier study's recording"
    assert sorted(p.name for p in out.iterdir()) == ["runs"]
    # A folder without runs (new, empty, or only an empty runs/) is taken.
    (out / "runs" / "stack-1" / "recording.mcap").unlink()
    (out / "runs" / "stack-1").rmdir()
    assert cli.earlier_runs(out) == "" and cli.earlier_runs(tmp_path / "new") == ""
