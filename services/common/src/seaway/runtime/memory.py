"""How a long-lived process keeps its memory: a cap on glibc's malloc arenas, and its start-up's
objects kept out of the cyclic garbage collector's walks, and the collector paused while a
reader builds a large graph of objects that has no cycles.

glibc gives a thread that finds the arena it uses locked a new arena of its own, up to eight per
CPU, and an arena keeps the pages its frees leave scattered. A process whose many threads allocate
at once (Zenoh's runtime and the Python threads that hear the bus) therefore grows in steps of an
arena's worth of pages whenever the machine is busy enough for two of them to meet in ``malloc``,
and keeps them, its Python heap flat all along. Capping the arenas bounds that growth at the cost
of some lock contention in ``malloc``, which a process off the control path does not notice.

``cap_malloc_arenas`` is the same as ``MALLOC_ARENA_MAX`` in the environment, set from inside the
process (``mallopt(M_ARENA_MAX)``); it acts on arenas made from then on, so it is called first
thing, before any thread starts. A C library other than glibc: nothing to do, False.

``freeze_start_up`` is called once a service is ready (``ServiceContext.ready``). By then the
process holds every module, class, schema and solver it will use, tens of thousands of objects
that live as long as it does. CPython's collector walks all of them at each full collection, which
a lockstep period's allocations set off every few hundred periods; frozen (``gc.freeze``), they are
never walked again, and a full collection cannot pause a real-time service (vehicle_io's thrust
commands, pymavlink's dialect being tens of thousands of objects) for tens of milliseconds. What a
service makes after start-up is collected as before.

``collection_paused`` is for code that makes many objects and keeps them, such as a recording
decoded into messages: each few hundred objects kept set off a collection, and each collection walks
everything kept so far, so that the collector's time grows with the square of what is kept. Messages
hold no cycles; reference counting frees them, and nothing is left for the collector to find.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import logging
import threading
from collections.abc import Iterator

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


def freeze_start_up() -> None:
    """Collect, then move every object the collector still tracks into its permanent generation
    (``gc.freeze``): start-up's objects, which live as long as the process, are not walked by later
    collections. Safe to call again: a composed process calls it as each of its nodes becomes ready
    (each call a full collection, then a splice of lists)."""
    gc.collect()  # garbage frozen would never be freed
    gc.freeze()


_paused_lock = threading.Lock()
_paused = 0
"""How many ``collection_paused`` blocks are open in this process (the collector is one per
process: it runs again when the last one closes, and only if it ran when the first one opened)."""
_was_enabled = False


@contextlib.contextmanager
def collection_paused() -> Iterator[None]:
    """No cyclic garbage collection inside the block, in this process (every thread); as it was
    before once the last open block closes. For building many acyclic objects that are kept."""
    global _paused, _was_enabled
    with _paused_lock:
        if _paused == 0:
            _was_enabled = gc.isenabled()
            gc.disable()
        _paused += 1
    try:
        yield
    finally:
        with _paused_lock:
            _paused -= 1
            if _paused == 0 and _was_enabled:
                gc.enable()
