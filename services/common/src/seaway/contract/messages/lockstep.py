"""The lockstep protocol's answers (producer: every lockstep member; ``seaway.runtime.lockstep``)."""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal, Self

from pydantic import Field, StringConstraints

from seaway.contract.messages.base import Message

LOCKSTEP_SERVICES = ("sim", "estimator", "controller", "recorder")
"""The services that take part in lockstep (``seaway.runtime.lockstep``), each on ``lockstep/<service>``."""
LockstepService = Literal["sim", "estimator", "controller", "recorder"]
_MAX_LISTED = 1000  # stamps listed per key in one period: far above any sensor rate x period
StampLists = dict[Annotated[str, StringConstraints(pattern=r"^[a-z_]+/[a-z_]+$", max_length=64)],
                  Annotated[list[Annotated[int, Field(ge=0)]], Field(max_length=_MAX_LISTED)]]


class PeriodDone(Message):
    """One lockstep member's answer to period ``stamp_ns`` (t_k) of episode ``episode``.

    It says what the member published for the period (``published``: key suffix -> the stamps of
    those messages) and, for the sim, what it consumed (``consumed``: the thrust command it applied
    over (t_{k-1}, t_k]), so a receiver knows exactly which messages to wait for and never waits on a
    timeout (``seaway.runtime.lockstep`` states the protocol). ``seq`` numbers a member's answers
    (unique across its restarts); ``covers`` (the recorder) names, per member, the ``seq`` of the
    answer whose messages it has written to disk. ``hold`` (the controller): nothing to fly, so the
    sim does not step until another answer comes (a mission is set). ``resent``: the recorder may
    trail the others by a period, so a member sends its previous bundle again before repeating its
    last one (``seaway.runtime.lockstep``).
    """

    SCHEMA: ClassVar[str] = "seaway.v1.PeriodDone"
    service: LockstepService
    episode: int = Field(ge=0, description="counts the sim's scenario (re)starts; time restarts at 0")
    seq: int = Field(ge=0)
    period_ns: int = Field(gt=0, le=60 * 10**9, description="the run's control period [ns]")
    published: StampLists = Field(default_factory=dict)
    consumed: StampLists = Field(default_factory=dict)
    hold: bool = False
    covers: dict[LockstepService, Annotated[int, Field(ge=0)]] = Field(default_factory=dict)
    members: list[LockstepService] = Field(default_factory=list, max_length=len(LOCKSTEP_SERVICES),
                                           description="sim: the members it waits for")
    resent: bool = Field(default=False, description="a copy of this member's previous answer (with "
                         "its messages), sent again for a recorder that (re)joined: only a "
                         "recorder takes it")

    @classmethod
    def decode(cls, data: bytes | bytearray | memoryview | str) -> Self:
        """The answer of a lockstep bundle (``seaway.contract.bundle``: its first line), or of a
        lone ``PeriodDone``: every reader of an answer reads it the same way, whichever it heard."""
        raw = bytes(data) if not isinstance(data, str) else data.encode()
        return super().decode(raw.split(b"\n", 1)[0])
