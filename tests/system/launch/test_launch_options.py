"""``seaway launch``'s mission options through the real processes: ``sim-batch --controller nmpc
--predict-disturbance --task-power-w 1`` flies paper-c1's mission with NMPC predicting with the
estimated tau_d, and the run folder, the recording and the report all say so; ``--cpus`` keeps every
process of the stack on the CPUs it names."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import SolveRecord, ThrustCommand
from seaway.recording import reader

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent


def test_the_launch_options_choose_the_controller_and_the_prediction(tmp_path, zenoh_env) -> None:
    run_dir = tmp_path / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", "paper-c1",
                          "--controller", "nmpc", "--predict-disturbance", "--task-power-w", "1",
                          "--run-dir", str(run_dir)],
                         env=zenoh_env, capture_output=True, text=True, timeout=400, check=False)
    log = out.stdout[-3000:] + out.stderr[-3000:]
    assert out.returncode == 0, log
    assert "mission paper-c1: accepted (nmpc, predicting the estimated tau_d, T^w 1 W)" in out.stdout, log
    sent = json.loads((run_dir / "mission.json").read_text())
    assert (sent["controller"], sent["predict_disturbance"], sent["task_power_w"]) == ("nmpc", True, 1.0)
    assert "nmpc, predicting the estimated tau_d" in (run_dir / "logs" / "controller.log").read_text()

    # The recording: every solve is NMPC's, and NMPC flew the mission.
    dec = reader.decode_vessel([run_dir / "recording.mcap"], None,
                                  [keys.SOLVE.suffix, keys.THRUST.suffix])
    solves = [m for m in dec.get(keys.SOLVE.suffix) if isinstance(m, SolveRecord)]
    assert solves and {s.controller for s in solves} == {"nmpc"}
    sources = [m.source for m in dec.get(keys.THRUST.suffix) if isinstance(m, ThrustCommand)]
    assert sources.count("nmpc") > 0.9 * len(solves)
    assert not {"cc-empc", "eo-empc"} & set(sources)

    # The report takes the mission the controller accepted and recorded (T^w = 1 W, not the
    # scenario's 0.49 W; nmpc, predicting tau_d).
    report = json.loads((run_dir / "report" / "metrics.json").read_text())
    assert report["mission"]["task_power_w"] == 1.0
    assert report["mission"]["source"] == f"recorded {keys.MISSION_ACCEPTED.suffix}", report["mission"]
    assert (report["mission"]["controller"], report["mission"]["predict_disturbance"]) == ("nmpc", True)
    assert report["metrics"]["completed"] and report["metrics"]["legs_completed"] == 2


def stack_affinities(tmp_path: Path, env: dict[str, str], cpus: str
                     ) -> tuple[str, dict[str, set[frozenset[int]]]]:
    """Start ``seaway launch sim-batch --cpus CPUS`` with no mission; once all are ready, the CPU
    sets of every thread (Zenoh's, the services' own, the launcher's), by process name; then stop
    it (it must exit 0). Returns the launcher's lines up to then, and those sets."""
    import psutil

    p = subprocess.Popen([str(BIN / "seaway"), "launch", "sim-batch", "--no-mission", "--stay",
                          "--cpus", cpus, "--run-dir", str(tmp_path / "run")],
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         start_new_session=True)
    lines: list[str] = []
    seen: dict[str, set[frozenset[int]]] = {}
    try:
        assert p.stdout is not None
        for line in p.stdout:  # the launcher's own lines, until the stack is up
            lines.append(line)
            if line.startswith("all ready"):
                break
        assert any(line.startswith("all ready") for line in lines), "".join(lines)
        for q in [psutil.Process(p.pid), *psutil.Process(p.pid).children(recursive=True)]:
            with contextlib.suppress(psutil.Error):
                seen[q.name()] = {frozenset(os.sched_getaffinity(t.id)) for t in q.threads()}
    finally:
        p.send_signal(signal.SIGINT)
        p.communicate(timeout=60)
    assert p.returncode == 0, "".join(lines)
    names = {"seaway", "seaway-sim", "seaway-estimato", "seaway-controll", "seaway-recorder"}
    assert names <= set(seen), seen
    return "".join(lines), seen


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs to pin to one")
def test_cpus_keep_the_whole_stack_on_them(tmp_path, zenoh_env) -> None:
    cpu = max(os.sched_getaffinity(0))
    lines, seen = stack_affinities(tmp_path, zenoh_env, str(cpu))
    assert f", CPUs {cpu}\n" in lines
    assert set().union(*seen.values()) == {frozenset({cpu})}


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs to split")
def test_cpus_in_lockstep_put_the_chain_on_one_and_the_rest_on_the_others(tmp_path, zenoh_env) -> None:
    """``--cpus`` with two CPUs or more in lockstep: the sim, estimator and controller (every thread)
    on the lowest, the recorder and the launcher on the others. (Missions flown so: the one-worker
    studies of tests/system/study, whose stack gets every CPU.)"""
    allowed = sorted(os.sched_getaffinity(0))
    chain, rest = frozenset(allowed[:1]), frozenset(allowed[1:])
    lines, seen = stack_affinities(tmp_path, zenoh_env, ",".join(str(c) for c in allowed))
    assert "(the lockstep chain on" in lines, lines
    for name in ("seaway-sim", "seaway-estimato", "seaway-controll"):
        assert seen[name] == {chain}, (name, seen)
    assert seen["seaway-recorder"] == {rest} and seen["seaway"] == {rest}, seen  # and the launcher


def test_a_cpu_list_that_cannot_be_used_is_refused_before_anything_starts(tmp_path, zenoh_env) -> None:
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--cpus", "0-4096",
                          "--run-dir", str(tmp_path / "run")],
                         env=zenoh_env, capture_output=True, text=True, timeout=60, check=False)
    assert out.returncode == 2
    assert "argument --cpus: CPU list '0-4096': CPU 4096 cannot be used by this process (allowed here: " \
        in out.stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("max_s", "code"), [(20.0, 3), (600.0, 0)])
def test_max_mission_s_ends_a_batch_run_whose_mission_goes_on(tmp_path, zenoh_env, max_s,
                                                              code) -> None:
    """paper-c1 by NMPC ends after about 35 s of simulated time: ``--max-mission-s 20`` stops the
    run at 20 s, the sim's clock holding there however fast the composed run goes (exit 3, the
    recording and the report of what was flown); 600 lets it complete."""
    run_dir = tmp_path / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--composed", "--scenario",
                          "paper-c1", "--controller", "nmpc", "--max-mission-s", f"{max_s:g}",
                          "--run-dir", str(run_dir)],
                         env=zenoh_env, capture_output=True, text=True, timeout=300, check=False)
    log = out.stdout[-3000:] + out.stderr[-3000:]
    assert out.returncode == code, log
    report = json.loads((run_dir / "report" / "metrics.json").read_text())
    metrics = report["metrics"]
    assert metrics["completed"] is (code == 0), log
    flown_s = (metrics["end_ns"] - metrics["start_ns"]) / 1e9
    if code == 3:
        assert "--max-mission-s" in out.stderr and "mission complete" not in out.stdout
        # The clock held at t = 20.0 s: the report and the recording end there.
        assert abs(flown_s - 20.0) < 0.15, log
        assert "--max-mission-s 20" in out.stderr
        assert metrics["legs_completed"] < 2
    else:
        assert "mission complete" in out.stdout and metrics["legs_completed"] == 2
    # The recording was closed as after any stop: its states reach where the report ends.
    dec = reader.decode_vessel([run_dir / "recording.mcap"], None, [keys.NAV_STATE.suffix])
    stamps = [m.stamp_ns for m in dec.get(keys.NAV_STATE.suffix)]
    assert stamps and max(stamps) / 1e9 >= flown_s - 0.15
    if code == 3:
        assert max(stamps) == 20 * 10**9
