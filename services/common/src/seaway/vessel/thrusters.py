"""The thrusters' limits, written once: saturation and the dead zone [N], per thruster.

What a thruster does with a command (the simulated plant, the estimator's prediction):

1. saturation: ``-reverse_max_n <= T <= thrust_max_n`` (the vessel file; reverse is weaker);
2. dead zone: ``|T| < dead_zone_n`` produces no thrust (the real boat's 10 N; 0 in the paper).

What to send so that the dead zone loses as little as possible (vehicle I/O):
``compensate_dead_zone`` replaces a demand inside the dead zone by the nearest producible thrust.

T1 is the port thruster, T2 starboard; positive is ahead.
"""

from __future__ import annotations

import math
from typing import Protocol


class ThrustBounds(Protocol):
    """Anything carrying a thruster's bounds [N]: ``VesselParams``, vehicle I/O's ``ThrusterLimits``."""

    @property
    def thrust_max_n(self) -> float: ...

    @property
    def reverse_max_n(self) -> float: ...


def saturate(thrust_n: float, bounds: ThrustBounds) -> float:
    """Clamp one thruster's command to ``[-reverse_max_n, thrust_max_n]`` [N]."""
    return min(max(thrust_n, -bounds.reverse_max_n), bounds.thrust_max_n)


def apply_dead_zone(thrust_n: float, dead_zone_n: float) -> float:
    """The thrust produced for a command [N]: 0 when ``|T| < dead_zone_n``, else the command."""
    return 0.0 if abs(thrust_n) < dead_zone_n else thrust_n


def compensate_dead_zone(thrust_n: float, dead_zone_n: float) -> float:
    """The producible thrust nearest to a demand [N]: outside the dead zone, the demand itself;
    inside it, ``sign(T) * dead_zone_n`` when ``|T| > dead_zone_n / 2``, else 0.

    The error is then at most ``dead_zone_n / 2``, and a small demand is not silently lost (6 N of a
    10 N dead zone gives 10 N, 4 N gives 0). Zero stays exactly zero.
    """
    mag = abs(thrust_n)
    if mag >= dead_zone_n or thrust_n == 0.0:
        return thrust_n
    return math.copysign(dead_zone_n, thrust_n) if mag > dead_zone_n / 2.0 else 0.0
