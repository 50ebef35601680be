"""Lockstep: how the sim, the estimator, the controller and the recorder share simulated time.

One mechanism, in one place; each service's loop only says when a period is ready for it and what it
publishes (services/sim/README.md, "The lockstep protocol", walks one period through).

THE PROTOCOL

* Time is split into episodes (``episode`` counts the sim's scenario starts; a restarted sim starts
  at 0 again) and, within one, into periods t_k = k * period (the run's control period), t_0 = 0.
* Each member answers each period with ONE sample on ``lockstep/<service>``, its bundle
  (``seaway.contract.bundle``): its ``PeriodDone``, which names what it published for the period
  (``published``: key suffix -> stamps), and those messages themselves. So whoever hears an answer
  has what it lists at once, and a receiver never waits on a timeout to learn that something is not
  coming. (One sample rather than one per message: each sample heard costs a process a hand-over
  from Zenoh's thread to Python, which was most of a period's time.)
* The sim answers first (its answer is the period's tick): the sensor samples due in (t_{k-1}, t_k],
  truth, disturbance and clock, and in ``consumed`` the thrust command it applied over
  (t_{k-1}, t_k]. It steps to t_{k+1} once every member but the recorder has answered t_k, the
  controller with a command the sim holds (an answer with ``hold`` means "nothing to fly": no step
  until another answer), and publishes t_{k+1} once the recorder has answered t_{k-1} or later:
  the recorder may trail by one period (``RECORDER_LAG``), so its writing overlaps the next
  period's work instead of adding a hand-over to every period. Every member keeps what it sent
  for its last three periods (``KEPT_PERIODS``: a held period can be answered several times) and,
  before it repeats its last bundle, sends the others again (``resent``; only a recorder takes
  them), so a restarted recorder gets everything it can have missed.
* The estimator answers t_k once it has the sim's answer and the thrust command the sim applied
  (``consumed``, from the controller's bundle of the period before); the controller once it has the
  estimator's answer; the recorder once every member's latest answer for t_k, with what it carries,
  is on disk.
* Members are the services whose member token (a liveliness token on ``lockstep/<service>``,
  ``lockstep_member.Member.join``) has appeared since the sim started. Once a member, always a
  member: a member that dies is waited for until it is back (the launcher restarts it), so nothing
  happens without it and nothing is lost.
* A member that (re)joins makes the sim repeat its answer (same messages, same stamps, new ``seq``);
  on a repeat every member repeats its last answer (the same bytes), so the newcomer finds the
  period complete and catches up from it; not one of an earlier episode, which would be no use.
  Receivers drop what they have already seen.
* An answer from another episode, or from earlier in the same one, means the world restarted (a sim
  restart or a scenario load): members start afresh from that answer. A scenario load first
  finishes the current period as a step would (every member answered, the recorder covering them),
  so no message of the old episode is still on its way when the new one starts. Stamps repeat from one
  episode to the next, so at each new period a member forgets anything stamped after it: that can
  only be a late message of an earlier episode (the services' own caches do the same).

``Ledger`` is the pure bookkeeping (which answers, which stamps seen), ``Member``
(``seaway.runtime.lockstep_member``) the bus side a
service's loop uses. Both are passed time, never read it. Processes that are not members (a display,
a test) need not know about bundles: ``Bus.subscribe`` of a key takes it out of its producer's
bundles too.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Literal, NamedTuple

from seaway.contract import keys
from seaway.contract.messages import LOCKSTEP_SERVICES, Message, PeriodDone
from seaway.runtime.stamps import LOCKSTEP_AHEAD_PERIODS, StampBounds, describe_ns

RECORDER_LAG = 1
"""Periods the recorder's answers may trail the sim's: the sim publishes t_{k+1} once the recorder
has answered t_{k-1} (the members keep their bundles of a period more, ``KEPT_PERIODS``)."""
RECORDER = "recorder"
"""The member that covers the others' answers (``PeriodDone.covers``) once they are on disk; it only
writes, so no request waits for it."""
MEMBERS = tuple(s for s in LOCKSTEP_SERVICES if s != "sim")
"""The services the sim waits for, once their member token has appeared."""
CHAIN = tuple(s for s in LOCKSTEP_SERVICES if s != RECORDER)
"""The services a period passes through one after another (sim, estimator, controller, and back to
the sim): the critical path, where only one of them works at a time. The recorder writes beside it
(``RECORDER_LAG``)."""
KEPT_PERIODS = RECORDER_LAG + 2
"""The periods whose bundles a member keeps, to send again for a restarted recorder (``repeat``).

The sim publishes t_{k+1} once the recorder's latest answer is for t_{k-1} or later. A recorder that
dies right after answering t_r can have missed answers given to t_r after its own: a member answers
a period again where it held (the controller taking a mission at a held period). The sim can
still publish t_{r+1} and t_{r+2}, and no more. So what the recorder may lack lies in the last
three periods a member answered."""
PASSIVE_POLL_S = 0.0005
"""How often a member looks again at its passive sources while it knows a bundle from one is due
(sent, on another connection than the bundle that says so) [wall s]: nothing wakes it for them."""
STALL_REPEAT_S = 2.0
"""A safety net, not a protocol step: a sim that has made no progress for this long (wall seconds)
repeats its answer, in case a newcomer's subscriptions reached the bus after the repeat it caused."""

Change = Literal["first", "next", "repeat", "restart", "stale"]

_NOTHING: frozenset[int] = frozenset()


class Period(NamedTuple):
    """(episode, t_k [ns]): the identity of one lockstep period.

    A named tuple, not a frozen dataclass: every member makes and compares several a period, and a
    tuple is made and compared in C, a frozen dataclass through Python code."""

    episode: int
    stamp_ns: int

    @classmethod
    def of(cls, answer: PeriodDone) -> Period:
        return cls(answer.episode, answer.stamp_ns)

    def leads_to(self, other: Period) -> bool:
        """Whether this period is ``other`` or comes before it in the same stretch of time: the same
        episode, not stamped later (stamps start again from 0 in a new episode, and a restarted
        sim's episode is 0 again, so neither the order of episodes nor of stamps alone says)."""
        return self.episode == other.episode and self.stamp_ns <= other.stamp_ns


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

    def refusal(self, answer: PeriodDone, own: PeriodDone | None = None) -> str | None:
        """Why ``answer`` cannot be taken (None: it can), named for the log: an answer that claims
        what no member can have done would otherwise count for ever.

        * ``ahead``: another member's answer for a period further ahead of the current one (the
          sim's latest answer; ``own``: the sim's own last answer, for the sim's ledger, which
          never hears itself) than ``LOCKSTEP_AHEAD_PERIODS``: no member answers a period before
          the sim has published it, and such an answer would stand in for every period up to it
          (``recorded``). One of another episode is judged by the sim's answers (``classify``).
        * ``listing``: a stamp in ``published`` or ``consumed`` after the answer's own period by
          more than ``LOCKSTEP_AHEAD_PERIODS``: a member publishes, and the sim applies, messages
          of the period it answers; a later stamp could never be seen (``see`` refuses it), so a
          member would wait on it for ever."""
        if own is not None:
            ref, ref_period_ns = Period.of(own), own.period_ns
        else:
            ref, ref_period_ns = self.period, self.period_ns
        if answer.service != "sim" and ref is not None and answer.episode == ref.episode \
                and answer.stamp_ns > ref.stamp_ns + LOCKSTEP_AHEAD_PERIODS * ref_period_ns:
            return (f"ahead: {answer.service}'s answer for t = {describe_ns(answer.stamp_ns)} "
                    f"(episode {answer.episode}) lies beyond the current period t = "
                    f"{describe_ns(ref.stamp_ns)} by more than {LOCKSTEP_AHEAD_PERIODS} periods")
        limit = answer.stamp_ns + LOCKSTEP_AHEAD_PERIODS * answer.period_ns
        for name, stamps_by_key in (("published", answer.published), ("consumed", answer.consumed)):
            for suffix, stamps in stamps_by_key.items():
                if stamps and (latest := max(stamps)) > limit:
                    return (f"listing: {answer.service}'s answer for t = "
                            f"{describe_ns(answer.stamp_ns)} (episode {answer.episode}) lists in "
                            f"{name} {suffix} @ t = {describe_ns(latest)}, more than "
                            f"{LOCKSTEP_AHEAD_PERIODS} periods after its own period")
        return None

    def give_up(self, suffix: str, stamp_ns: int) -> None:
        """Note a message as seen that will never come (its sender died putting it), whatever its
        stamp: a stamp ``see`` would refuse must not be waited for either (an answer's listings are
        bounded by ``refusal``, so this cannot fill the ledger)."""
        self.seen.setdefault(suffix, set()).add(stamp_ns)

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
            # What already belongs to the new period stays: another member's answer can come before
            # the sim's (another connection; the controller often hears the estimator's first answer
            # of an episode first, and that is the one that moves it on). Dropped, it was waited for
            # until the sim repeated the period for the stall, seconds later.
            self.answers = {s: a for s, a in self.answers.items() if Period.of(a) == incoming}
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
        # Compared field by field: asked several times a period by every member.
        return a if (a is not None and period is not None and a.stamp_ns == period.stamp_ns
                     and a.episode == period.episode) else None

    def _unseen(self, answer: PeriodDone) -> Iterator[tuple[str, int]]:
        """The (key suffix, stamp) an answer lists, on watched keys, not seen yet, lazily."""
        watched, seen_by = self.watched, self.seen
        for listing in (answer.published, answer.consumed) if self.consumed else (answer.published,):
            for suffix, stamps in listing.items():
                if watched is not None and suffix not in watched:
                    continue
                seen = seen_by.get(suffix, _NOTHING)
                for s in stamps:
                    if s not in seen:
                        yield suffix, s

    def missing(self, answer: PeriodDone) -> list[tuple[str, int]]:
        """The (key suffix, stamp) an answer lists, on watched keys, that have not been seen."""
        return list(self._unseen(answer))

    def lacks(self, answer: PeriodDone) -> bool:
        """Whether ``missing(answer)`` is not empty, stopping at the first miss (asked for every
        bundle, and nearly always of an answer that lacks nothing)."""
        return next(self._unseen(answer), None) is not None

    def missing_consumed(self, answer: PeriodDone) -> list[tuple[str, int]]:
        """The (key suffix, stamp) an answer lists as consumed, on watched keys, not seen: another
        member's messages, which reach this one in that member's bundle, not in this answer's."""
        if not self.consumed:
            return []
        return [(suffix, s) for suffix, stamps in answer.consumed.items()
                if self.watched is None or suffix in self.watched
                for s in stamps if s not in self.seen.get(suffix, set())]

    def complete(self, answer: PeriodDone | None) -> bool:
        return answer is not None and not self.lacks(answer)

    def current(self, answer: PeriodDone) -> bool:
        """Whether ``answer`` is for the current period."""
        period = self.period
        return (period is not None and answer.stamp_ns == period.stamp_ns
                and answer.episode == period.episode)

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

    def recorded(self, period: Period, published: Period | None = None) -> bool:
        """Whether the recorder's latest answer is for ``period`` or a later period of its episode:
        all the members' bundles up to it are on disk (it answers a period once it has written the
        bundles of that period, and each member's come in order). ``published``: the latest period
        the sim has published; an answer stamped after it is for a period nobody has published yet,
        so it says nothing of what is on disk (taken as written, it would let the sim run on
        unrecorded for the rest of the episode)."""
        a = self.answers.get(RECORDER)
        return (a is not None and a.episode == period.episode and a.stamp_ns >= period.stamp_ns
                and (published is None or (a.episode == published.episode
                                           and a.stamp_ns <= published.stamp_ns)))

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
