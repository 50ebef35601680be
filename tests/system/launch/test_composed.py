"""``seaway launch sim-batch --composed``: the same services as nodes of one process over the
in-memory bus, against the same launch through the real processes.

Paper condition #1 flown by NMPC (36 s of simulated time) both ways:

* the report's metrics are equal field for field (to the last digit);
* the recordings have the same channels, and on every bus key but the ones whose count depends on
  wall-clock timing (log lines, the recorder's own answers) the same messages in the same order,
  equal but for the fields that time the run (``WALL``);
* every message of the composed recording validates against the JSON Schema its channel carries
  (``jsonschema``, not our writer);
* the composed launch ran in one process: every node's pid in the launcher's events is the
  launcher's, and each node wrote its own log.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.conftest import solver_built
from tests.unit.recorder.foxglove_check import invalid_messages

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent
V = "vessel1"
TIMING = ("logs/line", "lockstep/recorder")
"""Bus keys whose messages depend on the wall clock: the log lines copied in as they grow, and the
recorder's answers (it answers again as each member joins, and the members join in any order)."""


def launch(run_dir: Path, env: dict[str, str], *extra: str) -> subprocess.CompletedProcess[str]:
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", "paper-c1",
                          "--controller", "nmpc", "--no-report", "--run-dir", str(run_dir), *extra],
                         env=env, capture_output=True, text=True, timeout=300, check=False)
    assert out.returncode == 0 and "mission complete" in out.stdout, (
        out.stdout[-3000:] + out.stderr[-3000:])
    return out


WALL = ("seq", "covers", "members", "solve_time_s")
"""Fields that say how a run went on the wall clock, not what it did: an answer's sequence number (a
clock's, per process), what it covers of others' and who had joined by then, a solve's time."""


def content(data: bytes) -> dict:
    return {k: v for k, v in json.loads(data).items() if k not in WALL}


def flown(answers: list[dict]) -> list[dict]:
    """Lockstep answers that fly (not ``hold``), each once."""
    out: list[dict] = []
    for a in answers:
        if not a.get("hold") and a not in out[-1:]:
            out.append(a)
    return out


def after_idle(statuses: list[dict]) -> list[dict]:
    """The statuses from the first that is not idle on."""
    n = next((i for i, st in enumerate(statuses) if st["state"] != "idle"), len(statuses))
    return statuses[n:]


def bus_messages(path: Path) -> dict[str, list[bytes]]:
    """Every message on a ``seaway/<vessel>/`` channel, by key suffix, in log-time order."""
    out: dict[str, list[bytes]] = {}
    with open(path, "rb") as fh:
        for _schema, channel, m in make_reader(fh).iter_messages(log_time_order=True):
            prefix = f"seaway/{V}/"
            if channel.topic.startswith(prefix):
                out.setdefault(channel.topic[len(prefix):], []).append(m.data)
    return out


def topics(path: Path) -> set[str]:
    with open(path, "rb") as fh:
        return {c.topic for c in make_reader(fh).get_summary().channels.values()}  # type: ignore[union-attr]


def test_a_composed_launch_records_what_the_processes_record(tmp_path: Path, zenoh_env) -> None:
    from seaway_lab.study.outcome import report_json

    # Both runs find the solver made: on a machine's first run the first launch would make it while
    # the clock holds, and its answers of period 0 would list the mission's acceptance elsewhere.
    solver_built("nmpc", "paper-sim")
    composed, processes = tmp_path / "composed", tmp_path / "processes"
    launch(composed, zenoh_env, "--composed")
    launch(processes, zenoh_env)

    a, _ = report_json(composed)
    b, _ = report_json(processes)
    assert a["metrics"]["completed"] and a["metrics"] == b["metrics"]

    rec_a, rec_b = composed / "recording.mcap", processes / "recording.mcap"
    assert topics(rec_a) == topics(rec_b)
    ours, theirs = bus_messages(rec_a), bus_messages(rec_b)
    assert set(ours) == set(theirs)
    compared = 0
    for suffix in sorted(set(ours) - set(TIMING)):
        mine, other = [content(d) for d in ours[suffix]], [content(d) for d in theirs[suffix]]
        if suffix.startswith("lockstep/"):
            # How often a period is answered before it is flown (held while members join and the
            # mission comes) is timing; which periods are answered with what, is not.
            mine, other = flown(mine), flown(other)
        elif suffix == "mission/status":
            # Whether the controller answered t_0 (idle) before the launcher's mission came.
            mine, other = after_idle(mine), after_idle(other)
        assert mine == other, suffix
        compared += len(mine)
    assert compared > 2000 and len(ours["sim/truth"]) > 300

    checked, invalid = invalid_messages(rec_a)
    assert checked > compared and invalid == {}, {t: (len(e), e[0]) for t, e in invalid.items()}

    events = [json.loads(line) for line in (composed / "events.jsonl").read_text().splitlines()]
    starts = {e["process"]: e["pid"] for e in events if e["event"] == "start"}
    assert set(starts) == {"recorder", "sim", "estimator", "controller"}
    assert len(set(starts.values())) == 1, starts  # one process
    for name in starts:
        assert "node of this process" in (composed / "logs" / f"{name}.log").read_text()


def test_a_real_time_profile_is_not_composed(tmp_path: Path, zenoh_env) -> None:
    """A real-time stack talks to an autopilot and keeps its services apart: refused, nothing run."""
    run_dir = tmp_path / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim", "--composed", "--run-dir",
                          str(run_dir)], env=zenoh_env, capture_output=True, text=True, timeout=60,
                         check=False)
    assert out.returncode == 2, out.stdout[-2000:] + out.stderr[-2000:]
    assert "--composed" in out.stderr and "lockstep" in out.stderr
    assert not (run_dir / "recording.mcap").exists()


def test_a_command_that_is_no_installed_service_is_named(tmp_path: Path, zenoh_env) -> None:
    """A composed profile naming a command no package installs: the launch says which, exit 1."""
    profile = tmp_path / "bad.toml"
    profile.write_text('name = "bad"\ndescription = "test"\nscenario = "paper-c1"\n'
                       'clock = "lockstep"\n[[processes]]\nname = "sim"\nservice = "sim"\n'
                       'command = ["seaway-no-such-service", "--vessel", "{vessel}"]\n')
    out = subprocess.run([str(BIN / "seaway"), "launch", str(profile), "--composed", "--run-dir",
                          str(tmp_path / "run")], env=zenoh_env, capture_output=True, text=True,
                         timeout=60, check=False)
    assert out.returncode == 1, out.stdout[-2000:] + out.stderr[-2000:]
    assert "seaway-no-such-service" in out.stderr and "Traceback" not in out.stdout + out.stderr
