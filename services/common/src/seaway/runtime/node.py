"""The node runtime: what a service declares, and the one driver per clock that runs it.

A service is a node: a pure core, and around it a small class that says what it hears, what it
publishes and what one period's work is. The runtime drives it; the service never sees the bus's
threads, the lockstep protocol (``seaway.runtime.lockstep``) or the rate loop::

    class EchoNode:                                   # a node of service "echo"
        name = "echo"
        member = MemberSpec("echo", needs=("sim",), inputs=frozenset({"sim/truth"}))
        live_inputs = (keys.SIM_TRUTH,)

        def take(self, key, msg, now_ns):             # an input, stamp already bounded
            self.last = msg
        def answer(self, at):                         # lockstep: period at.period answered
            return Answer([(keys.NAV_STATE, estimate_from(self.last, at.period.stamp_ns))])
        def tick(self, now_ns, out):                  # real time: every period of the wall clock
            out.put(keys.NAV_STATE, estimate_from(self.last, now_ns))

    from seaway.runtime.runner import run_node       # the one entry point, above the drivers

    with run_service("echo", args) as ctx:
        run_node(ctx, EchoNode(), period_s=0.1)      # lockstep or real time: the run says which

Modes:

* **real time** (``LiveDriver``): each of ``live_inputs`` is subscribed and handed to ``take`` with
  the wall clock (the node bounds its stamps: ``seaway.runtime.stamps``); every ``period_s`` of the
  wall clock (``RateLoop``, drift-free) ``tick`` runs and publishes through ``out``; ``idle`` runs
  at each wake. Signals, the health token and restarts are ``run_service``'s and the launcher's.
* **lockstep member** (``MemberDriver``): the inputs come in the bundles of the members the node
  hears; the driver admits each stamp (``Member.admit``), hands it to ``take`` (``now_ns`` None)
  and notes it seen; once the answers of the period the node ``needs`` are in, with everything they
  list, it calls ``answer`` once for the period and publishes the returned messages as the node's
  bundle (``hold``: nothing to fly, the clock waits). ``rethink`` asks for a held period to be
  answered again (a mission came); a new episode calls ``restart``; a restarted node catches up
  from the clock's repeat of the current period (the protocol's). ``answered`` runs after the
  bundle left (a checkpoint).
* **lockstep clock**: the sim (``seaway_sim.node``) or a recording (``seaway replay --lockstep``),
  ``seaway.runtime.lockstep_clock`` (``lockstep_replay`` for a recording).

Composition (``seaway.runtime.host``) runs the same nodes as threads of one process over the
in-memory bus: the drivers are the same, only the bus differs.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from seaway.contract import keys
from seaway.contract.messages import Message, PeriodDone, Reply
from seaway.runtime.bus import Bus
from seaway.runtime.bus_typed import TypedPublisher
from seaway.runtime.clock import RateLoop
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.runtime.stamps import StampGate

__all__ = ["Answer", "LiveDriver", "MemberDriver", "MemberSpec", "Node", "Outputs", "Period",
           "PeriodAt"]

log = logging.getLogger("seaway.runtime.node")

WAKE_S = 0.1
"""How long a driver's loop sleeps at most between looks when nothing wakes it [wall s]: the
``idle`` housekeeping (a signal's request, a stats line) is never later than this."""


@dataclass(frozen=True)
class MemberSpec:
    """How a node takes part in lockstep (``seaway.runtime.lockstep`` states the protocol).

    ``needs``: the members whose answers for the period must be in, with all they list on watched
    keys, before this one answers (the estimator the sim's, the controller the sim's and the
    estimator's). ``inputs``: the key suffixes handed to ``take``; ``watched``: those whose listed
    stamps must be seen before answering (default ``inputs``). ``hears``: whose bundles (default
    ``needs`` and the producers of ``inputs``); ``passive``: those of them that never move this one
    on by themselves (taken when an active one's comes; in process only, where a bundle is
    delivered inside its sender's put: over a transport each bundle is taken as it arrives)."""

    service: str
    needs: tuple[str, ...]
    inputs: frozenset[str]
    watched: frozenset[str] | None = None
    hears: tuple[str, ...] | None = None
    passive: tuple[str, ...] = ()


class PeriodAt(NamedTuple):
    """What a node answers: the period, its length, the answers it needed (by service), and
    ``admit(suffix, stamp_ns)``: whether a message so stamped may still wait for a later period of
    this episode (one further ahead never will: drop it)."""

    period: Period
    period_ns: int
    answers: Mapping[str, PeriodDone]
    admit: Callable[[str, int], bool]


class Answer(NamedTuple):
    """A node's answer to one period: the messages it publishes for it, in order, and ``hold``
    (nothing to fly: the clock waits for another answer)."""

    messages: Sequence[tuple[keys.KeySpec, Message]] = ()
    hold: bool = False


class Outputs:
    """The node's publishers in real time, made on first use: ``put(spec, msg)``, from any of the
    node's threads (the controller's keeper sends a thrust beside its rate loop)."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self._pubs: dict[keys.KeySpec, TypedPublisher[Any]] = {}
        self._making = threading.Lock()  # one publisher per key, whichever thread puts first

    def put(self, spec: keys.KeySpec, msg: Message) -> None:
        pub = self._pubs.get(spec)
        if pub is None:
            with self._making:
                pub = self._pubs.get(spec)
                if pub is None:
                    pub = self._pubs[spec] = self.bus.publisher(spec)
        pub.put(msg)

    def put_all(self, messages: Sequence[tuple[keys.KeySpec, Message]]) -> None:
        for spec, msg in messages:
            self.put(spec, msg)


class Node:
    """A service's node (see the module's description): the declarations and the hooks with what
    they do by default (nothing). A node of one clock only leaves the other's methods out (the
    driver of that clock never asks for them)."""

    name: str = ""
    member: MemberSpec | None = None
    """How it takes part in lockstep; None: it does not (a node of the wall clock only)."""
    live_inputs: Sequence[keys.KeySpec] = ()
    """Real time: the keys it hears (``take`` with the wall clock)."""
    side_inputs: Sequence[keys.KeySpec] = ()
    """Keys it hears apart from the lockstep bundles, in either clock (``take`` with ``now_ns``
    the wall clock in real time, None in lockstep): what no lockstep member produces."""
    inline_inputs: frozenset[keys.KeySpec] = frozenset()
    """Real time: those of its inputs taken on the transport's own receive thread, with no
    hand-over to a Python thread first (``Bus.subscribe``'s ``inline``): for a short handler on the
    latency path (vehicle_io's thrust)."""
    paced = False
    """Real time: the node says when it next needs a tick (``wake_s``) instead of ticking on the
    rate loop's grid; the driver waits at most ``period_s`` between ticks either way."""

    def wake_s(self) -> float:
        """A paced node, after a tick: how long until it needs the next one [s]."""
        return 0.0

    def sleep(self, timeout_s: float, stop: threading.Event) -> None:
        """A paced node, between two ticks: wait ``timeout_s`` [s] or until ``stop``; a node that
        something else can wake sooner waits on that instead (the recorder on a sample)."""
        stop.wait(timeout_s)

    def requests(self) -> Mapping[keys.KeySpec, Callable[[Any], Reply]]:
        """The requests it answers: key -> handler (on a request thread of the bus)."""
        return {}

    def attach(self, driver: MemberDriver | LiveDriver) -> None:
        """The driver that runs it, before anything is heard: ``now_ns()`` is the node's time in
        either clock, ``rethink()`` (lockstep) answers a held period again, ``out`` (real time)
        publishes."""

    def take(self, key: str, msg: Any, now_ns: int | None) -> None:
        """An input on ``key``."""

    def joining(self) -> None:
        """Real time, just before the health token: a node that takes part in lockstep beside the
        clock of its own (the recorder's witness) joins here, so that it is a member once it is
        ready (``MemberDriver.run`` says why)."""

    def restart(self, period: Period) -> None:
        """Lockstep: a new episode starts at ``period`` (the sim restarted or loaded a scenario)."""

    def answer(self, at: PeriodAt) -> Answer:
        """Lockstep: the answer to ``at.period``."""
        raise NotImplementedError(f"node {self.name} has no lockstep answer")

    def answered(self) -> None:
        """Lockstep: after the answer's bundle left."""

    def tick(self, now_ns: int, out: Outputs) -> None:
        """Real time: one period of the wall clock at ``now_ns``."""
        raise NotImplementedError(f"node {self.name} has no real-time tick")

    def idle(self) -> None:
        """At each wake of the driver's loop (at least every ``WAKE_S``): housekeeping."""

    def finish(self) -> None:
        """Once the driver's loop ended (the service is stopping)."""


def _suffix(key: str) -> str:
    """``seaway/<vessel>/<suffix>`` -> ``<suffix>``."""
    return key.split("/", 2)[2]


@dataclass
class MemberDriver:
    """Runs a node as a lockstep member (see the module's description)."""

    bus: Bus
    node: Node
    stamps: StampGate | None = None
    """The node's own stamp gate, so that one count of dropped stamps says all (default the
    member's)."""
    member: Member = field(init=False)
    _answered: PeriodDone | None = field(default=None, init=False)
    _rethink: bool = field(default=False, init=False)
    _restarts: list[Period] = field(default_factory=list, init=False)
    _step_lock: threading.Lock = field(default_factory=threading.Lock, init=False)

    def __post_init__(self) -> None:
        spec = self.node.member
        assert spec is not None, f"node {self.node.name} is no lockstep member"
        producers = {s for s in spec.inputs if keys.spec_for_suffix(s) is not None}
        hears = spec.hears if spec.hears is not None else tuple(sorted(
            set(spec.needs) | {_bundler(s) for s in producers}))
        # Passive sources only in process, where a bundle is delivered inside its sender's put: over
        # a transport every bundle is taken on the bus's thread, which answers there once the
        # period is complete (``answer_on_arrival``). A passive source's bundle came on another
        # connection than the active one's and was often not in its ring yet when that one came:
        # the loop then woke to look for it every ``PASSIVE_POLL_S``, and answered itself.
        passive = spec.passive if self.bus.delivers_in_put else ()
        self.member = Member(self.bus, spec.service,
                             watched=spec.watched if spec.watched is not None else spec.inputs,
                             inputs=spec.inputs, hears=hears, passive=passive)
        if self.stamps is not None:
            self.member.stamps = self.stamps
        self.member.deliver = self._deliver
        self.member.on_restart = lambda _before, now: self._restarts.append(now)

    # -- from the bus's threads, or the loop --------------------------------------------------

    def _deliver(self, key: str, msg: Message) -> None:
        suffix = _suffix(key)
        if not self.member.admit(suffix, msg.stamp_ns):
            return  # beyond any period to come soon: counted and logged by the member
        self.node.take(key, msg, None)  # first: what the ledger has seen, the node has
        self.member.saw(suffix, msg.stamp_ns)

    def rethink(self) -> None:
        """Answer the current period again if it was held (a mission came, a solver is ready)."""
        with self.member.changed:
            self._rethink = True
            self.member.version += 1
            self.member.changed.notify_all()

    def now_ns(self) -> int:
        """The current period's stamp (0 before the first): the node's time in lockstep."""
        with self.member.changed:
            period = self.member.ledger.period
        return period.stamp_ns if period is not None else 0

    def step(self) -> None:
        """Answer the current period if all it needs is in and it has not been answered (or was
        held and a rethink came since); one caller at a time."""
        member, spec = self.member, self.node.member
        with self._step_lock:
            with member.changed:
                ledger = member.ledger
                period = ledger.period
                answers = {s: ledger.answer(s) for s in spec.needs}
                complete = all(ledger.complete(a) for a in answers.values())
                restart = self._restarts[-1] if self._restarts else None
                self._restarts.clear()
                rethink = self._rethink
            if restart is not None:
                self.node.restart(restart)
                self._answered = None
            if not complete or period is None:
                # Not now; a rethink that came meanwhile is still to be thought of when the period
                # can be answered (consumed here, a hold answered just before stood for good).
                return
            answered = self._answered
            if answered is not None and Period.of(answered) == period and not (
                    answered.hold and rethink):
                if not answered.hold:
                    with member.changed:
                        self._rethink = False  # the period is flown: nothing held to think again
                return
            with member.changed:
                self._rethink = False  # answered now, with whatever came
            period_ns = next(iter(answers.values())).period_ns  # type: ignore[union-attr]
            member.working(period)
            at = PeriodAt(period, period_ns, answers,  # type: ignore[arg-type]
                          lambda suffix, stamp: member.admit(suffix, stamp, period.stamp_ns,
                                                             period_ns))
            result = self.node.answer(at)
            self._answered = member.answer(period, period_ns, result.messages, hold=result.hold)
            self.node.answered()

    def answer_on_arrival(self) -> None:
        """From now on, answer on the bus's thread as the bundle that completes a period is taken
        (``Member.on_ready``): once the node is attached (its inputs are taken from the start, and
        the loop answers what came before)."""
        self.member.on_ready = self.step

    def join(self) -> None:
        """Answer from now on (``answer_on_arrival``) and declare the member token."""
        self.answer_on_arrival()
        self.member.join()

    def run(self, stop: threading.Event, ready: Callable[[Callable[[], None]], None]) -> None:
        """Join (within ``ready``, before the node's health token), then answer until ``stop``.

        The member token comes first because a launcher starts the clock, or a replay, once the
        members' health tokens are up, and a replay paces each period by the members it knows then:
        a member that joined only after its health token would miss the periods sent before it (a
        replay runs open loop: it does not wait for a command, as the sim does)."""
        for spec in self.node.side_inputs:
            self.bus.subscribe(spec, callback=lambda key, msg: self.node.take(key, msg, None))
        ready(self.join)
        version = 0
        try:
            while not stop.is_set():
                version = self.member.wait(version, WAKE_S)
                self.node.idle()
                self.step()
        finally:
            self.node.finish()


def _bundler(suffix: str) -> str:
    from seaway.contract import bundle  # the node runtime needs it only here

    spec = keys.spec_for_suffix(suffix)
    assert spec is not None
    return bundle.bundled_by(spec)


class LiveDriver:
    """Runs a node on the wall clock (see the module's description)."""

    def __init__(self, ctx: Any, node: Node, period_s: float) -> None:
        self.ctx, self.node, self.period_s = ctx, node, period_s
        self.stop: threading.Event = ctx.stop
        self.out = Outputs(ctx.bus)
        self.loop = RateLoop(period_s, ctx.clock, ctx.stop)
        """Its ``tick`` counts the periods since the first (missed ones too)."""

    def now_ns(self) -> int:
        return self.ctx.clock.now_ns()

    def run(self) -> None:
        ctx, node = self.ctx, self.node
        for spec in (*node.live_inputs, *node.side_inputs):
            ctx.bus.subscribe(spec, callback=self._take, inline=spec in node.inline_inputs)
        ctx.ready(node.joining)
        loop = self.loop
        try:
            if node.paced:
                while not ctx.stop.is_set():
                    node.idle()
                    node.tick(ctx.clock.now_ns(), self.out)
                    node.sleep(min(max(0.0, node.wake_s()), self.period_s), ctx.stop)
            else:
                while loop.wait():
                    node.idle()
                    node.tick(ctx.clock.now_ns(), self.out)
        finally:
            node.finish()

    def _take(self, key: str, msg: Message) -> None:
        self.node.take(key, msg, self.ctx.clock.now_ns())
