"""Where a lockstep period's time goes: each member's marks, on the one clock all processes share.

Off unless ``$SEAWAY_LOCKSTEP_TRACE`` names a folder (``seaway bench lockstep`` sets it). Then each
lockstep member (``seaway.runtime.lockstep_member.Member``) notes, per period t_k (its ``stamp_ns``):

* ``arrived``: another member's bundle for t_k reached this process's Python (Zenoh's callback was
  entered; ``of`` names whose). Only for a source that moves the member on: a passive one's bundle
  waits in a ring by design;
* ``heard``: that member's answer for t_k was taken: the passive sources' bundles first, then this
  one decoded and its inputs handed to the service (which may do its own work there: the estimator
  advances its filter on each input);
* ``work``: the service's loop started on t_k (everything it needed was in);
* ``sent``: this member's messages for t_k are out and its answer is being put (the answer's own
  put counts as transport: with several peers it can outlast the first peer's receipt).

Times are ``CLOCK_MONOTONIC`` nanoseconds, one clock for every process on a Linux machine, so marks
of different processes subtract: ``sent`` of the sim to ``arrived`` of the estimator is the
transport (the put, Zenoh, the hand-over to Python); ``arrived`` to ``heard`` the intake; ``heard``
to ``work`` the wake-up of the service's loop; ``work`` to ``sent`` the service's own work. At exit
the marks are written as JSON lines to ``<folder>/<service>-<pid>.jsonl`` (``[t_ns, what, of,
stamp_ns]``); at most ``MAX_MARKS`` are kept (about half an hour of periods at 10 Hz), so a
forgotten variable cannot grow a process for ever.
"""

from __future__ import annotations

import atexit
import json
import os
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

ENV_TRACE = "SEAWAY_LOCKSTEP_TRACE"
MAX_MARKS = 100_000
Mark = Literal["arrived", "heard", "work", "sent"]


class Timeline:
    """One member's marks (``mark`` is a no-op when off, so callers never test)."""

    def __init__(self, service: str, folder: Path | None) -> None:
        self.service, self.folder = service, folder
        self.marks: list[tuple[int, str, str, int]] | None = [] if folder is not None else None
        if folder is not None:
            atexit.register(self.write)

    @classmethod
    def from_env(cls, service: str) -> Timeline:
        folder = os.environ.get(ENV_TRACE)
        return cls(service, Path(folder) if folder else None)

    def mark(self, what: Mark, stamp_ns: int, of: str = "", at_ns: int | None = None) -> None:
        """Note ``what`` for period ``stamp_ns`` now, or at ``at_ns`` (``time.monotonic_ns``) when
        the period was only known later (a bundle's arrival is noted once its answer is read)."""
        if self.marks is not None and len(self.marks) < MAX_MARKS:
            self.marks.append((time.monotonic_ns() if at_ns is None else at_ns, what, of, stamp_ns))

    def write(self) -> Path | None:
        if self.folder is None or self.marks is None:
            return None
        path = self.folder / f"{self.service}-{os.getpid()}.jsonl"
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            path.write_text("".join(json.dumps(m) + "\n" for m in self.marks))
        except OSError:  # a trace is a measurement aid: never a reason to fail an exit
            return None
        return path


@dataclass(frozen=True)
class Event:
    t_ns: int
    service: str
    what: str
    of: str
    stamp_ns: int


def read(folder: Path) -> Iterator[Event]:
    """Every mark written to ``folder`` (a restarted member leaves a second file: both are read)."""
    for path in sorted(folder.glob("*.jsonl")):
        service = path.stem.rsplit("-", 1)[0]
        for line in path.read_text().splitlines():
            t_ns, what, of, stamp_ns = json.loads(line)
            yield Event(t_ns, service, what, of, stamp_ns)


def first_marks(events: Iterable[Event]) -> dict[tuple[str, str, str], dict[int, int]]:
    """(service, what, of) -> stamp -> the first time it was marked (a repeat is not a new one)."""
    out: dict[tuple[str, str, str], dict[int, int]] = {}
    for e in events:
        out.setdefault((e.service, e.what, e.of), {}).setdefault(e.stamp_ns, e.t_ns)
    return out
