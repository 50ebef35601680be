"""``seaway record recover`` (and the repaired copies readers make) on damage other than a cut: a
chunk that does not decompress is skipped by its length, counted and named by the byte it starts
at, and everything after it kept; files joined one after another are each copied in turn."""

from __future__ import annotations

import os
from pathlib import Path

from mcap.reader import make_reader
from seaway.recording import reader
from seaway.recording.recover import recover
from seaway_recorder import main as recorder_main

from tests.unit.common.test_recording_damage import middle_chunk, write


def zero_chunk(path: Path) -> int:
    """Zero the middle chunk's compressed bytes (zstd says corrupt); its start [byte]."""
    start, length = middle_chunk(path)
    data = bytearray(path.read_bytes())
    data[start + length - 30:start + length - 10] = bytes(20)
    path.write_bytes(bytes(data))
    return start


def recover_metadata(path: Path) -> dict[str, str]:
    with open(path, "rb") as fh:
        return {m.name: dict(m.metadata) for m in make_reader(fh).iter_metadata()}["seaway.recover"]


def test_a_damaged_chunk_is_skipped_and_the_rest_kept(tmp_path: Path) -> None:
    src = tmp_path / "recording.mcap"
    data = write(src)
    with open(src, "rb") as fh:
        chunks = len(make_reader(fh).get_summary().chunk_indexes)
    start = zero_chunk(src)
    fixed = tmp_path / "fixed.mcap"
    res = recover(src, fixed)
    got = [m.data for m in reader.iter_messages([fixed])]
    lost = [d for d in data if d not in got]
    assert 0 < len(lost) < 10 and got == [d for d in data if d not in lost]
    assert got[-1] == data[-1]  # the chunks after the damaged one are kept
    assert (res.bad_chunks, res.bad_chunk_offsets, res.chunks) == (1, [start], chunks - 1)
    assert not res.complete and f"byte {start}" in res.reason
    meta = recover_metadata(fixed)
    assert (meta["bad_chunks"], meta["bad_chunk_offsets"], meta["complete"]) == ("1", str(start),
                                                                                 "false")
    assert f"byte {start}" in meta["reason"]


def test_the_command_says_what_it_skipped(tmp_path: Path, capsys) -> None:
    src = tmp_path / "recording.mcap"
    write(src)
    start = zero_chunk(src)
    assert recorder_main.main(["recover", str(src), str(tmp_path / "fixed.mcap")]) == 0
    out = capsys.readouterr().out
    assert f"chunk at byte {start}" in out and '"complete": false' in out


def test_a_cut_file_with_a_damaged_chunk_is_read_past_it(tmp_path: Path, monkeypatch) -> None:
    """The repaired copy a reader makes of a cut file: the chunks after a damaged one are in it."""
    monkeypatch.setenv("SEAWAY_REPAIR_DIR", str(tmp_path / "repairs"))
    src = tmp_path / "recording.mcap"
    data = write(src)
    start = zero_chunk(src)
    whole = src.read_bytes()
    src.write_bytes(whole[:len(whole) - 200])  # cut in its summary: every chunk is there
    (copy,) = reader.open_paths([src])
    got = [m.data for m in reader.iter_messages([copy])]
    assert got[-1] == data[-1] and len(got) < len(data)
    info = reader.read_info([copy])
    (line,) = reader.repaired(info)
    assert f"byte {start}" in line


def test_joined_files_are_each_copied(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    first, second = write(a, 20), write(b, 60, first=1000)
    joined = tmp_path / "joined.mcap"
    joined.write_bytes(a.read_bytes() + b.read_bytes())
    fixed = tmp_path / "fixed.mcap"
    res = recover(joined, fixed)
    assert [m.data for m in reader.iter_messages([fixed])] == first + second
    assert res.recordings == 2 and res.messages == 80 and "2 recordings" in res.reason
    with open(fixed, "rb") as fh:  # the second recording's channel is the first's
        assert len(make_reader(fh).get_summary().channels) == 1
    assert recover_metadata(fixed)["recordings"] == "2"


def test_a_cut_recording_followed_by_another_keeps_both_and_is_not_complete(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    first, second = write(a, 60), write(b, 60, first=1000)
    start, length = middle_chunk(a)
    joined = tmp_path / "joined.mcap"
    joined.write_bytes(a.read_bytes()[:start + length // 2] + b.read_bytes())
    res = recover(joined, tmp_path / "fixed.mcap")
    got = [m.data for m in reader.iter_messages([tmp_path / "fixed.mcap"])]
    kept = got[:len(got) - len(second)]
    assert got[len(kept):] == second and kept == first[:len(kept)] and 0 < len(kept) < 60
    assert res.recordings == 2 and not res.complete and f"byte {start}" in res.reason


def test_a_file_cut_by_a_power_loss_keeps_every_chunk_before_its_tail(tmp_path: Path) -> None:
    """After a power loss a file may end in zeros (its size grew before its data reached the disk)
    or in junk (blocks never written): every whole chunk before is kept, the tail said, not read."""
    src = tmp_path / "recording.mcap"
    data = write(src)
    start, _ = middle_chunk(src)
    whole = src.read_bytes()[:start]  # up to the middle chunk: the chunks before it are whole
    for name, tail in (("zeros", bytes(65536)), ("junk", os.urandom(65536))):
        cut = tmp_path / f"{name}.mcap"
        cut.write_bytes(whole + tail)
        res = recover(cut, tmp_path / f"{name}-fixed.mcap")
        got = [m.data for m in reader.iter_messages([tmp_path / f"{name}-fixed.mcap"])]
        assert got and got == data[:len(got)], name  # nothing from the tail, nothing out of order
        assert len(got) >= len(data) // 2 - 10, (name, len(got))
        assert not res.complete and str(start) in res.reason, (name, res.reason)
