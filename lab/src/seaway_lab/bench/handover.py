"""``seaway bench handover``: what one lockstep hand-over costs at the least, in CPU, on this machine.

A lockstep period is three hand-overs in a row (sim -> estimator -> controller -> sim), each a put
in one process and a receive in others, and every bundle also goes to the recorder and the
launcher. This bench measures those two operations alone, with nothing else running: processes of
their own on the stack's Zenoh (``zenoh_bus.ZenohBus``: a peer on loopback, one Zenoh thread per
process as in a lockstep stack, ``zenoh_bus.use_lockstep_runtime``; the members' express, blocking
publisher), a payload the size of a bundle put every ``--interval-ms`` (paced like periods, not a
flood), and each process's CPU time (all its threads, ``time.process_time``) over the timed
messages, divided by their number. Cases, each on processes started for it:

* a put from a Python thread that is not Zenoh's (as the sim's loop publishes), heard by one
  listener and by three (the sim's bundle goes to the estimator, the controller, the recorder and
  the launcher); less the same loop putting to nobody, so the pacing is not counted;
* a put from Zenoh's own thread, inside the callback of the message that moves the process on (as
  the estimator and the controller answer): a relay's CPU per message with the put, less without;
* a receive through a ring (no Python per message: a passive source, the launcher's watch) and
  through a Python callback on Zenoh's thread (an active source).

The hand-over at the least is a relay's put plus a callback's receive; three of them are the
least the transport adds to a lockstep period before any service does anything (compare
``seaway bench lockstep``'s periods through the processes and composed). With authentication on (the stack's
mutual TLS, a fresh authority) and off, alternating; medians over ``--repeat`` rounds each.
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing as mp
import os
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from seaway.runtime import zenoh_bus
from seaway.runtime.argtypes import positive_float, whole_number
from seaway.runtime.credentials import ENV_CREDENTIALS, ENV_IDENTITY, NONE
from seaway.vessel.metrics import median

from seaway_lab.bench.common import BenchResult, bench_credentials, free_port, restored_environ

VESSEL = "bench"
KEY_OUT = "seaway/bench/handover/out"
KEY_IN = "seaway/bench/handover/in"
WARMUP = 200
"""Messages put before the timed ones, once every process hears them (caches warm)."""
FIRST_WITHIN_S = 30.0
"""How long the peers may take to find each other (gossip) and declare, before a bench process
that has heard nothing is an error."""
DRAIN_S = 0.02
"""How often a ring listener takes what its ring holds (Python wakes 50 times a second, as the
launcher's poll; the ring holds ``RING`` meanwhile)."""
RING = 4096
GO_S = 0.2
"""Between the go and the first timed put: every bench process has started counting."""


def _connect(port: int) -> Any:
    return zenoh_bus.ZenohBus.connect(VESSEL, rendezvous=f"tcp/127.0.0.1:{port}")


def _quiet() -> None:
    """A bench process's own: authentication off is half of the comparison, asked for, not worth a
    warning from every session it opens."""
    zenoh_bus.log.setLevel(logging.ERROR)


def _listener(conn: Connection, port: int, kind: str) -> None:
    """Hear ``KEY_OUT`` through a ring or a callback; report CPU and messages between go and stop."""
    _quiet()
    bus = _connect(port)
    heard = [0]
    stop, first = threading.Event(), threading.Event()
    if kind == "callback":
        def on_out(_s: Any) -> None:
            heard[0] += 1
            first.set()
        bus.subscribe_raw(KEY_OUT, on_out, inline=True)
    else:
        ring = bus.ring_raw(KEY_OUT, RING)

        def drain() -> None:
            while not stop.wait(DRAIN_S):
                while ring.take() is not None:
                    heard[0] += 1
                    first.set()
        threading.Thread(target=drain, daemon=True).start()
    _serve(conn, heard, first, stop)
    bus.close()


def _relay(conn: Connection, port: int, put: bool, payload_bytes: int) -> None:
    """Hear ``KEY_IN`` through a callback on Zenoh's thread, and in it put on ``KEY_OUT`` (``put``)."""
    _quiet()
    bus = _connect(port)
    pub = bus.raw_publisher(KEY_OUT, block=True, express=True)
    payload = b"x" * payload_bytes
    heard = [0]
    first = threading.Event()

    def on_in(_s: Any) -> None:
        heard[0] += 1
        if put:
            pub.put(payload)
        first.set()
    bus.subscribe_raw(KEY_IN, on_in, inline=True)
    _serve(conn, heard, first, threading.Event())
    bus.close()


def _serve(conn: Connection, heard: list[int], first: threading.Event, stop: threading.Event) -> None:
    """The bench process's side: "first" once it heard something, then its CPU and the messages it
    heard between the parent's go and stop."""
    if first.wait(FIRST_WITHIN_S):
        conn.send("first")
    conn.recv()  # go: the warm-up's last messages may still be in a ring, taken within DRAIN_S
    time.sleep(2 * DRAIN_S)  # (the parent waits GO_S before its first timed put)
    c0, n0 = time.process_time(), heard[0]
    conn.recv()  # stop
    time.sleep(2 * DRAIN_S)  # a ring's last messages taken
    c1, n1 = time.process_time(), heard[0]
    stop.set()
    conn.send({"cpu_s": c1 - c0, "timed": n1 - n0})
    conn.recv()  # close


def _case(port: int, children: list[tuple[Callable[..., None], tuple[Any, ...]]], key: str,
          messages: int, interval_s: float, payload_bytes: int) -> tuple[float, list[dict[str, Any]]]:
    """Start ``children`` (each ``fn(conn, port, *args)``); put on ``key`` from this process's own
    thread, paced, until every child heard something, then ``WARMUP`` more and ``messages`` timed
    ones; this process's CPU per timed put [s], and each child's report. Raises if a child heard
    nothing, or not every timed message."""
    ctx = mp.get_context("spawn")
    links, procs = [], []
    bus = _connect(port)  # first: it holds the rendezvous
    try:
        for fn, args in children:
            ours, theirs = ctx.Pipe()
            p = ctx.Process(target=fn, args=(theirs, port, *args), daemon=True)
            p.start()
            links.append(ours)
            procs.append(p)
        pub = bus.raw_publisher(key, block=True, express=True)
        payload = b"x" * payload_bytes
        waiting, deadline = set(range(len(links))), time.monotonic() + 60.0 + FIRST_WITHIN_S
        while waiting:  # started, found each other, heard: a process may take seconds to start
            if time.monotonic() > deadline or not all(procs[i].is_alive() for i in waiting):
                raise RuntimeError(f"{len(waiting)} of {len(links)} bench processes heard nothing")
            pub.put(payload)
            time.sleep(max(interval_s, 0.005))
            waiting = {i for i in waiting if not (links[i].poll(0) and links[i].recv() == "first")}
        for _ in range(WARMUP):
            pub.put(payload)
            time.sleep(interval_s)
        for link in links:
            link.send("go")
        time.sleep(GO_S)
        c0 = time.process_time()
        for _ in range(messages):
            pub.put(payload)
            time.sleep(interval_s)
        own = (time.process_time() - c0) / messages
        time.sleep(0.1)
        reports = []
        for link in links:
            link.send("stop")
            reports.append(link.recv())
        for link in links:
            link.send("close")
        for r in reports:
            if r["timed"] != messages:
                raise RuntimeError(f"a bench process heard {r['timed']} of the {messages} timed "
                                   "messages: the figures would not be per message")
            r["cpu_per_msg_s"] = r["cpu_s"] / messages
        return own, reports
    finally:
        for p in procs:
            p.join(10.0)
            if p.is_alive():
                p.kill()
        bus.close()


def measure(messages: int, interval_s: float, payload_bytes: int) -> dict[str, float]:
    """One round of every case (in this process's environment: authentication as it says); the
    figures [us per message]."""
    us = 1e6

    def case(children: list[tuple[Callable[..., None], tuple[Any, ...]]],
             key: str = KEY_OUT) -> tuple[float, list[dict[str, Any]]]:
        return _case(free_port(), children, key, messages, interval_s, payload_bytes)

    alone, _ = case([])
    one, (ring,) = case([(_listener, ("ring",))])
    three, _ = case([(_listener, ("ring",))] * 3)
    _, (callback,) = case([(_listener, ("callback",))])
    _, (relay_put, _) = case([(_relay, (True, payload_bytes)), (_listener, ("ring",))], KEY_IN)
    _, (relay_idle,) = case([(_relay, (False, payload_bytes))], KEY_IN)
    put_thread = one - alone
    put_zenoh = relay_put["cpu_per_msg_s"] - relay_idle["cpu_per_msg_s"]
    receive_cb = callback["cpu_per_msg_s"]
    return {
        "put_from_python_thread_us": us * put_thread,
        "put_from_python_thread_3_listeners_us": us * (three - alone),
        "per_extra_listener_sender_us": us * (three - one) / 2,
        "put_from_zenoh_thread_us": us * put_zenoh,
        "receive_ring_us": us * ring["cpu_per_msg_s"],
        "receive_callback_us": us * receive_cb,
        "handover_least_us": us * (put_zenoh + receive_cb),
        "three_handovers_least_ms": 1e3 * 3 * (put_zenoh + receive_cb),
    }


def measure_rounds(repeat: int, messages: int, interval_s: float, payload_bytes: int,
                   auths: tuple[bool, ...] = (True, False)) -> dict[bool, list[dict[str, float]]]:
    """``repeat`` rounds of ``measure`` per authentication setting in ``auths`` (on: a fresh
    authority's mutual TLS, as a stack runs; off), alternating; this process's environment and
    logging as they were after. Call it before this process opens any Zenoh session of its own:
    the sessions here run Zenoh on one thread, as a lockstep stack's, and Zenoh reads that once."""
    creds = bench_credentials() if True in auths else {}
    rounds: dict[bool, list[dict[str, float]]] = {a: [] for a in auths}
    level = zenoh_bus.log.level
    with restored_environ(ENV_CREDENTIALS, ENV_IDENTITY, zenoh_bus.ENV_RUNTIME):
        # Before this process's first session (Zenoh reads it once), and for its children.
        zenoh_bus.use_lockstep_runtime()
        _quiet()
        try:
            for _ in range(repeat):
                for auth in auths:
                    os.environ.update(creds if auth else {ENV_CREDENTIALS: NONE,
                                                          ENV_IDENTITY: "harness"})
                    rounds[auth].append(measure(messages, interval_s, payload_bytes))
        finally:
            zenoh_bus.log.setLevel(level)  # the caller's (a test's) logging as it was
    return rounds


LABELS = {
    "put_from_python_thread_us": "a put from a Python thread, one listener [us CPU]: as the sim's "
                                 "loop publishes (less the same loop putting to nobody)",
    "put_from_python_thread_3_listeners_us": "the same, three listeners [us CPU]",
    "per_extra_listener_sender_us": "each further listener, in the sender [us CPU]",
    "put_from_zenoh_thread_us": "a put from Zenoh's thread, in the callback, one listener [us CPU]: "
                                "as the estimator and the controller answer",
    "receive_ring_us": "a receive into a ring, no Python [us CPU]: a passive source, the launcher",
    "receive_callback_us": "a receive into a Python callback on Zenoh's thread [us CPU]: an active "
                           "source",
    "handover_least_us": "a hand-over at the least [us CPU]: a put from Zenoh's thread and a "
                         "receive into a callback",
    "three_handovers_least_ms": "three hand-overs, a lockstep period's chain [ms CPU]: the least "
                                "the transport adds to a period",
}
"""Figure (JSON name) -> what it is, with its unit."""


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench handover", description=__doc__.split("\n\n")[0])
    ap.add_argument("--messages", type=whole_number(100), default=3000,
                    help="timed messages per case (>= 100)")
    ap.add_argument("--interval-ms", type=positive_float, default=0.5,
                    help="pause between two puts [ms] (a lockstep period's pace)")
    ap.add_argument("--payload-bytes", type=whole_number(1, 1 << 20), default=2000,
                    help="bytes per message (a lockstep bundle is 1-3 KB)")
    ap.add_argument("--repeat", type=whole_number(1), default=2,
                    help="rounds with authentication on and off each, alternating (medians)")
    args = ap.parse_args(argv)
    rounds = measure_rounds(args.repeat, args.messages, args.interval_ms / 1e3, args.payload_bytes)
    on = {k: median([r[k] for r in rounds[True]]) for k in LABELS}
    off = {k: median([r[k] for r in rounds[False]]) for k in LABELS}
    res = BenchResult("handover", "A lockstep hand-over at the least: the CPU of a put and of a "
                                  "receive on the stack's Zenoh, nothing else running")
    for k, what in LABELS.items():
        res.add(k, on[k], note=f"{what}; auth off {off[k]:.4g}")
    ratios = {k: on[k] / off[k] if off[k] > 0 else float("nan") for k in LABELS}
    # No target on the ratio: issue 15's (within 10 %) is a stack's, `seaway bench lockstep`'s;
    # here it is what TLS adds to one message, with nothing else to spread it over.
    res.add("auth_on_off_handover_least", ratios["handover_least_us"],
            note="authentication on / off, a hand-over at the least")
    res.sections.update(auth_on=on, auth_off=off, auth_overhead_ratio=ratios)
    res.meta.update(messages_per_case=args.messages, interval_ms=args.interval_ms,
                    payload_bytes=args.payload_bytes, rounds_each=args.repeat,
                    cpus=len(os.sched_getaffinity(0)))
    return res
