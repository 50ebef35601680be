"""The thrusters' limits, written once: saturation and the dead zone [N], per thruster.

What a thruster does with a command (the simulated plant, the estimator's prediction):

1. saturation: ``-reverse_max_n <= T <= thrust_max_n`` (the vessel file; reverse is weaker);
2. dead zone: ``|T| < dead_zone_n`` produces no thrust (the real boat's 10 N; 0 in the paper).

What Seaway sends a thruster for the controller's demand, ``output_stage``: saturation, then
``compensate_dead_zone``, which replaces a demand inside the dead zone by the nearest producible
thrust (so the dead zone loses as little as possible). Vehicle I/O applies it before normalising for
the autopilot; the lockstep sim and the in-process loop, which take the controller's demand
straight, apply it in vehicle I/O's place; the estimator predicts with it. So a demand produces the
same thrust on a real boat, in a real-time simulation and in lockstep.

A demand far outside the bounds (``absurd_thrust``) is not saturated but refused, by vehicle I/O and
by the lockstep sim alike: it is corrupt or forged, not a controller asking for full power.

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


class ThrustLimits(ThrustBounds, Protocol):
    """Bounds and the dead zone [N]: ``VesselParams``, vehicle I/O's ``ThrusterLimits``."""

    @property
    def dead_zone_n(self) -> float: ...


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


def output_stage(thrust_n: float, limits: ThrustLimits) -> float:
    """What Seaway sends one thruster for a demand [N]: saturated, then dead-zone compensated with
    the limits of the vessel file the services model (the only figures vehicle I/O has). The
    thruster's own dead zone then passes it unchanged (0, or at least ``dead_zone_n``)."""
    return compensate_dead_zone(saturate(thrust_n, limits), limits.dead_zone_n)


def output_pair(port_n: float, starboard_n: float, limits: ThrustLimits) -> tuple[float, float]:
    """``output_stage`` of (T1 port, T2 starboard) [N]."""
    return output_stage(port_n, limits), output_stage(starboard_n, limits)


ABSURD_THRUST_FACTOR = 2.0
"""A demand beyond this multiple of its thruster's bound (``thrust_max_n`` ahead, ``reverse_max_n``
astern) is not a controller asking for full power: it is corrupt or forged, and is refused rather
than saturated (a controller's own plan never leaves the bounds; twice them leaves room for any
rounding or a fallback's overshoot)."""


def absurd_thrust(port_n: float, starboard_n: float, limits: ThrustBounds) -> str | None:
    """Why the demand (T1 port, T2 starboard) [N] is absurd for these thrusters, or None.

    Non-finite values never get here: the bus refuses them (``seaway.contract.messages``)."""
    ahead, astern = ABSURD_THRUST_FACTOR * limits.thrust_max_n, ABSURD_THRUST_FACTOR * limits.reverse_max_n
    for name, t in (("thrust_port_n", port_n), ("thrust_starboard_n", starboard_n)):
        if not -astern <= t <= ahead:
            return (
                f"{name} = {t:g} N is outside [{-astern:g}, {ahead:g}] N ({ABSURD_THRUST_FACTOR:g} "
                f"x the vessel's thrust bounds -{limits.reverse_max_n:g} .. {limits.thrust_max_n:g} N)"
            )
    return None


FULL_THRUST: tuple[float, float] = (1.0, 1.0)
"""Each thruster giving all of its command: the (port, starboard) fractions without a loss."""


def given_fractions(short_side: str | None, short_frac: float | None) -> tuple[float, float]:
    """(port, starboard): the fraction of its command each thruster gives, all of it but for a
    side found short by ``short_frac`` of its command (``StateEstimate.thrust_short_side`` and
    ``thrust_short_frac``, from the estimator's asymmetry watch); at most all of it is lost."""
    if short_side is None or short_frac is None:
        return FULL_THRUST
    given = max(0.0, 1.0 - short_frac)
    return (given, 1.0) if short_side == "port" else (1.0, given)


def given_pair(port_n: float, starboard_n: float, fractions: tuple[float, float]
               ) -> tuple[float, float]:
    """The thrust (T1 port, T2 starboard) the thrusters give for this command [N]."""
    return port_n * fractions[0], starboard_n * fractions[1]


def loss_of(port_n: float, starboard_n: float, fractions: tuple[float, float], arm_m: float
            ) -> tuple[float, float]:
    """What the thrusters giving ``fractions`` of this command take off it: ``(surge_n, yaw_nm)``
    in the body frame (paper eq. 1: surge ``T1 + T2``, yaw ``(T1 - T2) l``, ``l = arm_m``)."""
    port_lost, starboard_lost = port_n * (fractions[0] - 1.0), starboard_n * (fractions[1] - 1.0)
    return port_lost + starboard_lost, (port_lost - starboard_lost) * arm_m


def command_for(port_n: float, starboard_n: float, fractions: tuple[float, float],
                bounds: ThrustBounds) -> tuple[float, float]:
    """The command (T1 port, T2 starboard) [N] for which thrusters giving ``fractions`` of theirs
    give this thrust: each side's divided by its fraction and saturated (a side giving nothing is
    asked for the thrust itself). Unchanged with ``FULL_THRUST``."""
    if fractions == FULL_THRUST:
        return port_n, starboard_n
    port = port_n / fractions[0] if fractions[0] > 0.0 else port_n
    starboard = starboard_n / fractions[1] if fractions[1] > 0.0 else starboard_n
    return saturate(port, bounds), saturate(starboard, bounds)
