"""The run's logs as the recorder copies them, when they are absurd: a line dated in month 13, in the
year 9999 or before 1970, a line of megabytes (or binary garbage) without a newline, a file
truncated or replaced under the tail, a folder of thousands of files, a file that cannot be
opened. Every line is still recorded, the recording validates, memory and file descriptors stay
bounded, and nothing raises into the recorder's loop (which would stop the recording)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
from seaway.contract.messages import LogRecord
from seaway_recorder import logtail
from seaway_recorder.core import RecordingWriter
from seaway_recorder.logtail import MAX_LINE_BYTES, MAX_LINE_CHARS, FileTail, LogTail, parse_line
from seaway_recorder.node import Tails

from tests.unit.recorder.foxglove_check import foxglove_messages

GOOD = "2026-05-01 09:00:00,250 sim INFO seaway.sim: started"


@pytest.mark.parametrize("stamp", ["2026-13-45 99:99:99,000", "0000-01-01 00:00:00,000",
                                   "0001-01-01 00:00:00,000", "1900-01-01 00:00:00,000",
                                   "2300-01-01 00:00:00,000", "9999-12-31 23:59:59,999"])
def test_a_line_dated_impossibly_is_recorded_whole_at_the_time_before_it(
        tmp_path: Path, stamp: str) -> None:
    bad = f"{stamp} sim ERROR seaway.sim: boom"
    line = parse_line(bad)
    assert (line.wall_ns, line.message) == (None, bad)  # the whole text, no made-up time
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "sim.log").write_text(f"{GOOD}\n{bad}\n")
    w = RecordingWriter(tmp_path / "r.mcap")
    w.open(1)
    published: list[LogRecord] = []
    tails = Tails(None, LogTail([str(logs)]), published.append)
    tails.copy(w)  # raised before: the loop stopped and the file was left unfinished
    tails.close()
    w.close(2)
    assert w.stats.logs == 2
    got = [(t, m) for topic, _, t, m in foxglove_messages(tmp_path / "r.mcap") if topic == "foxglove/log"]
    assert [m.message for _, m in got] == ["seaway.sim: started", bad]
    assert got[1][0] == got[0][0]  # the time of the line before it
    assert [r.message for r in published] == ["started", bad]


def test_a_line_without_a_newline_is_held_bounded_then_recorded_cut(tmp_path: Path) -> None:
    path = tmp_path / "x.log"
    path.write_bytes(b"")
    tail = LogTail([str(path)])
    chunk = b"\xff\x00garbage" * 100_000  # 1 MB of binary garbage, no newline
    with open(path, "ab") as f:
        for k in range(20):
            f.write(chunk)
            f.flush()
            assert tail.poll(k) == []
            _, ft = tail._tails[str(path)]
            assert len(ft._partial) <= MAX_LINE_BYTES  # 20 MB before, copied at every look
        f.write(b"\nnext\n")
    lines = [line.message for _, line in tail.poll(99)]
    tail.close()
    assert lines[1] == "next"
    cut = lines[0]
    assert len(cut) <= MAX_LINE_CHARS + 60
    assert f"{20 * len(chunk) - MAX_LINE_BYTES} more bytes" in cut
    LogRecord.make(stamp_ns=1, process="x", level="", logger="", message=cut)  # fits the bus too


def test_a_long_backlog_is_read_over_several_looks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(logtail, "READ_BYTES", 1000)
    path = tmp_path / "x.log"
    path.write_bytes(b"".join(b"line %05d\n" % i for i in range(1000)))  # 11 kB
    tail = LogTail([str(path)])
    looks = []
    while len(looks) < 100 and (got := tail.poll(0)):
        looks.append(len(got))
    tail.close()
    assert sum(looks) == 1000 and max(looks) <= 100


def test_a_truncated_log_is_read_again_from_its_start(tmp_path: Path) -> None:
    path = tmp_path / "sim.log"
    path.write_text("a\nb\n")
    tail = FileTail(path)
    assert tail.poll() == [b"a", b"b"]
    path.write_text("c\n")  # logrotate's copytruncate, or ': > sim.log'
    assert tail.poll() == [b"c"]  # before: nothing, ever again
    assert tail.restarts == 1
    tail.close()


def test_a_replaced_log_is_read_from_the_new_files_start(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(logtail, "CHECK_NS", 0)
    path = tmp_path / "sim.log"
    path.write_text("a\n")
    tail = FileTail(path)
    assert tail.poll() == [b"a"]
    with open(path, "a") as f:
        f.write("b\npart")
    os.rename(path, tmp_path / "sim.log.1")  # logrotate's rename, then a new file
    path.write_text("new\n")
    assert tail.poll() == [b"b"]  # what the old file still had first
    assert tail.poll() == [b"part", b"new"]  # the cut line ends there; then the new file
    tail.close()


def test_thousands_of_log_files_do_not_use_up_file_descriptors(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    n = logtail.MAX_OPEN_FILES + 500
    for i in range(n):
        (logs / f"p{i:04d}.log").write_text(f"hello {i}\n")
    before = len(os.listdir("/proc/self/fd"))
    tail = LogTail([str(logs)])
    assert len(tail.poll(0)) == n
    assert len(os.listdir("/proc/self/fd")) - before <= logtail.MAX_OPEN_FILES + 5
    with open(logs / f"p{n - 1:04d}.log", "a") as f:  # a file past those kept open still tails
        f.write("again\n")
    assert [(p, line.message) for p, line in tail.poll(1)] == [(f"p{n - 1:04d}", "again")]
    tail.close()


def test_a_log_that_cannot_be_opened_is_tried_again_not_raised(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "sim.log"
    path.write_text("a\n")
    tail = FileTail(path)
    real_open = open

    def no_fd(*args: object, **kwargs: object) -> object:
        raise OSError(errno.EMFILE, "Too many open files")

    monkeypatch.setattr("builtins.open", no_fd)
    assert tail.poll() == []  # raised before: the recorder's node took it for a failed write
    monkeypatch.setattr("builtins.open", real_open)
    assert tail.poll() == [b"a"]
    tail.close()
