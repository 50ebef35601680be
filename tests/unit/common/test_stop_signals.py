"""The services' stop signals (``seaway.runtime.service.install_stop_signals``, ``on_signals``): real
signals sent to real child processes (so this test process keeps its own handlers), for a stop, a
signal the kernel hands to a thread other than the main one, a signal inside the main thread's own
``stop.set()``, and the exit on a second Ctrl-C."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading

WAIT_S = 30.0
"""How long a child may take to say what it must: only a failing test waits this long."""

HEADER = """
import signal, sys, threading, time
from seaway.runtime.service import install_stop_signals, on_signals
stop = threading.Event()
install_stop_signals(stop)
"""


def _child(body: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", HEADER + body], stdout=subprocess.PIPE, text=True)


def _lines(proc: subprocess.Popen[str], n: int) -> list[str]:
    """The child's next ``n`` lines, or fewer if it says no more within WAIT_S (a hang)."""
    got: list[str] = []

    def read() -> None:
        assert proc.stdout is not None
        for _ in range(n):
            line = proc.stdout.readline()
            if not line:
                return
            got.append(line.strip())

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(WAIT_S)
    return list(got)


def _end(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def test_a_signal_sets_stop() -> None:
    proc = _child('print("ready", flush=True)\nstop.wait()\nprint("stopping", flush=True)\n')
    try:
        assert _lines(proc, 1) == ["ready"]
        proc.send_signal(signal.SIGTERM)
        assert _lines(proc, 1) == ["stopping"]
        assert proc.wait(WAIT_S) == 0
    finally:
        _end(proc)


def test_a_signal_delivered_to_another_thread_wakes_a_main_thread_waiting_for_good() -> None:
    """A process-directed signal may go to any thread (Zenoh's, a writer's). Python runs its
    handlers on the main thread between bytecodes, so a main thread blocked on ``stop.wait()``
    never ran one: 2 of 29 test responders sent SIGTERM went on waiting (2026-11-28). Here the signal
    goes to a sleeping thread on purpose (``pthread_kill``) while the main thread waits."""
    proc = _child("""
sleeper = threading.Thread(target=time.sleep, args=(600,), daemon=True)
sleeper.start()
def send() -> None:
    time.sleep(0.5)  # the main thread is inside stop.wait() by then (if not, this proves less)
    signal.pthread_kill(sleeper.ident, signal.SIGTERM)
threading.Thread(target=send, daemon=True).start()
stop.wait()
print("stopping", flush=True)
""")
    try:
        assert _lines(proc, 1) == ["stopping"], "the main thread never heard the signal"
        assert proc.wait(WAIT_S) == 0
    finally:
        _end(proc)


def test_a_signal_inside_stops_own_set_does_not_wait_on_its_lock() -> None:
    """The parent-death SIGTERM and a second SIGTERM: a handler that ran inside the first
    ``stop.set()`` (its lock held by the same thread) waited on that lock for good. Here the main
    thread holds the lock as ``set()`` holds it and signals itself: the signal's handler returns at
    once, and stop is set once the lock is free."""
    proc = _child("""
with stop._cond:  # as inside Event.set(): the lock is not reentrant
    signal.raise_signal(signal.SIGTERM)
    print("handler returned", flush=True)
print("stop set" if stop.wait(30) else "stop not set", flush=True)
""")
    try:
        assert _lines(proc, 2) == ["handler returned", "stop set"]
    finally:
        _end(proc)


def test_other_routed_signals_reach_their_own_act_and_do_not_stop() -> None:
    """The estimator's SIGUSR1 (re-initialise) goes through the same pipe, to its own act."""
    proc = _child("""
heard = threading.Event()
on_signals((signal.SIGUSR1,), lambda signum: heard.set())
print("ready", flush=True)
print("heard" if heard.wait(30) else "not heard", "stopped" if stop.is_set() else "running",
      flush=True)
""")
    try:
        assert _lines(proc, 1) == ["ready"]
        proc.send_signal(signal.SIGUSR1)
        assert _lines(proc, 1) == ["heard running"]
    finally:
        _end(proc)


def test_a_second_sigint_exits_a_stuck_stop_at_once() -> None:
    proc = _child("""
print("ready", flush=True)
stop.wait()
print("stopping", flush=True)
time.sleep(60)  # a stuck stop: only a second Ctrl-C ends it at once
""")
    try:
        assert _lines(proc, 1) == ["ready"]
        proc.send_signal(signal.SIGTERM)
        assert _lines(proc, 1) == ["stopping"]
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        assert proc.wait(WAIT_S) == 130
    finally:
        _end(proc)
