"""What a vessel can physically do: bounds past which a state is a diverged estimate, not a boat.

The model's terminal speeds under full thrust (linear damping, paper eq. 1) give each vessel its own
scale: surge and sway ``2 T_max / X_u``, yaw rate ``2 T_max l / N_r``. A state several times past
them (``MARGIN``), or past the absolute limits of a small surface vessel, cannot be reached by
thrust and any credible disturbance; it comes from a filter that went unstable (an estimate of
10^27 m/s has been published as finite) and must not be flown on. The same bounds serve the
estimator, which drops such a state and re-initialises from the measurements, and the controller,
which refuses to plan from one.

Body frame, through the water (the model's u, v, r): surge and sway [m/s], yaw rate [rad/s].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from seaway.vessel.model import VesselParams

MARGIN = 5.0
"""How many times the model's terminal speed or rate a state may reach before it is absurd: room
for gusts, currents the model takes as forces, and model error, none of them a factor of five."""
MAX_SPEED_MPS = 25.0
"""No small twin-thruster surface vessel goes faster through the water (about 50 knots), whatever
its vessel file's damping says (an identified X_u can be small)."""
MAX_YAW_RATE_RADPS = 2.0 * math.pi
"""A turn a second: past any hull's yaw rate."""


@dataclass(frozen=True)
class Envelope:
    """The largest credible |u|, |v| [m/s] and |r| [rad/s] of one vessel (body frame), and of the
    disturbance tau_d acting on it: |force| [N] and |moment| [N m]."""

    speed_mps: float
    yaw_rate_radps: float
    force_n: float = math.inf
    moment_nm: float = math.inf

    def absurd_disturbance(self, surge_n: float, sway_n: float, yaw_nm: float) -> str | None:
        """Why tau_d cannot act on this vessel (None: it can). Non-finite is absurd."""
        if not (math.isfinite(surge_n) and math.isfinite(sway_n) and math.isfinite(yaw_nm)):
            return "the disturbance estimate is not finite"
        force = math.hypot(surge_n, sway_n)
        if force > self.force_n:
            return (f"disturbance force {force:.3g} N is past the vessel's envelope "
                    f"({self.force_n:.3g} N)")
        if abs(yaw_nm) > self.moment_nm:
            return (f"disturbance moment {yaw_nm:.3g} N m is past the vessel's envelope "
                    f"({self.moment_nm:.3g} N m)")
        return None

    def absurd(self, u_mps: float, v_mps: float, r_radps: float) -> str | None:
        """Why the body speeds cannot be this vessel's (None: they can). Non-finite is absurd."""
        isfinite = math.isfinite  # no generator: this runs at every filter step
        if not (isfinite(u_mps) and isfinite(v_mps) and isfinite(r_radps)):
            return "the state is not finite"
        speed = math.hypot(u_mps, v_mps)
        if speed > self.speed_mps:
            return (f"speed through the water {speed:.3g} m/s is past the vessel's envelope "
                    f"({self.speed_mps:.3g} m/s)")
        if abs(r_radps) > self.yaw_rate_radps:
            return (f"yaw rate {r_radps:.3g} rad/s is past the vessel's envelope "
                    f"({self.yaw_rate_radps:.3g} rad/s)")
        return None


def envelope(p: VesselParams) -> Envelope:
    """``p``'s envelope: ``MARGIN`` times its terminal speed and yaw rate under full thrust, capped
    by ``MAX_SPEED_MPS`` and ``MAX_YAW_RATE_RADPS``; a disturbance up to ``MARGIN`` times its full
    thrust and full turning moment (a disturbance the thrusters could not answer five times over
    leaves nothing to control; an estimate past that is a filter gone wrong)."""
    thrust_n = 2.0 * p.thrust_max_n
    speed = MARGIN * thrust_n / min(p.xu_kgps, p.yv_kgps)
    rate = MARGIN * thrust_n * p.arm_m / p.nr_kgm2ps
    return Envelope(min(speed, MAX_SPEED_MPS), min(rate, MAX_YAW_RATE_RADPS),
                    MARGIN * thrust_n, MARGIN * thrust_n * p.arm_m)
