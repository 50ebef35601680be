"""The estimator core's measurement updates, and what a run of rejections or a motion fault does.

Each update is a Kalman update in Joseph form (``kalman.Updater``: one compiled function), gated on
its normalised innovation squared against a chi-square threshold per measurement (``gate_*``):

* GNSS position (x, y) through the NED origin: a run of ``gnss_reject_reinit_count`` rejections
  means the filter, not the fix, is wrong, and the position is moved to the fix;
* GNSS velocity over ground (north, east) = R(psi) [u, v] (paper eq. 2 without current): a run of
  ``reject_run_reopen_count`` rejections re-opens the disturbance force's variance (a thrust lost, a
  tow), and the sample is tried again;
* heading psi (innovation wrapped to (-pi, pi]): re-initialised after a run of rejections, like the
  position;
* yaw rate r: a run of rejections re-opens the yaw moment's variance.

The motion fault detector (``seaway_estimator.mismatch``) is fed at each fix; at a fault's onset the
state is moved to the fix and the disturbance forgotten (``_judge_motion``). So is the thrust
asymmetry watch (``seaway_estimator.asymmetry``: a thruster short of its command, from the
disturbance moment it leaves; ``_judge_asymmetry``).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from seaway.vessel.frames import wrap_pi

from seaway_estimator.kalman import ID1, ID2, ID3, IPSI, IR, IU, IV, IX, IY, NZ, Updater
from seaway_estimator.mismatch import FixSample, MotionMismatch
from seaway_estimator.notices import Notice

if TYPE_CHECKING:
    from seaway_estimator.asymmetry import ThrustAsymmetry
    from seaway_estimator.config import EstimatorConfig
    from seaway_estimator.kalman import Filter
    from seaway_estimator.notices import Counters

_H_POS = np.zeros((2, NZ))
_H_POS[0, IX] = _H_POS[1, IY] = 1.0


class MeasurementUpdates:
    """The update part of ``EstimatorCore``: each measurement into the filter, gated."""

    # read from the other parts
    config: EstimatorConfig
    filter: Filter | None
    counters: Counters
    mismatch: MotionMismatch
    asymmetry: ThrustAsymmetry
    thrust_withheld: str | None
    body_disturbance: Callable[[], tuple[float, float, float] | None]
    _commanded_at: Callable[[int], tuple[float, float]]
    _notices: deque[Notice]
    _world: bool
    _init_force_std_n: tuple[float, float]
    _back: Callable[[np.ndarray, float], np.ndarray]

    def _init_updates(self, thrust_max_n: float, arm_m: float) -> None:
        self._R_sog = np.eye(2) * self.config.sog_std_mps ** 2
        self._H_sog = np.zeros((2, NZ))  # rows refilled at each velocity update
        # What a lost thruster leaves unexplained: its full thrust, and that thrust's moment.
        self._reopen_force_var = thrust_max_n ** 2
        self._reopen_moment_var = (thrust_max_n * arm_m) ** 2
        self._updaters = {m: Updater(m) for m in (1, 2)}  # by the number of values measured
        self._last_nis = math.nan  # of the last gated update


    def _gated_update(self, nu: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float) -> bool:
        """Kalman update (``kalman.Updater``, Joseph form) with a chi-square gate on the
        innovation; False if rejected."""
        f = self.filter
        assert f is not None
        nis, z, P = self._updaters[len(nu)].step(f.z, f.P, nu, H, R)
        self._last_nis = nis
        if not (math.isfinite(nis) and nis <= gate):  # also false for NaN
            return False
        z[IPSI] = wrap_pi(z.item(IPSI))
        f.z, f.P = z, P
        return True

    def _gated_scalar(self, nu: float, i: int, var: float, gate: float) -> bool:
        """``_gated_update`` for a measurement of one state ``i`` (H a unit row, R its variance)."""
        f = self.filter
        assert f is not None
        nis, z, P = self._updaters[1].scalar(f.z, f.P, nu, i, var)
        if not (math.isfinite(nis) and nis <= gate):
            return False
        z[IPSI] = wrap_pi(z.item(IPSI))
        f.z, f.P = z, P
        return True

    def _update_position(self, north: float, east: float, std: float, delay: float, t: int) -> None:
        f = self.filter
        assert f is not None
        zp = self._back(f.z, delay) if delay > 0 else f.z
        nu = np.array([north - zp[IX], east - zp[IY]])
        var = std * std
        R = np.array([[var, 0.0 * var], [0.0 * var, var]])  # np.eye(2) * var, value for value
        if self._gated_update(nu, _H_POS, R, self.config.gate_gnss):
            self.counters.inc("gnss_accepted")
            f.gnss_reject_run = 0
            f.last_gnss_ns = max(f.last_gnss_ns, t)
            return
        self.counters.inc("gnss_rejected")
        f.gnss_reject_run += 1
        off_m = math.hypot(nu[0], nu[1])
        self._notices.append(Notice(t, "gnss_rejected", f"fix {off_m:.2f} m from the estimate "
                                    f"(std {std:.2f} m)", f.gnss_reject_run))
        if f.gnss_reject_run >= self.config.gnss_reject_reinit_count:
            # Consistently far from every fix: the filter is what is wrong. Take the fix.
            self._reinit_block((IX, IY), (north - zp[IX], east - zp[IY]), std * std)
            self._notices.append(Notice(t, "gnss_reinit", f"position moved {off_m:.2f} m to the "
                                        "fix", f.gnss_reject_run))
            f.gnss_reject_run = 0
            f.last_gnss_ns = max(f.last_gnss_ns, t)
            self.counters.inc("gnss_reinit")

    def _update_sog(self, vn: float, ve: float, delay: float) -> None:
        f = self.filter
        assert f is not None
        zp = self._back(f.z, delay) if delay > 0 else f.z
        u, v, psi = zp[IU], zp[IV], zp[IPSI]
        c, s = math.cos(psi), math.sin(psi)
        # h(z) = R(psi) [u, v]: the kinematic rows of the model (paper eq. 2) without current.
        nu = np.array([vn - (u * c - v * s), ve - (u * s + v * c)])
        H = self._H_sog  # the other entries stay zero
        H[0, IU], H[0, IV], H[0, IPSI] = c, -s, -u * s - v * c
        H[1, IU], H[1, IV], H[1, IPSI] = s, c, u * c - v * s
        R = self._R_sog
        ok = self._gated_update(nu, H, R, self.config.gate_sog)
        if ok:
            f.sog_reject_run = 0
        else:
            f.sog_reject_run += 1
            if f.sog_reject_run >= self.config.reject_run_reopen_count:
                # The boat does not move as the model says (a thrust lost, a tow): let the force
                # take up what the model lacks, and the speeds follow, then try the sample again.
                size = float(nu @ nu)
                self._reopen(((ID1, self._reopen_force_var), (ID2, self._reopen_force_var),
                              (IU, size), (IV, size)), "velocity over ground", f.sog_reject_run)
                f.sog_reject_run = 0
                ok = self._gated_update(nu, H, R, self.config.gate_sog)
        self.counters.inc("sog_accepted" if ok else "sog_rejected")

    def _update_heading(self, psi_m: float, delay: float, t: int) -> None:
        f = self.filter
        assert f is not None
        zp = self._back(f.z, delay) if delay > 0 else f.z
        innov = wrap_pi(psi_m - zp[IPSI])
        var = self.config.heading_std_rad ** 2
        if self._gated_scalar(innov, IPSI, var, self.config.gate_heading):
            self.counters.inc("heading_accepted")
            f.heading_reject_run = 0
            f.last_heading_ns = max(f.last_heading_ns, t)
            return
        self.counters.inc("heading_rejected")
        f.heading_reject_run += 1
        self._notices.append(Notice(t, "heading_rejected", f"heading {innov:+.3f} rad from the "
                                    "estimate", f.heading_reject_run))
        if f.heading_reject_run >= self.config.heading_reject_reinit_count:
            self._reinit_block((IPSI,), (innov,), var)
            self._notices.append(Notice(t, "heading_reinit", f"heading moved {innov:+.3f} rad to "
                                        "the measurement", f.heading_reject_run))
            f.heading_reject_run = 0
            f.last_heading_ns = max(f.last_heading_ns, t)
            self.counters.inc("heading_reinit")

    def _update_yaw_rate(self, r_m: float, delay: float) -> None:
        f = self.filter
        assert f is not None
        zp = self._back(f.z, delay) if delay > 0 else f.z
        nu, var = r_m - zp[IR], self.config.yaw_rate_std_radps ** 2
        ok = self._gated_scalar(nu, IR, var, self.config.gate_yaw_rate)
        if ok:
            f.yaw_rate_reject_run = 0
        else:
            f.yaw_rate_reject_run += 1
            if f.yaw_rate_reject_run >= self.config.reject_run_reopen_count:
                # The boat does not turn as the model says: the same for the yaw moment. Left
                # alone, the heading followed the model away (radians) and was re-initialised
                # again and again.
                self._reopen(((ID3, self._reopen_moment_var), (IR, nu * nu)), "yaw rate",
                             f.yaw_rate_reject_run)
                f.yaw_rate_reject_run = 0
                ok = self._gated_scalar(nu, IR, var, self.config.gate_yaw_rate)
        self.counters.inc("yaw_rate_accepted" if ok else "yaw_rate_rejected")

    def _judge_motion(self, sample: FixSample, std: float,
                      sog: tuple[float | None, float | None]) -> None:
        """Feed the motion fault detector (``mismatch``); re-anchor to the measurements on it.

        At the onset the state is moved to the fix (position, and speeds from its velocity over
        ground) and the disturbance forgotten (it had taken up thrust the vessel never gave); while
        a ``not_moving`` fault lasts the prediction stops using a thrust the vessel does not follow,
        and while any fault lasts a fix the filter gates out moves the state to it at once, instead
        of dead-reckoning until ``gnss_reject_reinit_count`` rejections."""
        f = self.filter
        event = self.mismatch.on_fix(sample)
        if event is not None:
            self._notices.append(Notice(event.t_ns, "motion_fault" if event.kind else
                                        "motion_fault_cleared",
                                        f"{event.kind}: {event.detail}" if event.kind else
                                        event.detail))
            if event.kind is not None:
                self.counters.inc("motion_faults")
                for i, std0 in zip((ID1, ID2, ID3), (*self._init_force_std_n,
                                                     self.config.init_moment_std_nm), strict=True):
                    if f is not None:
                        self._reinit_block((i,), (-f.z[i],), std0 * std0)
        onset = event is not None and event.kind is not None
        if f is None or not (onset or (self.mismatch.kind is not None and sample.rejected)):
            return
        self._anchor(sample.north_m, sample.east_m, std, sog, sample.t_ns)
        self.counters.inc("motion_anchored")

    def _judge_asymmetry(self, t_ns: int) -> None:
        """Feed the thrust asymmetry watch (``asymmetry``) the disturbance moment and the thrust
        commanded, while the thrust is applied and no motion fault stands (that one says more)."""
        d = self.body_disturbance()
        if d is None or self.thrust_withheld is not None or self.mismatch.kind is not None:
            return
        port_n, starboard_n = self._commanded_at(t_ns)
        before = self.asymmetry.loss(port_n, starboard_n)
        event = self.asymmetry.on_estimate(t_ns, d[2], port_n, starboard_n)
        after = self.asymmetry.loss(port_n, starboard_n)
        if after != before:
            # The prediction now takes off ``after``, not ``before``: the disturbance keeps the
            # rest, so that what is unexplained (and published) stays what it was at this command.
            self._shift_disturbance(before[0] - after[0], before[1] - after[1])
        if event is None:
            return
        if event.side is not None:
            self.counters.inc("thrust_asymmetries")
            self._notices.append(Notice(t_ns, "thrust_asymmetry", event.detail))
        else:
            self._notices.append(Notice(t_ns, "thrust_asymmetry_cleared", event.detail,
                                        routine=True))

    def _shift_disturbance(self, surge_n: float, yaw_nm: float) -> None:
        """Add a body-frame surge force [N] and yaw moment [N m] to the filter's disturbance (in
        the world frame, the force rotated by the heading), each as uncertain as it is large."""
        f = self.filter
        assert f is not None
        if self._world:
            psi = float(f.z[IPSI])
            f.z[ID1] += surge_n * math.cos(psi)
            f.z[ID2] += surge_n * math.sin(psi)
            f.P[ID2, ID2] += surge_n * surge_n
        else:
            f.z[ID1] += surge_n
        f.P[ID1, ID1] += surge_n * surge_n
        f.z[ID3] += yaw_nm
        f.P[ID3, ID3] += yaw_nm * yaw_nm

    def _anchor(self, north_m: float, east_m: float, std_m: float,
                sog: tuple[float | None, float | None], t_ns: int) -> None:
        """Move the position (NED, m) to a fix of standard deviation ``std_m``, and the speeds to
        its velocity over ground (``sog``, north and east, m/s) when it has one."""
        f = self.filter
        assert f is not None
        self._reinit_block((IX, IY), (north_m - f.z[IX], east_m - f.z[IY]), std_m * std_m)
        if sog[0] is not None and sog[1] is not None:
            c, s = math.cos(f.z[IPSI]), math.sin(f.z[IPSI])
            u, v = c * sog[0] + s * sog[1], -s * sog[0] + c * sog[1]
            self._reinit_block((IU, IV), (u - f.z[IU], v - f.z[IV]), self.config.sog_std_mps ** 2)
        f.gnss_reject_run = f.sog_reject_run = 0
        f.last_gnss_ns = max(f.last_gnss_ns, t_ns)

    def _reopen(self, added: tuple[tuple[int, float], ...], sensor: str, run: int) -> None:
        """Add variance to states ``(index, variance)``: ``run`` samples of ``sensor`` in a row
        said the model, not the sensor, is wrong. Routine: a turn does it, with several in a row
        where the model is a rough identification; a boat that keeps doing other than commanded is
        the motion fault detector's to say (``_judge_motion``)."""
        f = self.filter
        assert f is not None
        for i, var in added:
            f.P[i, i] += var
        self.counters.inc("disturbance_reopened")
        self._notices.append(Notice(f.t_ns, "disturbance_reopened", f"{run} {sensor} samples in a "
                                    "row disagree with the model: the disturbance's uncertainty "
                                    "is re-opened", run, routine=True))

    def _reinit_block(self, idx: tuple[int, ...], shift: tuple[float, ...], var: float) -> None:
        """Move states ``idx`` by ``shift`` and decorrelate them with variance ``var``."""
        f = self.filter
        assert f is not None
        for i, d in zip(idx, shift, strict=True):
            f.z[i] += d
            f.P[i, :] = 0.0
            f.P[:, i] = 0.0
            f.P[i, i] = var
        f.z[IPSI] = wrap_pi(f.z[IPSI])
