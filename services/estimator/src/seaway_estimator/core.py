"""The estimator's pure core: an extended Kalman filter on the shared vessel model.

State (9), in the units of ``StateEstimate``::

    z = [u, v, r, x, y, psi, d1, d2, d3]

``[u, v, r, x, y, psi]`` is the vessel state of ``seaway.vessel.model`` (body speeds through the water, NED
position and heading). ``d`` is the disturbance (the paper's tau_d), a random walk: with
``disturbance_frame = "world"`` (default) ``d1, d2`` are a world-frame force (north, east) [N] that
``seaway.vessel.model.derivative`` rotates into the body frame (its ``force_ne``), otherwise ``d1, d2`` are
body-frame surge and sway forces (its ``tau_body``); ``d3`` is always the body yaw moment [N m].
Whatever the internal frame, ``StateEstimate`` carries the body-frame values and their covariance.

The core is one class in four parts, each a module: the inputs and initialisation (here); the
published estimate (``core_estimate``: ``predict_to``, the checks before an estimate goes out, the
body-frame disturbance and covariance); the prediction (``core_predict``: the mean with
``seaway.vessel.model.rk4_step`` and the thrust held, the covariance with the exact Jacobian, one
compiled function); the updates (``core_updates``: GNSS position and velocity over ground, heading,
yaw rate, each when it arrives, Joseph form, one compiled function each).

Every update is gated on its normalised innovation squared (chi-square threshold per measurement);
a rejected sample is counted and ignored. Before that, what a message says past what a receiver or
the vessel can give, and a copy of a measurement already used, are refused (``core_inputs``).
Refusals, rejections and re-initialisations are also kept as ``Notice``s for the service to log
(``take_notices``). Time is always passed in (``stamp_ns`` of the messages and ``predict_to(t_ns)``);
there is no clock and no randomness, so the same inputs give the same outputs bit for bit.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from seaway.contract import keys
from seaway.contract.messages import (
    THRUST_APPLIED_ANYWAY,
    Attitude,
    GnssFix,
    NavOrigin,
    ThrustCommand,
    VehicleStatus,
)
from seaway.contract.units import NS_PER_S
from seaway.runtime.stamps import MAX_AHEAD_LIVE_S
from seaway.vessel import model
from seaway.vessel.envelope import envelope
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import VesselParams
from seaway.vessel.thrusters import apply_dead_zone, output_pair

from seaway_estimator.asymmetry import ThrustAsymmetry
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core_estimate import PublishedEstimate
from seaway_estimator.core_inputs import (
    ATTITUDE_SPACING_NS,
    GNSS_SPACING_NS,
    EstimatorError,
    RecentStamps,
    check_finite,
    check_stamp,
    fix_problem,
    sog_problem,
    yaw_rate_problem,
)
from seaway_estimator.core_predict import Prediction
from seaway_estimator.core_updates import MeasurementUpdates
from seaway_estimator.kalman import IPSI, IX, IY, NZ, Filter, Predictor
from seaway_estimator.mismatch import FixSample, MotionMismatch
from seaway_estimator.notices import MAX_NOTICES, Counters, Notice

INPUT_KEYS: dict[str, keys.KeySpec] = {"gnss": keys.GNSS, "attitude": keys.ATTITUDE,
                                      "thrust": keys.THRUST}
"""The estimator's measurement inputs by kind: the key each comes from (and so its message type),
under the name an input trace gives it (``replay.py``). In the order same-stamp inputs are applied."""
STATUS_KEY = keys.VEHICLE_STATUS
"""Whether the autopilot applies the commanded thrust (``VehicleStatus.thrust_withheld``): an input
in real time only (in lockstep the sim applies exactly the command it says it consumed); traced as
kind ``"status"``, applied after the inputs of the same stamp."""


@dataclass
class _Pending:
    """Measurements kept until the filter can initialise (a position and a heading)."""

    fix: tuple[int, float, float, float | None, float | None, float] | None = None
    attitude: tuple[int, float, float | None] | None = None
    """(stamp, heading, yaw rate or None if it was refused)."""


def _initial_force_std(c: EstimatorConfig, p: VesselParams, world: bool) -> tuple[float, float]:
    """The prior std of ``(d1, d2)`` [N]: ``init_force_std_n`` and the force that holds a drift of
    ``init_current_std_mps`` against the damping (the model has no current, so a current is a
    speed through the water ``c`` kept up by ``D c``). Without it the prior of a 0.15 m/s current
    is a 25-sigma force on the paper's vessel, and the first fixes of a drifting boat are gated out.
    In the world frame the current's direction is unknown: the larger damping on both axes."""
    surge = p.xu_kgps * c.init_current_std_mps
    sway = p.yv_kgps * c.init_current_std_mps
    if world:
        surge = sway = max(surge, sway)
    return math.hypot(c.init_force_std_n, surge), math.hypot(c.init_force_std_n, sway)


class EstimatorCore(PublishedEstimate, Prediction, MeasurementUpdates):
    """Messages and time in, ``StateEstimate`` out. See the module docstring for the model."""

    def __init__(self, config: EstimatorConfig | None = None, vessel: VesselParams | None = None,
                 vessel_dir: Path | None = None) -> None:
        self.config = config or EstimatorConfig()
        c = self.config
        if vessel is None:
            name = c.vessel if vessel_dir is None else str(vessel_dir / f"{c.vessel}.toml")
            vessel = model.load_vessel(name)
        self.p = vessel
        self._world = c.disturbance_frame == "world"
        self._dead_zone_n = vessel.dead_zone_n if c.apply_dead_zone else 0.0
        self._q = np.array([
            c.accel_surge_std_per_sqrt_s, c.accel_sway_std_per_sqrt_s, c.accel_yaw_std_per_sqrt_s,
            c.position_std_per_sqrt_s, c.position_std_per_sqrt_s, c.heading_std_per_sqrt_s,
            c.force_std_per_sqrt_s, c.force_std_per_sqrt_s, c.moment_std_per_sqrt_s]) ** 2
        self._max_step_ns = round(c.max_step_s * NS_PER_S)
        # Per-configuration bounds in ns, as each comparison below computed them at every sample.
        self._max_gap_ns = round(c.max_gap_s * NS_PER_S)
        # A request this far behind the filter's time comes from a clock stepped back: the filter
        # is ahead of the clock by at most a measurement's allowance (MAX_AHEAD_LIVE_S), and a
        # late request by at most late_tolerance_s (core_estimate.predict_to).
        self._step_back_ns = round((MAX_AHEAD_LIVE_S + c.late_tolerance_s) * NS_PER_S)
        self._late_ns = round(c.late_tolerance_s * NS_PER_S)  # the motion kept for late ones
        self._gnss_timeout_ns = c.gnss_timeout_s * NS_PER_S
        self._heading_timeout_ns = c.heading_timeout_s * NS_PER_S
        self._T_body = np.eye(NZ)  # ``_body_d``'s Jacobian, its six entries refilled at each call
        self._init_force_std_n = _initial_force_std(c, vessel, self._world)
        self._envelope = envelope(vessel)
        self._predictor = Predictor(vessel, self._world, self._q)
        self._init_updates(vessel.thrust_max_n, vessel.arm_m)
        self._fixed_origin = (None if c.origin is None else GeoOrigin.from_degrees(
            c.origin.lat_deg, c.origin.lon_deg, c.origin.alt_m))
        self.counters = Counters()
        self._notices: deque[Notice] = deque(maxlen=MAX_NOTICES)
        self.origin: GeoOrigin | None = self._fixed_origin
        self.filter: Filter | None = None
        self._pending = _Pending()
        late_ns = round(c.late_tolerance_s * NS_PER_S)
        self._used = {"gnss": RecentStamps(late_ns, GNSS_SPACING_NS),
                      "attitude": RecentStamps(late_ns, ATTITUDE_SPACING_NS)}
        """The stamps of the fixes and attitudes the filter used, while a copy could be applied
        again (``core_inputs.RecentStamps``)."""
        self._thrust: tuple[float, float] = (0.0, 0.0)
        self._thrust_until_ns: int | None = None
        self.mismatch = MotionMismatch(c.mismatch)
        """The motion fault detector (``seaway_estimator.mismatch``), fed at each GNSS fix."""
        self.asymmetry = ThrustAsymmetry(vessel.arm_m, vessel.thrust_max_n)
        """A thruster giving less than commanded (``seaway_estimator.asymmetry``), judged at each
        GNSS fix from the disturbance moment."""
        self.thrust_withheld: str | None = None
        """Why the autopilot does not apply the commanded thrust now (the last ``VehicleStatus``
        said so: disarmed, no link, another mode); None: it does, or nobody said otherwise."""
        self._anchor_next_fix = False
        """The next GNSS fix moves the state to it (``on_vehicle_status``: the thrust was found
        withheld, so the prediction since some unknown moment used a thrust never applied)."""

    # ------------------------------------------------------------------------------------------
    # Public API
    # ------------------------------------------------------------------------------------------

    @property
    def initialised(self) -> bool:
        return self.filter is not None

    def reset(self, keep_origin: bool = True) -> None:
        """Forget the state (and the origin unless ``keep_origin`` or one is configured).

        The filter re-initialises from the next position and heading, exactly as at start-up.
        Counters are kept (``resets`` counts this); the last thrust command is kept, since the
        thrusters do not stop because the estimator restarted.
        """
        self._forget()
        self.mismatch.reset()
        self.asymmetry = ThrustAsymmetry(self.p.arm_m, self.p.thrust_max_n)
        if not keep_origin:
            self.origin = self._fixed_origin
        self.counters.inc("resets")

    def _forget(self) -> None:
        """Drop the state and what was kept to initialise it: the next position and heading
        initialise the filter again."""
        self.filter = None
        self._pending = _Pending()
        for used in self._used.values():
            used.clear()

    def take_notices(self) -> list[Notice]:
        """The notices since the last call, oldest first (see ``Notice``)."""
        out = list(self._notices)
        self._notices.clear()
        return out

    def nav_origin(self, stamp_ns: int) -> NavOrigin | None:
        """The NED origin as a message, once fixed."""
        o = self.origin
        if o is None:
            return None
        return NavOrigin(stamp_ns=stamp_ns, lat_rad=o.lat_rad, lon_rad=o.lon_rad, alt_m=o.alt_m)

    def on_thrust(self, msg: ThrustCommand) -> None:
        """The commanded thrust, held from ``max(stamp, filter time)`` until replaced or stale.

        The filter is first brought to the stamp with the thrust held until then, at most
        ``max_gap_s`` ahead: a command stamped further ahead is refused (counted in ``too_new``),
        since integrating to it would take unbounded time and leave the filter in the future.
        """
        t = self._check(msg.stamp_ns, "ThrustCommand", thrust_port_n=msg.thrust_port_n,
                        thrust_starboard_n=msg.thrust_starboard_n)
        f = self.filter
        if not self._bring_to(t):
            return
        t_apply = t if f is None else max(t, f.t_ns)
        # What the thrusters produce: the dead zone (if modelled) of what Seaway sends them, vehicle
        # I/O's output stage (the lockstep sim applies it too). The stage sends 0 or at least this
        # vessel's dead zone, so the dead zone passes it unchanged today; it stays as the thruster's
        # physics, not as a second definition of the stage.
        port, starboard = output_pair(msg.thrust_port_n, msg.thrust_starboard_n, self.p)
        self._thrust = (apply_dead_zone(port, self._dead_zone_n),
                        apply_dead_zone(starboard, self._dead_zone_n))
        self._thrust_until_ns = t_apply + round(self.config.thrust_timeout_s * NS_PER_S)
        self.counters.inc("thrust_received")

    def on_vehicle_status(self, msg: VehicleStatus) -> None:
        """Whether the autopilot applies the commanded thrust (``VehicleStatus.thrust_withheld``).

        From the status's stamp on, while it says the thrust is withheld (disarmed, no link, a mode
        in which manual control does not drive the thrusters), the filter predicts with zero thrust
        whatever is commanded: a rebooted autopilot comes back disarmed with the boat still, and
        dead-reckoning on the commands would run away from it. A status stamped more than
        ``max_gap_s`` ahead of the filter is refused (``too_new``), as a thrust command is.
        """
        t = self._check(msg.stamp_ns, "VehicleStatus")
        withheld = None if msg.thrust_withheld in THRUST_APPLIED_ANYWAY else msg.thrust_withheld
        if withheld == self.thrust_withheld:
            self.counters.inc("status_received")
            return
        if not self._bring_to(t):
            return
        if withheld is not None and self.thrust_withheld is None and self.filter is not None:
            # The autopilot stopped applying the thrust (rebooted, link lost, disarmed) some time
            # before this status said so, up to its link timeout: the filter dead-reckoned on
            # commands the vessel never got. The next fix re-anchors the state, and the motion
            # fault detector starts a new window: a vessel not obeying an autopilot that was not
            # passing the commands on is no motion fault.
            self._anchor_next_fix = True
            self.mismatch.reset()
        self.thrust_withheld = withheld
        self.counters.inc("status_received")

    def on_gnss(self, msg: GnssFix) -> None:
        """A GNSS fix: position (and velocity over ground when the fix has it).

        A fix already used (a stale copy) is ignored (``duplicates``). A fix whose position is no
        position (``core_inputs.fix_problem``: a std past ``MAX_GNSS_STD_M``, past ``MAX_RANGE_M``
        from the origin) is refused whole (``gnss_refused``) and never becomes the origin; a
        velocity over ground past the vessel's envelope is refused (``sog_refused``) and the
        position kept; a fix closer to the last one used than a receiver's fastest rate allows is
        refused (``too_frequent``)."""
        t = self._check(msg.stamp_ns, "GnssFix", lat_rad=msg.lat_rad, lon_rad=msg.lon_rad,
                        alt_m=msg.alt_m, vel_n_mps=msg.vel_n_mps, vel_e_mps=msg.vel_e_mps,
                        horizontal_std_m=msg.horizontal_std_m)
        if msg.fix_type < self.config.min_fix_type:
            self.counters.inc("gnss_no_fix")
            return
        if self.filter is not None and t in self._used["gnss"]:
            self.counters.inc("duplicates")
            return
        origin = (self.origin if self.origin is not None else
                  GeoOrigin(msg.lat_rad, msg.lon_rad, msg.alt_m))
        north, east, _ = origin.to_ned(msg.lat_rad, msg.lon_rad, msg.alt_m)
        std = self._gnss_std(msg)
        why = fix_problem(north, east, std)
        if why is not None:
            self._refuse(t, "gnss_refused", f"GNSS fix refused: {why}")
            return
        self.origin = origin
        sog = (msg.vel_n_mps, msg.vel_e_mps)
        if sog[0] is not None and sog[1] is not None:
            why = sog_problem(sog[0], sog[1], self._envelope)
            if why is not None:
                self._refuse(t, "sog_refused", f"GNSS velocity refused, position kept: {why}")
                sog = (None, None)
        if self.filter is not None and (why := self._used["gnss"].too_soon(t)) is not None:
            self._refuse(t, "too_frequent", f"GNSS fix refused: {why}")  # after what it says
            return
        if self.filter is None:
            self._pending.fix = (t, north, east, sog[0], sog[1], std)
            self._try_initialise()
            return
        delay = self._to_time(t)
        if delay is None:
            return
        self._used["gnss"].add(t, self.filter.t_ns)
        if self._anchor_next_fix:
            self._anchor_next_fix = False
            off_m = math.hypot(north - self.filter.z[IX], east - self.filter.z[IY])
            self._anchor(north, east, std, sog, t)
            self.counters.inc("withheld_anchored")
            self._notices.append(Notice(t, "withheld_reanchor", f"position moved {off_m:.2f} m to "
                                        "the fix: the thrust was withheld since an unknown moment",
                                        routine=True))
            return
        rejected = self.counters["gnss_rejected"] + self.counters["sog_rejected"]
        self._update_position(north, east, std, delay, t)
        nis = self._last_nis if math.isfinite(self._last_nis) else math.inf
        if sog[0] is not None and sog[1] is not None:
            self._update_sog(sog[0], sog[1], delay)
        rejected = self.counters["gnss_rejected"] + self.counters["sog_rejected"] > rejected
        psi = self.filter.z[IPSI] if self.filter is not None else 0.0
        self._judge_motion(FixSample(
            t, north, east, rejected, min(nis, self.config.gate_gnss),
            None if sog[0] is None or sog[1] is None else
            sog[0] * math.cos(psi) + sog[1] * math.sin(psi),
            model.steady_surge_speed_mps(sum(self.asymmetry.effective(*self._commanded_at(t))),
                                         self.p)), std, sog)
        self._judge_asymmetry(t)

    def on_attitude(self, msg: Attitude) -> None:
        """Heading and yaw rate (roll and pitch are not used by a 3-DOF model).

        An attitude already used (a stale copy) is ignored (``duplicates``); a yaw rate past the
        vessel's envelope is refused (``yaw_rate_refused``) and the heading kept; one closer to the
        last used than an autopilot streams is refused (``too_frequent``)."""
        t = self._check(msg.stamp_ns, "Attitude", yaw_rad=msg.yaw_rad,
                        yaw_rate_radps=msg.yaw_rate_radps)
        if self.filter is not None and t in self._used["attitude"]:
            self.counters.inc("duplicates")
            return
        r: float | None = msg.yaw_rate_radps
        why = yaw_rate_problem(r, self._envelope)
        if why is not None:
            self._refuse(t, "yaw_rate_refused", f"yaw rate refused, heading kept: {why}")
            r = None
        if self.filter is not None and (why := self._used["attitude"].too_soon(t)) is not None:
            self._refuse(t, "too_frequent", f"attitude refused: {why}")
            return
        if self.filter is None:
            self._pending.attitude = (t, msg.yaw_rad, r)
            self._try_initialise()
            return
        delay = self._to_time(t)
        if delay is None:
            return
        self._used["attitude"].add(t, self.filter.t_ns)
        self._update_heading(msg.yaw_rad, delay, t)
        if r is not None:
            self._update_yaw_rate(r, delay)

    # ------------------------------------------------------------------------------------------
    # Input checks
    # ------------------------------------------------------------------------------------------

    def _check(self, t_ns: object, where: str, **values: float | None) -> int:
        if type(t_ns) is int and t_ns >= 0:  # the usual case: no exception handling set up
            isfinite = math.isfinite
            for v in values.values():
                if v is not None and not isfinite(v):
                    break
            else:
                return t_ns
        try:
            t = check_stamp(where, t_ns)
            check_finite(where, **values)
        except EstimatorError:
            self.counters.inc("refused_non_finite")
            raise
        return t

    def _refuse(self, t: int, kind: str, detail: str) -> None:
        """Part of an input refused for what it says (``core_inputs``): counted under ``kind``
        and noticed, with the value and the bound, for the service to log."""
        self.counters.inc(kind)
        self._notices.append(Notice(t, kind, detail))

    def _gnss_std(self, msg: GnssFix) -> float:
        c = self.config
        if c.use_reported_gnss_std and msg.horizontal_std_m is not None:
            return max(msg.horizontal_std_m, c.gnss_std_min_m)
        return c.gnss_std_m

    # ------------------------------------------------------------------------------------------
    # Initialisation
    # ------------------------------------------------------------------------------------------

    def _try_initialise(self) -> None:
        fix, att = self._pending.fix, self._pending.attitude
        if fix is None or att is None:
            return
        t_fix, north, east, vn, ve, gstd = fix
        t_att, psi, r = att
        if abs(t_fix - t_att) > self.config.init_max_skew_s * NS_PER_S:
            return  # keep the newer of each; the older one will be replaced
        c = self.config
        cps, sps = math.cos(psi), math.sin(psi)
        if vn is not None and ve is not None:
            u, v, sstd = cps * vn + sps * ve, -sps * vn + cps * ve, c.sog_std_mps
        else:
            u, v, sstd = 0.0, 0.0, c.init_speed_std_mps
        # Without a yaw rate (refused as absurd), none yet: the prior's.
        r, rstd = (0.0, c.init_yaw_rate_std_radps) if r is None else (r, c.yaw_rate_std_radps)
        z = np.array([u, v, r, north, east, psi, 0.0, 0.0, 0.0])
        P = np.diag(np.array([sstd, sstd, max(rstd, 1e-4), gstd, gstd,
                              c.heading_std_rad, *self._init_force_std_n,
                              c.init_moment_std_nm]) ** 2)
        t0 = max(t_fix, t_att)
        self.filter = Filter(t_ns=t0, z=z, P=P, last_gnss_ns=t_fix, last_heading_ns=t_att)
        self._pending = _Pending()
        self._used["gnss"].add(t_fix, t0)
        self._used["attitude"].add(t_att, t0)
