"""``seaway replay`` of a recording with a damaged chunk: what was read before it is published,
then the replay stops and says where and how much it published; no decompressor's traceback."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path

from seaway.recording import reader
from seaway.runtime.memory_bus import MemoryHub
from seaway_recorder import replay as replay_mod
from seaway_recorder.replay import KeyFilter, replay

from tests.unit.common.test_recording_damage import TOPIC, garble_middle_chunk, write
from tests.unit.recorder.test_recorder_runinfo_replay import listening_bus, msg


def test_the_replay_stops_at_an_unreadable_message_and_says_so() -> None:
    def messages() -> Iterator[reader.RecordedMessage]:
        for k in range(3):
            yield msg("seaway/v/a", k)
        raise reader.UnreadableRecordingError("r.mcap: the chunk at byte 99 is damaged")

    bus, heard = listening_bus()
    stats = replay(messages(), bus, KeyFilter(), None, threading.Event())
    assert stats.published == 3 and len(heard) == 3
    assert stats.error is not None and "byte 99" in stats.error


def test_replay_of_a_damaged_file_publishes_what_comes_before_and_fails(tmp_path: Path,
                                                                       monkeypatch, capsys) -> None:
    src = tmp_path / "recording.mcap"
    data = write(src)
    start = garble_middle_chunk(src)
    hub = MemoryHub()
    heard: list = []
    hub.bus().subscribe_raw("**", heard.append)

    class MemoryBusOpener:
        @staticmethod
        def open(vessel: str, *_args, **_kw):
            return hub.bus(vessel)

    monkeypatch.setattr(replay_mod, "Bus", MemoryBusOpener)
    assert replay_mod.main([str(src), "--fast", "--wait", "0"]) == 1
    out, err = capsys.readouterr()
    done = json.loads(out.splitlines()[-1])
    assert 0 < done["published"] < len(data) and f"byte {start}" in done["error"]
    assert f"stopped after {done['published']} messages" in err and f"byte {start}" in err
    assert "Traceback" not in err
    assert [s.payload for s in heard if s.key == TOPIC] == data[:done["published"]]
