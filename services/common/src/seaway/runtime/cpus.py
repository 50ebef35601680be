"""Which CPUs a stack's processes may run on (Linux CPU affinity), defined once.

``seaway launch --cpus 0`` keeps a whole stack (the launcher, every service it starts, all their
threads) on CPU 0; ``seaway study`` gives each of its parallel stacks a CPU set of its own
(``partition``). Why: in lockstep a period's work runs one process after another (sim, estimator,
controller), each waking the next; kept on one CPU they wake each other without an inter-processor
interrupt, find their caches warm, and never migrate; and two stacks pinned apart do not take
each other's CPU in the middle of a hand-over (``seaway bench lockstep`` and ``seaway study`` with
``--pin`` and ``--no-pin`` measure what it is worth on a machine).

Given two CPUs or more, a lockstep stack's chain (``seaway.runtime.lockstep.CHAIN``: sim, estimator,
controller, which work one at a time) gets the lowest CPU of the set to itself and everything else
(the recorder, the launcher) the others (``split_chain``): the chain's hand-overs stay on one CPU,
and the recorder's writing neither takes that CPU nor evicts the chain's caches.

A thread's affinity is its own: a new thread, and a child process, inherit their creator's. So a
process is pinned by setting every one of its threads (``pin_threads``), before it starts the
processes that should follow it.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable
from pathlib import Path


class CpuSetError(ValueError):
    """A CPU list that cannot be used here; the text says what is wrong and what is allowed."""


def allowed() -> frozenset[int]:
    """The CPUs this process may run on now (its affinity: a container or ``taskset`` narrows it)."""
    return frozenset(os.sched_getaffinity(0))


def format_cpus(cpus: Iterable[int]) -> str:
    """A CPU set as the kernel's list format: ``{0, 1, 2, 5}`` -> ``'0-2,5'``."""
    runs = [[c for _, c in run] for _, run in
            itertools.groupby(enumerate(sorted(set(cpus))), lambda ic: ic[1] - ic[0])]
    return ",".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else str(r[0]) for r in runs)


def parse_cpus(text: str, available: frozenset[int] | None = None) -> frozenset[int]:
    """The CPU set of a list in the kernel's format (``0``, ``0,2``, ``0-3,6``), each CPU one this
    process may run on (``available``, default ``allowed()``); CpuSetError naming the bad part and
    the CPUs allowed otherwise."""
    available = allowed() if available is None else available
    allowed_text = f"allowed here: {format_cpus(available)}"
    cpus: set[int] = set()
    for part in text.strip().split(","):
        lo, sep, hi = part.strip().partition("-")
        try:
            first = int(lo)
            last = int(hi) if sep else first
        except ValueError:
            raise CpuSetError(f"CPU list {text!r}: {part.strip()!r} is not a CPU number or a range "
                              f"like 0-3 ({allowed_text})") from None
        if first < 0 or last < first:
            raise CpuSetError(f"CPU list {text!r}: {part.strip()!r} is not a range of CPU numbers "
                              f"from low to high ({allowed_text})")
        if last > max(available, default=-1):  # checked before the set is made: '0-99999999'
            raise CpuSetError(f"CPU list {text!r}: CPU {last} cannot be used by this process "
                              f"({allowed_text})")
        cpus.update(range(first, last + 1))
    outside = cpus - available
    if outside:
        raise CpuSetError(f"CPU list {text!r}: CPU {format_cpus(outside)} cannot be used by this "
                          f"process ({allowed_text})")
    return frozenset(cpus)


def partition(cpus: frozenset[int], groups: int) -> list[frozenset[int]] | None:
    """``cpus`` split into ``groups`` sets of consecutive CPUs as even as they come (sizes differ by
    at most one), one per parallel stack; None when there is nothing to split: fewer than two
    groups, or more groups than CPUs (stacks would then share a CPU while another is idle)."""
    ordered = sorted(cpus)
    if groups < 2 or groups > len(ordered):
        return None
    size, extra = divmod(len(ordered), groups)
    out, start = [], 0
    for i in range(groups):
        end = start + size + (1 if i < extra else 0)
        out.append(frozenset(ordered[start:end]))
        start = end
    return out


def split_chain(cpus: frozenset[int]) -> tuple[frozenset[int], frozenset[int]] | None:
    """(the lockstep chain's CPUs, everything else's) of a stack kept on ``cpus``: the lowest CPU,
    and the others; None for fewer than two CPUs (nothing to split: all share the one)."""
    if len(cpus) < 2:
        return None
    first = min(cpus)
    return frozenset({first}), frozenset(cpus - {first})


def pin_threads(pid: int, cpus: frozenset[int]) -> int:
    """Set the affinity of every thread of process ``pid`` (0: this one) to ``cpus``; the number
    of threads set. A thread that ends meanwhile is skipped; OSError if the process cannot be
    pinned at all (gone, or not ours)."""
    task_dir = Path("/proc/self/task" if pid == 0 else f"/proc/{pid}/task")
    tids = [int(t.name) for t in task_dir.iterdir()] if task_dir.is_dir() else [pid]
    done = 0
    for tid in tids:
        try:
            os.sched_setaffinity(tid, cpus)
            done += 1
        except ProcessLookupError:  # the thread ended between the listing and now
            continue
    if not done:
        raise ProcessLookupError(f"process {pid} has no thread left to pin")
    return done
