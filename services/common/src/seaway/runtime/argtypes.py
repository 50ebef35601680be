"""Types for the command lines' numbers: a bad value stops argparse before any work starts.

argparse names the option, these say what was given and what is allowed, e.g. ``seaway bench
model: error: argument --batches: '0' is not a whole number of at least 1`` (exit 2). A number
parsed with a bare ``type=int`` or ``type=float`` lets 0, negatives, ``nan`` and ``inf`` through, to
fail later with a traceback, or never (a study run's ``--timeout-s nan`` waited for ever).

In the runtime, beside the services' own flags (``seaway.runtime.service``, ``seaway.runtime.run``),
so that services and tools alike take them from here.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def whole_number(at_least: int, at_most: int | None = None) -> Callable[[str], int]:
    """An integer >= ``at_least`` (counts: 1; how many to skip: 0), and <= ``at_most`` if given."""
    allowed = (f"of at least {at_least}" if at_most is None
               else f"from {at_least} to {at_most}")

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < at_least or (at_most is not None and value > at_most):
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number {allowed}")
        return value

    parse.__name__ = f"whole number {allowed}"  # argparse's fallback message names the type
    return parse


positive_int = whole_number(1)
"""A count of at least 1 (runs, repeats, clients, batches)."""


def _finite(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def positive_float(text: str) -> float:
    """A finite number above 0 (durations, rates, periods, speeds, lengths)."""
    value = _finite(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number above 0")
    return value


def non_negative_float(text: str) -> float:
    """A finite number of at least 0 (a dead zone, a margin)."""
    value = _finite(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number of at least 0")
    return value


def finite_number(gt: float | None = None, ge: float | None = None, lt: float | None = None,
                  le: float | None = None) -> Callable[[str], float]:
    """A finite number within the bounds given (``gt``: above, ``ge``: at least, ``lt``: below,
    ``le``: at most); ``positive_float`` and ``non_negative_float`` are its two common cases."""
    parts = [f"above {gt:g}" if gt is not None else "", f"at least {ge:g}" if ge is not None else "",
             f"below {lt:g}" if lt is not None else "", f"at most {le:g}" if le is not None else ""]
    allowed = " and ".join(p for p in parts if p)

    def parse(text: str) -> float:
        value = _finite(text)
        if not (math.isfinite(value) and (gt is None or value > gt) and (ge is None or value >= ge)
                and (lt is None or value < lt) and (le is None or value <= le)):
            raise argparse.ArgumentTypeError(f"{text!r} is not a finite number"
                                             + (f" {allowed}" if allowed else ""))
        return value

    parse.__name__ = f"finite number {allowed}".strip()
    return parse
