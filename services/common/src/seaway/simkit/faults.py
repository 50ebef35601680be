"""Scheduled faults of a scenario (its ``[[faults]]``) and how the simulator applies them.

A fault happens at a fixed time of the scenario (seconds since the scenario started: the plant's
and the sensors' time, whatever the sim's clock or epoch), so a run with faults is as deterministic
as one without, in lockstep and in real time alike. Kinds (``kind = ...``):

* ``gnss_dropout``: no GNSS fix is produced for ``start_s <= t < start_s + duration_s`` (and the
  simulated autopilot says its GNSS is lost), as the seeded random dropouts of ``[sensors]`` do;
* ``position_jump``: GNSS positions are moved ``distance_m`` toward ``direction_rad`` (NED, from
  north, clockwise). With ``duration_s`` every fix in ``[time_s, time_s + duration_s)`` is moved (an
  offset, multipath); without, only the first fix due at or after ``time_s`` (one outlier). The
  velocity over ground is not changed;
* ``heading_bias``: ``bias_rad`` is added to the measured heading from ``start_s`` (for
  ``duration_s``, or to the end);
* ``thruster``: from ``time_s`` (for ``duration_s``, or to the end) the ``port``, ``starboard`` or
  ``both`` thrusters produce ``factor`` times the thrust they would (0: failed, 0.5: half lost to a
  fouled propeller). The energy metric counts the thrust produced;
* ``stuck_thruster``: from ``time_s`` (for ``duration_s``, or to the end) the ``port``, ``starboard``
  or ``both`` thrusters produce ``thrust_n`` whatever is commanded (0: stopped; within the vessel's
  thrust range, checked when the plant is built);
* ``grounding``: from ``time_s`` (for ``duration_s``, or to the end) the vessel is held where it is:
  its speeds are zero and its pose does not change, whatever the thrust (aground, or moored).

Faults of one kind that overlap combine: outages unite, jumps and biases add, factors multiply;
a stuck thruster overrides its factor, and of two stuck values the later-starting one holds. Jumps
that act on one fix together may add up to ``MAX_POSITION_JUMP_M`` (``jump_peak``; checked when
the scenario is read), what one may be.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Any, Literal

from pydantic import Field

from seaway.contract.config import ConfigError, ConfigModel
from seaway.contract.units import NS_PER_S

MAX_FAULT_TIME_S = 86_400.0
"""When a fault may start, and how long it may last [s]: a day, longer than any scenario."""
MAX_POSITION_JUMP_M = 1000.0
"""How far a GNSS position may jump [m]: far past any receiver error, short of a spoofed city."""
MAX_HEADING_BIAS_RAD = math.pi
"""A heading bias, either way [rad]."""
MAX_DIRECTION_RAD = 2.0 * math.pi
"""A jump's direction, either way [rad]."""
MAX_STUCK_THRUST_N = 10_000.0
"""A stuck thruster's thrust, either way [N]: the plant checks it against the vessel's own range."""


def _time() -> Any:
    return Field(ge=0.0, le=MAX_FAULT_TIME_S, description="since the scenario started [s]")


def _until_end() -> Any:
    return Field(default=None, gt=0.0, le=MAX_FAULT_TIME_S, description="[s]; default: to the end")


class GnssDropoutFault(ConfigModel):
    kind: Literal["gnss_dropout"]
    start_s: float = _time()
    duration_s: float = Field(gt=0.0, le=MAX_FAULT_TIME_S, description="[s]")


class PositionJumpFault(ConfigModel):
    kind: Literal["position_jump"]
    time_s: float = _time()
    distance_m: float = Field(gt=0.0, le=MAX_POSITION_JUMP_M, description="[m]")
    direction_rad: float = Field(
        ge=-MAX_DIRECTION_RAD,
        le=MAX_DIRECTION_RAD,
        description="toward which the fix moves, from north clockwise [rad]",
    )
    duration_s: float | None = Field(
        default=None,
        gt=0.0,
        le=MAX_FAULT_TIME_S,
        description="[s]; default: the first fix at or after time_s only",
    )


class HeadingBiasFault(ConfigModel):
    kind: Literal["heading_bias"]
    start_s: float = _time()
    bias_rad: float = Field(ge=-MAX_HEADING_BIAS_RAD, le=MAX_HEADING_BIAS_RAD, description="[rad]")
    duration_s: float | None = _until_end()


class ThrusterFault(ConfigModel):
    kind: Literal["thruster"]
    time_s: float = _time()
    thruster: Literal["port", "starboard", "both"]
    factor: float = Field(ge=0.0, le=1.0, description="thrust produced / thrust demanded; 0: failed")
    duration_s: float | None = _until_end()


class StuckThrusterFault(ConfigModel):
    kind: Literal["stuck_thruster"]
    time_s: float = _time()
    thruster: Literal["port", "starboard", "both"]
    thrust_n: float = Field(ge=-MAX_STUCK_THRUST_N, le=MAX_STUCK_THRUST_N,
                            description="thrust produced whatever the command [N]; 0: stopped")
    duration_s: float | None = _until_end()


class GroundingFault(ConfigModel):
    kind: Literal["grounding"]
    time_s: float = _time()
    duration_s: float | None = _until_end()


Fault = Annotated[
    GnssDropoutFault | PositionJumpFault | HeadingBiasFault | ThrusterFault | StuckThrusterFault
    | GroundingFault, Field(discriminator="kind")
]


def jump_peak(faults: Sequence[object], outlier_window_s: float) -> tuple[float, float]:
    """(the largest sum of ``position_jump`` distances acting on one fix [m], the time it first
    acts [s]). Overlapping jumps add (``SensorFaults.position_offset_m``): a jump with a duration
    acts over ``[time_s, time_s + duration_s)``, an outlier on the first fix at or after ``time_s``,
    counted over ``outlier_window_s`` (the slowest GNSS period: the fix it moves may be any in it)."""
    edges: list[tuple[float, int, float]] = []  # (time, 0 end / 1 start, distance)
    for f in faults:
        if isinstance(f, PositionJumpFault):
            span = f.duration_s if f.duration_s is not None else outlier_window_s
            edges += [(f.time_s, 1, f.distance_m), (f.time_s + span, 0, -f.distance_m)]
    peak, at, total = 0.0, 0.0, 0.0
    for t, _, d in sorted(edges):  # an end before a start at the same time: half-open windows
        total += d
        if total > peak:
            peak, at = total, t
    return peak, at


def jumps_too_far(faults: Sequence[object], outlier_window_s: float) -> str | None:
    """Why the ``position_jump`` faults acting on one fix add up past ``MAX_POSITION_JUMP_M``
    (``jump_peak``), or None."""
    peak_m, at_s = jump_peak(faults, outlier_window_s)
    if peak_m <= MAX_POSITION_JUMP_M:
        return None
    return (f"the position jumps acting on one fix from {at_s:g} s add up to {peak_m:g} m, at most "
            f"{MAX_POSITION_JUMP_M:g} m (what one jump may be: jumps that overlap add)")


def _ns(seconds: float) -> int:
    return round(seconds * NS_PER_S)


def _within(t_ns: int, start_s: float, duration_s: float | None) -> bool:
    start = _ns(start_s)
    return t_ns >= start and (duration_s is None or t_ns < start + _ns(duration_s))


class SensorFaults:
    """The sensor faults of a scenario, asked at sample instants ``t_ns`` (since the scenario
    started). Stateless: the answer depends on the instant alone."""

    def __init__(self, faults: Sequence[object], gnss_period_ns: int) -> None:
        self.dropouts = [f for f in faults if isinstance(f, GnssDropoutFault)]
        self.jumps = [f for f in faults if isinstance(f, PositionJumpFault)]
        self.biases = [f for f in faults if isinstance(f, HeadingBiasFault)]
        self.gnss_period_ns = gnss_period_ns

    def gnss_lost(self, t_ns: int) -> bool:
        return any(_within(t_ns, f.start_s, f.duration_s) for f in self.dropouts)

    def position_offset_m(self, t_ns: int) -> tuple[float, float]:
        """(north, east) [m] to add to a fix sampled at ``t_ns``."""
        north = east = 0.0
        for f in self.jumps:
            if f.duration_s is None:
                first = -(-_ns(f.time_s) // self.gnss_period_ns) * self.gnss_period_ns
                hit = t_ns == first
            else:
                hit = _within(t_ns, f.time_s, f.duration_s)
            if hit:
                north += f.distance_m * math.cos(f.direction_rad)
                east += f.distance_m * math.sin(f.direction_rad)
        return north, east

    def heading_bias_rad(self, t_ns: int) -> float:
        return sum((f.bias_rad for f in self.biases if _within(t_ns, f.start_s, f.duration_s)), 0.0)


class ThrusterFaults:
    """The thruster faults of a scenario, asked along the plant's own time [s]."""

    def __init__(self, faults: Sequence[object], thrust_range_n: tuple[float, float] | None = None
                 ) -> None:
        """``thrust_range_n``: (most reverse, most ahead) the vessel's thrusters give [N]; a stuck
        thrust outside it is refused (ConfigError naming the fault and the range)."""
        self.items = [f for f in faults if isinstance(f, ThrusterFault | StuckThrusterFault)]
        self.stuck_items = sorted((f for f in self.items if isinstance(f, StuckThrusterFault)),
                                  key=lambda f: f.time_s)
        self.groundings = [f for f in faults if isinstance(f, GroundingFault)]
        if thrust_range_n is not None:
            lo, hi = thrust_range_n
            for i, f in enumerate(faults):
                if isinstance(f, StuckThrusterFault) and not lo <= f.thrust_n <= hi:
                    raise ConfigError(f"faults.{i}.thrust_n = {f.thrust_n:g} N: a stuck thruster "
                                      f"gives what the vessel's can, {lo:g} to {hi:g} N")

    def stuck(self, t_s: float) -> tuple[float | None, float | None]:
        """(port, starboard) thrust held whatever is commanded over a step at ``t_s`` [N]; None:
        not stuck."""
        port = starboard = None
        t_ns = _ns(t_s)
        for f in self.stuck_items:
            if _within(t_ns, f.time_s, f.duration_s):
                if f.thruster in ("port", "both"):
                    port = f.thrust_n
                if f.thruster in ("starboard", "both"):
                    starboard = f.thrust_n
        return port, starboard

    def grounded(self, t_s: float) -> bool:
        """Whether the vessel is held where it is over a step that starts at ``t_s``."""
        t_ns = _ns(t_s)
        return any(_within(t_ns, f.time_s, f.duration_s) for f in self.groundings)

    def factors(self, t_s: float) -> tuple[float, float]:
        """(port, starboard) thrust factors over a plant step that starts at ``t_s`` [s]; 1, 1
        without faults. A step is taken as starting at ``t_s`` to the nanosecond, so that a fault
        at 10 s applies from the internal step that starts at 10 s, whatever the float sum of the
        steps before it."""
        port = starboard = 1.0
        t_ns = _ns(t_s)
        for f in self.items:
            if isinstance(f, ThrusterFault) and _within(t_ns, f.time_s, f.duration_s):
                if f.thruster in ("port", "both"):
                    port *= f.factor
                if f.thruster in ("starboard", "both"):
                    starboard *= f.factor
        return port, starboard
