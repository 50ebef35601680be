"""``seaway report`` and ``seaway replay`` on recordings a crash cut short (issue 14, item 4).

A recorder killed with SIGKILL leaves a file with no summary; the report used to die on it with a
traceback (``RecordLengthLimitExceeded``). Now a cut file, named alone or found in a run folder, is
read through its repaired copy, and the report says so; a file nothing can be rebuilt from is a
clear error that points to ``seaway record recover``.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from seaway.recording import recover
from seaway.recording.reader import finished
from seaway_recorder import report

GOLDEN = Path(__file__).resolve().parents[2] / "replay" / "data" / "lake-30s.mcap"


@pytest.fixture
def cut(tmp_path: Path) -> Path:
    """The replay golden recording cut in the middle, as a SIGKILL leaves it."""
    data = GOLDEN.read_bytes()
    path = tmp_path / "run" / "recording.mcap"
    path.parent.mkdir()
    path.write_bytes(data[: len(data) // 2])
    assert not finished(path)
    return path


def test_report_on_a_cut_file_reads_its_repaired_copy_and_says_so(cut: Path, tmp_path: Path,
                                                                  monkeypatch, capsys) -> None:
    monkeypatch.setenv(recover.ENV_REPAIR_DIR, str(tmp_path / "repairs"))
    assert report.main([str(cut), "--no-plots", "--out", str(cut.parent / "report")]) == 0
    out = capsys.readouterr().out
    assert "NOTE: recording.mcap was not finished" in out
    assert "read through the repaired copy" in out and "seaway record recover" in out
    doc = json.loads((cut.parent / "report" / "metrics.json").read_text())
    (line,) = doc["recording"]["repaired"]
    assert "messages kept" in line and doc["recording"]["messages"] > 100
    assert not finished(cut)  # the original is left as it was, and nothing is written beside it
    assert sorted(p.name for p in cut.parent.iterdir()) == ["recording.mcap", "report"]
    (copy,) = (tmp_path / "repairs").glob("*/recording.*.recovered.mcap")
    assert finished(copy)


def test_a_run_folder_after_a_recorder_restart_reports_both_files(cut: Path, capsys) -> None:
    # The restarted recorder's file beside the cut one (what the launcher leaves in the run folder).
    shutil.copy(GOLDEN, cut.with_name("recording.restart-001.mcap"))
    assert report.main([str(cut.parent), "--no-plots", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["files"]) == 2 and len(doc["recording"]["repaired"]) == 1
    assert doc["recording"]["duplicates"] > 0  # what both files hold is read once


def test_a_file_that_cannot_be_rebuilt_is_a_clear_error(tmp_path: Path, capsys) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    assert report.main([str(junk), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "junk.mcap: not finished, and nothing can be rebuilt from it" in err
    assert "Traceback" not in err


def test_the_report_of_a_cut_file_goes_beside_it_not_into_the_repair_cache(
        cut: Path, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv(recover.ENV_REPAIR_DIR, str(tmp_path / "repairs"))
    assert report.main([str(cut), "--no-plots"]) == 0
    assert (cut.parent / "report" / "metrics.json").is_file()
    assert not list((tmp_path / "repairs").glob("**/report"))
    assert report.main([str(cut.parent), "--no-plots"]) == 0  # a run folder: its report/ too
    assert sorted(p.name for p in cut.parent.iterdir()) == ["recording.mcap", "report"]
