"""The services' stop signals (``seaway.runtime.service.install_stop_signals``): the handler, called
directly as Python calls it (between two bytecodes of the main thread), and a real process sent
real signals for the exit on a second Ctrl-C."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading

import pytest
from seaway.runtime.service import install_stop_signals


@pytest.fixture
def handler():
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    stop = threading.Event()
    install_stop_signals(stop)
    yield stop, signal.getsignal(signal.SIGTERM)
    for s, h in saved.items():
        signal.signal(s, h)


def test_a_signal_sets_stop(handler) -> None:
    stop, h = handler
    h(signal.SIGTERM, None)
    assert stop.wait(5.0)


@pytest.mark.parametrize("flag_set", [True, False], ids=["after-the-flag", "before-the-flag"])
def test_a_signal_inside_stops_own_set_does_not_wait_on_its_lock(handler, flag_set: bool) -> None:
    """The parent-death SIGTERM and a second SIGTERM: the second handler ran inside the first
    ``stop.set()`` (its lock held by the same thread) and waited on that lock for good. Here the
    lock is held as ``set()`` holds it, the flag set or not yet; the handler must return at once,
    and stop is set once the lock is free."""
    stop, h = handler
    done = threading.Event()

    def second_signal() -> None:
        with stop._cond:  # as inside Event.set(): the lock is not reentrant
            stop._flag = flag_set
            h(signal.SIGTERM, None)
            done.set()

    t = threading.Thread(target=second_signal, daemon=True)
    t.start()
    assert done.wait(5.0), "the signal's handler waited on stop's own lock"
    assert stop.wait(5.0)


CHILD = """
import sys, threading, time
from seaway.runtime.service import install_stop_signals
stop = threading.Event()
install_stop_signals(stop)
print("ready", flush=True)
stop.wait()
print("stopping", flush=True)
time.sleep(60)  # a stuck stop: only a second Ctrl-C ends it at once
"""


def test_a_second_sigint_exits_a_stuck_stop_at_once() -> None:
    proc = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        proc.send_signal(signal.SIGTERM)
        assert proc.stdout.readline().strip() == "stopping"
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30.0) == 130
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
