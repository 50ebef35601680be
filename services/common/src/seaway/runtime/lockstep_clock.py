"""The lockstep clock: the node that owns simulated time (``seaway.runtime.lockstep`` states the
protocol), driven by ``LockstepClock``; the sim's node (``seaway_sim.node``) is one.

For each period t_k of the current episode, from one bus session and in this order:

  (a) publish the node's messages for t_k (``ClockNode.outputs``: the sim's sensor samples due in
      (t_{k-1}, t_k], its truth, disturbance and clock), then the clock's answer on
      ``lockstep/<clock>`` listing them, the thrust command applied over (t_{k-1}, t_k] and the
      members it waits for;
  (b) wait until every member has answered t_k (``ready``): the controller with a command stamped
      t_k that the clock holds, the recorder covering everyone's latest answer. A member joining
      (its member token appears) makes the clock repeat (a); so does a stall of ``STALL_REPEAT_S``;
  (c) apply that command for one period (``ClockNode.advance``), so the world goes to t_{k+1};
      back to (a).

With a time limit (``ClockNode.until_s``, the sim's ``--until-s``), the clock does not step
(c) past it: it holds at the last period t_k <= the limit (``last_period_ns``), as it holds for a
controller with nothing to fly, and the launcher, seeing the states stop there, ends the run
(``seaway launch --max-mission-s``).

Without a controller among the members (a test's responder), (b) takes any command stamped >= t_k.
A scenario load (the node's request, which calls ``before_load`` and ``after_load``) starts a new
episode: time restarts at 0 and every member starts afresh (the estimator re-initialises, the
controller waits for a new mission).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import Message, ThrustCommand
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import (
    MEMBERS,
    PASSIVE_POLL_S,
    RECORDER,
    RECORDER_LAG,
    STALL_REPEAT_S,
    Period,
)
from seaway.runtime.lockstep_member import Member
from seaway.runtime.node import Node

log = logging.getLogger("seaway.runtime.lockstep_clock")

EPISODE_WAIT_S = 5.0
"""How long a scenario load waits at most, half for the old episode's last period to be finished
(``Lockstep.finish_episode``), half for the members to answer the new episode's first period
(``Lockstep.await_episode``), before it goes on anyway (a member restarting: the launcher brings it
back) [wall s]. Clients of ``sim/scenario`` wait 10 s for the reply."""

EPISODE_POLL_S = 0.01
"""How often a scenario load's waits look again (the estimator's answers come through a passive
source, which wakes nobody) [wall s]."""


@dataclass
class LockstepStats:
    periods: int = 0
    stale_commands: int = 0
    repeats: int = 0
    holds: int = 0


class ClockNode(Node):
    """A node that owns simulated time (the sim): what ``LockstepClock`` asks of it. ``lock`` is
    held while a period is published or stepped, and by a scenario load, which bumps ``episode``
    and calls ``before_load`` (under the lock) and ``after_load`` (after it), set by the clock."""

    lock: threading.Lock
    episode: int = 0
    stall_s: float = STALL_REPEAT_S
    """Wall seconds without progress after which the clock repeats its period (a safety net)."""
    until_s: float | None = None
    """Simulated seconds of an episode after which the clock flies no further period (None: no
    limit): it holds at the last period at or before them."""
    before_load: Callable[[], str] | None = None
    after_load: Callable[[int, int], str] | None = None

    def time_ns(self) -> int:
        """The current period's stamp t_k [ns] (0 at an episode's start)."""
        raise NotImplementedError

    def outputs(self, period_ns: int) -> list[tuple[keys.KeySpec, Message]]:
        """The messages of the current period, in publishing order (lock held)."""
        raise NotImplementedError

    def advance(self, cmd: ThrustCommand, period_ns: int) -> None:
        """Apply ``cmd`` over one period, to t_{k+1} (lock held)."""
        raise NotImplementedError


def last_period_ns(until_s: float, period_ns: int) -> int:
    """The last period t_k a clock limited to ``until_s`` [s] flies to [ns]: the last multiple of
    the period at or before the limit (t_0 = 0 at the least)."""
    return round(until_s * 1e9) // period_ns * period_ns


class LockstepClock:
    """The lockstep loop over one ``ClockNode``."""

    def __init__(self, bus: Bus, app: ClockNode, period_s: float, stop: threading.Event,
                 stall_s: float = STALL_REPEAT_S) -> None:
        if not period_s > 0 or not stall_s > 0:
            raise ValueError("period and stall time must be > 0")
        self.app = app
        self.period_ns = round(period_s * 1e9)
        self.stall_s = stall_s
        self.stop = stop
        self.stats = LockstepStats()
        self.members: set[str] = set()
        self._joined = False
        self._commands: dict[int, ThrustCommand] = {}  # stamp -> latest command with that stamp
        self._applied: int | None = None  # stamp of the command applied over the last period
        self._progress = threading.Lock()  # one thread at a time moves the period on
        self._at: Period | None = None  # the period published last (under ``_progress``)
        self._stepped = False  # whether ``_at``'s command was applied (under ``_progress``)
        self._max_periods: int | None = None
        # The last period flown to (``ClockNode.until_s``) [ns]; None: no limit.
        self.last_ns = (None if app.until_s is None
                        else last_period_ns(app.until_s, self.period_ns))
        # The controller's command comes in its bundle; a stand-in that is no member (a test's
        # responder) publishes it alone, on its key.
        # Over a transport, every member's bundle is taken on the bus's thread as it arrives, and
        # the period moves on there as soon as it can (``_on_ready``), as a member answers there:
        # waking this loop for it cost a thread hand-over every period, and the estimator's and the
        # recorder's bundles, taken from rings, were often not in yet when the controller's came
        # (another connection), so the loop polled for them every ``PASSIVE_POLL_S``.
        # In process, the controller's bundle reaches the sim inside the put that carries the chain
        # along (the sim's own, on this loop's thread) or inside the controller's own put, whose
        # thread must not run the chain on (it holds the controller's step): the loop moves on,
        # taking the estimator's answer with the controller's and the recorder's for the period
        # before, nearly always in by then (``_passive_due``).
        self.member = Member(bus, app.name, watched={keys.THRUST.suffix},
                             passive=("estimator", RECORDER) if bus.delivers_in_put else ())
        self.member.deliver = lambda _key, cmd: self._keep(cmd)  # once ``self.member`` names it
        if not bus.delivers_in_put:
            self.member.on_ready = self._on_ready
        bus.subscribe(keys.THRUST, callback=self._on_thrust, inline=True, bundles=False)
        bus.watch_lockstep_members(self._on_member)
        app.before_load = self.finish_episode
        app.after_load = self.await_episode

    # -- bus threads --------------------------------------------------------------------------------

    def _on_thrust(self, _key: str, cmd: ThrustCommand) -> None:
        """A command alone on its key (a stand-in that is no member): wakes the loop."""
        if self._keep(cmd):
            self._wake()

    def _keep(self, cmd: ThrustCommand) -> bool:
        """Hold a command for the period it answers; whether it was admitted."""
        # A command answers a period the sim has published; one stamped further ahead of the sim's
        # time is wrong (or a late one of an earlier episode): dropped, counted, logged once.
        if not self.member.admit(keys.THRUST.suffix, cmd.stamp_ns, self.app.time_ns(),
                                 self.period_ns):
            return False
        with self.member.changed:
            self._commands[cmd.stamp_ns] = cmd
            if len(self._commands) > 64:  # commands for periods long gone (stale or repeated)
                for stamp in sorted(self._commands)[:-8]:
                    del self._commands[stamp]
        # Not ``member.saw``: the sim's ledger never learns a period of its own (it does not hear
        # its own answers), so nothing would ever prune what it noted there.
        return True

    def _wake(self) -> None:
        """Wake the loop: it looks again at the period."""
        with self.member.changed:
            self.member.version += 1
            self.member.changed.notify_all()

    def _on_ready(self) -> None:
        """After a member's bundle was taken (on the bus's thread): apply the controller's command
        and publish the next period here if they can be now. When another thread is moving the period
        on (the loop, or the in-memory bus delivering inside its put), that one looks again."""
        if not self._progress.acquire(blocking=False):
            self._wake()
            return
        try:
            self._advance(blocking=False)
        finally:
            self._progress.release()

    def _on_member(self, service: str, alive: bool) -> None:
        if alive and service in MEMBERS:
            with self.member.changed:
                if service not in self.members:
                    log.info("lockstep: %s joined; waiting for it every period from now on", service)
                self.members.add(service)
                self._joined = True
                self.member.version += 1
                self.member.changed.notify_all()
        elif not alive and service in self.members:
            # Expected at every stop (the launcher stops the members first); after a crash the
            # launcher restarts it and says so. Nothing for the user to do here.
            log.info("lockstep: %s is gone; holding until it is back", service)

    def finish_episode(self) -> str:
        """A scenario load's wait before the new episode starts (``ClockNode.before_load``, under the
        app's lock, so the loop publishes no further period): until every member has answered the
        sim's last period and the recorder covers those answers, as before any step. The old
        episode's last messages are then on disk in its own time: the controller's last status,
        stamped at the old episode's end and heard by the recorder after the new episode began, was
        logged in the new one's time and ended its mission there. '' once so; after
        half of ``EPISODE_WAIT_S`` (a member dead or restarting), a note saying who had not."""
        deadline = time.monotonic() + EPISODE_WAIT_S / 2
        last = self.member.last_answer
        if last is None:  # nothing published yet: nothing to finish
            return ""
        period = Period.of(last)  # after a step, the core is a period on: not yet published
        while True:
            self.member.drain()  # the estimator's answer comes through a passive source
            with self.member.changed:
                if self.answered(period, lag=0):  # the recorder too: the episode ends on disk
                    return ""
                left = deadline - time.monotonic()
                if left <= 0:
                    absent = self._absent(period)
                    lacking = (f"no answer from {', '.join(absent)}" if absent
                               else "the recorder has not covered every answer")
                    log.warning("lockstep: t = %.3f s of episode %d not finished after %.1f s (%s); "
                                "starting the new episode anyway", period.stamp_ns / 1e9,
                                period.episode, EPISODE_WAIT_S / 2, lacking)
                    return f"; the last episode's last period was not finished ({lacking})"
                self.member.changed.wait(min(left, EPISODE_POLL_S))

    def await_episode(self, episode: int, stamp_ns: int) -> str:
        """A scenario load's wait before its reply (``ClockNode.after_load``, on the request's thread):
        wake the loop, so that it publishes the new episode's first period now, and wait until every
        member that serves requests (all but the recorder, which only writes) has answered that
        period. A request sent after the reply (a mission, say) then finds the stack in the new
        episode; before, it could reach the controller first and be taken at the old episode's held
        period (its acceptance then recorded in the new episode's time). '' once they answered;
        after half of ``EPISODE_WAIT_S``, or if another load came, a note saying so."""
        first = Period(episode, stamp_ns)
        deadline = time.monotonic() + EPISODE_WAIT_S / 2
        with self.member.changed:
            self.member.version += 1
            self.member.changed.notify_all()
        while True:
            self.member.drain()  # the estimator's answer comes through a passive source
            with self.member.changed:
                if self.app.episode != episode:
                    return "; another scenario was loaded since"
                lacking = [m for m in sorted(self.members - {RECORDER})
                           if not self._answered_since(m, first)]
                if not lacking:
                    return ""
                left = deadline - time.monotonic()
                if left <= 0:
                    log.warning("lockstep: episode %d's first period not yet answered by %s after "
                                "%.1f s; replying to the scenario request anyway", episode,
                                ", ".join(lacking), EPISODE_WAIT_S / 2)
                    return f"; its first period not yet answered by {', '.join(lacking)}"
                self.member.changed.wait(min(left, EPISODE_POLL_S))

    def _answered_since(self, service: str, first: Period) -> bool:
        """Whether ``service``'s latest answer is for ``first`` or a later period of its episode.
        Only the latest is kept, and a stack with a mission to fly is periods past the first by the
        time a waiting thread looks; under ``member.changed``."""
        a = self.member.ledger.answers.get(service)
        return a is not None and a.episode == first.episode and a.stamp_ns >= first.stamp_ns

    # -- the period -----------------------------------------------------------------------------------

    @property
    def period(self) -> Period:
        return Period(self.app.episode, self.app.time_ns())

    def publish_period(self, blocking: bool = True) -> Period | None:
        """Step (a); the period it published (None: not ``blocking`` and the app's lock is held,
        by a scenario load)."""
        app = self.app
        if not app.lock.acquire(blocking=blocking):
            return None
        try:
            out = app.outputs(self.period_ns)
            period = self.period
            with self.member.changed:
                members = sorted(self.members)
                self._joined = False
                # A command for t_k can only come after this answer: one here already is a late
                # one from an earlier episode (stamps repeat across episodes).
                for stamp in [s for s in self._commands if s >= period.stamp_ns]:
                    del self._commands[stamp]
            consumed = ({keys.THRUST.suffix: [self._applied]}
                        if self._applied is not None and period.stamp_ns > 0 else {})
            self.member.answer(period, self.period_ns, out, consumed=consumed, members=members)
            return period
        finally:
            app.lock.release()

    def repeat_period(self, period: Period, why: str) -> None:
        """Step (a) again, unchanged (the same messages), for a newcomer or after a stall."""
        with self.member.changed:
            members = sorted(self.members)
            self._joined = False
        log.info("lockstep: repeating t = %.3f s (%s)", period.stamp_ns / 1e9, why)
        self.stats.repeats += 1
        self.member.repeat(members)

    def command(self, period: Period) -> ThrustCommand | None:
        """The command to apply over period t_k, once the controller (or, without one, anybody)
        has answered with it; under ``member.changed``."""
        if "controller" in self.members:
            ans = self.member.ledger.answer("controller", period)
            if ans is None or ans.hold:
                return None
            return self._commands.get(period.stamp_ns)
        stamps = [s for s in self._commands if s >= period.stamp_ns]
        return self._commands[min(stamps)] if stamps else None

    def answered(self, period: Period, lag: int = RECORDER_LAG) -> bool:
        """Whether every member but the recorder has answered t_k, and the recorder t_{k-lag} or
        later (all bundles up to it on disk; ``RECORDER_LAG``); under ``member.changed``."""
        ledger = self.member.ledger
        others = self.members - {RECORDER}
        if not ledger.all_answered(period, others, self.member.last_answer.seq):  # type: ignore[union-attr]
            return False
        if RECORDER not in self.members:
            return True
        return ledger.recorded(self._back(period, lag), period)

    def _back(self, period: Period, lag: int) -> Period:
        """The period ``lag`` periods before ``period`` (t_0 at the most): the one the recorder must
        have answered before the sim moves on from ``period``."""
        return Period(period.episode, max(0, period.stamp_ns - lag * self.period_ns))

    def wait_for(self, period: Period, test: Callable[[Period], Any]) -> Any:
        """Step (b): block until ``test(period)`` is truthy (its value), repeating the period for
        newcomers and after stalls; None if stopped or the scenario changed."""
        member = self.member
        version = -1
        stalled_since = time.monotonic()
        held = False
        while not self.stop.is_set():
            if self.app.episode != period.episode:
                return None
            member.drain()
            with member.changed:
                value = test(period)
                joined = self._joined
                if not value and not joined and member.version == version:
                    member.changed.wait(PASSIVE_POLL_S if self._passive_due(period)
                                        else min(self.stall_s, 0.25))
                version = member.version
            if value:
                return value
            if joined:
                self.repeat_period(period, "a member joined")
                stalled_since = time.monotonic()
                continue
            if member.ledger.held(period):
                if not held:
                    self.stats.holds += 1
                    log.info("lockstep: holding at t = %.3f s (the controller has nothing to fly)",
                             period.stamp_ns / 1e9)
                held = True
                stalled_since = time.monotonic()  # holding is not stalling
                continue
            if time.monotonic() - stalled_since >= self.stall_s:
                self.repeat_period(period, self._waiting_for(period))
                stalled_since = time.monotonic()
        return None

    def _passive_due(self, period: Period) -> bool:
        """Whether a passive source's bundle is due (under ``member.changed``): once the controller
        answered ``period``, the estimator had (its bundle comes on another connection), and the
        recorder's answer to the period ``RECORDER_LAG`` before is what the next one waits for.
        Never over a transport, where the sim has no passive sources (every bundle wakes it)."""
        ledger = self.member.ledger
        if not self.member.passive or ledger.answer("controller", period) is None:
            return False
        if "estimator" in self.members and ledger.answer("estimator", period) is None:
            return True
        return RECORDER in self.members and not ledger.recorded(self._back(period, RECORDER_LAG),
                                                                period)

    def _absent(self, period: Period) -> list[str]:
        """The members that have not answered ``period``; under ``member.changed``."""
        return [m for m in sorted(self.members) if self.member.ledger.answer(m, period) is None]

    def _waiting_for(self, period: Period) -> str:
        lacking = self._absent(period)
        if not lacking:
            return "stalled: waiting for the recorder to cover every answer, or for the command"
        return f"stalled: no answer yet from {', '.join(lacking)}"

    def at_limit(self, period: Period) -> bool:
        """Whether ``period`` is the last the time limit lets the clock fly to."""
        return self.last_ns is not None and period.stamp_ns >= self.last_ns

    def step(self, cmd: ThrustCommand, period: Period, blocking: bool = True) -> bool | None:
        """Step (c); False (nothing done) if the scenario changed since step (a), None if not
        ``blocking`` and the app's lock is held (by a scenario load)."""
        if not self.app.lock.acquire(blocking=blocking):
            return None
        try:
            self.member.working(period)
            if self.period != period:
                return False
            self.app.advance(cmd, self.period_ns)
            self._applied = cmd.stamp_ns
        finally:
            self.app.lock.release()
        if cmd.stamp_ns != period.stamp_ns:
            self.stats.stale_commands += 1
        self.stats.periods += 1
        return True

    def _advance(self, blocking: bool) -> None:
        """Move the period on as far as it can go now: apply the command of the period published
        once it is in (c), publish the next once every member answered (a). Under ``_progress``;
        not ``blocking`` (the bus's thread), what would wait (a scenario load holding the app's
        lock) is left to the loop, woken for it."""
        while not self.stop.is_set():
            period = self._at
            if period is None or self.app.episode != period.episode:
                return  # the loop starts the episode
            self.member.drain()  # the estimator's and the recorder's answers, in their rings
            if not self._stepped:
                if self.at_limit(period):
                    return  # the time limit: the loop holds here (``run``)
                with self.member.changed:
                    cmd = self.command(period)
                if cmd is None:
                    return
                stepped = self.step(cmd, period, blocking)
                if not stepped:
                    if stepped is None:
                        self._wake()
                    return
                self._stepped = True
            with self.member.changed:
                done = self.answered(period)
                due = not done and not blocking and self._passive_due(period)
            if not done:
                if due:  # the loop polls the rings for it
                    self._wake()
                return
            if self._max_periods is not None and self.stats.periods >= self._max_periods:
                self._wake()
                return
            published = self.publish_period(blocking)
            if published is None:
                self._wake()
                return
            self._at, self._stepped = published, False

    def run(self, max_periods: int | None = None) -> LockstepStats:
        """Run until stopped (or ``max_periods`` commands applied and answered).

        The plant steps as soon as the command is in; the next period is published once every
        member (the recorder last) has answered this one, so integrating overlaps the recorder's
        write. Both happen on the thread that takes the controller's answer when they can
        (``_on_ready``); this loop starts each episode, repeats a period for a newcomer or after a
        stall, and looks at the passive sources while an answer from one is due."""
        log.info("lockstep: period %.3f s; members join as their health tokens appear",
                 self.period_ns / 1e9)
        self._max_periods = max_periods
        member = self.member
        version = -1
        seen: tuple[Period | None, bool, int] | None = None
        held: Period | None = None
        stalled_since = time.monotonic()
        while not self.stop.is_set():
            with self._progress:
                if self._at is None or self.app.episode != self._at.episode:
                    if self._at is not None:  # a new episode: time restarts at 0
                        self._applied = None
                        with member.changed:
                            self._commands.clear()
                    self._at, self._stepped = self.publish_period(), False
                self._advance(blocking=True)
                period, stepped = self._at, self._stepped
                assert period is not None
                with member.changed:
                    if (max_periods is not None and self.stats.periods >= max_periods
                            and stepped and self.answered(period)):
                        break
            with member.changed:
                if not self._joined and member.version == version:
                    member.changed.wait(PASSIVE_POLL_S if self._passive_due(period)
                                        else min(self.stall_s, 0.25))
                version = member.version
            with self._progress:
                period = self._at
                if (now := (period, self._stepped, self.stats.periods)) != seen:
                    seen, stalled_since = now, time.monotonic()
                with member.changed:
                    joined, holding = self._joined, member.ledger.held(period)
                if joined:
                    self.repeat_period(period, "a member joined")
                    stalled_since = time.monotonic()
                elif holding or self.at_limit(period):
                    if held != period:
                        held = period
                        self.stats.holds += 1
                        log.info("lockstep: holding at t = %.3f s (%s)", period.stamp_ns / 1e9,
                                 "the controller has nothing to fly" if holding
                                 else f"the time limit, --until-s {self.app.until_s:g}")
                    stalled_since = time.monotonic()  # holding is not stalling
                elif time.monotonic() - stalled_since >= self.stall_s:
                    self.repeat_period(period, self._waiting_for(period))
                    stalled_since = time.monotonic()
        log.info("lockstep ended at t = %.3f s: %d periods, %d repeats, %d holds",
                 self.app.time_ns() / 1e9, self.stats.periods, self.stats.repeats, self.stats.holds)
        return self.stats
