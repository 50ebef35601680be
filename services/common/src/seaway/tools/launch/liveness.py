"""What each service must keep publishing, and the watch that tells a hung process from a quiet one.

A process can hang without dying (SIGSTOP, a deadlock, a driver stuck in the kernel): its exit code
never comes, and its health token stays as long as its Zenoh session answers. The launcher restarts
such a process like a dead one when it is *overdue*: it stopped publishing what it must, or its
health token has been gone for ``TOKEN_GRACE_S`` while the process still runs. What a service must
publish is defined once, here (``DUTIES``, per service and per clock); a profile's process may
replace its list with ``must_publish`` (``[]``: watch nothing but the token).

A duty is one of:

* ``Duty(key, within_s)``, a stream: once the process has published ``key`` since it became ready,
  it publishes it at least every ``within_s`` (real time: the sim's truth, vehicle_io's status, the
  estimator's state, the controller's command).
* ``Duty(key, within_s, after=T)``, a lockstep answer (``seaway.runtime.lockstep``): every answer
  heard on ``T`` for period P is matched within ``within_s`` by an answer on ``key`` for P, or for a
  later period heard after it (a member answers each period its inputs reached; one it answered
  before the trigger was heard counts).
* ``Duty(key, within_s, after=T, moves_on=True)``: every answer on ``T`` for P that is not a hold is
  followed within ``within_s`` by an answer on ``key`` for a later period, or by any answer on
  ``key`` heard after it (the sim steps once everyone answered, and repeats a stalled period every
  ``STALL_REPEAT_S``). A hold stops simulated time legitimately: it opens no duty.

So simulated time that stands still because the controller has nothing to fly (it answers "hold")
makes nobody overdue, while a member that does not answer a period its inputs reached is.

A duty only counts for a period the sim has reached: its answers are the only ones that move
simulated time, and no member can answer a period before it. A trigger for a period the sim has
not reached yet is *parked* until the sim's answer for it is heard (the launcher hears each key on
its own, so another member's answer can come first), and dropped, with a warning naming it, if the
sim does not get there within the duty's time: an answer stamped for a period nobody will reach (a
stamp far ahead, a later episode) would otherwise open a duty no healthy member can meet.

``Watch`` is the pure bookkeeping (samples and time in, overdue processes out), unit-tested; the
supervisor feeds it from the launcher's Zenoh session.
"""

from __future__ import annotations

import collections
import json
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from pydantic import Field, model_validator

from seaway.contract import bundle, keys
from seaway.contract.config import ConfigModel
from seaway.contract.messages import LOCKSTEP_SERVICES, PeriodDone
from seaway.runtime.lockstep import STALL_REPEAT_S
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import describe_ns

log = logging.getLogger(__name__)

WALL_WITHIN_S = 5.0
"""A real-time stream silent this long is a hung producer: each of them publishes at 2 Hz or more,
also with nothing to do (the controller's zero commands, the estimator's predictions)."""
LOCKSTEP_WITHIN_S = 30.0
"""A lockstep member that has not answered a period its inputs reached after this long is hung: a
period takes milliseconds, a first one after a start a few seconds; and the sim repeats a stalled
period every ``STALL_REPEAT_S``, so it is never silent this long unless held."""
TOKEN_GRACE_S = 5.0
"""A health token gone this long while its process still runs: hung (a process that exits withdraws
its token just before; its exit code is noticed first). Zenoh itself drops a silent peer's token
after its lease (10 s by default), so a stopped process is seen within about 15 s."""
RECENT_PERIODS = 64
"""Lockstep answers remembered per key (to match a trigger heard after the answer)."""
MAX_OPEN = 256
"""Open duties kept per process and duty (the oldest decide; more would say nothing new)."""

assert LOCKSTEP_WITHIN_S > 5 * STALL_REPEAT_S


class Duty(ConfigModel):
    """One thing a process must keep publishing (see the module docstring)."""

    key: str = Field(description="suffix of a registered key the process publishes")
    within_s: float = Field(gt=0, description="wall seconds it may take")
    after: str | None = Field(default=None, description="lockstep answer key (suffix) whose every "
                              "answer this key must match; None: a stream")
    moves_on: bool = Field(default=False, description="with 'after': a later period must follow "
                           "every answer that is not a hold (the sim)")

    @model_validator(mode="after")
    def _known(self) -> Duty:
        for name, suffix in (("key", self.key), ("after", self.after)):
            if suffix is None:
                continue
            spec = keys.spec_for_suffix(suffix)
            if spec is None or spec.kind != "topic":
                topics = ", ".join(s.suffix for s in keys.REGISTRY if s.kind == "topic")
                raise ValueError(f"must_publish: {name} {suffix!r} is not a registered topic; "
                                 f"topics: {topics}")
            if self.after is not None and spec.message is not PeriodDone:
                raise ValueError(f"must_publish: {name} {suffix!r}: a duty with 'after' pairs "
                                 "lockstep answers (lockstep/<service>)")
        if self.moves_on and self.after is None:
            raise ValueError("must_publish: moves_on needs 'after'")
        return self

    def describe(self) -> str:
        if self.after is None:
            return f"{self.key} at least every {self.within_s:g} s"
        what = "a later period" if self.moves_on else "each period"
        return f"{self.key} for {what} of {self.after} within {self.within_s:g} s"


def _stream(spec: keys.KeySpec) -> Duty:
    return Duty(key=spec.suffix, within_s=WALL_WITHIN_S)


def _answers(spec: keys.KeySpec, after: keys.KeySpec, moves_on: bool = False) -> Duty:
    return Duty(key=spec.suffix, within_s=LOCKSTEP_WITHIN_S, after=after.suffix, moves_on=moves_on)


DUTIES: dict[str, dict[str, tuple[Duty, ...]]] = {
    "wall": {
        "sim": (_stream(keys.SIM_TRUTH),),
        "vehicle_io": (_stream(keys.VEHICLE_STATUS),),
        "estimator": (_stream(keys.NAV_STATE),),
        "controller": (_stream(keys.THRUST),),
    },
    # The lockstep chain: the sim's answer, then the estimator's, the controller's and the
    # recorder's for the same period; the sim moves on after every answer that is not a hold.
    "lockstep": {
        "sim": (_answers(keys.LOCKSTEP_SIM, keys.LOCKSTEP_CONTROLLER, moves_on=True),),
        "estimator": (_answers(keys.LOCKSTEP_ESTIMATOR, keys.LOCKSTEP_SIM),),
        "controller": (_answers(keys.LOCKSTEP_CONTROLLER, keys.LOCKSTEP_ESTIMATOR),),
        "recorder": (_answers(keys.LOCKSTEP_RECORDER, keys.LOCKSTEP_CONTROLLER),),
    },
}
"""What each service must publish, by the run's clock (``wall`` or ``lockstep``). A service not
listed (the recorder in real time, the router) is watched through its health token only."""


def duties_for(service: str | None, clock: str, override: Sequence[Duty] | None = None
               ) -> tuple[Duty, ...]:
    """The duties of a process: the profile's ``override`` if given, else ``DUTIES``'s."""
    if override is not None:
        return tuple(override)
    if service is None:
        return ()
    return DUTIES.get(clock, {}).get(service, ())


Period = tuple[int, int]
"""(episode, stamp_ns) of a lockstep answer: orders the periods of a run."""

SIM_ANSWERS = keys.LOCKSTEP_SIM.suffix
"""The key whose answers say which period simulated time has reached."""


def describe_period(period: Period) -> str:
    """A period for a person; any stamp an answer can carry (a float cannot hold every int)."""
    return f"{describe_ns(period[1])} (episode {period[0]})"


@dataclass
class _Open:
    period: Period
    since_s: float


@dataclass
class _DutyState:
    duty: Duty
    last_s: float | None = None  # a stream: when the key was last heard
    open: collections.deque[_Open] = field(default_factory=collections.deque)
    parked: collections.deque[_Open] = field(default_factory=collections.deque)
    """Triggers for periods the sim had not reached when they were heard (the module docstring)."""


class _Recent:
    """The periods of the last ``RECENT_PERIODS`` answers heard on a key, with their count per
    period and their latest: ``_met`` asks each trigger in O(1) instead of walking them all."""

    def __init__(self) -> None:
        self._order: collections.deque[Period] = collections.deque()
        self._count: collections.Counter[Period] = collections.Counter()
        self._latest: Period | None = None

    def add(self, period: Period) -> None:
        order, count = self._order, self._count
        order.append(period)
        count[period] += 1
        if self._latest is None or period > self._latest:
            self._latest = period
        if len(order) > RECENT_PERIODS:
            gone = order.popleft()
            count[gone] -= 1
            if not count[gone]:
                del count[gone]
                if gone == self._latest:  # a restart's lower periods since: the latest of those left
                    self._latest = max(count)

    def has(self, period: Period) -> bool:
        return period in self._count

    def has_after(self, period: Period) -> bool:
        return self._latest is not None and self._latest > period


class Watch:
    """Which armed processes are overdue on their duties, from the samples the launcher hears.

    ``arm`` when a process becomes ready (its duties start then), ``disarm`` when it exits or is
    restarted; ``heard`` for every sample on a watched key; ``overdue`` says who is late and why.
    Time (monotonic seconds) is passed in; no thread safety here (the supervisor holds a lock).
    """

    def __init__(self) -> None:
        self._armed: dict[str, list[_DutyState]] = {}
        self._recent: dict[str, _Recent] = collections.defaultdict(_Recent)
        self._sim: Period | None = None  # the period of the sim's latest answer
        self.unreached: collections.Counter[str] = collections.Counter()
        """Triggers dropped per key because the sim never reached their period."""
        self._log = RateLimitedLog(log, every_s=60.0)

    @staticmethod
    def keys_of(duties: Iterable[Duty]) -> set[str]:
        """The key suffixes ``duties`` need to hear: with a lockstep answer among them, the sim's
        answers too (they say which periods a duty can count for)."""
        out = set()
        for d in duties:
            out.add(d.key)
            if d.after is not None:
                out.update((d.after, SIM_ANSWERS))
        return out

    def arm(self, process: str, duties: Sequence[Duty], now_s: float) -> None:
        """``process`` is ready: its duties count from ``now_s``."""
        self._armed[process] = [_DutyState(d) for d in duties]
        for d in duties:  # what it answered before this start is not its own
            self._recent.pop(d.key, None)

    def disarm(self, process: str) -> None:
        self._armed.pop(process, None)

    def armed(self, process: str) -> bool:
        return process in self._armed

    def heard(self, suffix: str, now_s: float, period: Period | None = None,
              hold: bool = False) -> None:
        """A sample on ``suffix``; ``period`` and ``hold`` for a lockstep answer."""
        if period is not None:
            self._recent[suffix].add(period)
            if suffix == SIM_ANSWERS:
                self._sim = period  # simulated time is there (a restart: back there)
        for states in self._armed.values():
            for st in states:
                d = st.duty
                if d.key == suffix:
                    if d.after is None:
                        st.last_s = now_s
                    elif period is not None:
                        self._close(st, period)
                opens = d.after == suffix and period is not None and not (d.moves_on and hold)
                if not opens:
                    continue
                if not self._reached(period):  # type: ignore[arg-type]
                    if len(st.parked) < MAX_OPEN:
                        st.parked.append(_Open(period, now_s))  # type: ignore[arg-type]
                elif not self._met(d, period) and len(st.open) < MAX_OPEN:  # type: ignore[arg-type]
                    st.open.append(_Open(period, now_s))  # type: ignore[arg-type]
        if period is not None and suffix == SIM_ANSWERS:
            for states in self._armed.values():
                self._unpark(states, now_s)

    def _reached(self, period: Period) -> bool:
        """Whether the sim has answered ``period`` (or a later one of its episode, or moved on to a
        later episode); True before its first answer is heard (nothing to judge by)."""
        sim = self._sim
        if sim is None:
            return True
        return period[1] <= sim[1] if period[0] == sim[0] else period[0] < sim[0]

    def _unpark(self, states: list[_DutyState], now_s: float) -> None:
        """After a sim answer: open the parked triggers the sim has reached, and drop those it has
        not reached within their duty's time (their period is not one the run will get to)."""
        for st in states:
            if not st.parked:
                continue
            d = st.duty
            keep: collections.deque[_Open] = collections.deque()
            for o in st.parked:
                if self._reached(o.period):
                    if not self._met(d, o.period) and len(st.open) < MAX_OPEN:
                        st.open.append(_Open(o.period, now_s))
                elif now_s - o.since_s > d.within_s:
                    self._drop_unreached(d, o, now_s)
                else:
                    keep.append(o)
            st.parked = keep

    def _drop_unreached(self, d: Duty, o: _Open, now_s: float) -> None:
        assert d.after is not None
        self.unreached[d.after] += 1
        sim = self._sim
        self._log.warning(
            ("unreached", d.after),
            "liveness: ignoring a %s answer for period %s: the sim has not reached it in %g s "
            "(it is at %s), so nobody can owe %s for it",
            d.after, describe_period(o.period), d.within_s,
            "no period" if sim is None else describe_period(sim), d.key,
            now_ns=round(now_s * 1e9))

    def _met(self, d: Duty, trigger: Period) -> bool:
        """Whether answers already heard on ``d.key`` meet a trigger for ``trigger`` heard now."""
        recent = self._recent.get(d.key)
        if recent is None:
            return False
        return recent.has_after(trigger) if d.moves_on else recent.has(trigger)

    @staticmethod
    def _close(st: _DutyState, answer: Period) -> None:
        """An answer for ``answer`` heard now: it meets the open duties it answers."""
        d = st.duty
        keep: collections.deque[_Open] = collections.deque()
        for o in st.open:
            # A member answers the period itself, or a later one (it skipped ahead: a fast
            # replay); the sim answers a later period, or repeats one (it is alive, stalled).
            met = True if d.moves_on else answer >= o.period
            if not met:
                keep.append(o)
        st.open = keep

    def overdue(self, now_s: float) -> dict[str, str]:
        """Armed processes overdue on a duty at ``now_s``, each with the reason."""
        out: dict[str, str] = {}
        for process, states in self._armed.items():
            for st in states:
                d = st.duty
                if d.after is None:
                    if st.last_s is not None and now_s - st.last_s > d.within_s:
                        out[process] = (f"published no {d.key} for {now_s - st.last_s:.1f} s "
                                        f"(it must: {d.describe()})")
                        break
                elif st.open and now_s - st.open[0].since_s > d.within_s:
                    o = st.open[0]
                    out[process] = (f"no {d.key} for period {describe_period(o.period)} "
                                    f"{now_s - o.since_s:.1f} s after {d.after} "
                                    f"(it must: {d.describe()})")
                    break
        return out


# -- lockstep answers as the launcher hears them ------------------------------------------------

CHAIN_RANK = {keys.lockstep_spec(s).suffix: i for i, s in enumerate(LOCKSTEP_SERVICES)}
"""A lockstep answer key's place in a period's chain (sim 0, estimator 1, controller 2, recorder 3)."""


def answer_period(payload: bytes, carried: Any = None) -> tuple[tuple[int, int] | None, bool]:
    """((episode, stamp_ns), hold) of a lockstep answer; (None, False) if it is malformed.

    Only the three fields needed, read as plainly as can be (each member validates the answers it
    acts on; a malformed one is no answer here, absurd numbers included: JSON's Infinity, an
    episode below 0 or a stamp outside the contract's 0..``MAX_STAMP_NS``, which every member
    refuses). Which periods an answer can oblige anybody to answer is the watch's to judge
    (``liveness.Watch``: only those the sim has reached).
    ``carried``: what an in-process bus handed along with the bytes (``bundle.Carried``): its
    answer is read instead of the bytes (a composed stack's launcher decodes no bundle)."""
    from seaway.contract.messages import MAX_STAMP_NS

    ans_carried = bundle.carried_answer(carried)
    if ans_carried is not None:
        if ans_carried.resent:
            return None, False
        return (ans_carried.episode, ans_carried.stamp_ns), ans_carried.hold
    try:
        ans = json.loads(bundle.answer_of(payload))  # a bundle's first line (seaway.contract.bundle)
        if ans.get("resent"):  # a copy of an earlier answer, for a restarted recorder: no news
            return None, False
        episode, stamp_ns = int(ans["episode"]), int(ans["stamp_ns"])
        if episode < 0 or not 0 <= stamp_ns <= MAX_STAMP_NS:
            return None, False
        return (episode, stamp_ns), bool(ans.get("hold"))
    except (ValueError, TypeError, KeyError, AttributeError, OverflowError):
        return None, False
