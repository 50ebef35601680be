"""How a long-lived process keeps its memory: a cap on glibc's malloc arenas.

glibc gives a thread that finds the arena it uses locked a new arena of its own, up to eight per
CPU, and an arena keeps the pages its frees leave scattered. A process whose many threads allocate
at once (Zenoh's runtime and the Python threads that hear the bus) therefore grows in steps of an
arena's worth of pages whenever the machine is busy enough for two of them to meet in ``malloc``,
and keeps them, its Python heap flat all along. Capping the arenas bounds that growth at the cost
of some lock contention in ``malloc``, which a process off the control path does not notice.

``cap_malloc_arenas`` is the same as ``MALLOC_ARENA_MAX`` in the environment, set from inside the
process (``mallopt(M_ARENA_MAX)``); it acts on arenas made from then on, so it is called first
thing, before any thread starts. A C library other than glibc: nothing to do, False.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging

log = logging.getLogger("seaway.runtime.memory")

M_ARENA_MAX = -8
"""glibc's ``mallopt`` parameter number for the arena cap (malloc.h)."""
DEFAULT_ARENAS = 2
"""The main arena and one for every other thread: what a process off the control path needs."""


def cap_malloc_arenas(arenas: int = DEFAULT_ARENAS) -> bool:
    """At most ``arenas`` malloc arenas in this process from now on; True if the C library took it
    (glibc), False where there is no such setting. ``arenas`` >= 1."""
    if arenas < 1:
        raise ValueError(f"arenas must be >= 1, got {arenas}")
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    ok = mallopt(M_ARENA_MAX, arenas) == 1
    if not ok:
        log.debug("mallopt(M_ARENA_MAX, %d) was refused", arenas)
    return ok
