"""The recorder's MCAP writer writes the very bytes the mcap library's ``Writer`` writes.

``seaway_recorder.mcapfile.McapWriter`` packs the per-message and per-chunk records itself (a
lockstep recorder ends a chunk every period). These tests give it and ``mcap.writer.Writer`` the
same random sequence of calls (schemas, channels, messages with out-of-order times, attachments
and metadata between them, flushes, chunks ended by size) and compare the files byte for byte,
for each compression; then read one back with the mcap reader, summary and indexes included.
"""

from __future__ import annotations

import errno
import io
import random
import subprocess
import sys

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from seaway.runtime.disk import disk_full
from seaway_recorder.mcapfile import COMPRESSIONS, McapWriter

LIBRARY_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                       "none": CompressionType.NONE}


def script(seed: int, calls: int = 600) -> list[tuple]:
    """A random sequence of writer calls: what a recorder does, and the odd cases (a message
    stamped before the chunk's first, a channel first seen mid-chunk, a schema-less channel,
    a flush with nothing in the chunk, an attachment or metadata while a chunk is open)."""
    rng = random.Random(seed)
    out: list[tuple] = [("schema", "seaway.v1.A", "jsonschema", b'{"type": "object"}'),
                        ("channel", "seaway/v/a", "json", 1, {"role": "bus"})]
    schemas, channels = 1, 1
    t = 10**18
    for _ in range(calls):
        r = rng.random()
        if r < 0.02:
            schemas += 1
            out.append(("schema", f"seaway.v1.S{schemas}", "jsonschema", rng.randbytes(rng.randint(0, 300))))
        elif r < 0.05:
            channels += 1
            out.append(("channel", f"seaway/v/c{channels}", rng.choice(["json", "protobuf"]),
                        rng.randint(0, schemas), {"k": str(rng.random())} if rng.random() < 0.5 else {}))
        elif r < 0.07:
            out.append(("attachment", rng.randint(0, 10**18), t, f"scenario/f{rng.randint(0, 9)}.toml",
                        "application/toml", rng.randbytes(rng.randint(0, 500))))
        elif r < 0.09:
            out.append(("metadata", f"seaway.m{rng.randint(0, 5)}", {"a": str(rng.random()), "b": ""}))
        elif r < 0.2:
            out.append(("flush",))
        else:
            t += rng.randint(0, 100_000_000)
            log = t - rng.randint(0, 200_000_000) if rng.random() < 0.1 else t
            out.append(("message", rng.randint(1, channels), log, rng.randbytes(rng.randint(0, 2_000)),
                        t + rng.randint(0, 10**6), rng.randint(0, 2**32 - 1)))
    return out


def play(writer: Writer | McapWriter, calls: list[tuple]) -> None:
    play_calls(writer, [("start",), *calls])
    writer.finish()


def play_calls(writer: Writer | McapWriter, calls: list[tuple]) -> None:
    for call in calls:
        kind, *args = call
        if kind == "start":
            writer.start(profile="", library="seaway-recorder/test")
        elif kind == "schema":
            writer.register_schema(*args)
        elif kind == "channel":
            writer.register_channel(*args)
        elif kind == "message":
            writer.add_message(*args)
        elif kind == "attachment":
            writer.add_attachment(*args)
        elif kind == "metadata":
            writer.add_metadata(*args)
        else:
            writer.flush()


def both(calls: list[tuple], compression: str, chunk_size: int) -> tuple[bytes, bytes]:
    ours, theirs = io.BytesIO(), io.BytesIO()
    play(McapWriter(ours, chunk_size=chunk_size, compression=compression), calls)
    play(Writer(theirs, chunk_size=chunk_size, compression=LIBRARY_COMPRESSION[compression]), calls)
    return ours.getvalue(), theirs.getvalue()


@pytest.mark.parametrize("compression", COMPRESSIONS)
@pytest.mark.parametrize("seed", range(4))
def test_the_same_bytes_as_the_mcap_writer(compression: str, seed: int) -> None:
    calls = script(seed)
    # Small chunks so that some end by size mid-period, as a 4 MB chunk would on a long quiet run.
    ours, theirs = both(calls, compression, chunk_size=[1 << 22, 4_000, 700, 0][seed])
    assert len(ours) == len(theirs)
    first = next((i for i, (a, b) in enumerate(zip(ours, theirs, strict=True)) if a != b), None)
    assert first is None, f"the files differ from byte {first} of {len(ours)}"


def test_a_file_reads_back_whole_with_its_indexes() -> None:
    calls = script(7)
    out = io.BytesIO()
    play(McapWriter(out, chunk_size=3_000, compression="zstd"), calls)
    sent = [c for c in calls if c[0] == "message"]
    reader = make_reader(io.BytesIO(out.getvalue()))
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(sent)
    assert summary.statistics.chunk_count == len(summary.chunk_indexes) > 10
    got = [(c.id, m.log_time, m.data, m.publish_time, m.sequence)
           for _, c, m in reader.iter_messages(log_time_order=False)]
    assert got == [tuple(c[1:]) for c in sent]
    in_order = [m.log_time for _, _, m in reader.iter_messages(log_time_order=True)]
    assert in_order == sorted(c[2] for c in sent)
    names = {a.name for a in reader.iter_attachments()}
    assert names == {c[3] for c in calls if c[0] == "attachment"}


def test_an_unknown_compression_is_refused_naming_the_choices() -> None:
    with pytest.raises(ValueError, match="zstd, lz4, none"):
        McapWriter(io.BytesIO(), compression="gzip")


def test_a_chunk_ends_past_its_size_at_the_same_byte() -> None:
    """Every chunk size from 1 to 400 bytes against 100-byte message records: a chunk that ends
    on reaching its size, instead of on passing it, differs."""
    calls = [("schema", "s", "jsonschema", b"{}"), ("channel", "t", "json", 1, {})]
    calls += [("message", 1, k, bytes(69), k, k) for k in range(12)]
    for size in range(1, 400):
        ours, theirs = both(calls, "none", chunk_size=size)
        assert ours == theirs, f"chunk size {size}"


class Disk(io.BytesIO):
    """A stream with ``room`` bytes left: a write it has no room for fails whole with ENOSPC, as
    ``seaway.runtime.disk.AllOrNothing`` makes a file's writes fail."""

    def __init__(self, room: int) -> None:
        super().__init__()
        self.room = room
        self.refused = 0

    def write(self, data) -> int:  # type: ignore[override]
        if len(data) > self.room:
            self.refused += 1
            raise OSError(errno.ENOSPC, "No space left on device")
        self.room -= len(data)
        return super().write(data)


def test_a_disk_with_no_room_loses_no_message_and_the_file_reads_whole() -> None:
    """Chunks that found no room (at a flush, or ended by size) stay in hand whole, messages keep
    coming, and once there is room the file holds every message once, in order, and its summary
    counts them: as if the disk had never been full."""
    calls = [c for c in script(11, calls=1_500) if c[0] != "flush"]
    cut = len(calls) // 3
    # Attachments and metadata are written as they come (a recorder writes them when it opens a
    # file): not while the disk is full here.
    calls = [c for i, c in enumerate(calls)
             if not (cut <= i < 2 * cut and c[0] in ("attachment", "metadata"))]
    disk = Disk(room=1 << 30)
    w = McapWriter(disk, chunk_size=2_000, compression="zstd")
    w.start(profile="", library="test")
    play_calls(w, calls[:cut])
    disk.room = 0
    with pytest.raises(OSError) as err:
        w.flush()
    assert disk_full(err.value)
    play_calls(w, calls[cut:2 * cut])  # chunks past their size found no room either: held
    assert w.deferred is not None and disk.refused >= 2
    with pytest.raises(OSError):
        w.finish()  # nor for the end: the file and the writer stay as they were
    disk.room = 1 << 30
    play_calls(w, calls[2 * cut:])
    w.finish()
    reader = make_reader(io.BytesIO(disk.getvalue()))
    summary = reader.get_summary()
    sent = [c for c in calls if c[0] == "message"]
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(sent)
    got = [(c.id, m.log_time, m.data, m.publish_time, m.sequence)
           for _, c, m in reader.iter_messages(log_time_order=False)]
    assert got == [tuple(c[1:]) for c in sent]
    assert {a.name for a in reader.iter_attachments()} == {c[3] for c in calls if c[0] == "attachment"}


def test_a_finish_with_no_room_then_with_room_writes_the_bytes_of_one_that_had_room() -> None:
    calls = script(12)
    expected = io.BytesIO()
    w = McapWriter(expected, chunk_size=3_000)
    play(w, calls)
    disk = Disk(room=1 << 30)
    w = McapWriter(disk, chunk_size=3_000)
    play_calls(w, [("start",), *calls, ("flush",)])
    disk.room = 0
    for _ in range(3):
        with pytest.raises(OSError):
            w.finish()
    disk.room = 1 << 30
    w.finish()
    assert disk.getvalue() == expected.getvalue()


def test_the_last_metadata_of_finish_is_add_metadata_then_finish() -> None:
    calls = script(13)
    ours, theirs = io.BytesIO(), io.BytesIO()
    w = McapWriter(ours, chunk_size=3_000)
    play_calls(w, [("start",), *calls, ("flush",)])
    w.finish(("seaway.recorder.summary", {"messages": "12"}))
    lib = Writer(theirs, chunk_size=3_000, compression=CompressionType.ZSTD)
    play_calls(lib, [("start",), *calls, ("flush",),
                     ("metadata", "seaway.recorder.summary", {"messages": "12"})])
    lib.finish()
    assert ours.getvalue() == theirs.getvalue()


def test_a_file_write_with_no_room_is_cut_back_off_whole(tmp_path) -> None:
    """``AllOrNothing`` on a real file: a write that fails after a part went out (here the
    process's file size limit, which fails a write part way as a full disk does) leaves the file
    as the writes before made it, and the next write goes on from there."""
    path = tmp_path / "f"
    script_ = f"""
import os, resource, signal, sys
sys.path[:0] = {sys.path!r}
from seaway.runtime.disk import AllOrNothing
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (1000, resource.RLIM_INFINITY))
f = AllOrNothing(open({str(path)!r}, "wb", buffering=0))
f.write(b"a" * 600)
try:
    f.write(b"b" * 600)
except OSError as err:
    print("refused", err.errno, os.path.getsize({str(path)!r}), f.tell())
f.write(b"c" * 300)
f.close()
"""
    out = subprocess.run([sys.executable, "-c", script_], capture_output=True, text=True,
                         timeout=60, check=True).stdout.split()
    assert out[:2] == ["refused", str(errno.EFBIG)] and out[2:] == ["600", "600"]
    assert path.read_bytes() == b"a" * 600 + b"c" * 300
