"""`seaway study` composed (the default): what a study worker process and the study say to each
other, the composed stack's launcher command against the real parser, and ``--processes``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from seaway.tools.launch.main import parser as launch_parser
from seaway_lab.study import cli
from seaway_lab.study.composed import COMPOSED_FLAG, launcher_argv, vessel
from seaway_lab.study.definitions import RunSpec
from seaway_lab.study.outcome import RunOutcome

SPECS = (RunSpec("paper-c1", "cc-empc", "#1", "cc-empc"),
         RunSpec("paper-c3", "cc-empc", "0.25", "cc-empc", predict_disturbance=True,
                 task_power_w=0.25, controller_modules=("/x/mine.py", "pkg.mod")))


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: s.key)
def test_a_run_and_its_outcome_cross_the_worker_pipe_unchanged(spec: RunSpec) -> None:
    """A worker answers in JSON lines: the run it is given and the outcome it gives back must be
    those it was (every field, floats to the last digit), or the study tabulates another run."""
    assert RunSpec.from_json(json.loads(json.dumps(spec.to_json()))) == spec
    out = RunOutcome(spec, "/r/stack-1", episode=2, ok=True, error="", port=None,
                     command=["seaway", "launch"], returncode=0,
                     report={"metrics": {"energy_j": 330.38032504981305, "completed": True}},
                     series={"t_s": [0.0, 0.1]}, timing={"mission_s": 7.123456789012345},
                     cpu_s={"composed": 6.9})
    back = RunOutcome.from_json(json.loads(json.dumps(out.to_json(with_series=True))))
    assert back.__dict__ == out.__dict__


def test_a_composed_stacks_launcher_takes_its_options(tmp_path: Path) -> None:
    mine = tmp_path / "mine.py"
    mine.write_text("")
    spec = RunSpec("paper-c3", "cc-empc", "0.25", "cc-empc", task_power_w=0.25,
                   controller_modules=(str(mine), "pkg.mod"))
    argv = launcher_argv(spec, tmp_path / "stack-1")
    assert argv[0] == "launch"
    args = launch_parser().parse_args(argv[1:])
    assert args.profile == "sim-batch" and args.composed and COMPOSED_FLAG in argv
    assert args.no_mission and args.stay and args.no_report
    assert args.scenario == "paper-c3" and args.run_dir == tmp_path / "stack-1"
    assert args.vessel == vessel()
    assert args.controller_module == [str(mine), "pkg.mod"]
    # the run's own options are its mission's, sent by the study, not the launcher's
    assert args.controller is None and args.task_power_w is None


@pytest.mark.parametrize(("extra", "composed"), [([], True), (["--processes"], False)])
def test_a_study_is_composed_unless_processes_are_asked_for(extra: list[str], composed: bool,
                                                            tmp_path: Path, monkeypatch) -> None:
    asked: list[dict[str, object]] = []

    def run_study(*a: object, **k: object) -> None:
        asked.append(k)
        raise KeyboardInterrupt  # nothing to run here

    monkeypatch.setattr(cli, "run_study", run_study)
    assert cli.main(["table1", "--rows", "#1", "--out", str(tmp_path / "s"), *extra]) == 130
    assert asked and asked[0]["composed"] is composed
