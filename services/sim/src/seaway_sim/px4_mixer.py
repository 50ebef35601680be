"""PX4's MANUAL_CONTROL -> thrusters mapping (differential rover/boat, Manual mode): the ONE place.

Source: docs/autopilots.md, A.1.1 (``MavlinkReceiver::handle_message_manual_control``) and A.1.3
(``rover_differential``: ``DifferentialManualMode``, ``computeInverseKinematics``), PX4 main 2025.

Forward (what the sim does with a MANUAL_CONTROL message)::

    roll     = y / 1000                      applied only if -1000 <= y <= 1000, else 0
    throttle = z / 500 - 1                   applied only if     0 <= z <= 1000, else 0 (stop)
    (x: pitch and r: yaw are decoded by PX4 but ignored by the differential Manual mode)
    diff = roll * RD_YAW_STK_GAIN             (DifferentialManualMode; PX4's default 1, SIH 10046: 0.6)
    if |throttle| + |diff| > 1:              PX4 "prioritizes yaw rate": the throttle is cut
        throttle = sign(throttle) * (1 - |diff|)      (|diff| <= 1, so this is >= 0 in magnitude)
    R = throttle - diff        -> actuator_motors.control[0] (Motor1, right / starboard)
    L = throttle + diff        -> actuator_motors.control[1] (Motor2, left / port)
    T1 (port)      = L * thrust_max_n    [N]
    T2 (starboard) = R * thrust_max_n    [N]

so ``y > 0`` (roll right) gives L > R, i.e. T1 > T2, a positive yaw moment (T1 - T2) l: the boat
turns clockwise (to starboard), as NED and the paper's tau = [T1 + T2, 0, (T1 - T2) l] require.

Inverse (what vehicle_io sends for wanted normalised thrusts L, R in [-1, 1])::

    y = round(500 * (L - R) / RD_YAW_STK_GAIN)   (= 1000 * d / gain, d = (L - R) / 2)
    z = round(500 + 250 * (L + R))           (= 500 * (thr + 1), thr = (L + R) / 2); 500 = stop

For |L|, |R| <= 1 the throttle cut never triggers (|thr| + |d| = max(|L|, |R|)), so forward(inverse)
is the identity up to the quantisation of y (0.001) and z (0.002). PX4's optional throttle slew
(RO_ACCEL_LIM, RO_DECEL_LIM) is not modelled: the sim behaves as PX4 with those limits disabled.
"""

from __future__ import annotations

import math

AXIS_MAX = 1000  # MANUAL_CONTROL axes are int16 "normalised to [-1000, 1000]"
Z_MIN = 0  # PX4 decodes z (throttle) only in [0, 1000], "for backwards compatibility"
Z_STOP = 500  # z that PX4 maps to throttle 0


def roll_from_y(y: int) -> float:
    """PX4's roll stick from MANUAL_CONTROL.y; out of [-1000, 1000] is left at 0."""
    return y / AXIS_MAX if -AXIS_MAX <= y <= AXIS_MAX else 0.0


def throttle_from_z(z: int) -> float:
    """PX4's throttle from MANUAL_CONTROL.z (z / 500 - 1); out of [0, 1000] is left at 0 (stop)."""
    return z / Z_STOP - 1.0 if Z_MIN <= z <= AXIS_MAX else 0.0


def mix(throttle: float, diff: float) -> tuple[float, float]:
    """``computeInverseKinematics``: (throttle, speed diff) -> normalised (L, R) in [-1, 1]."""
    excess = abs(throttle) + abs(diff) - 1.0
    if excess > 0.0:
        throttle = math.copysign(max(0.0, abs(throttle) - excess), throttle)
    return throttle + diff, throttle - diff


def manual_control_to_normalised(y: int, z: int,
                                 yaw_stick_gain: float = 1.0) -> tuple[float, float]:
    """MANUAL_CONTROL (y, z) -> normalised (L, R), exactly as PX4's differential Manual mode with
    RD_YAW_STK_GAIN = ``yaw_stick_gain``."""
    return mix(throttle_from_z(z), roll_from_y(y) * yaw_stick_gain)


def manual_control_to_thrust_n(y: int, z: int, thrust_max_n: float,
                               yaw_stick_gain: float = 1.0) -> tuple[float, float]:
    """MANUAL_CONTROL (y, z) -> (T1 port, T2 starboard) [N]: normalised thrust * thrust_max_n."""
    left, right = manual_control_to_normalised(y, z, yaw_stick_gain)
    return left * thrust_max_n, right * thrust_max_n


def normalised_to_manual_control(left: float, right: float) -> tuple[int, int]:
    """The inverse vehicle_io uses: normalised (L, R) in [-1, 1] -> MANUAL_CONTROL (y, z).

    Inputs are clamped to [-1, 1] first, so the result is always inside PX4's accepted ranges.
    """
    left = min(max(left, -1.0), 1.0)
    right = min(max(right, -1.0), 1.0)
    return round(500.0 * (left - right)), round(500.0 + 250.0 * (left + right))
