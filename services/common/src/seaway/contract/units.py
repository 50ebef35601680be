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


def in_range(lo: float, hi: float, unit: str, *, lo_open: bool = False) -> BeforeValidator:
    """A pydantic check whose error names the allowed range: ``95 deg is outside the allowed range
    [-90, 90] deg`` (pydantic's own ``ge``/``le`` name only the bound crossed). Put it beside the
    field's ``ge``/``le`` (or ``gt``), which stay for the JSON Schema; values that are not finite
    numbers are left to the other checks."""
    opening = "(" if lo_open else "["

    def check(value: Any) -> Any:
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 1e300:
            # An integer past a float's range: math.isfinite would raise OverflowError, which
            # pydantic does not turn into a validation error (it would escape the edge).
            raise ValueError(f"an integer of {len(str(abs(value)))} digits is outside the allowed "
                             f"range {opening}{lo:g}, {hi:g}] {unit}")
        if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
            low_ok = value > lo if lo_open else value >= lo
            if not (low_ok and value <= hi):
                raise ValueError(f"{value:g} {unit} is outside the allowed range "
                                 f"{opening}{lo:g}, {hi:g}] {unit}")
        return value

    return BeforeValidator(check)
