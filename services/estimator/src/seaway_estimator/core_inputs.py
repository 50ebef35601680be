"""What a message may say before the estimator's core uses it, and the copies it must not use.

An input that is not finite, or whose time is no time, is refused whole (``EstimatorError``, which
the service logs and counts).

A message that passed its contract (finite, in its type's ranges) can still say what no vessel and
no receiver does: a fix of 10^6 m standard deviation, a position 4000 km from the origin, a velocity
over ground of 10^5 m/s, a yaw rate of 10^5 rad/s. Used, each of them drops the state: an update
with an infinite variance leaves a covariance that cannot be published, and a speed past the
vessel's envelope (``seaway.vessel.envelope``) is one the core itself would refuse to publish. So
the part of a message that says such a thing is refused before it reaches the filter, and the rest
of the message is kept (a heading with an absurd yaw rate is still a heading). Each refusal says
what it refused, the value and the bound.

A measurement the filter has used once must not be used again: the service drops a sample that
repeats its key's last stamp, but a stale copy of an older one (re-sent, or twice in a bundle) would
be applied as a late measurement, and twenty copies of each fix made the filter four times too sure
of its position. ``RecentStamps`` remembers what was used for as long as a copy could still be.
"""

from __future__ import annotations

import math

import numpy as np
from seaway.contract.messages import MAX_ATTITUDE_RATE_HZ, MAX_GNSS_RATE_HZ, MAX_GNSS_STD_M
from seaway.vessel.envelope import Envelope
from seaway.vessel.frames import MAX_RANGE_M


class EstimatorError(ValueError):
    """An input the core refuses (non-finite value, bad time); the text names what and why."""


def check_finite(where: str, **values: float | None) -> None:
    """Refuse (``EstimatorError``) any of ``values`` that is not finite, naming it."""
    for name, v in values.items():
        if v is not None and not math.isfinite(v):
            raise EstimatorError(f"{where}.{name} = {v!r} is not finite; input refused")


def check_stamp(where: str, t_ns: object) -> int:
    """``t_ns`` as a time [ns]: a non-negative integer, else refused (``EstimatorError``)."""
    if type(t_ns) is int and t_ns >= 0:  # the usual case, decided without the checks below
        return t_ns
    if isinstance(t_ns, bool) or not isinstance(t_ns, int | np.integer):
        if isinstance(t_ns, float) and not math.isfinite(t_ns):
            raise EstimatorError(f"{where}: time {t_ns!r} is not finite; input refused")
        raise EstimatorError(f"{where}: time must be an integer number of ns, got {t_ns!r}")
    if t_ns < 0:
        raise EstimatorError(f"{where}: time {t_ns} ns is negative")
    return int(t_ns)


def fix_problem(north_m: float, east_m: float, std_m: float) -> str | None:
    """Why a fix at ``(north_m, east_m)`` of the NED origin [m], of horizontal standard deviation
    ``std_m`` [m], is no position (None: it is one)."""
    if std_m > MAX_GNSS_STD_M:
        return (f"horizontal std {std_m:.3g} m is past {MAX_GNSS_STD_M:g} m (a fix that uncertain "
                "is no fix)")
    if abs(north_m) > MAX_RANGE_M or abs(east_m) > MAX_RANGE_M:
        return (f"position ({north_m:.3g}, {east_m:.3g}) m is more than {MAX_RANGE_M:g} m from the "
                "origin on an axis (allowed: within the local frame's range)")
    return None


def sog_problem(vel_n_mps: float, vel_e_mps: float, env: Envelope) -> str | None:
    """Why a velocity over ground (north, east) [m/s] cannot be the vessel's (None: it can be).

    The filter takes it as the speed through the water (``h(z) = R(psi) [u, v]``), so one past the
    envelope's speed would put the state where the core drops it."""
    speed = math.hypot(vel_n_mps, vel_e_mps)
    if speed > env.speed_mps:
        return (f"velocity over ground {speed:.3g} m/s is past the vessel's envelope "
                f"({env.speed_mps:.3g} m/s)")
    return None


def yaw_rate_problem(r_radps: float, env: Envelope) -> str | None:
    """Why a measured yaw rate [rad/s] cannot be the vessel's (None: it can be)."""
    if abs(r_radps) > env.yaw_rate_radps:
        return (f"yaw rate {r_radps:.3g} rad/s is past the vessel's envelope "
                f"({env.yaw_rate_radps:.3g} rad/s)")
    return None


SPACING_FACTOR = 0.8
"""A sensor's samples closer together than this over its fastest rate (``MAX_GNSS_RATE_HZ``,
``MAX_ATTITUDE_RATE_HZ``) are a flood: a fifth below that period, so that the stamp jitter of a
source at its fastest rate does not refuse its samples."""
GNSS_SPACING_NS = round(SPACING_FACTOR * 1e9 / MAX_GNSS_RATE_HZ)
ATTITUDE_SPACING_NS = round(SPACING_FACTOR * 1e9 / MAX_ATTITUDE_RATE_HZ)


class RecentStamps:
    """The stamps [ns] of one sensor's measurements the filter used, kept while a copy could still
    be applied: a stamp more than ``window_ns`` (``late_tolerance_s``) before the filter's time is
    refused as too old anyway, so it is forgotten. ``too_soon``: a stamp within ``spacing_ns`` of
    the newest used, faster than any such sensor reports."""

    def __init__(self, window_ns: int, spacing_ns: int) -> None:
        self.window_ns, self.spacing_ns = window_ns, spacing_ns
        self._stamps: set[int] = set()
        self._prune_at = 64  # forget old stamps when the set reaches this size (amortised)
        self.newest_ns: int | None = None

    def __contains__(self, stamp_ns: int) -> bool:
        return stamp_ns in self._stamps

    def too_soon(self, stamp_ns: int) -> str | None:
        """Why a sample stamped ``stamp_ns`` [ns] comes faster than the sensor can (None: it
        does not): within ``spacing_ns`` of the newest one used."""
        newest = self.newest_ns
        if newest is None or abs(stamp_ns - newest) >= self.spacing_ns:
            return None
        return (f"{abs(stamp_ns - newest) / 1e6:.3g} ms from the last one used, less than "
                f"{self.spacing_ns / 1e6:.3g} ms (faster than any such sensor reports)")

    def add(self, stamp_ns: int, filter_t_ns: int) -> None:
        """Note ``stamp_ns`` used with the filter at ``filter_t_ns``."""
        if self.newest_ns is None or stamp_ns > self.newest_ns:
            self.newest_ns = stamp_ns
        stamps = self._stamps
        stamps.add(stamp_ns)
        if len(stamps) >= self._prune_at:
            oldest = filter_t_ns - self.window_ns
            self._stamps = stamps = {s for s in stamps if s >= oldest}
            self._prune_at = max(64, 2 * len(stamps))

    def clear(self) -> None:
        self._stamps.clear()
        self._prune_at = 64
        self.newest_ns = None
