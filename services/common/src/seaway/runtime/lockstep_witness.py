"""The lockstep witness: the recorder's part in lockstep (``seaway.runtime.lockstep`` states the
protocol). It hears every member's bundle, and answers a period once all of it is on disk."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from seaway.contract import keys
from seaway.contract.messages import LOCKSTEP_SERVICES, MessageError, PeriodDone
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import Period, classify
from seaway.runtime.lockstep_member import Member

REPEAT_MEMORY = 256
"""Payloads per key a lockstep recorder remembers, to write a repeat (the same bytes again) once. A
repeat carries what a member kept of its last periods (``lockstep.KEPT_PERIODS``); with the 32 of
before, a key of more than about ten samples a period was written twice when the sim repeated."""


class LockstepWitness:
    """The recorder as a lockstep member: it answers a period once every member's bundle for it is
    written (its messages on their own keys) and flushed to disk.

    So a SIGKILL never loses a period the sim has moved past; a restarted recorder catches up from the
    repeat its arrival causes. Repeats (the same bytes again on a key) are not written twice. A bundle
    carries every message its answer lists (``seaway.contract.bundle``), and its answer is noted
    after them: an answer noted is complete, there is nothing else to wait for.
    """

    def __init__(self, bus: Bus, vessel: str, exprs: Sequence[str]) -> None:
        self.member = Member(bus, "recorder", watched=(), subscribe=False, consumed=False)
        self.answer_keys = {keys.lockstep_spec(s).key(vessel) for s in LOCKSTEP_SERVICES if s != "recorder"}
        self.sim_key = keys.lockstep_spec("sim").key(vessel)
        self.prefix = f"{keys.ROOT}/{vessel}/"
        self._recent: dict[str, dict[bytes, None]] = {}
        """Per key, the last ``REPEAT_MEMORY`` payloads written, oldest first (a dict: an ordered
        set with one lookup a sample)."""
        self._covered: dict[str, int] | None = None
        self._news = False
        """Whether an answer was noted since ``maybe_answer`` last looked: nothing else changes
        what the ledger covers."""
        self._started = False
        """Whether the first period has come (``lacking``: from then on never again)."""
        self.repeats_skipped = 0
        # A new episode repeats the old one's first messages byte for byte (deterministic): those
        # are new messages, to be written again.
        self.member.on_restart = lambda _before, _now: self._recent.clear()

    def heard(self, key: str, payload: bytes, carried: PeriodDone | None = None) -> PeriodDone | None:
        """The last sample a bus sample stands for (a bundle's answer: ``RecordingWriter.unpack``),
        about to be written after the rest: the answer decoded if it is another member's (None: it
        is not, or it is malformed, which is logged and then written as malformed), so that neither
        the writer nor ``written`` decodes it again. A sim answer from a restarted world (another
        episode, or time gone back) forgets the payloads remembered first: the new episode's first
        messages repeat the old one's byte for byte, and come in its bundle before the answer that
        would tell the ledger (a sim killed at 12 s restarted without its t_0 in the recording).
        ``carried``: the answer an in-process member encoded ``payload`` from, taken as it is."""
        if key not in self.answer_keys:
            return None
        if type(carried) is PeriodDone:
            answer = carried
        else:
            try:
                answer = PeriodDone.decode(payload)
            except MessageError as err:
                self.member.ratelog.warning(("malformed answer", key),
                                            "lockstep answer on %s ignored: %s", key, err)
                return None
        if key == self.sim_key and not answer.resent:
            with self.member.changed:
                current = self.member.ledger.period
            if classify(current, Period.of(answer)) == "restart":
                self._recent.clear()
        return answer

    def admit(self, key: str, payload: bytes) -> bool:
        """Whether to write this sample: not when it repeats bytes just written on its key."""
        known = self._recent.get(key)
        if known is None:
            if not key.startswith(self.prefix):
                return True
            known = self._recent[key] = {}
        if payload in known:
            self.repeats_skipped += 1
            return False
        known[payload] = None
        if len(known) > REPEAT_MEMORY:
            del known[next(iter(known))]  # the oldest
        return True

    def written(self, answers: list[tuple[str, PeriodDone]]) -> None:
        """Note the answers just written (or skipped as repeats of what was), after what they list."""
        for key, answer in answers:
            if not answer.resent:  # a copy of an earlier one: its messages are written, no news
                self.member.on_answer(key, answer)
                self._news = True

    def lacking(self) -> bool:
        """Whether the writer must wake for every sample, not only for answers: before the first
        period (a bundle carries what its answer lists, so after that nothing is ever lacking)."""
        if self._started:  # a ledger's period, once set, is never unset
            return False
        with self.member.changed:
            self._started = self.member.ledger.period is not None
        return not self._started

    def covers(self) -> tuple[Period, int, dict[str, int]] | None:
        """(period, period_ns, covers) when the current period is all written, else None."""
        member = self.member
        with member.changed:
            ledger = member.ledger
            tick = ledger.answer("sim")
            if tick is None or not ledger.complete(tick):
                return None
            covers = {"sim": tick.seq}
            for m in tick.members:
                if m == "recorder":
                    continue
                ans = ledger.answer(m)
                if ans is None or not ledger.complete(ans):
                    return None
                covers[m] = ans.seq
            return Period.of(tick), tick.period_ns, covers

    def maybe_answer(self, flush: Callable[[], None]) -> bool:
        """Flush (``flush``: onto the disk, the OS has it) and answer if the current period is
        complete and not yet answered as it is (only an answer noted since it last looked can
        make it so). A ``flush`` that raises (no room on the disk) leaves the news for the next
        look, which answers once a flush goes through."""
        if not self._news:
            return False
        ready = self.covers()
        if ready is None or ready[2] == self._covered:
            self._news = False
            return False
        period, period_ns, covers = ready
        flush()  # on disk before we say so
        self._news = False
        self.member.answer(period, period_ns, covers=covers)
        self._covered = covers
        return True


