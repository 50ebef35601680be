"""Unit conversions every part shares: time on the wire is integer nanoseconds (``stamp_ns``)."""

from __future__ import annotations

NS_PER_S = 1_000_000_000
"""Nanoseconds per second: ``stamp_ns`` and every ``*_ns`` duration are integers in these."""


def s_to_ns(seconds: float) -> int:
    """Seconds -> whole nanoseconds, rounded to the nearest."""
    return round(seconds * NS_PER_S)


def ns_to_s(nanoseconds: int) -> float:
    """Nanoseconds -> seconds."""
    return nanoseconds / NS_PER_S
