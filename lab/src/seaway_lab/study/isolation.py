"""Keeping stacks that run side by side apart: a Zenoh rendezvous port of its own for each
(``free_port``, ``stack_env``), and CPUs of its own where that pays (``cpu_groups``, ``cpus_option``)."""

from __future__ import annotations

import os
import random
import socket
import threading
from pathlib import Path

from seaway.runtime import cpus as cpusets
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS

CPUS_FLAG = "--cpus"
"""The launcher's option that keeps a stack on a CPU set (``seaway.runtime.cpus``); passed when the
study pins its stacks and the launcher has it."""


# -- a rendezvous port per stack ------------------------------------------------------------------

_ports_lock = threading.Lock()
_ports_given: set[int] = set()


def _ephemeral_low() -> int:
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port(rng: random.Random | None = None) -> int:
    """A loopback TCP port that is free now, below the ephemeral range and not given out before.

    Below the ephemeral range, no process of another stack can be handed the port by the kernel
    (each Zenoh process also listens on an ephemeral port) between this check and its first use.
    """
    rng = rng or random.Random()
    low, high = 20000, max(20001, min(_ephemeral_low(), 32768))
    with _ports_lock:
        for _ in range(200):
            port = rng.randrange(low, high)
            if port in _ports_given:
                continue
            with socket.socket() as s:
                try:
                    s.bind(("127.0.0.1", port))
                except OSError:
                    continue
            _ports_given.add(port)
            return port
    raise RuntimeError(f"no free loopback port in {low}..{high}")


def stack_env(port: int, base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of one stack: its own rendezvous port, the packaged Zenoh config."""
    env = dict(os.environ if base is None else base)
    env[ENV_RENDEZVOUS] = f"tcp/127.0.0.1:{port}"
    env.pop(ENV_CONFIG, None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


# -- CPUs per stack -------------------------------------------------------------------------------

def cpu_groups(workers: int, pin: bool | None) -> list[frozenset[int]] | None:
    """The CPU set of each of ``workers`` local stacks (``cpus.partition`` of the CPUs this process
    may use), or None to leave them to the kernel. ``pin``: None pins where it pays, False never,
    True wherever it can be done (an error otherwise, saying why). It pays for two or more stacks
    and no more than the CPUs (each stack gets CPUs of its own), and for one stack given two CPUs or
    more (all of them: its launcher puts the lockstep chain on one and the rest on the others,
    ``cpus.split_chain``)."""
    if pin is False:
        return None
    available = cpusets.allowed()
    if workers == 1:
        groups = [available] if cpusets.split_chain(available) is not None else None
    else:
        groups = cpusets.partition(available, workers)
    if groups is None and pin:
        n = len(available)
        raise ValueError(f"--pin: {workers} stack(s) at once cannot each have CPUs of their own: "
                         f"this process may use {n} CPU(s) ({cpusets.format_cpus(available)}), so "
                         + (f"--pin takes 1 to {n} workers" if n >= 2 else "nothing can be pinned"))
    return groups


def cpus_option(group: frozenset[int] | None, supported: set[str]) -> list[str]:
    """``--cpus LIST`` for a stack pinned to ``group``, if the launcher has the option."""
    if group is None or CPUS_FLAG not in supported:
        return []
    return [CPUS_FLAG, cpusets.format_cpus(group)]
