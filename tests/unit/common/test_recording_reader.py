"""``reader.decode_vessel`` reads each file in file order, only for the topics it wants, and sorts
each key by log time afterwards; it must give exactly what decoding the merge of every message in
log-time order (``reader.iter_messages``, the reader's ordering heap) gives: the same messages in
the same order, ties in file order and a series in name order, repeats across files read once."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest
from mcap.writer import Writer
from seaway.contract import keys
from seaway.contract.messages import MessageError, NavOrigin
from seaway.recording import reader

ORIGIN = keys.NAV_ORIGIN


def origin(stamp_ns: int, lat_rad: float) -> bytes:
    return NavOrigin(stamp_ns=stamp_ns, lat_rad=lat_rad, lon_rad=0.1, alt_m=0.0).encode()


def write(path: Path, records: list[tuple[str, int, bytes]], chunk_size: int = 300) -> None:
    """An MCAP file of ``(topic, log time, bytes)`` in this order (small chunks: many of them)."""
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=chunk_size)
        w.start()
        schema = w.register_schema("seaway.v1.NavOrigin", "jsonschema", b"{}")
        channels: dict[str, int] = {}
        for seq, (topic, log_ns, data) in enumerate(records):
            if topic not in channels:
                channels[topic] = w.register_channel(topic, "json", schema)
            w.add_message(channels[topic], log_time=log_ns, data=data, publish_time=log_ns,
                          sequence=seq)
        w.finish()


def reference(files: list[Path], vessel: str | None, suffixes: list[str] | None):
    """What decoding the log-time merge of every message gives (the ordering heap)."""
    by: dict[str, list[tuple[int, bytes]]] = {}
    seen, dups, bad, vessels = set(), 0, 0, set()
    for m in reader.iter_messages(files):
        spec = keys.spec_for_key(m.topic)
        if spec is None or spec.message is None:
            continue
        v = m.topic.split("/", 2)[1]
        vessels.add(v)
        if (suffixes is not None and spec.suffix not in suffixes) or (vessel and v != vessel):
            continue
        if len(files) > 1:
            if (m.topic, m.data) in seen:
                dups += 1
                continue
            seen.add((m.topic, m.data))
        try:
            spec.message.decode(m.data)
        except MessageError:
            bad += 1
            continue
        by.setdefault(spec.suffix, []).append((m.log_time_ns, m.data))
    return by, dups, bad, vessels


@pytest.fixture
def series(tmp_path: Path) -> list[Path]:
    """Two files of a series: messages out of log-time order within a file, equal log times (not in
    the order of their bytes), a repeat of the first file's last period in the second, a message that
    does not decode, another vessel, an unregistered topic and a Foxglove one."""
    a, b = ORIGIN.key("vessel1"), ORIGIN.key("vessel2")
    first = [(a, 50, origin(5, 0.5)), (a, 10, origin(1, 0.1)), (a, 30, origin(3, 0.35)),
             (a, 30, origin(3, 0.31)), (b, 20, origin(2, 0.2)), ("foxglove/vessel1/x", 5, b"{}"),
             ("other/topic", 1, b"?"), (a, 40, b'{"not": "an origin"}'), (a, 70, origin(7, 0.7))]
    second = [(a, 70, origin(7, 0.7)), (a, 60, origin(6, 0.6)), (a, 30, origin(3, 0.33)),
              (a, 90, origin(9, 0.9)), (keys.SIM_CLOCK.key("vessel1"), 80, b'{"broken"')]
    paths = [tmp_path / "recording.mcap", tmp_path / "recording.restart-001.mcap"]
    write(paths[0], first)
    write(paths[1], second)
    return paths


@pytest.mark.parametrize("vessel", ["vessel1", "vessel2"])
@pytest.mark.parametrize("suffixes", [None, [ORIGIN.suffix], [keys.SIM_TRUTH.suffix]])
@pytest.mark.parametrize("n_files", [1, 2])
def test_decode_equals_the_log_time_merge(series: list[Path], vessel: str, suffixes,
                                          n_files: int) -> None:
    files = series[:n_files]
    dec = reader.decode_vessel(files, vessel, suffixes)
    by, dups, bad, vessels = reference(files, vessel, suffixes)
    got = {s: list(zip(dec.log_ns[s], [m.encode() for m in msgs], strict=True))
           for s, msgs in dec.by_suffix.items()}
    want = {s: [(t, NavOrigin.decode(d).encode() if s == ORIGIN.suffix else d) for t, d in items]
            for s, items in by.items()}
    assert got == want
    assert (dec.duplicates, dec.undecodable, dec.vessels) == (dups, bad, vessels)
    assert gc.isenabled()


def test_the_order_is_by_log_time_then_file_order(series: list[Path]) -> None:
    dec = reader.decode_vessel(series, "vessel1", [ORIGIN.suffix])
    lat = [round(m.lat_rad, 2) for m in dec.get(ORIGIN.suffix)]
    # 30 ns three times: the first file's two in its order, then the second file's; 70 ns once.
    assert lat == [0.1, 0.35, 0.31, 0.33, 0.5, 0.6, 0.7, 0.9]
    assert dec.log_ns[ORIGIN.suffix] == [10, 30, 30, 30, 50, 60, 70, 90]
    assert (dec.duplicates, dec.undecodable) == (1, 1)  # the repeat; the non-origin (the clock: not read)


def test_several_vessels_without_one_named_is_an_error(series: list[Path]) -> None:
    with pytest.raises(ValueError, match=r"several vessels \(vessel1, vessel2\)"):
        reader.decode_vessel(series, None, [ORIGIN.suffix])


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("topics", [None, "one"])
@pytest.mark.parametrize("message_indexes", [True, False])
def test_the_chunk_scan_yields_what_the_mcap_reader_yields(tmp_path: Path, compression: str,
                                                           topics: str | None,
                                                           message_indexes: bool) -> None:
    """``reader.chunked_messages`` reads chunks itself (the reader made an object of every
    message): the same messages, in the same order, as ``iter_messages(log_time_order=False)``;
    chunks of one channel only (skipped when another is wanted), and chunks whose index does not
    name their channels (another tool's file: read, not skipped)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, IndexType

    a, b = ORIGIN.key("vessel1"), keys.SIM_CLOCK.key("vessel1")
    records = [(a if i % 3 else b, (i * 7919) % 500, origin(i, i / 1000)) for i in range(200)]
    records += [(b, 600 + i, origin(i, 0.0)) for i in range(40)]  # chunks with b alone
    path = tmp_path / "r.mcap"
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=400, compression=CompressionType[compression.upper()],
                   index_types=IndexType.ALL if message_indexes else IndexType.CHUNK)
        w.start()
        schema = w.register_schema("x", "jsonschema", b"{}")
        ids = {t: w.register_channel(t, "json", schema) for t in (a, b)}
        for seq, (topic, log_ns, data) in enumerate(records):
            w.add_message(ids[topic], log_time=log_ns, data=data, publish_time=0, sequence=seq)
        w.finish()
    wanted = None if topics is None else {a}
    with open(path, "rb") as fh:
        mr = make_reader(fh)
        want = [(c.topic, m.log_time, bytes(m.data)) for _, c, m in
                mr.iter_messages(topics=wanted, log_time_order=False)]
        summary = mr.get_summary()
        assert summary is not None and len(summary.chunk_indexes) > 10
        got = list(reader._file_messages(fh, reader.read_summary(fh), wanted or {a, b}))
    assert got == want
    assert len(got) == (240 if topics is None else sum(1 for r in records if r[0] == a))


def test_a_damaged_chunk_is_named_with_the_way_to_repair_it(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    a = ORIGIN.key("vessel1")
    path = tmp_path / "recording.mcap"
    write(path, [(a, i, origin(i, i / 1000)) for i in range(100)], chunk_size=2000)
    with open(path, "rb") as fh:
        chunk = sorted(make_reader(fh).get_summary().chunk_indexes,
                       key=lambda c: c.chunk_start_offset)[1]
    data = bytearray(path.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 40] = bytes(40)  # compressed bytes zeroed: zstd says it is corrupt
    path.write_bytes(bytes(data))
    with pytest.raises(reader.UnreadableRecordingError,
                       match=rf"recording.mcap: the chunk at byte {chunk.chunk_start_offset} is "
                             r"damaged .*seaway record recover"):
        reader.decode_vessel([path], "vessel1", [ORIGIN.suffix])
    assert gc.isenabled()  # paused while it decoded, running again after the error


def _fields(record: object) -> dict:
    return dict(vars(record))


@pytest.mark.parametrize("chunk_size", [0, 300, 1 << 20])
def test_the_summary_is_the_mcap_readers(tmp_path: Path, chunk_size: int) -> None:
    """``read_summary`` (chunk indexes by ``struct``) gives what the reader's ``get_summary`` gives:
    every schema, channel, statistic, chunk index, attachment and metadata index, field by field."""
    import random

    from mcap.reader import make_reader

    rng = random.Random(chunk_size)
    path = tmp_path / "r.mcap"
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=chunk_size)
        w.start()
        schemas = [w.register_schema(f"s{i}", "jsonschema", rng.randbytes(40)) for i in range(3)]
        topics = [w.register_channel(f"seaway/v/t{i}", "json", rng.choice(schemas), {"i": str(i)})
                  for i in range(12)]
        for k in range(2_000):
            w.add_message(rng.choice(topics), log_time=k * 1000 + rng.randint(0, 5000),
                          data=rng.randbytes(rng.randint(1, 120)), publish_time=k, sequence=k)
            if k % 500 == 0:
                w.add_attachment(k, k, f"a{k}.toml", "application/toml", rng.randbytes(64))
                w.add_metadata(f"m{k}", {"k": str(k)})
        w.finish()
    with open(path, "rb") as fh:
        theirs = make_reader(fh).get_summary()
        ours = reader.read_summary(fh)
    assert theirs is not None and ours is not None
    assert len(ours.chunk_indexes) == len(theirs.chunk_indexes) > (10 if chunk_size < 1000 else 0)
    assert [_fields(c) for c in ours.chunk_indexes] == [_fields(c) for c in theirs.chunk_indexes]
    assert _fields(ours.statistics) == _fields(theirs.statistics)
    for name in ("schemas", "channels"):
        mine, lib = getattr(ours, name), getattr(theirs, name)
        assert {k: _fields(v) for k, v in mine.items()} == {k: _fields(v) for k, v in lib.items()}
    for name in ("attachment_indexes", "metadata_indexes"):
        assert [_fields(r) for r in getattr(ours, name)] == [_fields(r) for r in getattr(theirs, name)]
    info = reader.read_info([path])  # attachments and metadata through those indexes
    assert sorted(info.attachments) == [f"a{k}.toml" for k in (0, 1000, 1500, 500)]
    assert info.metadata["m1500"] == {"k": "1500"}


def test_a_file_without_a_footer_is_refused_by_name(tmp_path: Path) -> None:
    path = tmp_path / "cut.mcap"
    write(path, [(ORIGIN.key("v1"), k, origin(k, 0.1)) for k in range(50)])
    path.write_bytes(path.read_bytes()[:-40])
    with open(path, "rb") as fh, pytest.raises(reader.McapError, match="footer"):
        reader.read_summary(fh)


def test_a_damaged_summary_is_named_with_the_way_to_repair_it(tmp_path: Path) -> None:
    """A summary record cut short (its schema's, then a chunk index's): the file is named, and how
    to repair it; nothing else escapes."""
    import struct

    path = tmp_path / "recording.mcap"
    write(path, [(ORIGIN.key("vessel1"), k, origin(k, 0.1)) for k in range(50)])
    whole = path.read_bytes()
    _, _, summary_start, _, _ = struct.unpack_from("<BQQQI", whole, len(whole) - 8 - 29)
    schema_at = summary_start  # the summary's first record: the repeated schema
    _, length = struct.unpack_from("<BQ", whole, schema_at)
    index_at = schema_at + 9 + length
    while whole[index_at] != 0x08:  # on to the first chunk index
        index_at += 9 + struct.unpack_from("<Q", whole, index_at + 1)[0]
    for at in (schema_at, index_at):
        data = bytearray(whole)
        data[at + 1:at + 9] = (3).to_bytes(8, "little")  # its record now 3 bytes long
        path.write_bytes(bytes(data))
        with pytest.raises(reader.UnreadableRecordingError,
                           match=r"recording.mcap: cannot read its summary .*seaway record recover"):
            reader.read_info([path])
        with pytest.raises(reader.UnreadableRecordingError, match="seaway record recover"):
            reader.decode_vessel([path], "vessel1", [ORIGIN.suffix])


def test_attachments_are_read_when_looked_up_not_when_listed(tmp_path: Path) -> None:
    # A recording carries its scenario's data and configs as attachments, which can be hundreds of
    # MB. Listing a recording (read_info) and finding its run, scenario and vessel read only the
    # few small documents wanted: here a 40 MB attachment is never read until asked for.
    import tracemalloc

    from seaway.recording import runinfo

    big = bytes(range(256)) * (40 * 4096)  # 40 MiB
    scenario = b'name = "s"\nseed = 1\nvessel = "paper-boat"\n[origin]\nlat_deg = 47.0\nlon_deg = 8.0\n'
    path = tmp_path / "r.mcap"
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start()
        ch = w.register_channel("seaway/v/nav/origin", "json", 0)
        w.add_message(ch, log_time=1, data=origin(1, 0.8), publish_time=1)
        w.add_attachment(1, 1, "scenario-data/grid.bin", "application/octet-stream", big)
        w.add_attachment(1, 1, "scenario/s.toml", "application/toml", scenario)
        w.finish()
    del w
    gc.collect()
    tracemalloc.start()
    try:
        info = reader.read_info([path])
        sc = runinfo.scenario_from_attachments(info.attachments)
        assert runinfo.vessel_from_attachments(info.attachments) is None
        assert runinfo.missions_from_attachments(info.attachments, None) == []
        peak_b = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert sc is not None and sc.name == "s"
    assert peak_b < 4 << 20, f"{peak_b / 2**20:.1f} MiB to list a recording and read its scenario"
    assert sorted(info.attachments) == ["scenario-data/grid.bin", "scenario/s.toml"]
    assert info.attachments.size_bytes["scenario-data/grid.bin"] == len(big)
    assert info.attachments["scenario-data/grid.bin"] == big  # read when asked for, whole
