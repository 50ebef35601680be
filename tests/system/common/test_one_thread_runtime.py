"""A process on the one-thread Zenoh runtime of lockstep stacks can publish, from a callback on that
thread, everything a lockstep member's repeat sends (``zenoh_bus.LOCKSTEP_TX_QUEUE``).

On one thread nothing is sent while a callback runs, and each express put holds a batch of the
link's queue until it returns: with Zenoh's default queue the third put of a callback waited for
ever. A member repeating three bundles for a restarted recorder stopped that way, its health token
lapsed and the stack stalled. Real processes, real sessions, the stack's own TLS credentials.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep_member import KEPT_BUNDLES
from seaway.runtime.zenoh_bus import ENV_RUNTIME, LOCKSTEP_RUNTIME, LOCKSTEP_TX_QUEUE

from tests.conftest import wait_for

pytestmark = pytest.mark.system
PUTS = 2 * KEPT_BUNDLES + 2  # two repeats' kept bundles (one intake can take both), two answers
TRIGGER, OUT = "seaway/vessel1/test/trigger", "seaway/vessel1/test/out"

# The member side, as ``lockstep.Member`` publishes: an express, blocking publisher, and the puts
# made inside a callback that Zenoh runs on its own (only) thread.
CHILD = textwrap.dedent(f"""
    import sys, threading
    from seaway.runtime.zenoh_bus import ZenohBus
    bus = ZenohBus.open("vessel1")
    pub = bus.raw_publisher({OUT!r}, block=True, express=True)
    done = threading.Event()
    def on_trigger(sample):
        for i in range({PUTS}):
            pub.put(b"%d " % i + b"x" * 3000)  # about a bundle of the sim's
        done.set()
    bus.subscribe_raw({TRIGGER!r}, on_trigger, inline=True)
    print("READY", flush=True)
    print("DONE" if done.wait(60) else "BLOCKED", flush=True)
""")


def test_the_lockstep_queue_holds_a_repeat_and_an_answer() -> None:
    assert PUTS <= LOCKSTEP_TX_QUEUE


def test_a_callback_on_the_one_zenoh_thread_publishes_a_whole_repeat(zenoh_env) -> None:
    env = {**zenoh_env, ENV_RUNTIME: LOCKSTEP_RUNTIME}
    child = subprocess.Popen([sys.executable, "-c", CHILD], env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "READY"
        got: list[bytes] = []
        with Bus.open("vessel1") as bus:
            bus.subscribe_raw(OUT, lambda s: got.append(s.payload))
            trigger = bus.raw_publisher(TRIGGER)
            # Until the child's callback ran (the first trigger can precede its subscriber's
            # declaration reaching this session), then until every put arrived.
            wait_for(lambda: got or trigger.put(b"go"), 30, interval_s=0.2,
                     what="the first put of the child's callback")
            wait_for(lambda: len(got) >= PUTS, 30, what=f"{PUTS} puts from one callback")
        out, _ = child.communicate(timeout=90)
        assert out.split() == ["DONE"], out
        assert [int(p.split()[0]) for p in got[:PUTS]] == list(range(PUTS))
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
