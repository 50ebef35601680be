"""The estimator core's published estimate: the filter brought to a time, checked, and given out
as a ``StateEstimate`` (body-frame disturbance and covariance, degraded flag, motion fault).

Never gives out a non-finite or absurd estimate (``seaway.vessel.envelope``), nor one whose
position is less certain than ``max_position_std_m``: the filter is dropped instead (counted in
``divergence_resets`` and ``publish_refused``) and re-initialises from the next measurements.
Times are the messages' stamps [ns], passed in.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from seaway.contract.messages import MAX_THRUST_SHORT_FRAC, MessageError, StateEstimate
from seaway.contract.units import NS_PER_S
from seaway.vessel.frames import wrap_pi

from seaway_estimator.core_inputs import check_stamp
from seaway_estimator.kalman import ID1, ID2, ID3, IPSI, IR, IU, IV, IX, IY

if TYPE_CHECKING:
    from seaway_estimator.asymmetry import ThrustAsymmetry
    from seaway_estimator.config import EstimatorConfig
    from seaway_estimator.kalman import Filter
    from seaway_estimator.mismatch import MotionMismatch
    from seaway_estimator.notices import Counters


class PublishedEstimate:
    """The output part of ``EstimatorCore``: ``predict_to`` and what it checks and builds."""

    # read from the other parts
    config: EstimatorConfig
    filter: Filter | None
    counters: Counters
    mismatch: MotionMismatch
    asymmetry: ThrustAsymmetry
    _max_gap_ns: int
    _step_back_ns: int
    _gnss_timeout_ns: int
    _heading_timeout_ns: int
    _world: bool
    _commanded_at: Callable[[int], tuple[float, float]]
    _T_body: np.ndarray
    # the prediction's (``core_predict``)
    _advance: Callable[[int], None]
    _back: Callable[[np.ndarray, float], np.ndarray]
    _time_jump: Callable[[int], None]
    _absurd: Callable[[list[float]], str | None]
    _diverged: Callable[[int, str], None]

    def predict_to(self, t_ns: int) -> StateEstimate | None:
        """The estimate at ``t_ns`` (the filter advances to it), or None before initialisation.

        A time before the filter's own (within ``late_tolerance_s``) gives a first-order
        back-extrapolated estimate without moving the filter; further back gives None (counted);
        further back than a measurement may lie ahead of the clock plus ``late_tolerance_s``
        (``_step_back_ns``), the clock was stepped back: the state is dropped, as for a gap over
        ``max_gap_s`` ahead.
        Never returns a non-finite or absurd estimate (``seaway.vessel.envelope``): a filter that went
        there is dropped (counted in
        ``divergence_resets``) and re-initialises from the next measurements.
        """
        t = check_stamp("predict_to", t_ns)
        f = self.filter
        if f is None:
            return None
        if t - f.t_ns > self._max_gap_ns or f.t_ns - t > self._step_back_ns:
            # Too far ahead to integrate, or further back than any late request: the clock the
            # times come from was stepped (NTP or GPS time on a computer without a real-time
            # clock). Nothing can be predicted across it: the state is dropped, and the next
            # measurements, stamped on the stepped clock, re-initialise it within a second or so.
            self._time_jump(t)
            return None
        if t >= f.t_ns:
            self._advance(t)
            if self.filter is None:  # it diverged on the way
                return None
            z, delay = f.z, 0.0
        else:
            delay = (f.t_ns - t) / NS_PER_S
            if delay > self.config.late_tolerance_s:
                self.counters.inc("too_old")
                return None
            z = self._back(f.z, delay)
        self._update_degraded(t)
        return self._estimate(t, z, f.P, f.degraded)

    step = predict_to

    def degraded_reasons(self, t_ns: int) -> list[str]:
        """Why the estimate at ``t_ns`` is degraded (empty if it is not)."""
        f = self.filter
        if f is None:
            return ["not initialised"]
        c, out = self.config, []
        if t_ns - f.last_gnss_ns > c.gnss_timeout_s * NS_PER_S:
            out.append(f"no GNSS position accepted for {(t_ns - f.last_gnss_ns) / NS_PER_S:.1f} s")
        if t_ns - f.last_heading_ns > c.heading_timeout_s * NS_PER_S:
            out.append(f"no heading accepted for {(t_ns - f.last_heading_ns) / NS_PER_S:.1f} s")
        return out

    def body_disturbance(self) -> tuple[float, float, float] | None:
        """What the vessel's model leaves unexplained now, body frame [N, N, N m]: the filter's
        disturbance and a thruster loss said (``_unexplained``)."""
        f = self.filter
        return None if f is None else self._unexplained(self._body_d(f.z.tolist())[0], f.t_ns)

    def _unexplained(self, d: tuple[float, float, float], t_ns: int) -> tuple[float, float, float]:
        """The body-frame disturbance ``d`` plus what a thruster said short takes off the command
        held at ``t_ns`` (``asymmetry.ThrustAsymmetry.loss``): the filter predicts with that loss,
        but the paper's disturbance (what the controller plans with, eq. 1) is all the model
        without it leaves unexplained. ``d`` itself with none said."""
        if self.asymmetry.side is None:
            return d
        surge_n, yaw_nm = self.asymmetry.loss(*self._commanded_at(t_ns))
        return d[0] + surge_n, d[1], d[2] + yaw_nm


    def _update_degraded(self, t: int) -> None:
        f = self.filter
        assert f is not None
        now = (t - f.last_gnss_ns > self._gnss_timeout_ns
               or t - f.last_heading_ns > self._heading_timeout_ns)
        if now and not f.degraded:
            self.counters.inc("degraded_entered")
        f.degraded = now

    def _body_d(self, z: list[float]) -> tuple[tuple[float, float, float], np.ndarray | None]:
        """Body-frame disturbance and the Jacobian T taking the internal covariance to it (``z``
        the state as floats)."""
        if not self._world:
            return (z[ID1], z[ID2], z[ID3]), None
        psi, dn, de = z[IPSI], z[ID1], z[ID2]
        c, s = math.cos(psi), math.sin(psi)
        du, dv = c * dn + s * de, -s * dn + c * de
        T = self._T_body  # the identity but for the entries set here; used before the next call
        T[ID1, ID1], T[ID1, ID2], T[ID1, IPSI] = c, s, dv
        T[ID2, ID1], T[ID2, ID2], T[ID2, IPSI] = -s, c, -du
        return (du, dv, float(z[ID3])), T

    def _estimate(self, t: int, z: np.ndarray, P: np.ndarray, degraded: bool) -> StateEstimate | None:
        # As floats: on 9 and 81 values numpy's per-call cost is the cost (the matrix products
        # stay numpy's, whose rounding the published covariance has).
        zl = z.tolist()
        d, T = self._body_d(zl)
        d = self._unexplained(d, t)
        if T is not None:
            Pout = T @ P @ T.T
            Pout = 0.5 * (Pout + Pout.T)
        else:
            Pout = P
        cov = Pout.ravel().tolist()
        pxx, pyy = P.item(IX, IX), P.item(IY, IY)
        pos_std = math.sqrt(max(pxx, pyy)) if math.isfinite(pxx) else math.inf
        isfinite = math.isfinite
        finite = all(map(isfinite, zl)) and all(map(isfinite, cov))
        why = ("the state is not finite" if not finite else self._absurd(zl)
               or (f"position std {pos_std:.0f} m (over max_position_std_m "
                   f"{self.config.max_position_std_m:g} m)"
                   if pos_std > self.config.max_position_std_m else None))
        if why is not None:
            self.counters.inc("publish_refused")
            self._diverged(t, why)
            return None
        try:
            est = StateEstimate(
                stamp_ns=t, u_mps=zl[IU], v_mps=zl[IV], r_radps=zl[IR],
                x_m=zl[IX], y_m=zl[IY], psi_rad=wrap_pi(zl[IPSI]),
                tau_d_surge_n=d[0], tau_d_sway_n=d[1], tau_d_yaw_nm=d[2],
                covariance=cov, degraded=degraded,
                motion_fault=self.mismatch.kind, motion_fault_detail=self.mismatch.detail,
                thrust_short_side=self.asymmetry.side,
                thrust_short_frac=None if self.asymmetry.side is None
                else min(round(self.asymmetry.fraction, 3), MAX_THRUST_SHORT_FRAC))
        except (MessageError, ValueError):
            self.counters.inc("publish_refused")
            return None
        self.counters.inc("published")
        return est
