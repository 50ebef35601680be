"""The recorder's MCAP writer writes the very bytes the mcap library's ``Writer`` writes.

``seaway_recorder.mcapfile.McapWriter`` packs the per-message and per-chunk records itself (a
lockstep recorder ends a chunk every period). These tests give it and ``mcap.writer.Writer`` the
same random sequence of calls (schemas, channels, messages with out-of-order times, attachments
and metadata between them, flushes, chunks ended by size) and compare the files byte for byte,
for each compression; then read one back with the mcap reader, summary and indexes included.
"""

from __future__ import annotations

import io
import random

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
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
    writer.start(profile="", library="seaway-recorder/test")
    for call in calls:
        kind, *args = call
        if kind == "schema":
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
    writer.finish()


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
