"""Units every part shares: time on the wire is integer nanoseconds (``stamp_ns``), and a value with a
unit that must lie in a range says the range when it does not."""

from __future__ import annotations

import math
from typing import Any

from pydantic import BeforeValidator

NS_PER_S = 1_000_000_000
"""Nanoseconds per second: ``stamp_ns`` and every ``*_ns`` duration are integers in these."""
NS_PER_MS = 1_000_000
"""Nanoseconds per millisecond (MAVLink's ``time_boot_ms`` and its timesync's milliseconds)."""


def s_to_ns(seconds: float) -> int:
    """Seconds -> whole nanoseconds, rounded to the nearest."""
    return round(seconds * NS_PER_S)


def ns_to_s(nanoseconds: int) -> float:
    """Nanoseconds -> seconds."""
    return nanoseconds / NS_PER_S


def finite_number(value: Any) -> float | None:
    """``value`` as a float if it is a JSON number (not a bool) that is finite as a float, else
    None. An integer literal too large for a float (``1e400`` written out in digits) is not one:
    ``math.isfinite`` would raise on it instead of answering."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def in_range(lo: float, hi: float, unit: str, *, lo_open: bool = False) -> BeforeValidator:
    """A pydantic check whose error names the allowed range: ``95 deg is outside the allowed range
    [-90, 90] deg`` (pydantic's own ``ge``/``le`` name only the bound crossed). Put it beside the
    field's ``ge``/``le`` (or ``gt``), which stay for the JSON Schema (inside one ``Annotated``,
    the ``Field`` first: pydantic writes bounds that follow a validator into the schema as they are,
    ``"gt": 0``, a key JSON Schema does not know); values that are not finite numbers are left to
    the other checks."""
    opening = "(" if lo_open else "["

    def check(value: Any) -> Any:
        if isinstance(value, int) and not isinstance(value, bool) and finite_number(value) is None:
            # An integer past a float's range: left to the other checks, pydantic's float
            # conversion would raise OverflowError, which it does not turn into a validation error.
            raise ValueError(f"an integer of {len(str(abs(value)))} digits is outside the allowed "
                             f"range {opening}{lo:g}, {hi:g}] {unit}")
        number = finite_number(value)
        if number is not None:
            low_ok = number > lo if lo_open else number >= lo
            if not (low_ok and number <= hi):
                raise ValueError(f"{number:g} {unit} is outside the allowed range "
                                 f"{opening}{lo:g}, {hi:g}] {unit}")
        return value

    return BeforeValidator(check)
