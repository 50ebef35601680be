"""PX4's MAVLink conventions as the simulated PX4 autopilot follows them: its custom modes (main
and sub mode in HEARTBEAT.custom_mode), C's rounding of command parameters, and ``time_boot_ms``.
Shared by the state machine (``px4_autopilot``) and its telemetry (``px4_telemetry``).
"""

from __future__ import annotations

import math

from seaway.contract.units import NS_PER_MS

# PX4 custom modes (px4_custom_mode.h): main mode in bits 16-23, sub mode in bits 24-31.
MAIN_MANUAL = 1
MAIN_AUTO = 4
SUB_AUTO_LOITER = 3
SUB_AUTO_RTL = 5
SUB_AUTO_LAND = 6
MANUAL = (MAIN_MANUAL, 0)
HOLD = (MAIN_AUTO, SUB_AUTO_LOITER)
RTL = (MAIN_AUTO, SUB_AUTO_RTL)
LAND = (MAIN_AUTO, SUB_AUTO_LAND)
MODE_NAMES = {MANUAL: "MANUAL", HOLD: "HOLD", RTL: "RTL", LAND: "LAND"}
# PX4 boots in Hold (AUTO.LOITER; measured on the 1.18 SITL, tests/system/sim/test_px4_imitation.py),
# so an operator (the launcher's profiles: mode_on_start) asks for MANUAL before arming.
BOOT_MODE = HOLD


def custom_mode(mode: tuple[int, int]) -> int:
    """HEARTBEAT.custom_mode of a PX4 (main, sub) mode."""
    return (mode[0] << 16) | (mode[1] << 24)


def lround(value: float) -> int:
    """C's lroundf, as PX4 rounds command params: halves away from zero (Python rounds to even)."""
    return int(math.copysign(math.floor(abs(value) + 0.5), value))


def boot_ms(since_boot_ns: int) -> int:
    """MAVLink time_boot_ms (uint32, wraps after 49.7 days) from time since boot [ns]."""
    return (since_boot_ns // NS_PER_MS) & 0xFFFFFFFF
