"""The services' stop signals (``seaway.runtime.service.install_stop_signals``): pure handler logic,
called directly as Python calls it, between two bytecodes of the main thread."""

from __future__ import annotations

import signal
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
    assert stop.is_set()


def test_a_second_signal_inside_the_first_set_does_not_wait_on_its_lock(handler) -> None:
    """The parent-death SIGTERM and a second SIGTERM: the second handler ran inside the first
    ``stop.set()`` (its flag set, its lock held by the same thread) and waited on that lock for good.
    Here the lock is held as ``set()`` holds it; the handler must return at once."""
    stop, h = handler
    done = threading.Event()

    def second_signal() -> None:
        with stop._cond:  # as inside Event.set(), after the flag: the lock is not reentrant
            stop._flag = True
            h(signal.SIGTERM, None)
            done.set()

    t = threading.Thread(target=second_signal, daemon=True)
    t.start()
    assert done.wait(5.0), "the second signal's handler waited on stop's own lock"
