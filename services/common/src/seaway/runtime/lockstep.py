"""Lockstep: how the sim, the estimator, the controller and the recorder share simulated time.

One mechanism, in one place; each service's loop only says when a period is ready for it and what it
publishes (services/sim/README.md, "The lockstep protocol", walks one period through).

THE PROTOCOL

* Time is split into episodes (``episode`` counts the sim's scenario starts; a restarted sim starts
  at 0 again) and, within one, into periods t_k = k * period (the run's control period), t_0 = 0.
* Each member answers each period with a ``PeriodDone`` on ``lockstep/<service>``, published AFTER
  the messages it lists: ``published`` names them by key suffix and stamp. So a receiver knows what
  is coming and waits for exactly that; it never waits on a timeout to learn that something is not.
* The sim answers first (its answer is the period's tick): the sensor samples due in (t_{k-1}, t_k],
  truth, disturbance and clock, and in ``consumed`` the thrust command it applied over
  (t_{k-1}, t_k]. It steps to t_{k+1} once every member has answered t_k: the controller with a
  command the sim holds (an answer with ``hold`` means "nothing to fly": no step until another
  answer), the recorder covering (``covers``) the latest answer of every member.
* The estimator answers t_k once it has the sim's answer and every message it lists (so also the
  thrust command the sim applied); the controller once it has the estimator's answer and the state
  it lists; the recorder once every member's latest answer for t_k and all they list is on disk.
* Members are the services whose member token (a liveliness token on ``lockstep/<service>``,
  ``Member.join``) has appeared since the sim started. Once a member, always a member: a member
  that dies is waited for until it is back (the launcher restarts it), so nothing happens without
  it and nothing is lost.
* A member that (re)joins makes the sim repeat its answer (same messages, same stamps, new ``seq``);
  on a repeat every member repeats its last answer (the same bytes), so the newcomer finds the
  period complete and catches up from it. Receivers drop what they have already seen.
* An answer from another episode, or from earlier in the same one, means the world restarted (a sim
  restart or a scenario load): members start afresh from that answer. A scenario load first
  finishes the current period as a step would (every member answered, the recorder covering them),
  so no message of the old episode is still on its way when the new one starts. Stamps repeat from one
  episode to the next, so at each new period a member forgets anything stamped after it: that can
  only be a late message of an earlier episode (the services' own caches do the same).

``Ledger`` is the pure bookkeeping (which answers, which stamps seen), ``Member`` the bus side a
service's loop uses. Both are passed time, never read it.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from seaway.contract import keys
from seaway.contract.messages import LOCKSTEP_SERVICES, Message, PeriodDone
from seaway.runtime.bus import Bus, TypedPublisher
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import StampBounds, StampGate
from seaway.runtime.timeline import Timeline

log = logging.getLogger("seaway.lockstep")

RECORDER = "recorder"
"""The member that covers the others' answers (``PeriodDone.covers``) once they are on disk; it only
writes, so no request waits for it."""
MEMBERS = tuple(s for s in LOCKSTEP_SERVICES if s != "sim")
"""The services the sim waits for, once their member token has appeared."""
STALL_REPEAT_S = 2.0
"""A safety net, not a protocol step: a sim that has made no progress for this long (wall seconds)
repeats its answer, in case a newcomer's subscriptions reached the bus after the repeat it caused."""

Change = Literal["first", "next", "repeat", "restart", "stale"]


@dataclass(frozen=True, order=True)
class Period:
    """(episode, t_k [ns]): the identity of one lockstep period."""

    episode: int
    stamp_ns: int

    @classmethod
    def of(cls, answer: PeriodDone) -> Period:
        return cls(answer.episode, answer.stamp_ns)


def classify(current: Period | None, incoming: Period) -> Change:
    """How a sim answer for ``incoming`` relates to the period a member is at."""
    if current is None:
        return "first"
    if incoming.episode != current.episode or incoming.stamp_ns < current.stamp_ns:
        return "restart"
    if incoming.stamp_ns == current.stamp_ns:
        return "repeat"
    return "next"


class Ledger:
    """What one member knows: the latest answer of each member, and the stamps it has seen per key.

    ``watched`` are the key suffixes whose messages this member receives: only those can make an
    answer incomplete (a member never waits for a key it does not subscribe to).
    """

    def __init__(self, watched: Iterable[str] | None, consumed: bool = True) -> None:
        self.watched = None if watched is None else frozenset(watched)  # None: every key
        # Whether an answer's ``consumed`` list counts: it does for the estimator (it must apply the
        # command the sim applied), not for the recorder (that command was written, and answered
        # for, in the period it was published; a restarted recorder finds it in the file it left).
        self.consumed = consumed
        self.answers: dict[str, PeriodDone] = {}
        self.seen: dict[str, set[int]] = {}
        self.period: Period | None = None
        self.period_ns = 0

    def see(self, suffix: str, stamp_ns: int) -> bool:
        """Note a message seen; False (not noted) if it is stamped further ahead of the current
        period than any answer can list before the next period forgets it (``bounds``)."""
        if not self.within(stamp_ns):
            return False
        self.seen.setdefault(suffix, set()).add(stamp_ns)
        return True

    def bounds(self) -> StampBounds | None:
        """How far ahead of the current period a stamp may be (``seaway.runtime.stamps``); None
        before the first answer of the sim."""
        return StampBounds.lockstep(self.period_ns) if self.period is not None else None

    def within(self, stamp_ns: int) -> bool:
        b = self.bounds()
        return b is None or b.judge(stamp_ns, self.period.stamp_ns) is None  # type: ignore[union-attr]

    def has(self, suffix: str, stamp_ns: int) -> bool:
        return stamp_ns in self.seen.get(suffix, ())

    def on_answer(self, answer: PeriodDone) -> Change | None:
        """Note an answer; for the sim's, say how its period relates to the current one."""
        self.answers[answer.service] = answer
        if answer.service != "sim":
            return None
        incoming = Period.of(answer)
        change = classify(self.period, incoming)
        if change != "repeat":
            # Nothing of this episode is stamped after t_k yet: what is, is a late message of an
            # earlier episode (stamps repeat from one episode to the next), not to be counted when
            # this one gets there. What belongs to t_k (the first stamps of a new episode) stays;
            # only a sim that died in its very first period can blur the two.
            for stamps in self.seen.values():
                stamps.difference_update([s for s in stamps if s > incoming.stamp_ns])
        if change == "restart":
            self.answers = {"sim": answer}
        self.period, self.period_ns = incoming, answer.period_ns
        if change == "next":
            self._prune(incoming.stamp_ns - 2 * answer.period_ns)
        return change

    def _prune(self, before_ns: int) -> None:
        for stamps in self.seen.values():
            if stamps and min(stamps) < before_ns:
                stamps.difference_update([s for s in stamps if s < before_ns])

    def answer(self, service: str, period: Period | None = None) -> PeriodDone | None:
        """``service``'s latest answer if it is for ``period`` (default: the current one)."""
        a = self.answers.get(service)
        period = period or self.period
        return a if a is not None and period is not None and Period.of(a) == period else None

    def missing(self, answer: PeriodDone) -> list[tuple[str, int]]:
        """The (key suffix, stamp) an answer lists, on watched keys, that have not been seen."""
        out = []
        for listing in (answer.published, answer.consumed) if self.consumed else (answer.published,):
            for suffix, stamps in listing.items():
                if self.watched is not None and suffix not in self.watched:
                    continue
                seen = self.seen.get(suffix, set())
                out.extend((suffix, s) for s in stamps if s not in seen)
        return out

    def complete(self, answer: PeriodDone | None) -> bool:
        return answer is not None and not self.missing(answer)

    def all_answered(self, period: Period, members: Iterable[str], sim_seq: int) -> bool:
        """Whether every one of ``members`` has answered ``period``, the recorder (if a member)
        covering the latest answer of each other member and the sim's (``sim_seq``): what the clock
        of a lockstep run (the sim, or ``seaway replay --lockstep``) waits for before the next period.
        """
        members = list(members)
        if any(self.answer(m, period) is None for m in members):
            return False
        if RECORDER in members:
            covers = self.answer(RECORDER, period).covers  # type: ignore[union-attr]
            latest = {"sim": sim_seq, **{m: self.answers[m].seq for m in members if m != RECORDER}}
            if any(covers.get(m) != seq for m, seq in latest.items()):
                return False
        return True

    def held(self, period: Period) -> bool:
        """Whether the controller answered ``period`` with ``hold`` (nothing to fly): the clock waits
        for another answer, and that wait is not a stall."""
        ans = self.answer("controller", period)
        return ans is not None and ans.hold


def listing(messages: Iterable[tuple[keys.KeySpec, Message]]) -> dict[str, list[int]]:
    """``published`` of an answer: key suffix -> stamps, in publishing order."""
    out: dict[str, list[int]] = {}
    for spec, msg in messages:
        out.setdefault(spec.suffix, []).append(msg.stamp_ns)
    return out


class Member:
    """A lockstep member's side of the bus: its ledger fed from the bus, its answers and repeats.

    The service subscribes to its own inputs as usual and calls ``saw`` for each message it wants
    counted; ``changed`` wakes its loop whenever the ledger moved (an answer or a message arrived).
    ``answer`` publishes the period's messages then the ``PeriodDone``; a repeat of the sim's answer
    republishes the last one (``on_repeat`` lets the service add to that, e.g. to nothing).
    """

    def __init__(self, bus: Bus, service: str, watched: Iterable[str] | None,
                 seq_start: int | None = None, subscribe: bool = True,
                 consumed: bool = True, hears: Iterable[str] | None = None) -> None:
        """``hears``: the members whose answers this one needs (default: every other). Only the
        sim's classify a period; an answer nobody waits for still costs every receiver a decode
        on the period's critical path, so the estimator hears only the sim, the controller the
        sim and the estimator."""
        self.bus = bus
        self.service = service
        self.hears = frozenset(LOCKSTEP_SERVICES if hears is None else hears) - {service}
        self.ledger = Ledger(watched, consumed)
        self.changed = threading.Condition()
        self.version = 0  # bumped on every ledger change, under ``changed``
        self.restarts: list[tuple[Period | None, Period]] = []
        self.repeats = 0
        self._seq = itertools.count(time.time_ns() if seq_start is None else seq_start)
        self._pub = bus.publisher(keys.lockstep_spec(service), lockstep=True, express=True)
        self._last: tuple[list[tuple[TypedPublisher[Any], Message]], PeriodDone] | None = None
        self._publishers: dict[str, TypedPublisher[Any]] = {}
        self.on_restart: Callable[[Period | None, Period], None] | None = None
        self.stamps = StampGate(f"{service} (lockstep)", log)
        self.ratelog = RateLimitedLog(log)  # repeated warnings, per kind and key
        self.timeline = Timeline.from_env(service)  # seaway.runtime.timeline: off unless asked
        if subscribe:  # else the service feeds ``on_answer`` itself (the recorder, from its stream)
            for other in sorted(self.hears):
                bus.subscribe(keys.lockstep_spec(other), callback=self.on_answer, inline=True)

    # -- from the bus's threads -------------------------------------------------------------------

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
        self.saw_many(((suffix, stamp_ns),))

    def saw_many(self, seen: Iterable[tuple[str, int]]) -> None:
        """Note messages seen; wake the loop only if an answer of the current period lacked some.

        A member publishes its messages before its answer, so they almost always arrive first,
        with nothing to do yet: waking the loop for each (2-3 a period) cost a thread hand-over on
        the period's critical path. A member that follows no period (the sim) is always woken."""
        with self.changed:
            ledger = self.ledger
            waiting = ledger.period is None or any(
                Period.of(a) == ledger.period and ledger.missing(a) for a in ledger.answers.values())
            for suffix, stamp_ns in seen:
                ledger.see(suffix, stamp_ns)
            if waiting:
                self.version += 1
                self.changed.notify_all()

    def on_answer(self, key: str, answer: PeriodDone) -> None:
        if not key.endswith(f"/lockstep/{answer.service}"):  # valid, but not who may say it there
            self.ratelog.warning(("impostor", key), "lockstep answer on %s claims to be %s's: "
                                  "ignored", key, answer.service)
            return
        repeat = False
        self.timeline.mark("heard", answer.stamp_ns, answer.service)
        with self.changed:
            before = self.ledger.period
            change = self.ledger.on_answer(answer)
            if change == "restart":
                self.restarts.append((before, Period.of(answer)))
                if self.on_restart is not None:
                    self.on_restart(before, Period.of(answer))
            repeat = change == "repeat"
            lacking = self.waiting_for() if repeat else ""
            self.version += 1
            self.changed.notify_all()
        if lacking:  # expected while members start or restart: the sim repeats for them
            log.info("%s, lockstep t = %.3f s (episode %d), repeated: %s", self.service,
                     answer.stamp_ns / 1e9, answer.episode, lacking)
        if repeat:
            self.repeat()

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
                  + ", ".join(f"{suffix} @ {stamp / 1e9:.3f} s" for suffix, stamp in lacks)
                  for s, lacks in missing.items()]
        return "; ".join(parts)

    # -- from the service's loop ------------------------------------------------------------------

    def wait(self, version: int, timeout_s: float) -> int:
        """Block until the ledger moved past ``version`` (or ``timeout_s``); the new version."""
        with self.changed:
            if self.version == version:
                self.changed.wait(timeout_s)
            return self.version

    def publisher(self, spec: keys.KeySpec) -> TypedPublisher[Any]:
        pub = self._publishers.get(spec.suffix)
        if pub is None:
            pub = self._publishers[spec.suffix] = self.bus.publisher(spec, lockstep=True)
        return pub

    def answer(self, period: Period, period_ns: int,
               messages: Sequence[tuple[keys.KeySpec, Message]] = (), *, hold: bool = False,
               consumed: dict[str, list[int]] | None = None, covers: dict[str, int] | None = None,
               members: Sequence[str] = ()) -> PeriodDone:
        """Publish ``messages`` in order, then this member's answer for ``period`` listing them."""
        outs = [(self.publisher(spec), msg) for spec, msg in messages]
        for pub, msg in outs:
            pub.put(msg)
        done = PeriodDone(stamp_ns=period.stamp_ns, service=self.service,  # type: ignore[arg-type]
                          episode=period.episode, seq=next(self._seq), period_ns=period_ns,
                          published=listing(messages), consumed=consumed or {}, hold=hold,
                          covers=covers or {}, members=list(members))  # type: ignore[arg-type]
        self.timeline.mark("sent", period.stamp_ns)  # its messages are out; the answer leaves now
        self._pub.put(done)
        self._last = (outs, done)
        return done

    def working(self, period: Period) -> None:
        """The service's loop starts on ``period`` (``seaway.runtime.timeline``)."""
        self.timeline.mark("work", period.stamp_ns)

    def repeat(self, members: Sequence[str] | None = None) -> PeriodDone | None:
        """Publish the last answer again (same messages, new ``seq``), for a newcomer; the sim's
        names the members it now waits for."""
        last = self._last
        if last is None:
            return None
        outs, done = last
        for pub, msg in outs:
            pub.put(msg)
        update: dict[str, Any] = {"seq": next(self._seq)}
        if members is not None:
            update["members"] = list(members)
        again = done.model_copy(update=update)
        self._pub.put(again)
        self._last = (outs, again)
        self.repeats += 1
        return again

    def join(self) -> None:
        """Declare this member's token; call once its subscriptions are in place (the sim then
        repeats its period for it)."""
        self.bus.declare_lockstep_member(self.service)

    @property
    def last_answer(self) -> PeriodDone | None:
        return self._last[1] if self._last is not None else None
