"""Which vessel an operator command (``seaway health``, ``vehicle``, ``mission``) speaks to.

``--vessel`` when given, else ``$SEAWAY_VESSEL``; else the vessel running on the bus, found by its
health tokens: in a fleet of several the command does not pick one for the operator (it used to
fall back to the default vessel without saying so) but names them and asks for ``--vessel``. With
no vessel seen it is the default one, and the command then says that nothing of it answers.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time

from seaway.runtime.bus import Bus
from seaway.runtime.service import DEFAULT_VESSEL, ENV_VESSEL

LOOK_S = 1.5
"""How long a command looks for the vessels on the bus, at most (a new session meets the mesh in
about a second)."""
SETTLE_S = 0.3
"""After the first vessel is seen, how long the others have to show too (the tokens already
declared come together)."""


def add_option(ap: argparse.ArgumentParser, wildcard: bool = False) -> None:
    """``--vessel`` of an operator command: default None (``resolve`` chooses)."""
    ap.add_argument(
        "--vessel",
        default=None,
        help="vessel name, the key namespace seaway/<vessel>/... "
        f"{'(* for every vessel) ' if wildcard else ''}(default ${ENV_VESSEL}, "
        "else the vessel running; with several running, name one)",
    )


def choose(named: str | None, seen: list[str]) -> tuple[str | None, str | None]:
    """(the vessel, None), or (None, what is wrong): ``named`` (the option or the environment)
    if any, else the one vessel ``seen`` running, else the default when none is."""
    if named:
        return named, None
    if len(seen) > 1:
        return None, (f"several vessels are running ({', '.join(sorted(seen))}): name one with --vessel V")
    return (seen[0] if seen else DEFAULT_VESSEL), None


def seen_vessels(bus: Bus, look_s: float = LOOK_S, settle_s: float = SETTLE_S) -> list[str]:
    """The vessels with a service's health token on the bus, looked for up to ``look_s``."""
    seen: set[str] = set()
    first = threading.Event()
    lock = threading.Lock()

    def on_health(vessel: str, _service: str, alive: bool) -> None:
        if alive:
            with lock:
                seen.add(vessel)
            first.set()

    watch = bus.watch_fleet_health(on_health)
    try:
        t0 = time.monotonic()
        if first.wait(look_s):
            time.sleep(min(settle_s, max(0.0, look_s - (time.monotonic() - t0))))
    finally:
        watch.undeclare()
    with lock:
        return sorted(seen)


def resolve(bus: Bus, named: str | None, prog: str) -> str | None:
    """The vessel of the command (``named``: its ``--vessel``), or None after saying on stderr why
    none can be chosen."""
    named = named or os.environ.get(ENV_VESSEL) or None
    seen = [] if named else seen_vessels(bus)
    vessel, problem = choose(named, seen)
    if problem:
        print(f"{prog}: {problem}", file=sys.stderr)
    elif seen:  # chosen here, not by the operator: say which
        print(f"{prog}: vessel {vessel} (the one running; --vessel names another)", file=sys.stderr)
    return vessel
