"""The malloc arena cap of long-lived processes (seaway.runtime.memory)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from seaway.runtime import memory


def test_a_cap_below_one_arena_is_refused_naming_the_bound() -> None:
    with pytest.raises(ValueError, match="arenas must be >= 1"):
        memory.cap_malloc_arenas(0)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_threads_allocating_at_once_stay_within_the_capped_arenas() -> None:
    """Eight threads allocating together get arenas of their own without the cap (glibc makes one
    for a thread that finds its arena locked); with it, the process keeps at most the cap. Counted
    from glibc's own ``malloc_info`` report, in a fresh process each way."""
    probe = textwrap.dedent("""
        import ctypes, ctypes.util, re, sys, threading, os
        from seaway.runtime import memory
        if sys.argv[1] == "cap":
            assert memory.cap_malloc_arenas(2)
        libc = ctypes.CDLL(ctypes.util.find_library("c"))
        libc.malloc.restype = ctypes.c_void_p
        libc.malloc.argtypes = [ctypes.c_size_t]
        libc.free.argtypes = [ctypes.c_void_p]
        go = threading.Barrier(8)
        def work():
            go.wait()
            for _ in range(20000):
                libc.free(libc.malloc(4096))
        ts = [threading.Thread(target=work) for _ in range(8)]
        for t in ts: t.start()
        for t in ts: t.join()
        libc.open_memstream.restype = ctypes.c_void_p
        buf, size = ctypes.c_char_p(), ctypes.c_size_t()
        f = libc.open_memstream(ctypes.byref(buf), ctypes.byref(size))
        libc.malloc_info(0, ctypes.c_void_p(f))
        libc.fclose(ctypes.c_void_p(f))
        print(len(re.findall(r'<heap nr="', buf.value.decode())))
    """)
    counts = {}
    for way in ("cap", "free"):
        done = subprocess.run([sys.executable, "-c", probe, way], capture_output=True, text=True,
                              timeout=60)
        assert done.returncode == 0, done.stderr
        counts[way] = int(done.stdout.strip())
    assert counts["cap"] <= 2, counts
    assert counts["free"] > counts["cap"], counts


def _probe(code: str) -> str:
    """``code`` run in a fresh interpreter (the collector is one per process); what it printed."""
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_start_up_frozen_is_out_of_the_collectors_reach_and_its_garbage_freed() -> None:
    out = _probe("""
        import gc, weakref
        from seaway.runtime import memory
        class Node: pass
        kept = [Node() for _ in range(1000)]
        cycle = Node(); cycle.me = cycle; dead = weakref.ref(cycle); del cycle
        memory.freeze_start_up()
        tracked = {id(o) for o in gc.get_objects()}
        print(gc.get_freeze_count() >= 1000, dead() is None, any(id(k) in tracked for k in kept))
        later = Node(); later.me = later; gone = weakref.ref(later); del later
        gc.collect()
        print(gone() is None)
    """)
    assert out.split() == ["True", "True", "False", "True"], out


def test_a_paused_collection_resumes_when_the_last_block_closes_and_frees_cycles_after() -> None:
    out = _probe("""
        import gc, weakref
        from seaway.runtime import memory
        class Node: pass
        with memory.collection_paused():
            with memory.collection_paused():
                print(gc.isenabled())
            print(gc.isenabled())
            cycle = Node(); cycle.me = cycle; dead = weakref.ref(cycle); del cycle
        print(gc.isenabled())
        gc.collect()
        print(dead() is None)
        gc.disable()
        with memory.collection_paused():
            pass
        print(gc.isenabled())
    """)
    assert out.split() == ["False", "False", "True", "True", "False"], out


@pytest.mark.parametrize("service_process", [True, False])
def test_a_service_freezes_its_start_up_once_ready_a_test_context_does_not(
        monkeypatch, service_process: bool) -> None:
    import threading

    from seaway.runtime.clock import WallClock
    from seaway.runtime.memory_bus import MemoryHub
    from seaway.runtime.run import RunDescription
    from seaway.runtime.service import ServiceContext

    frozen: list[int] = []
    monkeypatch.setattr(memory, "freeze_start_up", lambda: frozen.append(1))
    ctx = ServiceContext("estimator", "vessel1", MemoryHub().bus("vessel1"), WallClock(),
                         threading.Event(), RunDescription(run_id="unit", vessel="vessel1"),
                         agree=False, freeze_when_ready=service_process)
    assert frozen == []
    ctx.ready()
    ctx.ready()  # declared once
    assert frozen == ([1] if service_process else [])
