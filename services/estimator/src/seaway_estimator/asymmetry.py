"""A thruster that gives less than commanded, told from what the filter's disturbance takes up.

A port thruster giving a fraction ``k`` of its command short leaves a yaw moment of ``-k T1 l`` the
model does not explain (paper eq. 1: r-dot carries ``(T1 - T2) l``; ``l`` the thrusters' distance
from the centre line), a starboard one ``+k T2 l``. The filter takes it up as its disturbance yaw
moment, routinely (``core_updates._reopen``), and the boat goes on; but it uses more energy than
planned, and a thruster going is worth a crew's look. A current, the wind and the waves of the
paper's model push the hull, not turn it: with no such loss the settled moment is a few percent of
that (the lake's current and wind: 0.07 N m, 4 % of a side's thrust on the arm).

So: an unexplained moment standing for ``HOLD_S``, as large as ``WARN_FRACTION`` of the weaker
side's commanded thrust on the arm, while that side is commanded at least ``MIN_THRUST_FRACTION``
of full thrust, is said once, naming the side and about how much it gives less; it is cleared once
below half that for ``HOLD_S``. A steady yaw moment of another cause (a fouled line, wind on a tall
superstructure) reads the same, and is worth the same look.

Once said, the loss is the filter's to predict (``effective``): a thruster short by a fraction of
its command takes off a force and a moment that follow that command through a turn, which a
disturbance held constant cannot (paper eq. 1). The unexplained moment judged is then the
disturbance's plus the said loss's (``loss``), so that the watch keeps seeing the whole of it:
while it stands, each ``HOLD_S`` of it measures the fraction again (what the prediction uses),
and a change of ``WARN_FRACTION`` or more from what was said is said again. Pure: times [ns] and
values in.
"""

from __future__ import annotations

from dataclasses import dataclass

from seaway.contract.messages import ThrusterSide
from seaway.contract.units import NS_PER_S
from seaway.vessel.thrusters import given_fractions, given_pair, loss_of

WARN_FRACTION = 0.2
"""Of the weaker side's commanded thrust: a moment this large (on the arm) is a thruster short."""
HOLD_S = 10.0
"""How long the moment must stand (or be gone) before it is said (or cleared) [s]."""
MIN_THRUST_FRACTION = 0.1
"""Of full thrust: below it a side is not judged (at rest, or idling, the moment means little)."""


@dataclass(frozen=True)
class AsymmetryEvent:
    """A side found short (``side``, about ``fraction`` of its command), or cleared (None)."""

    t_ns: int
    side: ThrusterSide | None
    fraction: float
    detail: str


@dataclass
class _Window:
    """Samples summed since ``since_ns`` [ns]: the thrust missing and the thrust commanded [N]."""

    since_ns: int | None = None
    short_n: float = 0.0
    commanded_n: float = 0.0

    def add(self, t_ns: int, short_n: float, commanded_n: float, hold_ns: int) -> float | None:
        """Add a sample; once the window spans ``hold_ns``, the fraction missing over all of it
        (a ratio of sums: one sample in a turn, the side barely commanded, overstates), and the
        window starts afresh."""
        if self.since_ns is None:
            self.since_ns, self.short_n, self.commanded_n = t_ns, 0.0, 0.0
        self.short_n += short_n
        self.commanded_n += commanded_n
        if t_ns - self.since_ns < hold_ns:
            return None
        self.since_ns = None
        return self.short_n / self.commanded_n


class ThrustAsymmetry:
    """Watches the filter's disturbance yaw moment against the commanded thrust (module doc)."""

    def __init__(self, arm_m: float, thrust_max_n: float) -> None:
        self.arm_m = arm_m
        self.min_thrust_n = MIN_THRUST_FRACTION * thrust_max_n
        self.side: ThrusterSide | None = None  # the side said short, until cleared
        self.fraction = 0.0  # how much of its command it was said to give less
        self.said_fraction = 0.0  # the fraction last said (a new one is said on a large change)
        self._change = _Window()  # the condition that would change ``side``, since it began
        self._again = _Window()  # the side said short, still short: ``fraction`` measured again
        self._hold_ns = round(HOLD_S * NS_PER_S)

    @property
    def given(self) -> tuple[float, float]:
        """(port, starboard): the fraction of its command each thruster gives, as said."""
        return given_fractions(self.side, self.fraction)

    def effective(self, port_n: float, starboard_n: float) -> tuple[float, float]:
        """The thrust the thrusters give for this command [N]: the side said short gives
        ``fraction`` less (what the filter predicts with, and the motion fault detector expects
        the boat to make)."""
        if self.side is None:
            return port_n, starboard_n
        return given_pair(port_n, starboard_n, self.given)

    def loss(self, port_n: float, starboard_n: float) -> tuple[float, float]:
        """What the said loss takes off this command: ``(surge_n, yaw_nm)``, body frame (zero with
        none said). The filter's disturbance plus this is what the model without the loss leaves
        unexplained: what the estimate publishes, and what this watch judges."""
        if self.side is None:
            return 0.0, 0.0
        return loss_of(port_n, starboard_n, self.given, self.arm_m)

    def on_estimate(self, t_ns: int, yaw_nm: float, port_n: float, starboard_n: float
                    ) -> AsymmetryEvent | None:
        """The settled unexplained moment ``yaw_nm`` [N m, body frame: the disturbance's plus the
        said loss's] at ``t_ns``, with the thrust commanded then [N]; an event when what is said
        changes. Between events, ``fraction`` may be measured again (module doc)."""
        side: ThrusterSide = "port" if yaw_nm < 0.0 else "starboard"
        commanded = port_n if side == "port" else starboard_n
        if commanded < self.min_thrust_n:  # at rest or idling: neither said nor cleared
            self._change.since_ns = self._again.since_ns = None
            return None
        short_n = abs(yaw_nm) / self.arm_m
        fraction = short_n / commanded
        if self.side is None:
            changing = fraction >= WARN_FRACTION
        else:
            changing = fraction < WARN_FRACTION / 2 or side != self.side
        if not changing:
            self._change.since_ns = None
            return None if self.side is None else self._measure_again(t_ns, yaw_nm, commanded)
        self._again.since_ns = None
        over = self._change.add(t_ns, short_n, commanded, self._hold_ns)
        if over is None:
            return None
        fraction = over  # over the whole hold
        if self.side is None:
            self.side, self.fraction = side, fraction
            self.said_fraction = fraction
            return AsymmetryEvent(t_ns, side, fraction, self._says(side, fraction, yaw_nm))
        self.side, self.fraction = None, 0.0
        return AsymmetryEvent(t_ns, None, fraction, "the thrusters give what they are commanded "
                              f"again (the unexplained yaw moment below {50 * WARN_FRACTION:.0f} % "
                              f"of a side's thrust for {HOLD_S:g} s)")

    def _measure_again(self, t_ns: int, yaw_nm: float, commanded_n: float) -> AsymmetryEvent | None:
        """A sample of the side said short, still short: each ``HOLD_S`` of them measures
        ``fraction`` again; an event if it moved ``WARN_FRACTION`` or more from what was said."""
        fraction = self._again.add(t_ns, abs(yaw_nm) / self.arm_m, commanded_n, self._hold_ns)
        if fraction is None:
            return None
        self.fraction = fraction
        if abs(self.fraction - self.said_fraction) < WARN_FRACTION:
            return None
        assert self.side is not None
        self.said_fraction = self.fraction
        return AsymmetryEvent(t_ns, self.side, self.fraction,
                              self._says(self.side, self.fraction, yaw_nm))

    @staticmethod
    def _says(side: ThrusterSide, fraction: float, yaw_nm: float) -> str:
        return (f"the {side} thruster gives about {100 * fraction:.0f} % less than commanded "
                f"(a yaw moment the model does not explain, {yaw_nm:+.2f} N m now, has stood for "
                f"{HOLD_S:g} s): check it, or what else turns the boat (a fouled line, wind on "
                "its superstructure)")
