"""The estimator core's prediction: the filter brought through time with the thrust held.

The mean with ``seaway.vessel.model.rk4_step`` (the model is never re-derived here), the commanded
thrust held (through ``seaway.vessel.thrusters.output_stage`` as vehicle I/O sends it, optionally
the dead zone; zero while the autopilot's status says it withholds the thrust, or while the vessel
is seen not to move with it), substeps of at most ``max_step_s``, through the thrust's expiry. The
covariance with ``F = I + A h + (A h)^2 / 2``, ``A`` the exact Jacobian of
``seaway.vessel.model.derivative`` (CasADi's automatic differentiation of the same expressions). Mean
and covariance are one compiled function (``kalman.Predictor``).

Time: a measurement at or after the filter's time brings the filter to it; one before it, within
``late_tolerance_s``, is applied against the state back at its stamp (``_back``): the filter's now,
less the motion the prediction made since (kept from the first late measurement on:
``Filter.moved``), so that a turn begun meanwhile is not taken back at today's yaw rate; a gap
over ``max_gap_s`` drops the state (``_time_jump``), as does a state no vessel could be in
(``_diverged``): the next measurements re-initialise the filter.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from seaway.contract.units import NS_PER_S
from seaway.vessel.envelope import Envelope
from seaway.vessel.frames import wrap_pi
from seaway.vessel.model import VesselParams

from seaway_estimator import kalman
from seaway_estimator.kalman import IPSI, IR, IU, IV, Predictor
from seaway_estimator.mismatch import MotionMismatch
from seaway_estimator.notices import Notice

if TYPE_CHECKING:
    from seaway_estimator.asymmetry import ThrustAsymmetry
    from seaway_estimator.config import EstimatorConfig
    from seaway_estimator.kalman import Filter
    from seaway_estimator.notices import Counters


class Prediction:
    """The prediction part of ``EstimatorCore``: time, the thrust held, integration, divergence."""

    # read from the other parts
    config: EstimatorConfig
    p: VesselParams
    filter: Filter | None
    counters: Counters
    mismatch: MotionMismatch
    asymmetry: ThrustAsymmetry
    thrust_withheld: str | None
    _notices: deque[Notice]
    _world: bool
    _predictor: Predictor
    _envelope: Envelope
    _max_gap_ns: int
    _max_step_ns: int
    _late_ns: int
    _thrust: tuple[float, float]
    _thrust_until_ns: int | None
    _forget: Callable[[], None]

    def _to_time(self, t: int) -> float | None:
        """Bring the filter to a measurement at ``t``: the delay to correct for [s], or None."""
        f = self.filter
        assert f is not None
        if t >= f.t_ns:
            if t - f.t_ns > self._max_gap_ns:
                self._time_jump(t)
                return None
            self._advance(t)
            return None if self.filter is None else 0.0
        delay = (f.t_ns - t) / NS_PER_S
        if delay > self.config.late_tolerance_s:
            self.counters.inc("too_old")
            return None
        self.counters.inc("late_applied")
        return delay

    def _bring_to(self, t: int) -> bool:
        """Integrate the filter to ``t`` for an input that changes the thrust from then on (a
        command, a status): False, counted in ``too_new``, if ``t`` is more than ``max_gap_s``
        ahead of the filter. A stamp at or before the filter's time changes it from now."""
        f = self.filter
        if f is None or t <= f.t_ns:
            return True
        if t - f.t_ns > self._max_gap_ns:
            self.counters.inc("too_new")
            return False
        self._advance(t)
        return True

    def _time_jump(self, t: int) -> None:
        """A gap too long to integrate: drop the state; the next measurements re-initialise."""
        self.counters.inc("time_jumps")
        f = self.filter
        gap_s = (t - f.t_ns) / NS_PER_S if f is not None else 0.0
        self._notices.append(Notice(t, "time_jump", f"a step of {gap_s:.1f} s (over max_gap_s "
                                    f"{self.config.max_gap_s:g} s): the state is dropped"))
        self._forget()


    def _deriv(self, z: list, thrust: tuple[float, float]) -> list:
        """d/dt of the six vessel states with the disturbance in ``z[6:9]`` (shared model), floats."""
        return kalman.derivative(z, thrust, self.p, self._world, math)

    def jacobian(self, z: np.ndarray, thrust: tuple[float, float]) -> np.ndarray:
        """A = d f / d z (9x9; the disturbance rows are zero), exact (automatic differentiation)."""
        return self._predictor.jacobian(z, thrust)

    def _commanded_at(self, t_ns: int) -> tuple[float, float]:
        """The thrust commanded and applied by the autopilot at ``t_ns`` [N]."""
        if (self.thrust_withheld is not None or self._thrust_until_ns is None
                or t_ns >= self._thrust_until_ns):
            return (0.0, 0.0)
        return self._thrust

    def _thrust_at(self, t_ns: int) -> tuple[float, float]:
        """The thrust the prediction uses: none while the vessel is seen not to move with it; a
        side said short gives that much less (``asymmetry.ThrustAsymmetry.effective``)."""
        if self.mismatch.kind == "not_moving":
            return (0.0, 0.0)
        if self.asymmetry.side is None:
            return self._commanded_at(t_ns)
        return self.asymmetry.effective(*self._commanded_at(t_ns))

    def _advance(self, t: int) -> None:
        """Integrate the filter from its time to ``t`` (later), through thrust expiry."""
        f = self.filter
        assert f is not None
        while f.t_ns < t:
            end = t
            until = self._thrust_until_ns
            if until is not None and f.t_ns < until < t:
                end = until
            thrust = self._thrust_at(f.t_ns)
            n = -(-(end - f.t_ns) // self._max_step_ns)
            t0 = f.t_ns
            for k in range(n):
                t1 = t0 + (end - t0) * (k + 1) // n
                z0 = f.z
                why = self._predict(f, thrust, (t1 - f.t_ns) / NS_PER_S)
                f.t_ns = t1
                if why is not None:  # integrating on would only make it worse
                    self._diverged(t1, why)
                    return
                if f.moved is not None:
                    self._moved(f, z0)

    def _moved(self, f: Filter, z0: np.ndarray) -> None:
        """Add the motion of the substep that just brought the filter from ``z0`` to ``f.z`` (at
        ``f.t_ns``) to ``f.moved``; forget what lies beyond ``late_tolerance_s``."""
        a, b = z0.tolist(), f.z.tolist()
        last = f.moved[-1][1] if f.moved else [0.0] * 6
        summed = [last[i] + b[i] - a[i] for i in range(6)]
        summed[IPSI] = last[IPSI] + wrap_pi(b[IPSI] - a[IPSI])
        f.moved.append((f.t_ns, summed))
        horizon = f.t_ns - self._late_ns
        while len(f.moved) > 2 and f.moved[1][0] <= horizon:
            f.moved.popleft()

    def _predict(self, f: Filter, thrust: tuple[float, float], h: float) -> str | None:
        """One substep of ``h`` [s]; why the state it reached is no vessel's (None: it is one)."""
        z, P = self._predictor.step(f.z, f.P, thrust, h)
        f.z, f.P = z, P
        zl = z.tolist()
        why = self._absurd(zl)
        if why is None:
            z[IPSI] = wrap_pi(zl[IPSI])
        return why

    def _absurd(self, zl: list[float]) -> str | None:
        """Why the state ``zl`` (as floats: on 9 values numpy's per-call cost is the cost) cannot
        be this vessel's (``seaway.vessel.envelope``), or None."""
        if not all(map(math.isfinite, zl)):
            return "the state is not finite"
        return self._envelope.absurd(zl[IU], zl[IV], zl[IR])

    def _diverged(self, t: int, why: str) -> None:
        """The filter went unstable (a model far from the vessel, a bad update): drop it, so that
        the next measurements re-initialise it, rather than publish or integrate it further."""
        self.counters.inc("divergence_resets")
        self._notices.append(Notice(t, "divergence_reset", f"{why}: the state is dropped"))
        self._forget()

    def _back(self, z: np.ndarray, delay_s: float) -> np.ndarray:
        """The state ``z`` (the filter's, at its time) ``delay_s`` earlier, for a late measurement:
        ``z`` less the motion the prediction made over those seconds (``Filter.moved``), which
        keeps the corrections made since. Before that is known (the first late measurement starts
        it), ``z`` less its derivative times ``delay_s``: a first-order extrapolation, which takes
        a turn begun meanwhile back at today's yaw rate, off by half the yaw acceleration times
        the delay squared."""
        f = self.filter
        back_ns = round(delay_s * NS_PER_S)
        if f is not None:
            if f.moved is None:
                f.moved = deque([(f.t_ns, [0.0] * 6)])
            since = _moved_since(f.moved, f.t_ns - back_ns)
            if since is not None:
                out = z.copy()
                out[:6] -= np.asarray(since)
                out[IPSI] = wrap_pi(out[IPSI])
                return out
        zl = z.tolist()
        xd = self._deriv(zl, self._thrust_at(f.t_ns if f else 0))
        out = z.copy()
        out[:6] -= np.asarray(xd) * delay_s
        out[IPSI] = wrap_pi(out[IPSI])
        return out


def _moved_since(moved: deque[tuple[int, list[float]]], t_ns: int) -> list[float] | None:
    """The motion summed in ``moved`` from ``t_ns`` to its last entry (linear between entries);
    None if ``t_ns`` lies before its first."""
    if not moved or t_ns < moved[0][0]:
        return None
    now = moved[-1][1]
    later_t, later = moved[-1]
    for earlier_t, earlier in reversed(moved):
        if earlier_t <= t_ns:
            w = 0.0 if later_t == earlier_t else (t_ns - earlier_t) / (later_t - earlier_t)
            at = [e + w * (lt - e) for e, lt in zip(earlier, later, strict=True)]
            return [n - a for n, a in zip(now, at, strict=True)]
        later_t, later = earlier_t, earlier
    return None
