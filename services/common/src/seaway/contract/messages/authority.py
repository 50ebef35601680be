"""Authority (producer: every process, about itself; ``seaway.runtime.refusals``)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import BaseModel, ConfigDict, Field

from seaway.contract.messages.base import Message

MAX_REFUSAL_ENTRIES = 256
"""Distinct (identity, action, key) triples one report lists; more are summed in ``overflow``."""


class RefusalCount(BaseModel):
    """How often one identity was refused one action on one key by the reporting process."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True)
    identity: str = Field(max_length=128, description="certificate common name of the sender, or "
                          "'unauthenticated' for a link refused before any identity was proven")
    action: str = Field(max_length=64, description="'put', 'delete', 'query', 'reply', "
                        "'declare_queryable', 'liveliness_token', ..., or 'connect' (a link)")
    key: str = Field(max_length=512, description="key expression refused ('' for a link)")
    count: int = Field(ge=1)
    last_ns: int = Field(ge=0, description="wall-clock time of the latest one [ns since epoch]")


class Refusals(Message):
    """What one process's access control refused since it started (``refusals/<identity>``).

    Counted by the receiving process from Zenoh's own access-control decisions; published when it
    changes (at most once a second) and answered on request. ``stamp_ns`` is wall-clock time, also
    in lockstep: a refusal is an event in the world, not in the simulation.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.Refusals"
    identity: str = Field(max_length=128, description="the process that refused (its identity)")
    total: int = Field(ge=0, description="every refusal since the process started")
    counts: list[RefusalCount] = Field(default_factory=list, max_length=MAX_REFUSAL_ENTRIES)
    overflow: int = Field(default=0, ge=0, description="refusals on triples beyond those listed")
