"""``seaway.runtime.service.dump_stacks_on_signal``: a process asked where it is prints every
thread's stack and goes on (the launcher and every service register it)."""

from __future__ import annotations

import subprocess
import sys

PROGRAM = """
import os, threading
from seaway.runtime.service import STACKS_SIGNAL, dump_stacks_on_signal
dump_stacks_on_signal()
inside = threading.Event()
def parked_in_a_worker():
    inside.set()
    threading.Event().wait(30)
threading.Thread(target=parked_in_a_worker, daemon=True).start()
inside.wait(30)
os.kill(os.getpid(), STACKS_SIGNAL)
print("still running")
"""


def test_the_signal_prints_every_threads_stack_and_the_process_goes_on() -> None:
    out = subprocess.run([sys.executable, "-c", PROGRAM], capture_output=True, text=True,
                         timeout=60, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "still running"
    assert out.stderr.count("most recent call first") >= 2, out.stderr  # main and the worker
    assert "parked_in_a_worker" in out.stderr
