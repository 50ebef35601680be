"""A lockstep member's side of the bus (``Member``): the bundles it hears, its answers and repeats.

The protocol, the periods and the pure bookkeeping (``Ledger``) are ``seaway.runtime.lockstep``'s;
this is the part that holds a bus: it feeds its ledger from the bundles of the members it hears,
publishes its own answer with what it carries, and repeats it when the sim repeats.
"""

from __future__ import annotations

import collections
import itertools
import logging
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from seaway.contract import bundle, keys
from seaway.contract.messages import LOCKSTEP_SERVICES, Message, MessageError, PeriodDone
from seaway.runtime.bus import Bus
from seaway.runtime.bus_raw import RawSample, carrying_put
from seaway.runtime.bus_typed import RawRing
from seaway.runtime.lockstep import (
    KEPT_PERIODS,
    PASSIVE_POLL_S,
    Ledger,
    Period,
    listing,
)
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import StampBounds, StampGate, describe_ns
from seaway.runtime.timeline import Timeline

log = logging.getLogger("seaway.lockstep")

KEPT_BUNDLES = 7
"""Bundles a member keeps in all: one a period while time flows; a held period is answered again
for each mission request the controller takes there. A repeat sends them all at once, often from
Zenoh's thread, where each express put holds a batch of the link's queue until the callback returns;
one intake can take two repeats of the sim (a ring held both): twice these and two answers must fit
in ``zenoh_bus.LOCKSTEP_TX_QUEUE``."""
PASSIVE_RING = 256
"""Bundles a passive source holds until they are taken (``Member``): a source sends one a period."""
GIVE_UP_LACKING_S = 10.0
"""How long a member waits, while the sim repeats its period, for a command the sim's answer says it
applied (``consumed``) before it takes that command as lost [wall s]. A member killed in the middle
of its put can reach the sim and no other member, and nobody alive holds its bundle to send again:
the estimator then waited for the dead controller's last command for ever, and the restarted
controller for the estimator (seen about once in fifteen kills at the return decision). Well below
the launcher's hang limit (30 s), well above any delivery of a live sender."""

Deliver = Callable[[str, Any], None]
"""A member's input: ``deliver(key, message)``, on the bus's thread, for each message of an input key
in a bundle it hears, before the bundle's answer is noted (the message came first)."""


class Member:
    """A lockstep member's side of the bus: its ledger fed from the bundles it hears, its answers and
    repeats.

    The member hears the bundles of ``hears``; each message in them on one of its ``inputs`` (key
    suffixes, default ``watched``) is decoded, validated and given to ``deliver`` (which usually
    admits its stamp and calls ``saw``), then the answer is noted; ``changed`` wakes the service's
    loop whenever the ledger moved. ``answer`` publishes the period's messages and the ``PeriodDone``
    listing them as one bundle; a repeat of the sim's answer republishes the last one.

    Active and passive sources: a bundle from an active source is taken on the bus's thread as it
    arrives and wakes the loop. One from a ``passive`` source waits in a ring the transport fills by
    itself (no Python runs for it) until the next active bundle, or the loop, takes it: each member
    has one source that moves it on (the estimator the sim, the controller the estimator, the sim the
    controller), and whatever else it needs was sent before that one's bundle, so it is almost
    always there by then; when it is not, the loop looks again every ``PASSIVE_POLL_S``. Each bundle
    heard through Python costs a thread hand-over at the busiest moment of the period.
    """

    def __init__(self, bus: Bus, service: str, watched: Iterable[str] | None,
                 seq_start: int | None = None, subscribe: bool = True,
                 consumed: bool = True, hears: Iterable[str] | None = None,
                 inputs: Iterable[str] | None = None, passive: Iterable[str] = (),
                 clock: Callable[[], int] = time.monotonic_ns) -> None:
        """``hears``: the members whose bundles this one needs (default: every other); ``passive``:
        those of them that never move it on by themselves. Only the sim's classify a period, and
        every bundle heard costs a hand-over to Python, so the estimator hears only the sim and the
        controller (the command the sim applied), the controller the sim and the estimator."""
        self.bus = bus
        self.service = service
        self.hears = frozenset(LOCKSTEP_SERVICES if hears is None else hears) - {service}
        self.ledger = Ledger(watched, consumed)
        self.inputs = frozenset(inputs if inputs is not None else (watched or ()))
        self.deliver: Deliver | None = None
        """Set by the service once it can take inputs (its handler usually names this member)."""
        unheard = sorted(s for s in self.inputs
                         if (spec := keys.spec_for_suffix(s)) is None
                         or bundle.bundled_by(spec) not in self.hears)
        if subscribe and unheard:
            raise ValueError(f"lockstep {service}: inputs {', '.join(unheard)} come in no bundle it "
                             f"hears ({', '.join(sorted(self.hears))})")
        self.changed = threading.Condition()
        self.version = 0  # bumped on every ledger change, under ``changed``
        self.restarts: list[tuple[Period | None, Period]] = []
        self.repeats = 0
        self._seq = itertools.count(time.time_ns() if seq_start is None else seq_start)
        self._key = keys.lockstep_spec(service).key(bus.vessel)
        self._pub = bus.raw_publisher(self._key, bundle.ENCODING, block=True, express=True)
        self._put_bundle = carrying_put(self._pub)  # in process, what it was encoded from too
        self._kept: list[tuple[list[tuple[str, bytes]], tuple[Message, ...], PeriodDone, Period]] = []
        """(lines, their messages, answer, its period) of every bundle sent for the last
        ``KEPT_PERIODS`` periods
        answered, in the order sent: what a restarted recorder may lack (``repeat``)."""
        self.on_restart: Callable[[Period | None, Period], None] | None = None
        self.on_ready: Callable[[], None] | None = None
        """A service that answers on the bus's thread: called there after each bundle taken from
        an active source (its loop is then woken only while a passive bundle is due, to look for
        it, and for its own business): each hand-over from Zenoh's thread to a loop's costs a
        thread switch at the busiest moment of the period."""
        self.stamps = StampGate(f"{service} (lockstep)", log)
        self.ratelog = RateLimitedLog(log)  # repeated warnings, per kind and key
        self.timeline = Timeline.from_env(service)  # seaway.runtime.timeline: off unless asked
        self.passive = frozenset(passive) & self.hears
        self._active = self.hears - self.passive
        self._seen_batch: list[tuple[str, int]] | None = None
        self._batch_thread = 0
        self._clock = clock  # wall, monotonic [ns]: only for giving up on a lost command
        self._lacking_since: dict[tuple[str, int], int] = {}
        self.given_up: list[tuple[str, int]] = []
        """(key suffix, stamp) of every command taken as lost (``GIVE_UP_LACKING_S``)."""
        self.refused: collections.Counter[str] = collections.Counter()
        """Answers refused, per reason (``Ledger.refusal``: 'ahead', 'listing')."""
        # One bundle taken at a time, in the order taken. Reentrant: taking one can publish a
        # repeat, and a transport that delivered it at once on this thread would come back here
        # (the in-memory bus queues it until the sample at hand has reached everybody).
        self._intake = threading.RLock()
        self._rings: list[tuple[str, RawRing]] = []
        if subscribe:  # else the service feeds ``on_answer`` itself (the recorder, from its stream)
            for other in sorted(self.hears):
                key = keys.lockstep_spec(other).key(bus.vessel)
                if other in self.passive:
                    self._rings.append((key, bus.ring_raw(key, PASSIVE_RING)))
                else:
                    bus.subscribe_raw(key, self.on_bundle, inline=True)

    # -- from the bus's threads -------------------------------------------------------------------

    def on_bundle(self, sample: RawSample) -> None:
        """A bundle heard from an active source: what the passive ones hold first (it was sent
        before), then this one."""
        arrived_ns = time.monotonic_ns()
        with self._intake:
            self._drain()
            self._take(sample.key, sample.payload, arrived_ns, sample.carried)
        if self.on_ready is not None:
            self.on_ready()
            with self.changed:
                if self.expecting():  # a passive bundle is due: the loop looks for it
                    self.changed.notify_all()

    def drain(self) -> bool:
        """Take what the passive sources hold (from the service's loop); whether anything came."""
        if not self._rings:
            return False
        with self._intake:
            return self._drain()

    def _drain(self) -> bool:
        got = False
        for key, ring in self._rings:
            while (item := ring.take_carried()) is not None:
                self._take(key, item[0], carried=item[1])
                got = True
        return got

    def _take(self, key: str, payload: bytes, arrived_ns: int | None = None,
              carried: Any = None) -> None:
        """One bundle: its inputs delivered, then its answer noted (``on_answer``); ``arrived_ns``:
        when Zenoh handed it over, for the timeline (none for a passive source's, held in a ring);
        ``carried``: what an in-process sender encoded it from (``RawSample.carried``)."""
        service = bundle.service_of(key)
        try:
            raw_answer, lines = bundle.parts(payload, carried)
        except MessageError as err:
            self.bus.stats.count_malformed(key, str(err))
            self.ratelog.warning(("malformed bundle", key), "lockstep bundle on %s dropped: %s",
                                 key, err)
            return
        answer = self.bus.decode_counted(PeriodDone, key, raw_answer, bundle.carried_answer(carried))
        if type(carried) is bundle.Carried:
            msgs: Sequence[Any] = carried.messages
        else:
            msgs = (None,) * len(lines)
        if answer is None or service is None:
            return
        if answer.service != service:
            self._impostor(key, answer)
            return
        prefix = key[: -len(f"lockstep/{service}")]
        if answer.resent:  # a copy for a recorder: its answer is old news, but see _lacking
            with self.changed:
                lacking = self._lacking()
            if lacking:
                self._deliver(service, prefix, key, lines, msgs, lacking)
            return
        if arrived_ns is not None:
            self.timeline.mark("arrived", answer.stamp_ns, service, at_ns=arrived_ns)
        self._deliver(service, prefix, key, lines, msgs)
        self.on_answer(key, answer)

    def _lacking(self) -> set[tuple[str, int]]:
        """(key suffix, stamp) that an answer of the current period lists and this member has not
        seen; under ``changed``.

        What a copy sent for a recorder (``resent``) may still give a member: a member killed in
        the middle of its put can have reached the controller and not the sim, so the controller
        answered the period after and repeats that one, while the sim repeats the period the dead
        member had not finished, whose ``consumed`` names the controller's command before. A
        restarted estimator finds that command only in the controller's copy of the period before.
        """
        ledger = self.ledger
        if ledger.period is None:
            return set()
        return {miss for a in ledger.answers.values() if Period.of(a) == ledger.period
                for miss in ledger.missing(a)}

    def _deliver(self, service: str, prefix: str, key: str, lines: Sequence[tuple[str, bytes]],
                 msgs: Sequence[Any], only: set[tuple[str, int]] | None = None) -> None:
        """Hand a bundle's messages on this member's inputs to the service (``only``: just those
        (suffix, stamp)); ``msgs``: per line, what it was encoded from (in process), or None.
        What the service notes seen meanwhile (``saw``) is noted once, after the last: each
        note asks every answer of the period what it lacks."""
        outer, self._seen_batch = self._seen_batch, []
        self._batch_thread = threading.get_ident()  # under ``_intake``: one thread at a time
        try:
            self._deliver_lines(service, prefix, key, lines, msgs, only)
        finally:
            batch, self._seen_batch = self._seen_batch, outer
            if batch:
                self.saw_many(batch)

    def _deliver_lines(self, service: str, prefix: str, key: str,
                       lines: Sequence[tuple[str, bytes]],
                       msgs: Sequence[Any], only: set[tuple[str, int]] | None) -> None:
        wanted = None if only is None else {suffix for suffix, _ in only}
        for (suffix, data), carried in zip(lines, msgs, strict=True):
            if suffix not in self.inputs or (wanted is not None and suffix not in wanted):
                continue
            try:
                spec = bundle.check_line(service, suffix)
            except MessageError as err:  # a member wrapping another's key: never taken
                self.bus.stats.count_malformed(key, str(err))
                self.ratelog.warning(("foreign line", key), "%s", err)
                continue
            msg = self.bus.decode_counted(spec.message, prefix + suffix, data,  # type: ignore[arg-type]
                                          carried)
            if msg is None or self.deliver is None or (
                    only is not None and (suffix, msg.stamp_ns) not in only):
                continue
            try:
                self.deliver(prefix + suffix, msg)
            except Exception:  # a bug in a handler must not lose the answer after it
                self.ratelog.exception(("deliver", suffix), "%s: input %s failed",
                                       self.service, suffix)

    def _impostor(self, key: str, answer: PeriodDone) -> None:
        self.ratelog.warning(("impostor", key), "lockstep answer on %s claims to be %s's: ignored",
                             key, answer.service)

    def admit(self, suffix: str, stamp_ns: int, ref_ns: int | None = None,
              period_ns: int | None = None) -> bool:
        """Whether a message on ``suffix`` stamped ``stamp_ns`` may be kept for a period: not when
        it lies further ahead of the current period than ``StampBounds.lockstep`` allows (counted,
        dropped, logged once). The sim, whose own answers never reach its ledger, passes its time
        and period (``ref_ns``, ``period_ns``)."""
        with self.changed:
            period, known_ns = self.ledger.period, self.ledger.period_ns
        if ref_ns is None and period is not None:
            ref_ns = period.stamp_ns
        period_ns = period_ns or known_ns
        bounds = StampBounds.lockstep(period_ns) if period_ns else None
        return self.stamps.admit(suffix, stamp_ns, ref_ns, bounds)

    def saw(self, suffix: str, stamp_ns: int) -> None:
        """Note a message seen (``saw_many``); while this thread hands a bundle's inputs to the
        service (``_deliver``), once with the others of the bundle, after them."""
        batch = self._seen_batch
        if batch is not None and self._batch_thread == threading.get_ident():
            batch.append((suffix, stamp_ns))
            return
        self.saw_many(((suffix, stamp_ns),))

    def saw_many(self, seen: Iterable[tuple[str, int]]) -> None:
        """Note messages seen; wake the loop only if an answer of the current period lacked some.

        A member's inputs come in the bundle before its answer is noted, so they almost always
        find nothing waiting for them: waking the loop for each cost a thread hand-over on the
        period's critical path. A member that follows no period (the sim) is always woken."""
        with self.changed:
            ledger = self.ledger
            waiting = ledger.period is None or any(
                ledger.current(a) and ledger.lacks(a) for a in ledger.answers.values())
            for suffix, stamp_ns in seen:
                ledger.see(suffix, stamp_ns)
            if waiting:
                self.version += 1
                if self.on_ready is None:
                    self.changed.notify_all()

    def on_answer(self, key: str, answer: PeriodDone) -> None:
        if not key.endswith(f"/lockstep/{answer.service}"):  # valid, but not who may say it there
            self._impostor(key, answer)
            return
        repeat = False
        self.timeline.mark("heard", answer.stamp_ns, answer.service)
        with self.changed:
            # The sim never hears itself: its own last answer says where time is.
            why = self.ledger.refusal(answer, self.last_answer if self.service == "sim" else None)
            if why is not None:
                self._refuse(key, why)
                return
            before = self.ledger.period
            change = self.ledger.on_answer(answer)
            if change == "restart":
                self.restarts.append((before, Period.of(answer)))
                if self.on_restart is not None:
                    self.on_restart(before, Period.of(answer))
            # A member repeats only what it said in this stretch of time: an answer of an earlier
            # episode (the sim restarted, a scenario loaded) is of no use to a newcomer, and a
            # recorder would write its messages again, in the new episode's time.
            last = self.last_answer
            repeat = change == "repeat" and last is not None and Period.of(last).leads_to(
                Period.of(answer))
            lost = self._give_up_lacking(answer) if change == "repeat" else []
            lacking = self.waiting_for() if change == "repeat" else ""
            self.version += 1
            if self.on_ready is None:  # else the service answers on this thread (``on_ready``)
                self.changed.notify_all()
        for suffix, stamp_ns in lost:
            log.warning("%s, lockstep t = %s (episode %d): %s @ %s, which the sim applied, "
                        "never came in %.0f s (its sender died putting it): taken as lost",
                        self.service, describe_ns(answer.stamp_ns), answer.episode, suffix,
                        describe_ns(stamp_ns), GIVE_UP_LACKING_S)
        if lacking:  # expected while members start or restart: the sim repeats for them
            log.info("%s, lockstep t = %s (episode %d), repeated: %s", self.service,
                     describe_ns(answer.stamp_ns), answer.episode, lacking)
        if repeat:
            self.repeat()

    def _refuse(self, key: str, why: str) -> None:
        """An answer ``Ledger.refusal`` refuses: counted per reason, logged (rate-limited)."""
        reason = why.split(":", 1)[0]
        self.refused[reason] += 1
        self.bus.stats.count_malformed(key, why)
        self.ratelog.warning(("refused", reason, key), "%s: lockstep answer on %s refused (%s)",
                             self.service, key, why)

    def _give_up_lacking(self, answer: PeriodDone) -> list[tuple[str, int]]:
        """At a repeat of the sim's answer: the commands it lists as applied that this member has
        lacked for ``GIVE_UP_LACKING_S``, now noted as seen (so no longer waited for). Under
        ``changed``."""
        if answer.service != "sim":
            return []
        now = self._clock()
        lacking = self.ledger.missing_consumed(answer)
        self._lacking_since = {k: self._lacking_since.get(k, now) for k in lacking}
        lost = [k for k, since in self._lacking_since.items()
                if now - since >= round(GIVE_UP_LACKING_S * 1e9)]
        for suffix, stamp_ns in lost:
            self.ledger.give_up(suffix, stamp_ns)
            del self._lacking_since[(suffix, stamp_ns)]
        self.given_up += lost
        return lost

    def waiting_for(self) -> str:
        """What keeps this member from answering the current period, for a person ('' if it has
        answered it, or has all it needs): the answers it needs that have not come, and the messages
        listed by those that have which it has not seen (key suffix and stamp). Under ``changed``.

        Logged when the sim repeats a period this member has not answered: a run that stalls says
        in each member's log what that member was waiting for."""
        ledger, period = self.ledger, self.ledger.period
        last = self.last_answer
        if period is None or (last is not None and Period.of(last) == period):
            return ""
        tick = ledger.answer("sim")
        absent = sorted(m for m in self.hears if m != "sim" and ledger.answer(m) is None
                        and (tick is None or m in tick.members))
        missing = {s: lacks for s, a in sorted(ledger.answers.items())
                   if s in self.hears and Period.of(a) == period and (lacks := ledger.missing(a))}
        parts = [f"no answer yet from {', '.join(absent)}"] if absent else []
        parts += [f"{s}'s answer lists, not seen: "
                  + ", ".join(f"{suffix} @ {describe_ns(stamp)}" for suffix, stamp in lacks)
                  for s, lacks in missing.items()]
        return "; ".join(parts)

    # -- from the service's loop ------------------------------------------------------------------

    def wait(self, version: int, timeout_s: float) -> int:
        """Block until the ledger moved past ``version`` (or ``timeout_s``); the new version. The
        passive sources are looked at before and after, and every ``PASSIVE_POLL_S`` while a bundle
        from one is due (``expecting``)."""
        self.drain()
        with self.changed:
            if self.version == version:
                self.changed.wait(PASSIVE_POLL_S if self.expecting() else timeout_s)
        self.drain()
        with self.changed:
            return self.version

    def expecting(self) -> bool:
        """Whether a passive source's bundle is due (under ``changed``): an answer of the current
        period lists a message not yet seen (the estimator's tick, the command the sim applied), or
        an active source answered another period than the sim's latest taken (the controller: the
        estimator answered a period, so the sim had sent it)."""
        ledger = self.ledger
        if not self._rings or ledger.period is None:
            return False
        active = self._active
        return any((a.service in active and not ledger.current(a))
                   or (ledger.current(a) and ledger.lacks(a))
                   for a in ledger.answers.values())

    def answer(self, period: Period, period_ns: int,
               messages: Sequence[tuple[keys.KeySpec, Message]] = (), *, hold: bool = False,
               consumed: dict[str, list[int]] | None = None, covers: dict[str, int] | None = None,
               members: Sequence[str] = ()) -> PeriodDone:
        """Publish this member's bundle for ``period``: its answer listing ``messages``, and them."""
        lines = [(spec.suffix, msg.encode()) for spec, msg in messages]
        msgs = tuple(msg for _, msg in messages)
        done = PeriodDone(stamp_ns=period.stamp_ns, service=self.service,  # type: ignore[arg-type]
                          episode=period.episode, seq=next(self._seq), period_ns=period_ns,
                          published=listing(messages), consumed=consumed or {}, hold=hold,
                          covers=covers or {}, members=list(members))  # type: ignore[arg-type]
        self.timeline.mark("sent", period.stamp_ns)  # encoded; the bundle leaves now
        self._put(done, lines, msgs)
        return done

    def _put(self, done: PeriodDone, lines: list[tuple[str, bytes]], msgs: tuple[Message, ...],
             again: bool = False) -> None:
        self._put_bundle(*bundle.Carried.of(done, done.encode(), lines, msgs))
        self.bus.stats.published += 1 + len(lines)
        self._keep(done, lines, msgs, again)

    def _keep(self, done: PeriodDone, lines: list[tuple[str, bytes]], msgs: tuple[Message, ...],
              again: bool) -> None:
        """Keep a bundle sent (``again``: a repeat of the last, which it stands for from now)."""
        kept = self._kept
        period = Period.of(done)
        if again and kept:
            kept[-1] = (lines, msgs, done, period)
            return
        if kept and not kept[-1][3].leads_to(period):
            # The world restarted (a sim restart, a scenario load): nothing kept leads here, and a
            # new t_0 would pass for the dead sim's (same episode 0, same stamp) in ``repeat``.
            kept.clear()
        elif kept and kept[-1][3] != period:
            # Keep the bundles of the last KEPT_PERIODS - 1 periods sent (the kept ones lead to
            # each other, so a period's bundles are next to each other): from the first of them.
            start, distinct = len(kept) - 1, 1
            while start > 0:
                if kept[start - 1][3] != kept[start][3]:
                    if distinct == KEPT_PERIODS - 1:
                        break
                    distinct += 1
                start -= 1
            if start:
                del kept[:start]
        kept.append((lines, msgs, done, period))
        if len(kept) > KEPT_BUNDLES:
            dropped = kept.pop(0)[0]
            # Only messages are worth a warning: a bundle that is an answer alone (the recorder's,
            # which answers its first period again as each member joins) leaves nothing to miss.
            if dropped:
                self.ratelog.warning(("kept", self.service), "%s sent more than %d bundles in %d "
                                     "periods: a recorder restarted now would miss the oldest",
                                     self.service, KEPT_BUNDLES, KEPT_PERIODS)

    def working(self, period: Period) -> None:
        """The service's loop starts on ``period`` (``seaway.runtime.timeline``)."""
        self.timeline.mark("work", period.stamp_ns)

    def repeat(self, members: Sequence[str] | None = None) -> PeriodDone | None:
        """Publish the last bundle again (same messages, new ``seq``), for a newcomer; the sim's
        names the members it now waits for. Every bundle kept before it goes first, in the order
        sent, marked ``resent``, for a recorder that (re)joined: it may not have them
        (``KEPT_PERIODS``); the others pass them over."""
        if not self._kept:
            return None
        lines, msgs, done, last = self._kept[-1]
        for old_lines, old_msgs, old, old_period in self._kept[:-1]:
            # Only what led to this period: after a sim restart (episode 0 again) a kept bundle can
            # be of the dead sim's later periods, which a recorder would write in the new time.
            if old_period.leads_to(last):
                copy = old.model_copy(update={"seq": next(self._seq), "resent": True})
                self._put_bundle(*bundle.Carried.of(copy, copy.encode(), old_lines, old_msgs))
        update: dict[str, Any] = {"seq": next(self._seq)}
        if members is not None:
            update["members"] = list(members)
        again = done.model_copy(update=update)
        self._put(again, lines, msgs, again=True)
        self.repeats += 1
        return again

    def join(self) -> None:
        """Declare this member's token; call once its subscriptions are in place (the sim then
        repeats its period for it)."""
        self.bus.declare_lockstep_member(self.service)

    @property
    def last_answer(self) -> PeriodDone | None:
        return self._kept[-1][2] if self._kept else None
