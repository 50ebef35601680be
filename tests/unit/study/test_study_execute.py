"""`seaway study`: one run's isolation, options and report, without starting a stack."""

from __future__ import annotations

import json
import random
import shutil
from pathlib import Path

import pytest
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.simkit.scenario import load_mission
from seaway_lab.study import execute as ex
from seaway_lab.study.definitions import RunSpec
from seaway_recorder import report

REPO = Path(__file__).resolve().parents[3]
LAKE_RECORDING = REPO / "tests" / "replay" / "data" / "lake-30s.mcap"
ALL = {"--scenario", "--controller", "--predict-disturbance", "--task-power-w", "--run-dir"}


def test_each_stack_gets_its_own_port_below_the_ephemeral_range() -> None:
    rng = random.Random(1)
    ports = [ex.free_port(rng) for _ in range(50)]
    assert len(set(ports)) == 50
    assert all(20000 <= p < ex._ephemeral_low() for p in ports)
    env = ex.stack_env(ports[0], {ENV_CONFIG: "/x.json5", "PATH": "/bin"})
    assert env[ENV_RENDEZVOUS] == f"tcp/127.0.0.1:{ports[0]}"
    assert ENV_CONFIG not in env and env["PATH"] == "/bin"


def test_options_pass_when_the_launcher_has_them() -> None:
    spec = RunSpec("paper-c1", "nmpc", "#1", "nmpc", predict_disturbance=True, task_power_w=2.0)
    assert ex.fit_options(spec, ALL) == ["--scenario", "paper-c1", "--controller", "nmpc",
                                         "--predict-disturbance", "--task-power-w", "2"]


def test_a_missing_option_is_dropped_only_when_it_changes_nothing() -> None:
    old = {"--scenario", "--run-dir"}
    same = RunSpec("paper-c1", "cc-empc", "#1", "cc-empc")  # the scenario's own controller
    assert ex.fit_options(same, old) == ["--scenario", "paper-c1"]
    with pytest.raises(ValueError, match="no --controller option, which run paper-c1-nmpc needs"):
        ex.fit_options(RunSpec("paper-c1", "nmpc", "#1", "nmpc"), old)
    with pytest.raises(ValueError, match="--task-power-w"):
        ex.fit_options(RunSpec("paper-c1", "cc-empc", "#1", "x", task_power_w=1.0), old | {"--controller"})


def test_the_launchers_lines_mark_the_phases() -> None:
    lines = {"all ready in 2.0 s": "ready",
             "mission paper-c1 (nmpc, tau_d = 0, T^w 0.49 W): accepted": "accepted",
             "mission paper-c1: accepted (cc-empc, tau_d = 0, T^w 0.49 W)": "accepted",
             "mission paper-c1: REFUSED: no such thing": "refused", "mission complete": "complete",
             "stopping...": "stopping", "stopped in 0.6 s; logs in x": "stopped"}
    for line, name in lines.items():
        assert [k for k, p in ex._MILESTONES.items() if p.search(line)] == [name], line
    seen = {"ready": 3.0, "accepted": 3.1, "complete": 13.0, "stopping": 13.0, "stopped": 13.6}
    ph = ex._phases(seen, 16.0)
    assert ph == pytest.approx({"startup_s": 3.0, "mission_s": 10.0, "stop_s": 0.6, "launcher_report_s": 2.4,
                                "launch_s": 16.0})
    assert ex._phases({}, 5.0) == {"launch_s": 5.0}


@pytest.mark.parametrize("sent_task_power_w", [None, 5.0])
def test_the_in_process_report_is_what_the_command_prints(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                          sent_task_power_w: float | None) -> None:
    shutil.copy(LAKE_RECORDING, tmp_path / "recording.mcap")
    if sent_task_power_w is not None:  # the launcher's mission.json: what was flown, here another T^w
        sent = load_mission("lake").to_request(1, task_power_w=sent_task_power_w)
        (tmp_path / ex.MISSION_FILE).write_text(sent.model_dump_json())
        assert ex.report_args(tmp_path) == [str(tmp_path), "--mission", str(tmp_path / ex.MISSION_FILE)]
    assert report.main([*ex.report_args(tmp_path), "--json", "--no-plots", "--out", str(tmp_path / "r")]) == 0
    printed = json.loads(capsys.readouterr().out)
    doc, series = ex.report_json(tmp_path)
    assert doc == printed
    assert doc["mission"]["task_power_w"] == (sent_task_power_w or 250.0)
    n = len(series["t_s"])
    assert n == doc["metrics"]["state_samples"] == len(series["x_m"]) == len(series["y_m"])
    assert series["t_s"][0] == 0.0
    assert len(series["thrust_t_s"]) == len(series["thrust_port_n"]) == len(series["thrust_starboard_n"]) > 0
    assert series["waypoints_m"] == doc["mission"]["waypoints_m"]
    json.dumps(series)


def test_a_run_the_launcher_cannot_express_fails_with_the_reason(monkeypatch: pytest.MonkeyPatch,
                                                                   tmp_path: Path) -> None:
    monkeypatch.setattr(ex, "launcher_options", lambda: {"--scenario", "--run-dir"})
    out = ex.run_one(RunSpec("paper-c1", "nmpc", "#1", "nmpc"), tmp_path / "run")
    assert not out.ok and "no --controller" in out.error
    assert not (tmp_path / "run").exists()


def test_long_runs_start_first() -> None:
    from seaway_lab.study.definitions import get_study

    jobs = [(s, Path(s.key)) for s in get_study("table1").runs]
    order = [s.controller for s, _ in ex.longest_first(jobs)]
    assert order[:10].count("nmpc") == 0 and order[10:] == ["nmpc"] * 5
    tw = {s.task_power_w: ex.expected_cost(s) for s in get_study("tw-sweep").runs}
    assert tw[0.49] == pytest.approx(10.0)
    assert tw[0.25] > tw[0.49] > tw[8.0] > 1.0


def test_process_names() -> None:
    assert ex.process_name(["/v/bin/python", "/v/bin/seaway-sim", "--run", "x"]) == "sim"
    assert ex.process_name(["/v/bin/seaway-controller", "--run", "x"]) == "controller"
    assert ex.process_name(["/v/bin/python", "/v/bin/seaway", "report", "d"]) == "report"
    assert ex.process_name(["/usr/bin/gcc", "-O2"]) == "gcc"
    assert ex.process_name([]) == "?"
