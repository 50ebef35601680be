"""``seaway launch``'s mission options (--controller, --predict-disturbance, --task-power-w) and the
default run folder's name. Nothing here starts a process: the refusals come before any start."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from seaway.contract.config import deploy_path
from seaway.contract.messages import MissionRequest, Waypoint
from seaway.tools.launch import main as launch

STAMP = "20260102-030405"


def parse(*argv: str):
    return launch.parser().parse_args(["sim-batch", *argv])


def test_mission_options_parse() -> None:
    args = parse()
    assert (args.controller, args.predict_disturbance, args.task_power_w) == (None, None, None)
    args = parse("--controller", "nmpc", "--predict-disturbance", "--task-power-w", "2.5")
    assert (args.controller, args.predict_disturbance, args.task_power_w) == ("nmpc", True, 2.5)
    assert parse("--no-predict-disturbance").predict_disturbance is False
    assert parse("--task-power-w", "10000").task_power_w == 10_000.0


@pytest.mark.parametrize(("argv", "problem"), [
    (["--controller", "PID!"], "--controller: 'PID!': a controller's name is lower case letters, "
                               "digits and '-', starting with a letter: cc-empc, eo-empc, nmpc, or "
                               "one a --controller-module registers"),
    (["--controller-module", "no/such/file.py"], "--controller-module: no/such/file.py: no such file "
                                                 "(a .py file that registers a controller, or an "
                                                 "importable module name)"),
    (["--controller-module", "my package"], "--controller-module: 'my package': neither a .py file "
                                            "nor a module name"),
    (["--task-power-w", "-1"], "--task-power-w: '-1': the task power must be finite, in (0, 10000] W"),
    (["--task-power-w=-0.5"], "--task-power-w: '-0.5': the task power must be finite, in (0, 10000] W"),
    (["--task-power-w", "0"], "'0': the task power must be finite, in (0, 10000] W"),
    (["--task-power-w", "1e300"], "'1e300': the task power must be finite, in (0, 10000] W"),
    (["--task-power-w", "nan"], "'nan': the task power must be finite"),
    (["--task-power-w", "inf"], "'inf': the task power must be finite"),
    (["--task-power-w", "two"], "'two' is not a number of watts"),
    (["--max-mission-s", "0"], "--max-mission-s: '0' is not a finite number above 0"),
    (["--max-mission-s", "inf"], "--max-mission-s: 'inf' is not a finite number above 0"),
])
def test_bad_options_exit_2_naming_the_problem(argv, problem, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        parse(*argv)
    assert exc.value.code == 2
    assert problem in capsys.readouterr().err


def test_the_options_change_the_mission_sent() -> None:
    plain = launch._mission_request("paper-c1", parse())
    assert (plain.mission_id, plain.controller, plain.predict_disturbance, plain.task_power_w) == (
        "paper-c1", "cc-empc", False, 0.49)
    req = launch._mission_request("paper-c1", parse("--controller", "eo-empc", "--predict-disturbance",
                                                    "--task-power-w", "2.5"))
    assert (req.controller, req.predict_disturbance, req.task_power_w) == ("eo-empc", True, 2.5)
    assert req.waypoints == plain.waypoints and req.coa_radius_m == plain.coa_radius_m


def test_a_controller_module_goes_to_the_controller_processes_only(tmp_path, capsys) -> None:
    """The file as an absolute path (the processes run in their own folders), after each
    controller's own options; a profile without a controller refuses it."""
    from seaway.tools.launch.plan import supervised
    from seaway.tools.launch.profile import instances, load_profile

    mine = tmp_path / "mine.py"
    mine.write_text("")
    args = parse("--controller-module", str(mine), "--controller", "mine")
    assert args.controller_module == [str(mine.resolve())] and args.controller == "mine"
    common = dict.fromkeys(("scenario", "run_dir", "profile", "recording", "mavlink_key"), "x")
    procs = supervised(instances(load_profile("sim-batch"), ["v"]), ["v"], tmp_path, common)
    before = {p.spec.name: list(p.argv) for p in procs}
    assert launch.hand_controller_modules(procs, args.controller_module)
    for p in procs:
        added = [] if p.spec.name != "controller" else ["--controller-module", str(mine.resolve())]
        assert p.argv == before[p.spec.name] + added
    assert launch.main(["shore", "--controller-module", str(mine), "--check"]) == 2
    assert "--controller-module: profile shore runs no controller" in capsys.readouterr().err


def _no_mission_scenario(tmp_path: Path) -> Path:
    text = deploy_path("scenarios", "paper-c1.toml").read_text()
    p = tmp_path / "quiet.toml"
    p.write_text(text[:text.index("[mission]")])
    return p


@pytest.mark.parametrize(("argv", "flags", "why"), [
    (["sim-batch", "--no-mission", "--controller", "nmpc"], "--controller", "(--no-mission was given)"),
    (["boat", "--predict-disturbance"], "--predict-disturbance", "(profile boat sends no mission)"),
    (["sim-batch", "--no-mission", "--max-mission-s", "600"], "--max-mission-s",
     "(--no-mission was given)"),
    (["sim-batch", "--scenario", "{quiet}", "--task-power-w", "1", "--no-predict-disturbance"],
     "--predict-disturbance, --task-power-w", "quiet.toml has no [mission])"),
])
def test_mission_options_without_a_mission_exit_2(argv, flags, why, tmp_path, capsys) -> None:
    argv = [a.format(quiet=_no_mission_scenario(tmp_path)) for a in argv]
    run_dir = tmp_path / "run"
    assert launch.main([*argv, "--run-dir", str(run_dir)]) == 2
    err = capsys.readouterr().err
    assert f"seaway launch: {flags}: option(s) of the mission sent, but this launch sends no mission" in err
    assert why in err
    assert not run_dir.exists()


def test_check_shows_the_mission_that_would_be_sent(tmp_path, capsys) -> None:
    argv = ["sim-batch", "--controller", "nmpc", "--predict-disturbance", "--task-power-w", "2",
            "--run-dir", str(tmp_path / "run"), "--check"]
    assert launch.main(argv) == 0
    out = capsys.readouterr().out
    assert "mission paper-c1 (nmpc, predicting the estimated tau_d, T^w 2 W)" in out
    assert launch.main(["sim-batch", "--no-mission", "--check", "--run-dir", str(tmp_path)]) == 0
    assert "mission" not in capsys.readouterr().out


def _req(controller: str, predict: bool) -> MissionRequest:
    return MissionRequest.make(stamp_ns=0, waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=1, y_m=0)],
                               coa_radius_m=1.0, task_power_w=0.49, controller=controller,
                               predict_disturbance=predict)


def test_run_folder_names() -> None:
    name = launch.run_dir_name
    assert name("sim", "lake", None, STAMP) == f"{STAMP}-sim"  # no mission sent: as before
    assert name("sim-batch", "paper-c1", _req("nmpc", False), STAMP) == f"{STAMP}-sim-batch-paper-c1-nmpc"
    assert name("sim-batch", "paper-c4", _req("cc-empc", True), STAMP) == (
        f"{STAMP}-sim-batch-paper-c4-cc-empc-tauD")
    # Profiles and scenarios given as paths are named by their file; odd characters are replaced.
    assert name("/x/deploy/my.toml", "/tmp/a b/storm #2.toml", _req("eo-empc", False), STAMP) == (
        f"{STAMP}-my-storm__2-eo-empc")
    assert time.strftime("%Y%m%d-") in name("sim", "", None)


def test_the_default_run_folder_is_new_and_says_what_was_flown(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(launch, "repo_root", lambda: tmp_path)
    args = parse("--controller", "nmpc", "--predict-disturbance")
    req = launch._mission_request("paper-c1", args)
    first = launch._run_dir(args, "paper-c1", req, STAMP)
    assert first == tmp_path / "runs" / f"{STAMP}-sim-batch-paper-c1-nmpc-tauD"
    first.mkdir(parents=True)
    second = launch._run_dir(args, "paper-c1", req, STAMP)  # same second: a new folder all the same
    assert second == tmp_path / "runs" / f"{STAMP}-sim-batch-paper-c1-nmpc-tauD-2"
    second.mkdir()
    assert launch._run_dir(args, "paper-c1", req, STAMP).name.endswith("-tauD-3")
    given = parse("--run-dir", str(first))
    assert launch._run_dir(given, "paper-c1", req) == first  # --run-dir is taken as given


@pytest.mark.parametrize(("profile", "where"), [("sim-batch", "."), ("fleet", "b")])
def test_a_run_dir_holding_an_earlier_recording_is_refused(profile, where, tmp_path, capsys) -> None:
    """A second launch into a used run folder wrote ``recording.restart-001.mcap`` beside the first
    launch's recording, and the report and the study read every recording of a folder. It is refused
    before anything starts; a folder with other files only (logs, a mission) is taken."""
    run_dir = tmp_path / "run"
    vessels = ["--vessels", "a,b"] if profile == "fleet" else []
    (run_dir / where).mkdir(parents=True, exist_ok=True)
    (run_dir / where / "notes.txt").write_text("kept")
    assert launch.main([profile, *vessels, "--run-dir", str(run_dir), "--check"]) == 0
    capsys.readouterr()
    held = run_dir / where / "recording.mcap"
    held.write_bytes(b"earlier")
    assert launch.main([profile, *vessels, "--run-dir", str(run_dir), "--check"]) == 2
    err = capsys.readouterr().err
    assert f"--run-dir {run_dir} holds an earlier launch's recording ({held})" in err
    assert "give a new --run-dir" in err
    assert held.read_bytes() == b"earlier"
    assert sorted(p.name for p in (run_dir / where).iterdir()) == ["notes.txt", "recording.mcap"]


@pytest.mark.parametrize(("argv", "problem"), [
    (["replay"], "profile replay plays a recording: give it with --recording PATH"),
    (["replay", "--recording", "{tmp}/nope"], "--recording {tmp}/nope: no such file or folder"),
    (["replay", "--recording", "{tmp}"], "--recording {tmp}: the folder holds no .mcap file"),
    (["replay", "--recording", "{tmp}/notes.txt"], "--recording {tmp}/notes.txt: not an .mcap file"),
    (["sim-batch", "--recording", "{tmp}"],
     "--recording: profile sim-batch plays no recording (the replay profile does)"),
])
def test_a_recording_the_profile_cannot_use_is_refused_before_anything_starts(
        argv, problem, tmp_path, capsys) -> None:
    """``launch replay`` with no recording, or a wrong one, started the whole stack and only then
    failed (an empty path, then a report of nothing); ``sim-batch --recording x`` flew a mission and
    ignored it."""
    (tmp_path / "notes.txt").write_text("not a recording")
    filled = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert launch.main([*filled, "--scenario", "paper-c1", "--run-dir", str(tmp_path / "run"),
                        "--check"]) == 2
    assert f"seaway launch: {problem.replace('{tmp}', str(tmp_path))}" in capsys.readouterr().err
    recorded = tmp_path / "rec"
    recorded.mkdir()
    (recorded / "recording.mcap").write_bytes(b"")
    assert launch.main(["replay", "--recording", str(recorded), "--scenario", "paper-c1",
                        "--run-dir", str(tmp_path / "run2"), "--check"]) == 0


def _recording(folder: Path, run_json: bytes | None) -> Path:
    """A run folder as the launcher leaves it: a recording and, if any, its run description."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "recording.mcap").write_bytes(b"")
    if run_json is not None:
        (folder / "run.json").write_bytes(run_json)
    return folder


RECORDED_RUN = {"run_id": "r", "vessel": "vessel1", "model_vessel_file": "paper-boat",
                "control_period_s": 0.1, "clock": "lockstep"}


def test_a_replay_takes_the_scenario_its_recording_was_made_on(tmp_path, capsys) -> None:
    """``launch replay --recording R`` without ``--scenario`` started a stack that waited at
    "sim t 0 s | idle" for good: no scenario, so no mission and no origin. The recorded run's
    description names its scenario: the launch flies that scenario's mission."""
    import json

    rec = _recording(tmp_path / "rec", json.dumps({**RECORDED_RUN, "scenario": "lake"}).encode())
    for given in (rec, rec / "recording.mcap"):  # the run folder, or the recording in it
        assert launch.main(["replay", "--recording", str(given), "--run-dir",
                            str(tmp_path / "run"), "--check"]) == 0
        assert "mission lake " in capsys.readouterr().out
    # --scenario still chooses.
    assert launch.main(["replay", "--recording", str(rec), "--scenario", "paper-c1",
                        "--run-dir", str(tmp_path / "run2"), "--check"]) == 0
    assert "mission paper-c1 " in capsys.readouterr().out


@pytest.mark.parametrize(("run_json", "missing"), [
    (None, "no run description"),
    (b'{"run_id": "r", "vessel": "vessel1", "model_vessel_file": "paper-boat", '
     b'"control_period_s": 0.1, "clock": "lockstep"}', "names no scenario"),
    (b'{"run_id": "r", "vessel": "vessel1", "model_vessel_file": "paper-boat", '
     b'"control_period_s": 0.1, "clock": "lockstep", "scenario": "/nowhere/sc.toml"}',
     "'/nowhere/sc.toml'"),
    (b'{"run_id": ', "run.json"),
])
def test_a_replay_whose_recording_names_no_usable_scenario_is_refused(
        run_json, missing, tmp_path, capsys) -> None:
    rec = _recording(tmp_path / "rec", run_json)
    assert launch.main(["replay", "--recording", str(rec), "--run-dir", str(tmp_path / "run"),
                        "--check"]) == 2
    err = capsys.readouterr().err
    assert missing in err and "--scenario" in err
    assert not (tmp_path / "run").exists()
