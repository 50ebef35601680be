"""Thrust in newtons (per thruster) -> normalised thruster command in [-1, 1].

This is the autopilot-independent half of the command path; the profiles (px4.py, ardupilot.py)
turn the normalised pair (L = port = T1, R = starboard = T2) into MANUAL_CONTROL axes.

Model of the thruster behind the autopilot (``seaway.vessel.thrusters``, as the simulator's plant
applies it): a normalised command ``u`` produces ``u * thrust_max_n`` ahead for ``u >= 0`` and
``u * reverse_max_n`` astern for ``u < 0``, and any demand whose magnitude is below
``dead_zone_n`` produces nothing.

Per thruster, in this order (steps 1-2 are ``thrusters.output_stage``, the one definition of what
Seaway sends a thruster, which the lockstep sim applies in vehicle I/O's place):

1. **saturation** to ``[-reverse_max_n, thrust_max_n]`` (the vessel file; ``thrusters.saturate``);
2. **dead-zone compensation** (``thrusters.compensate_dead_zone``): a demand ``0 < |T| < dead_zone_n``
   cannot be produced. We send the achievable value nearest to it: ``sign(T) * dead_zone_n`` when
   ``|T| > dead_zone_n / 2``, else 0. That keeps the error at most ``dead_zone_n / 2`` and keeps a
   small demand from being silently lost (a controller asking for 6 N of a 10 N dead zone gets
   10 N, one asking for 4 N gets 0);
3. **normalisation** by the bound of the demand's direction (asymmetric reverse);
4. **quantisation guard**: the wire encoding rounds (PX4's z has a step of 0.002), which could put a
   value at the dead-zone edge back inside it. A non-zero output is therefore never smaller than
   ``dead_zone_n`` normalised plus ``guard`` (the profile's worst-case reconstruction error);
5. **clamp** to [-1, 1].

Zero in gives exactly 0 out: neutral is always exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from seaway.vessel.model import VesselParams
from seaway.vessel.thrusters import output_stage


@dataclass(frozen=True)
class ThrusterLimits:
    """The thruster limits that matter for mapping [N]."""

    thrust_max_n: float
    reverse_max_n: float
    dead_zone_n: float = 0.0

    def __post_init__(self) -> None:
        if not (self.thrust_max_n > 0 and self.reverse_max_n > 0 and self.dead_zone_n >= 0):
            raise ValueError(f"invalid thruster limits {self}")
        if self.dead_zone_n >= min(self.thrust_max_n, self.reverse_max_n):
            raise ValueError("dead_zone_n must be smaller than both thrust bounds")

    @classmethod
    def from_vessel(cls, p: VesselParams) -> ThrusterLimits:
        return cls(p.thrust_max_n, p.reverse_max_n, p.dead_zone_n)


def normalise(thrust_n: float, limits: ThrusterLimits, guard: float = 0.0) -> float:
    """One thruster's demand [N] -> normalised command in [-1, 1] (steps 1-5 above)."""
    if not math.isfinite(thrust_n):
        raise ValueError(f"thrust must be finite, got {thrust_n}")
    t = output_stage(thrust_n, limits)
    if t == 0.0:
        return 0.0
    scale = limits.thrust_max_n if t > 0 else limits.reverse_max_n
    u = t / scale
    if limits.dead_zone_n > 0:
        u_min = limits.dead_zone_n / scale + guard
        if abs(u) < u_min:
            u = math.copysign(u_min, u)
    return min(max(u, -1.0), 1.0)


def normalise_pair(port_n: float, starboard_n: float, limits: ThrusterLimits,
                   guard: float = 0.0) -> tuple[float, float]:
    """(T1 port, T2 starboard) [N] -> (L, R) normalised."""
    return normalise(port_n, limits, guard), normalise(starboard_n, limits, guard)
