"""`seaway study --processes` on a shared stack: one `seaway launch sim-batch --stay` flies run after
run (a scenario load and a mission each, sent as the operator), and each run's numbers are those of a
stack of its own (``execute.SharedStack``). The composed shared stacks are test_study_table1's and
test_study_parity's.

Real processes, real Zenoh sessions and recordings: NMPC on paper conditions #1 and #5 (#5 loads a
scenario whose disturbance grid is a file beside it), one worker, once on one stack and once on a
stack per run (``--fresh-stacks``); a failed run; and a run whose sim is SIGKILLed mid-mission.
"""

from __future__ import annotations

import json
import subprocess
import threading
import time
from pathlib import Path

import pytest
from seaway.recording import reader
from seaway_recorder.report import episodes, read_for_report

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system

KEYS = ("paper-c1-nmpc", "paper-c5-nmpc")


def study(out: Path, env: dict[str, str], *extra: str) -> dict:
    p = subprocess.run([str(BIN / "seaway"), "study", "table1", "--rows", "#1", "#5", "--columns",
                        "nmpc", "--workers", "1", "--no-figures", "--out", str(out), "--json",
                        "--processes", *extra],
                       env=env, cwd=REPO, capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    assert json.loads(p.stdout)["failures"] == {}
    return json.loads((out / "results.json").read_text())


@pytest.mark.timeout(600)
def test_runs_flown_one_after_another_on_one_stack_equal_fresh_stacks(tmp_path: Path,
                                                                      zenoh_env: dict[str, str]) -> None:
    shared = study(tmp_path / "shared", zenoh_env)
    fresh = study(tmp_path / "fresh", zenoh_env, "--fresh-stacks")
    assert shared["executor"]["stacks"] == "shared" and fresh["executor"]["stacks"] == "one per run"
    runs = {r["key"]: r for r in shared["runs"]}
    assert set(runs) == set(KEYS)
    # One stack, one folder, one recording: each run its own episode of it.
    folders = {r["run_dir"] for r in runs.values()}
    assert folders == {str(tmp_path / "shared" / "runs" / "stack-1")}
    assert sorted(r["episode"] for r in runs.values()) == [0, 1]
    assert len({r["port"] for r in runs.values()}) == 1
    files = reader.open_paths(folders)
    assert len(episodes(read_for_report(files)[1])) == 2
    first, second = sorted(runs.values(), key=lambda r: r["episode"])
    assert "startup_s" in first["timing"] and "switch_s" not in first["timing"]
    assert "switch_s" in second["timing"] and "startup_s" not in second["timing"]
    assert "stop_s" in second["timing"]  # the last run of its stack
    for r in (first, second):  # the stack's CPU, split between its runs
        assert r["cpu_s"]["controller"] > 0 and r["cpu_s"]["recorder"] > 0
    assert first["cpu_s"]["launch"] > second["cpu_s"]["launch"]  # the start-up is the first's
    # The numbers of a stack of its own, each (the same code on the same machine: to rounding).
    for row, key in (("#1", "paper-c1-nmpc"), ("#5", "paper-c5-nmpc")):
        a, b = shared["results"][row]["nmpc"], fresh["results"][row]["nmpc"]
        assert a["completed"] and b["completed"]
        for m in ("energy_j", "avg_cross_track_m", "travel_time_s"):
            assert a[m] == pytest.approx(b[m], rel=1e-9), (key, m, a[m], b[m])
    # The two conditions differ (the grid of #5 was loaded, not #1's calm water flown twice).
    c1, c5 = (shared["results"][r]["nmpc"] for r in ("#1", "#5"))
    assert abs(c1["energy_j"] - c5["energy_j"]) > 1.0, (c1, c5)


@pytest.mark.timeout(300)
def test_a_failed_run_stops_its_stack_and_the_next_run_gets_a_new_one(tmp_path: Path,
                                                                     zenoh_env: dict[str, str],
                                                                     monkeypatch: pytest.MonkeyPatch
                                                                     ) -> None:
    """The run before the failed one is reported from the stopped stack's recording, the failed
    one says why, and the run after it flies on a stack of its own."""
    from seaway_lab.study import execute as ex
    from seaway_lab.study.definitions import RunSpec

    for k, v in zenoh_env.items():
        monkeypatch.setenv(k, v)
    specs = [RunSpec("paper-c1", "nmpc", "#1", "nmpc"),
             RunSpec("paper-c2", "nmpc", "#2", "nmpc", task_power_w=-1.0),  # no valid mission
             RunSpec("paper-c5", "nmpc", "#5", "nmpc")]
    done: list[ex.RunOutcome] = []
    ex.run_shared(specs, tmp_path / "runs", 1, done.append, timeout_s=120)
    by = {o.spec.key: o for o in done}
    assert sorted(by) == sorted(s.key for s in specs)
    first, bad, after = (by[s.key] for s in specs)
    assert first.ok and first.episode == 0 and first.run_dir.endswith("stack-1"), first.error
    assert not bad.ok and "task_power_w" in bad.error and bad.run_dir.endswith("stack-1")
    assert "stop_s" in bad.timing and "wall_s" in bad.timing  # its stack stopped with it ...
    assert "stop_s" not in first.timing and first.returncode is None  # ... once, counted to it
    assert after.ok and after.episode == 0 and after.run_dir.endswith("stack-2"), after.error
    assert after.port != first.port
    assert first.report["metrics"]["energy_j"] != pytest.approx(after.report["metrics"]["energy_j"])


def kill_sim_once_flying(stack, mission_id: str, after_s: float, killed: list[int]) -> None:
    """SIGKILL the stack's sim once the controller's status says ``mission_id`` has flown
    ``after_s`` of simulated time (its stamp), as a crash would; the launcher restarts it."""
    import psutil

    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        s = stack.status.get() if stack.status is not None else None
        if s is not None and s.mission_id == mission_id and s.state == "active" \
                and s.stamp_ns >= after_s * 1e9:
            for p in psutil.Process(stack.proc.pid).children(recursive=True):
                if any("seaway-sim" in part for part in p.cmdline()):
                    p.kill()
                    killed.append(p.pid)
                    return
        time.sleep(0.002)


@pytest.mark.timeout(300)
def test_a_sim_killed_in_a_later_run_flies_it_again_in_its_own_scenario(tmp_path: Path,
                                                                        zenoh_env: dict[str, str],
                                                                        monkeypatch: pytest.MonkeyPatch
                                                                        ) -> None:
    """The second run of a stack loaded its scenario (#5's current grid); its sim is killed
    mid-mission. The restarted sim comes back in #5 (``--state-file``), not the stack's first
    scenario, time starts again, the controller flies the mission again, and the run is reported
    from that episode with the numbers of a stack of its own."""
    from seaway_lab.study import execute as ex
    from seaway_lab.study.definitions import RunSpec

    for k, v in zenoh_env.items():
        monkeypatch.setenv(k, v)
    first, second = RunSpec("paper-c1", "nmpc", "#1", "nmpc"), RunSpec("paper-c5", "nmpc", "#5", "nmpc")
    alone: list[ex.RunOutcome] = []
    ex.run_shared([second], tmp_path / "alone", 1, alone.append, timeout_s=120)
    assert alone[0].ok, alone[0].error

    killed: list[int] = []
    mission = ex.SharedStack._mission

    def killing(stack, spec, out, deadline) -> None:
        if spec.key == second.key:
            threading.Thread(target=kill_sim_once_flying, args=(stack, spec.key, 8.0, killed),
                             daemon=True).start()
        mission(stack, spec, out, deadline)

    monkeypatch.setattr(ex.SharedStack, "_mission", killing)
    done: list[ex.RunOutcome] = []
    ex.run_shared([first, second], tmp_path / "shared", 1, done.append, timeout_s=120)
    by = {o.spec.key: o for o in done}
    assert len(killed) == 1, "the sim was not killed while the second run flew"
    assert by[first.key].ok and by[first.key].episode == 0, by[first.key].error
    run = by[second.key]
    assert run.ok, run.error
    # Episodes of the stack's recording: #1, #5 until the kill, #5 again from t = 0.
    assert run.episode == 2 and run.run_dir == by[first.key].run_dir
    events = [json.loads(line) for line in (Path(run.run_dir) / "events.jsonl").read_text().splitlines()]
    sims = [e for e in events if e["process"] == "sim"]
    assert [e["event"] for e in sims][:3] == ["start", "exit", "start"], sims  # restarted once
    assert sims[0]["pid"] == killed[0] and sims[1]["code"] == -9
    a, b = run.report["metrics"], alone[0].report["metrics"]
    assert a["completed"] and b["completed"]
    # Flown again from t = 0 in the same water by the same code: the same numbers (the issue asks
    # for 1 %; #1 and #5 differ by 0.4 % in energy, so only a tight tolerance tells them apart).
    for m in ("energy_j", "avg_cross_track_m", "travel_time_s"):
        assert a[m] == pytest.approx(b[m], rel=1e-6), (m, a[m], b[m])
    # Not the stack's first water (#1: 2219.2 J where #5 is 2227.1 J).
    assert abs(a["energy_j"] - by[first.key].report["metrics"]["energy_j"]) > 1.0
    log = (Path(run.run_dir) / "logs" / "sim.log").read_text()
    assert "paper-c5, as loaded over the bus before this sim started" in log
