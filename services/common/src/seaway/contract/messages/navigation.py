"""Navigation (producer: the estimator)."""

from __future__ import annotations

import math
from typing import ClassVar, Literal

from pydantic import Field

from seaway.contract.messages.base import MAX_REASON_CHARS, Message
from seaway.contract.messages.sensors import GNSS_ALT_MAX_M, GNSS_ALT_MIN_M


class NavOrigin(Message):
    """Geodetic origin of the local NED frame every position on the bus is expressed in."""

    SCHEMA: ClassVar[str] = "seaway.v1.NavOrigin"
    lat_rad: float = Field(ge=-math.pi / 2, le=math.pi / 2)
    lon_rad: float = Field(ge=-math.pi, le=math.pi)
    alt_m: float = Field(ge=GNSS_ALT_MIN_M, le=GNSS_ALT_MAX_M, description="the origin's altitude [m] (a "
                         "fix's, within the same bounds)")


MotionFaultKind = Literal["not_moving", "not_as_modelled"]
"""A persistent disagreement between what the commanded thrust should do and what the GNSS measures
(``seaway_estimator.mismatch``)."""
MOTION_FAULT_TEXT: dict[str, str] = {
    "not_moving": "the vessel does not move as commanded (grounded, fouled, or held)",
    "not_as_modelled": "the vessel does not move as the model predicts from the thrust "
                       "(a thruster stuck or lost)",
}
"""Each ``MotionFaultKind`` for a person."""
ThrusterSide = Literal["port", "starboard"]
"""One of the two thrusters (port: ``thrust_port_n``, T1 of paper eq. 1)."""
MAX_THRUST_SHORT_FRAC = 10.0
"""The most ``StateEstimate.thrust_short_frac`` says: a thruster driving the wrong way reads over 1."""


class StateEstimate(Message):
    """Estimated state [u, v, r, x, y, psi] (paper eq. 1-2) and disturbance tau_d (body frame).

    ``covariance`` is the row-major 9x9 covariance of [u, v, r, x, y, psi, tau_u, tau_v, tau_r]
    in the units of those fields.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.StateEstimate"
    u_mps: float = Field(description="surge speed through the water [m/s]")
    v_mps: float = Field(description="sway speed through the water [m/s]")
    r_radps: float = Field(description="yaw rate [rad/s]")
    x_m: float = Field(description="north of the origin [m]")
    y_m: float = Field(description="east of the origin [m]")
    psi_rad: float = Field(ge=-math.pi, le=math.pi, description="heading from north [rad]")
    tau_d_surge_n: float = 0.0
    tau_d_sway_n: float = 0.0
    tau_d_yaw_nm: float = 0.0
    covariance: list[float] | None = Field(default=None, min_length=81, max_length=81)
    degraded: bool = False
    motion_fault: MotionFaultKind | None = Field(default=None, description="the vessel does not do "
                                                 "what it is told (``MOTION_FAULT_TEXT``); None: "
                                                 "no such fault")
    motion_fault_detail: str | None = Field(default=None, max_length=MAX_REASON_CHARS,
                                            description="the evidence, for a person")
    thrust_short_side: ThrusterSide | None = Field(default=None, description="a thruster gives "
                                                   "less than commanded, as the yaw moment the "
                                                   "model does not explain says "
                                                   "(``seaway_estimator.asymmetry``); None: none")
    thrust_short_frac: float | None = Field(default=None, ge=0.0, le=MAX_THRUST_SHORT_FRAC,
                                            description="how much less, of its command (0.5: "
                                            "half); None with the side")
