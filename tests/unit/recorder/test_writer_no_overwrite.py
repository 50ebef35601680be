"""A recorder restarted into the same run folder never overwrites the earlier recording."""

from pathlib import Path

from seaway_recorder.core import free_path


def test_free_path_keeps_existing_files_and_sorts_after_them(tmp_path: Path) -> None:
    base = tmp_path / "recording.mcap"
    assert free_path(base) == base
    base.write_bytes(b"first run")
    first = free_path(base)
    assert first.name == "recording.restart-001.mcap"
    first.write_bytes(b"after a restart")
    second = free_path(base)
    assert second.name == "recording.restart-002.mcap"
    rotated_next = tmp_path / "recording-001.mcap"
    names = sorted(p.name for p in (base, first, second))
    assert names == ["recording.mcap", "recording.restart-001.mcap", "recording.restart-002.mcap"]
    assert sorted([(tmp_path / "recording-000.restart-001.mcap").name, rotated_next.name,
                   "recording-000.mcap"]) == ["recording-000.mcap", "recording-000.restart-001.mcap",
                                              "recording-001.mcap"]
    assert base.read_bytes() == b"first run"
