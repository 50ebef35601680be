"""``seaway.runtime.atomic.LatestWriter``: a durable file written off the caller's thread, the latest
text only, errors reported and survived, what is pending written at close."""

from __future__ import annotations

import os
import threading

import pytest
from seaway.runtime import atomic


def test_writes_durably_off_the_callers_thread_and_the_caller_never_waits(tmp_path, monkeypatch
                                                                         ) -> None:
    path = tmp_path / "state.json"
    gate, writing, threads, synced = threading.Event(), threading.Event(), [], []
    real_write = atomic.write_text

    def slow_write(p, text, durable=True):  # a disk that takes its time (an fsync behind a big write)
        threads.append(threading.current_thread().name)
        writing.set()
        assert gate.wait(10)
        real_write(p, text, durable)

    monkeypatch.setattr(atomic, "write_text", slow_write)
    real_fsync = os.fsync
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: synced.append(fd) or real_fsync(fd))
    w = atomic.LatestWriter(path, on_error=pytest.fail, name="checkpoint")
    w.submit("A")
    assert writing.wait(10)  # A is being written, and stays so until the gate opens
    w.submit("B")  # these return although the disk has not taken A: the caller does not wait
    w.submit("C")
    assert not w.flush(0.05)
    gate.set()
    assert w.flush(10)
    assert path.read_text() == "C"  # the latest; B, given while A was written, was never written
    assert w.written == 2 and threads == ["checkpoint", "checkpoint"]
    assert len(synced) == 2  # each write was fsynced: durable
    assert w.close()


def test_a_failed_write_is_reported_and_the_next_text_is_written(tmp_path, monkeypatch) -> None:
    path = tmp_path / "state.json"
    errors: list[OSError] = []
    real_write = atomic.write_text
    fail = [True]

    def flaky(p, text, durable=True):
        if fail[0]:
            fail[0] = False
            raise OSError(28, "No space left on device")
        real_write(p, text, durable)

    monkeypatch.setattr(atomic, "write_text", flaky)
    w = atomic.LatestWriter(path, on_error=errors.append)
    w.submit("first")
    assert w.flush(10)
    assert [e.strerror for e in errors] == ["No space left on device"] and not path.exists()
    w.submit("second")
    assert w.flush(10) and path.read_text() == "second" and w.written == 1
    w.close()


def test_close_writes_what_is_pending_and_then_takes_no_more(tmp_path, monkeypatch) -> None:
    path = tmp_path / "state.json"
    gate = threading.Event()
    real_write = atomic.write_text

    def slow_write(p, text, durable=True):
        assert gate.wait(10)
        real_write(p, text, durable)

    monkeypatch.setattr(atomic, "write_text", slow_write)
    w = atomic.LatestWriter(path, on_error=pytest.fail)
    w.submit("one")
    w.submit("last")
    threading.Timer(0.05, gate.set).start()
    assert w.close(10)
    assert path.read_text() == "last"
    with pytest.raises(RuntimeError, match="writer closed"):
        w.submit("late")
    assert atomic.LatestWriter(tmp_path / "never.json", on_error=pytest.fail).close()  # never used
