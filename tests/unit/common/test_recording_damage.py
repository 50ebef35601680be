"""Recordings damaged after they were finished, read back: a chunk whose bytes no longer match its
CRC (a flipped bit that still decompresses, or a wrong CRC on whole data), a chunk that does not
decompress, files joined one after another, a folder holding a sub-folder named ``*.mcap``. Each
is refused naming the file and what is wrong (the damaged chunk by the byte it starts at), never
read as if whole, never a library's traceback."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.writer import CompressionType, Writer
from seaway.contract import keys
from seaway.recording import reader
from seaway.recording.layout import CHUNK_HEAD, RECORD_HEAD

from tests.unit.common.test_recording_reader import ORIGIN, origin

TOPIC = ORIGIN.key("vessel1")
CRC_AT = RECORD_HEAD.size + CHUNK_HEAD.size - 4
"""Where a chunk's CRC field sits from the chunk's start [byte]."""


def write(path: Path, n: int = 60, compression: str = "zstd", first: int = 0) -> list[bytes]:
    """A recording of ``n`` origins on one topic in small chunks; the messages' bytes."""
    data = [origin(first + i, (first + i) / 1000) for i in range(n)]
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=600, compression=CompressionType[compression.upper()])
        w.start()
        schema = w.register_schema("seaway.v1.NavOrigin", "jsonschema", b"{}")
        channel = w.register_channel(TOPIC, "json", schema)
        for i, d in enumerate(data):
            w.add_message(channel, log_time=first + i, data=d, publish_time=first + i, sequence=i)
        w.finish()
    return data


def middle_chunk(path: Path) -> tuple[int, int]:
    """(start, length) of the recording's middle chunk [bytes]."""
    with open(path, "rb") as fh:
        summary = reader.read_summary(fh)
    assert summary is not None and len(summary.chunk_indexes) >= 5
    ci = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[
        len(summary.chunk_indexes) // 2]
    return ci.chunk_start_offset, ci.chunk_length


def damage(path: Path, at: int) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= 0x10
    path.write_bytes(bytes(data))


def garble_middle_chunk(path: Path) -> int:
    """Zero 20 bytes near the end of the middle chunk's compressed data (it no longer decodes);
    the chunk's start [bytes]."""
    start, length = middle_chunk(path)
    data = bytearray(path.read_bytes())
    data[start + length - 30:start + length - 10] = bytes(20)
    path.write_bytes(bytes(data))
    return start


def every_reader_refuses(path: Path, start: int) -> None:
    """The report's decode, the messages in log-time order (replay) and in file order all refuse
    ``path`` naming the chunk that starts at byte ``start``."""
    named = rf"recording.mcap: the chunk at byte {start} is damaged .*seaway record recover"
    with pytest.raises(reader.UnreadableRecordingError, match=named):
        reader.decode_vessel([path], "vessel1", [ORIGIN.suffix])
    with pytest.raises(reader.UnreadableRecordingError, match=named):
        list(reader.iter_messages([path]))
    with pytest.raises(reader.UnreadableRecordingError, match=named):
        list(reader.iter_file_records(path, log_time_order=False))
    with open(path, "rb") as fh, pytest.raises(reader.UnreadableRecordingError, match=named):
        list(reader._file_messages(fh, None, None))  # every topic: through the mcap reader


def test_a_flipped_bit_in_an_uncompressed_chunk_is_found_by_its_crc(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    write(path, compression="none")
    start, length = middle_chunk(path)
    damage(path, start + length - 20)  # inside the last message's bytes: nothing fails to parse
    every_reader_refuses(path, start)


def test_a_wrong_crc_on_whole_data_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    write(path)
    start, _ = middle_chunk(path)
    damage(path, start + CRC_AT)
    every_reader_refuses(path, start)


def test_a_chunk_that_does_not_decompress_is_the_readers_error(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    write(path)
    start = garble_middle_chunk(path)
    every_reader_refuses(path, start)


def test_whole_chunks_read_as_before(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    data = write(path)
    assert [m.data for m in reader.iter_messages([path])] == data
    dec = reader.decode_vessel([path], "vessel1", [ORIGIN.suffix])
    assert len(dec.get(ORIGIN.suffix)) == len(data) and dec.undecodable == 0


@pytest.mark.parametrize("first_whole", [True, False])
def test_files_joined_are_refused_as_more_than_one_recording(tmp_path: Path,
                                                             first_whole: bool) -> None:
    """``cat a.mcap b.mcap``: the footer at the end is the second's, its offsets its own. A first
    recording as long as the second (the footer's offsets land on the first's own summary) or
    shorter (they land anywhere)."""
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    write(a, 60 if first_whole else 20)
    write(b, 60, first=1000)
    joined = tmp_path / "joined.mcap"
    joined.write_bytes(a.read_bytes() + b.read_bytes())
    assert reader.finished(joined)
    with pytest.raises(reader.UnreadableRecordingError,
                       match=rf"joined.mcap: .*more than one recording.* byte {a.stat().st_size}"):
        reader.read_info(reader.open_paths([joined]))


def test_a_folder_named_mcap_in_a_run_folder_is_not_a_recording(tmp_path: Path) -> None:
    data = write(tmp_path / "recording.mcap")
    (tmp_path / "zz.mcap").mkdir()
    files = reader.open_paths([tmp_path])
    assert files == [tmp_path / "recording.mcap"]
    assert [m.data for m in reader.iter_messages(files)] == data


def test_undecodable_messages_are_counted_by_topic(tmp_path: Path) -> None:
    path = tmp_path / "recording.mcap"
    clock = keys.SIM_CLOCK.key("vessel1")
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start()
        schema = w.register_schema("x", "jsonschema", b"{}")
        ids = {t: w.register_channel(t, "json", schema) for t in (TOPIC, clock)}
        for i in range(6):
            w.add_message(ids[TOPIC], i, origin(i, 0.1) if i % 3 else b'{"no": 1}', i, i)
            w.add_message(ids[clock], i, b"{broken", i, i)
        w.finish()
    dec = reader.decode_vessel([path], "vessel1")
    assert dec.undecodable_by_topic == {TOPIC: 2, clock: 6}
    assert dec.undecodable == 8 and len(dec.get(ORIGIN.suffix)) == 4
    assert dec.between(0, None).undecodable_by_topic == dec.undecodable_by_topic
