"""The log-file tail, and the recording's time convention (``seaway.recording.timebase``) through the
writer: in lockstep every log time is the sim time on the run's epoch (no clock read: times passed
in). The convention alone: tests/unit/common/test_recording_timebase.py."""

from __future__ import annotations

import json
import logging
from pathlib import Path

from mcap.reader import make_reader
from seaway.contract import keys
from seaway.contract.messages import NavOrigin, SimTruth
from seaway.recording.timebase import RecordingTime
from seaway.tools.launch.events import EVENTS_TOPIC
from seaway_recorder.core import RecordingWriter
from seaway_recorder.logtail import LogLine, LogTail, parse_line

from tests.unit.recorder.foxglove_check import foxglove_messages, t_ns

V = "v1"
E = 1_780_000_000_000_000_000  # the run's epoch [ns]
TRUTH = keys.SIM_TRUTH.key(V)


def test_log_lines_are_parsed_as_the_services_write_them() -> None:
    rec = logging.LogRecord("seaway.controller", logging.WARNING, "f.py", 1, "solver slow: %d ms", (12,),
                            None)
    # The services' format (seaway.runtime.service.configure_logging), made by logging itself.
    text = logging.Formatter("%(asctime)s controller %(levelname)s %(name)s: %(message)s").format(rec)
    line = parse_line(text + "\n")
    assert (line.level, line.logger, line.message) == ("WARNING", "seaway.controller", "solver slow: 12 ms")
    assert line.wall_ns is not None and abs(line.wall_ns - rec.created * 1e9) < 1_000_000  # ms in the text
    assert parse_line("Traceback (most recent call last):") == \
        LogLine(None, "", "", "Traceback (most recent call last):")


def test_log_tail_reads_whole_new_lines_of_every_file_as_they_appear(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    tail = LogTail([str(logs / "*.log")])
    assert tail.poll(1) == []
    (logs / "sim.log").write_text("2026-05-01 09:00:00,250 sim ERROR seaway.sim: boom\nTraceback (x)\npart")
    got = tail.poll(5)
    t0 = parse_line("2026-05-01 09:00:00,250 sim ERROR seaway.sim: boom").wall_ns
    assert got == [("sim", LogLine(t0, "ERROR", "seaway.sim", "boom")),
                   ("sim", LogLine(t0, "ERROR", "", "Traceback (x)"))]  # the error's line goes on
    with open(logs / "sim.log", "a") as f:
        f.write("ial line\n")
    (logs / "controller.log").write_text("READY\n")
    assert sorted(tail.poll(9)) == [("controller", LogLine(9, "INFO", "", "READY")),
                                    ("sim", LogLine(t0, "ERROR", "", "partial line"))]


def test_lockstep_recording_logs_every_message_at_its_sim_time_on_the_epoch(tmp_path: Path) -> None:
    """The writer on the convention: bus samples, derived Foxglove messages, log lines and events."""
    w = RecordingWriter(tmp_path / "r.mcap", time=RecordingTime(lockstep=True, epoch_ns=E))
    w.open(0)
    wall0 = 1_790_000_000_000_000_000
    w.write(keys.NAV_ORIGIN.key(V), NavOrigin.make(stamp_ns=0, lat_rad=0.8, lon_rad=0.1, alt_m=0.0)
            .encode(), "application/json", wall0)
    for k in range(20):  # 2 s of sim in 0.2 s of wall
        truth = SimTruth.make(stamp_ns=k * 100_000_000, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.1 * k,
                              y_m=0.0, psi_rad=0.0, thrust_port_n=1.0, thrust_starboard_n=1.0,
                              energy_j=0.0)
        w.write(TRUTH, truth.encode(), "application/json", wall0 + k * 10_000_000)
    w.write_log("controller", LogLine(wall0 + 55_000_000, "INFO", "seaway.controller", "leg 1"))
    w.write_event(json.dumps({"t_unix_s": (wall0 + 105_000_000) / 1e9, "process": "sim",
                              "event": "start"}).encode())
    w.close(1)
    with open(tmp_path / "r.mcap", "rb") as fh:
        reader = make_reader(fh)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        bus = [(c.topic, m.log_time, m.publish_time, json.loads(m.data))
               for _, c, m in reader.iter_messages() if c.message_encoding == "json"]
    assert meta["seaway.time"]["log_time"] == "sim" and int(meta["seaway.time"]["epoch_ns"]) == E
    truths = [(lt, pt, d) for topic, lt, pt, d in bus if topic == TRUTH]
    assert len(truths) == 20
    for k, (lt, pt, d) in enumerate(truths):
        assert lt == E + d["stamp_ns"]  # log time = the epoch + sim time
        assert pt == wall0 + k * 10_000_000  # publish time = the wall time it was received
    (event,) = [lt for topic, lt, _, d in bus if topic == EVENTS_TOPIC]
    assert event == E + 1_000_000_000  # at 0.105 s of wall the sim had reached 1.0 s
    fox = foxglove_messages(tmp_path / "r.mcap")
    (log,) = [(lt, m) for _, name, lt, m in fox if name == "foxglove.Log"]
    assert log[0] == E + 500_000_000 and t_ns(log[1].timestamp) == log[0]
    assert log[1].message == "seaway.controller: leg 1" and log[1].name == "controller"
    fixes = [(lt, m) for _, name, lt, m in fox if name == "foxglove.LocationFix"]
    assert len(fixes) == 20
    assert all(t_ns(m.timestamp) == lt for lt, m in fixes)  # a date on the same epoch
