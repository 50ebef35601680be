"""The lockstep clock from a recording (``seaway replay --lockstep``): a lockstep recording replayed
as its sim would, paced by the members.

A recording of a lockstep run holds the sim's answers (``lockstep/sim``, ``seaway.runtime.lockstep``):
each closes one period and lists the samples published for it. Replayed at a fixed rate, the live
members (estimator, controller, recorder) either idle (at the recorded pace, which for a lockstep
recording is simulated time) or are outrun (``--fast``: the next period arrives before they have
answered this one, and what they skip is lost). Here the recorded answers are the clock instead:

* the samples kept before an answer go out, then the answer, naming the live members it waits for
  (the recorded one named the recorded run's; the recorder covers the members an answer names);
* the next period waits until every live member (its member token present) has answered this one,
  the recorder covering the latest answers, exactly as the sim waits (``Ledger.all_answered``); a
  controller answering ``hold`` before it has flown in this episode (no mission yet) is waited for
  without limit, one holding after it flew (its mission ended before the recorded one did: another
  controller, or a replay that diverged) is an answer, and the replay goes on to the recording's end;
* a member that joins, or a period nobody completes within ``STALL_REPEAT_S``, makes the replay send
  the period again (the same samples): the members then repeat their answers, as they do for the
  sim.

So the replay goes as fast as the members do, loses nothing, and waits for a restarted one. Open
loop: the recorded vessel does not respond to the new commands.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence

from seaway.contract import bundle, keys
from seaway.contract.messages import PeriodDone
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import MEMBERS, STALL_REPEAT_S, Ledger, Period
from seaway.runtime.ratelog import RateLimitedLog

log = logging.getLogger("seaway.runtime.lockstep_replay")

SIM_ANSWER_SUFFIX = keys.lockstep_spec("sim").suffix


class LockstepPacer:
    """Holds each replayed period until the live lockstep members of ``bus.vessel`` have answered it.

    ``clock`` [s, monotonic] is passed in for the stall timer.
    """

    def __init__(self, bus: Bus, stop: threading.Event, stall_s: float = STALL_REPEAT_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not stall_s > 0:
            raise ValueError("stall time must be > 0")
        self.stop, self.stall_s, self.clock = stop, stall_s, clock
        self.ledger = Ledger(watched=(), consumed=False)  # answers only: the members check samples
        self.changed = threading.Condition()
        self.members: set[str] = set()
        self.periods = 0
        self.repeats = 0
        self.holds = 0
        self.ended_early = False
        """Whether the controller's mission ended before the recording's (``play``)."""
        self.ratelog = RateLimitedLog(log)  # a flood of impostor answers is counted, not echoed
        self._joined = False
        self._version = 0
        self._flew_episode: int | None = None
        """The episode in which the controller last answered with a command (not a hold)."""
        self._pub = bus.raw_publisher(keys.lockstep_spec("sim").key(bus.vessel), bundle.ENCODING,
                                      block=True, express=True)
        for member in MEMBERS:
            bus.subscribe(keys.lockstep_spec(member), callback=self._on_answer, inline=True)
        bus.watch_lockstep_members(self._on_member)

    # -- bus threads --------------------------------------------------------------------------------

    def _on_answer(self, key: str, answer: PeriodDone) -> None:
        if not key.endswith(f"/lockstep/{answer.service}") or answer.service == "sim":
            self.ratelog.warning(("impostor", key), "lockstep answer on %s claims to be %s's: "
                                 "ignored", key, answer.service)
            return
        if answer.resent:  # a copy of an earlier answer, for a restarted recorder
            return
        with self.changed:
            self.ledger.on_answer(answer)
            if answer.service == "controller" and not answer.hold:
                self._flew_episode = answer.episode
            self._version += 1
            self.changed.notify_all()

    def _on_member(self, service: str, alive: bool) -> None:
        if not alive or service not in MEMBERS:
            return
        with self.changed:
            if service not in self.members:
                log.info("lockstep replay: %s joined; waiting for it every period from now on",
                         service)
            self.members.add(service)
            self._joined = True
            self._version += 1
            self.changed.notify_all()

    # -- the replay's thread ------------------------------------------------------------------------

    def play(self, answer: PeriodDone, publish: Callable[[], None],
             lines: Sequence[tuple[str, bytes]] = (), hold_ends: bool = False) -> bool:
        """``publish`` the samples of the period ``answer`` closes that its bundle does not carry,
        then its bundle (``seaway.contract.bundle``): ``answer`` naming the live members, with
        ``lines`` (key suffix, bytes: the sim's messages of the period, as recorded); and hold
        until every live member has answered it; False if stopped first.

        The controller's ``hold`` is waited past (its mission has not come yet), unless
        ``hold_ends``: the recording does not go on past this period (it ends, or repeats it), so
        the hold is the mission's end; or unless the controller flew earlier in this episode: its
        mission ended before the recorded one, and waiting would never end."""
        period = Period.of(answer)

        def send() -> None:
            with self.changed:
                members = sorted(self.members)
                self._joined = False
            publish()
            tick = answer.model_copy(update={"members": members})
            with self.changed:
                self.ledger.on_answer(tick)
            self._pub.put(bundle.encode(tick.encode(), lines))

        send()
        since = self.clock()
        version = -1
        held = False
        while not self.stop.is_set():
            with self.changed:
                ended = hold_ends or self._flew_episode == period.episode
                done = self.ledger.all_answered(period, self.members, answer.seq) and (
                    ended or not self.ledger.held(period))
                if done and not hold_ends and self.ledger.held(period) and not self.ended_early:
                    self.ended_early = True
                    log.warning("lockstep replay: the controller holds at t = %.3f s after flying "
                                "(its mission ended before the recorded one): the replay goes on "
                                "to the recording's end", period.stamp_ns / 1e9)
                joined, self._joined = self._joined, False
                if not done and not joined and self._version == version:
                    self.changed.wait(min(self.stall_s, 0.25))
                version = self._version
                holding = self.ledger.held(period)
            if done:
                self.periods += 1
                return True
            if holding and not joined:  # the controller has nothing to fly yet: not a stall
                if not held:
                    self.holds += 1
                    log.info("lockstep replay: holding at t = %.3f s (the controller has nothing "
                             "to fly)", period.stamp_ns / 1e9)
                held = True
                since = self.clock()
                continue
            if joined or self.clock() - since >= self.stall_s:
                log.info("lockstep replay: sending t = %.3f s again (%s)", period.stamp_ns / 1e9,
                         "a member joined" if joined else self._waiting_for(period))
                send()
                self.repeats += 1
                since = self.clock()
        return False

    def _waiting_for(self, period: Period) -> str:
        with self.changed:
            lacking = [m for m in sorted(self.members) if self.ledger.answer(m, period) is None]
        return (f"no answer yet from {', '.join(lacking)}" if lacking
                else "waiting for the recorder to cover every answer")
