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
