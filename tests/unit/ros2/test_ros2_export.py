"""``seaway export ros2`` on recordings that are not one whole file: a rotated series (each file
numbers its channels itself) keeps every message on its own topic in the companion file; a
damaged chunk is a clear error that leaves no half-written output behind."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from seaway.recording import reader
from seaway.ros2 import export
from seaway.vessel.model import load_vessel

from tests.unit.common.test_recording_damage import garble_middle_chunk
from tests.unit.common.test_recording_damage import write as write_origins

TOPICS = ("other/a", "other/b", "other/c")


def write(path: Path, order: tuple[str, ...], first: int) -> None:
    """One file of a series: its channels registered in ``order``; each message names its topic."""
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=300)
        w.start()
        schema = w.register_schema("x", "jsonschema", b"{}")
        ids = {t: w.register_channel(t, "json", schema) for t in order}
        for i in range(30):
            topic = TOPICS[i % 3]
            w.add_message(ids[topic], first + i, f"{topic}:{first + i}".encode(), first + i, i)
        w.finish()


def test_a_rotated_series_keeps_each_message_on_its_topic(tmp_path: Path) -> None:
    series = tmp_path / "run"
    series.mkdir()
    write(series / "recording-000.mcap", TOPICS, 0)
    write(series / "recording-001.mcap", TOPICS[::-1], 100)  # the same ids, other topics
    out = tmp_path / "ros2.mcap"
    stats = export.export([series], out, vessel=load_vessel("paper-sim"))
    assert stats.copied == 60 and stats.companion is not None
    with open(stats.companion, "rb") as fh:
        r = make_reader(fh)
        got = [(c.topic, bytes(m.data).decode()) for _, c, m in r.iter_messages()]
        assert sorted(c.topic for c in r.get_summary().channels.values()) == list(TOPICS)
    assert len(got) == 60
    assert all(data.startswith(topic + ":") for topic, data in got)


def test_a_damaged_chunk_leaves_no_output(tmp_path: Path, capsys) -> None:
    src = tmp_path / "recording.mcap"
    write_origins(src)
    start = garble_middle_chunk(src)
    out = tmp_path / "ros2.mcap"
    with pytest.raises(reader.UnreadableRecordingError, match=rf"chunk at byte {start}"):
        export.export([src], out, vessel=load_vessel("paper-sim"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["recording.mcap"]
    assert export.main([str(src), str(out), "--vessel-file", "paper-sim"]) == 2
    err = capsys.readouterr().err
    assert f"chunk at byte {start}" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["recording.mcap"]
