"""``seaway.recording.tail.tail_of``: the end of a killed recorder's file, for its restart.

Checked against the mcap library's own reader on the same bytes (every record parsed), on files
the recorder's writer leaves when killed, cut anywhere; and that only the last chunks are opened,
so a long recording is not parsed message by message."""

from __future__ import annotations

import contextlib
import io
import struct
from pathlib import Path

import pytest
from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel, Chunk, DataEnd, Footer, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import Writer
from seaway.recording import tail as tail_module
from seaway.recording.tail import tail_of
from seaway_recorder.mcapfile import McapWriter

T0 = 1_800_000_000_000_000_000
STEP = 50_000_000  # one message every 50 ms
PER_CHUNK = 4


def killed(path: Path, n: int, topics: int = 3) -> list[int]:
    """A file as a recorder killed after ``n`` messages leaves it (a chunk every ``PER_CHUNK``
    messages, no summary); returns each chunk's end byte."""
    ends = []
    with open(path, "wb") as f:
        w = McapWriter(f, chunk_size=1 << 20)
        w.start()
        sid = w.register_schema("s", "jsonschema", b"{}")
        ids = [w.register_channel(f"t/{k}", "json", sid) for k in range(topics)]
        for i in range(n):
            w.add_message(ids[i % topics], T0 + i * STEP, b'{"i": %d}' % i, T0 + i * STEP, i)
            if (i + 1) % PER_CHUNK == 0:
                w.flush()
                ends.append(f.tell())
    return ends


def library_tail(path: Path, since_ns: int) -> tuple[int, set[tuple[str, bytes]]]:
    """(last log time, messages from ``since_ns``) by the mcap library, every record parsed, up
    to where the file is cut."""
    topics: dict[int, str] = {}
    last, found = 0, set()
    with open(path, "rb") as f, contextlib.suppress(EndOfFile, McapError, struct.error):
        for record in StreamReader(f, emit_chunks=True).records:
            inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else [record]
            for r in inner:
                if isinstance(r, Channel):
                    topics[r.id] = r.topic
                elif isinstance(r, Message):
                    last = max(last, r.log_time)
                    if r.log_time >= since_ns:
                        found.add((topics[r.channel_id], bytes(r.data)))
            if isinstance(record, DataEnd | Footer):
                break
    return last, found


@pytest.mark.parametrize("cut_back", [0, 1, 7, 60, 131])
def test_a_killed_file_cut_anywhere_gives_what_the_library_reads(tmp_path: Path, cut_back: int) -> None:
    path = tmp_path / "run.mcap"
    killed(path, 400)
    data = path.read_bytes()
    path.write_bytes(data[:len(data) - cut_back])  # the last records cut short, as a kill leaves
    since = T0 + 380 * STEP
    last, expected = library_tail(path, since)
    tail = tail_of(path, since)
    assert expected and tail.messages == expected
    assert tail.last_log_ns == last


def test_only_the_last_chunks_are_opened(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "run.mcap"
    killed(path, 4000)  # 1,000 chunks
    opened = []
    real = tail_module.chunk_body

    def counting(rec: bytes) -> bytes:
        opened.append(len(rec))
        return real(rec)

    monkeypatch.setattr(tail_module, "chunk_body", counting)
    tail = tail_of(path, T0 + 3990 * STEP)
    assert len(tail.messages) == 10 and tail.last_log_ns == T0 + 3999 * STEP
    # The three last chunks for their messages, the first for the channels they name.
    assert len(opened) == 4


def test_a_channel_declared_a_chunk_before_its_first_message_is_found(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with open(path, "wb") as f:
        w = McapWriter(f, chunk_size=1 << 20)
        w.start()
        sid = w.register_schema("s", "jsonschema", b"{}")
        a = w.register_channel("t/a", "json", sid)
        w.add_message(a, T0, b"a0", T0)
        late = w.register_channel("t/late", "json", sid)  # in the first chunk, with no message
        w.flush()
        for i in range(1, 200):
            w.add_message(a, T0 + i * STEP, b"a%d" % i, T0 + i * STEP)
            w.flush()
        w.add_message(late, T0 + 200 * STEP, b"late", T0 + 200 * STEP)
        w.flush()
    tail = tail_of(path, T0 + 199 * STEP)
    assert tail.messages == {("t/a", b"a199"), ("t/late", b"late")}


def test_a_damaged_last_chunk_is_skipped_and_its_time_not_trusted(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    ends = killed(path, 40)
    data = bytearray(path.read_bytes())
    data[ends[-2] + 60] ^= 0xFF  # the last chunk starts at ends[-2]: a byte of its records
    path.write_bytes(bytes(data))
    tail = tail_of(path, T0 + 32 * STEP)
    # The chunk before it is read whole; the damaged one's messages are unknown, never invented.
    assert {m for _, m in tail.messages} == {b'{"i": %d}' % i for i in range(32, 36)}
    assert tail.last_log_ns == T0 + 35 * STEP


def test_what_is_not_a_recording_gives_an_empty_tail(tmp_path: Path) -> None:
    for name, content in (("empty.mcap", b""), ("text.mcap", b"not an mcap file at all\n" * 10),
                          ("magic.mcap", b"\x89MCAP0\r\n")):
        path = tmp_path / name
        path.write_bytes(content)
        tail = tail_of(path, 0)
        assert tail.last_log_ns == 0 and not tail.messages


def test_messages_outside_chunks_are_read(tmp_path: Path) -> None:
    buf = io.BytesIO()
    w = Writer(buf, use_chunking=False)
    w.start()
    sid = w.register_schema("s", "jsonschema", b"{}")
    cid = w.register_channel("t/x", "json", sid)
    for i in range(10):
        w.add_message(cid, T0 + i * STEP, b"x%d" % i, T0 + i * STEP)
    path = tmp_path / "plain.mcap"
    path.write_bytes(buf.getvalue())  # killed: no finish
    tail = tail_of(path, T0 + 8 * STEP)
    assert tail.messages == {("t/x", b"x8"), ("t/x", b"x9")}
    assert tail.last_log_ns == T0 + 9 * STEP
