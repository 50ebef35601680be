"""How the report reads a recording: each file's summary once (``report.read_for_report``)."""

from __future__ import annotations

from pathlib import Path

from seaway.recording import reader
from seaway_recorder import report

from tests.unit.common.test_recording_reader import ORIGIN, origin, write


def test_a_report_reads_each_summary_once(tmp_path: Path, monkeypatch) -> None:
    path = tmp_path / "r.mcap"
    write(path, [(ORIGIN.key("vessel1"), k, origin(k, 0.1)) for k in range(50)])
    read = []
    real = reader.read_summary
    monkeypatch.setattr(reader, "read_summary", lambda fh: read.append(1) or real(fh))
    info, dec = report.read_for_report([path], "vessel1")
    assert len(read) == 1 and len(dec.get(ORIGIN.suffix)) == 50 and info.message_count == 50
