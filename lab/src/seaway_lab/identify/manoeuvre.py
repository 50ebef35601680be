"""The identification manoeuvre: a scripted thrust sequence, a pure function of time.

The sequence is a list of phases, each ``(duration_s, port, starboard)`` with the two thrusters'
commands as fractions of a level (ahead: ``level_n``; astern: ``reverse_level_n``), held over the
phase, or ramped linearly from the previous phase's end value when marked as a ramp. It is built
to excite every term of the paper's model (``seaway.vessel.model``):

1. rest (3 s), then a slow ramp of both thrusters from 0 to 0.3 of the level over 20 s: the speed
   at which the vessel starts to move gives the thrusters' dead zone;
2. surge steps (both thrusters equal): 24 levels, 1.6 s each, twice, with coasting to zero: the
   steady speeds give X_u, the many transients (surge time constant m11/X_u) give m11;
3. turns in both directions at speed (0.8/0.2 and 1.0/0.45, 10 s: the yaw time constant m33/N_r),
   spins in place both ways (+-0.5), each followed by coasting: N_r, m33 and, through the
   centripetal terms m11 u r and m22 v r, the sway coefficients m22 and Y_v;
4. weaving at speed: 16 alternating turns (1.0/0.3, 2.5 s each), then coasting: the sway speed
   driven by u r keeps changing sign, which separates m22 from Y_v.

The whole block is flown twice, the second time with other levels (x0.8) and the turns in the other
order, so that a held-out tail of the run has the same kinds of motion as the part fitted.
``thrust_n(t_s)`` gives the commands at any time; before 0 and after ``duration_s`` they are 0.
"""

from __future__ import annotations

import bisect
import itertools
from dataclasses import dataclass, field

Phase = tuple[float, float, float, bool]
"""(duration_s, port fraction, starboard fraction, ramp): ramp means linear from the last value."""

# Surge levels in an order that mixes small and large steps up and down; each held _STEP_S, a few
# surge time constants of a small boat (m11/X_u is 0.38 s for the paper's): the transients carry m11.
_STEP_LEVELS = (0.5, 1.0, 0.2, 0.7, 0.0, 0.4, 0.9, 0.15, 0.6, 0.0, 0.8, 0.3, 1.0, 0.45,
                0.1, 0.65, 0.25, 0.95, 0.55, 0.0, 0.75, 0.35, 0.85, 0.05)
_STEP_S = 1.6
_TURN_S = 10.0
_SPIN_S = 6.0
_COAST_S = 5.0
_WEAVES = 16
_WEAVE_S = 2.5


def _block(scale: float, turns_first_port: bool) -> list[Phase]:
    out: list[Phase] = [(3.0, 0.0, 0.0, False), (20.0, 0.3, 0.3, True), (2.0, 0.3, 0.3, False)]
    for _ in range(2):
        out += [(_STEP_S, scale * f, scale * f, False) for f in _STEP_LEVELS]
    out.append((_COAST_S, 0.0, 0.0, False))
    turns = [(_TURN_S, scale * 0.8, scale * 0.2, False), (_COAST_S, 0.0, 0.0, False),
             (_TURN_S, scale * 0.2, scale * 0.8, False), (_COAST_S, 0.0, 0.0, False),
             (_TURN_S, scale * 1.0, scale * 0.45, False), (_TURN_S, scale * 0.45, scale * 1.0, False),
             (_COAST_S, 0.0, 0.0, False),
             (_SPIN_S, scale * 0.5, -scale * 0.5, False), (_SPIN_S, -scale * 0.5, scale * 0.5, False),
             (_COAST_S, 0.0, 0.0, False)]
    if turns_first_port:  # the mirror image: every turn's direction swapped
        turns = [(d, s, p, r) for d, p, s, r in turns]
    out += turns
    # Weaving at speed: the turn rate reverses every few seconds, so u r (and with it the sway
    # speed) keeps changing sign: what separates m22 from Y_v.
    for k in range(_WEAVES):
        hi, lo = (1.0, 0.3) if k % 2 == 0 else (0.3, 1.0)
        out.append((_WEAVE_S, scale * hi, scale * lo, False))
    out.append((_COAST_S, 0.0, 0.0, False))
    return out


def default_phases() -> list[Phase]:
    """The manoeuvre's phases: the block twice (the second at 0.8 of the levels, mirrored)."""
    return _block(1.0, False) + _block(0.8, True)


@dataclass(frozen=True)
class Manoeuvre:
    """The scripted sequence at a given thrust level [N] (ahead ``level_n``, astern ``reverse_level_n``).

    Pick ``level_n`` so that full level stays within the thrusters' bound and the vessel's speed
    and turn rate stay safe on the water: the fit is only valid over the range flown.
    """

    level_n: float
    reverse_level_n: float | None = None
    phases: tuple[Phase, ...] = field(default_factory=lambda: tuple(default_phases()))

    def __post_init__(self) -> None:
        if not self.level_n > 0:
            raise ValueError(f"level_n must be > 0 N, got {self.level_n}")
        if self.reverse_level_n is not None and not self.reverse_level_n > 0:
            raise ValueError(f"reverse_level_n must be > 0 N, got {self.reverse_level_n}")
        if not self.phases or any(p[0] <= 0 for p in self.phases):
            raise ValueError("a manoeuvre needs phases, each of positive duration")

    @property
    def starts_s(self) -> list[float]:
        return [0.0, *itertools.accumulate(p[0] for p in self.phases)]

    @property
    def duration_s(self) -> float:
        return self.starts_s[-1]

    def _newtons(self, fraction: float) -> float:
        rev = self.level_n if self.reverse_level_n is None else self.reverse_level_n
        return fraction * (self.level_n if fraction >= 0 else rev)

    def fractions(self, t_s: float) -> tuple[float, float]:
        """The commands at ``t_s`` as fractions of the level (port, starboard)."""
        starts = self.starts_s
        if t_s < 0 or t_s >= starts[-1]:
            return (0.0, 0.0)
        i = bisect.bisect_right(starts, t_s) - 1
        dur, port, stbd, ramp = self.phases[i]
        if not ramp:
            return (port, stbd)
        p0, s0 = (0.0, 0.0) if i == 0 else self.phases[i - 1][1:3]
        a = (t_s - starts[i]) / dur
        return (p0 + a * (port - p0), s0 + a * (stbd - s0))

    def thrust_n(self, t_s: float) -> tuple[float, float]:
        """Commanded thrust (T1 port, T2 starboard) [N] at ``t_s`` s from the manoeuvre's start."""
        port, stbd = self.fractions(t_s)
        return (self._newtons(port), self._newtons(stbd))
