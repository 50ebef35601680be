"""Frames and angles: WGS84 geodetic <-> local NED at an origin, and angle wrapping.

Local NED (design.md): x north, y east, z down, metres, tangent plane at the origin. The conversion is
exact (through ECEF), not a flat-earth approximation, so it holds over any lake or bay.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
_TWO_PI = 2.0 * math.pi
MAX_RANGE_M = 100_000.0
"""How far from the NED origin any coordinate may lie, each axis [m]: a local tangent frame is
already poor at 100 km, and a position past it is corruption (an operating area, a waypoint, a
home, a state estimate and a fix are each bounded by it)."""


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle to (-pi, pi] [rad]."""
    a = math.fmod(angle_rad + math.pi, _TWO_PI)
    if a <= 0.0:
        a += _TWO_PI
    return a - math.pi


def wrap_2pi(angle_rad: float) -> float:
    """Wrap an angle to [0, 2 pi) [rad]."""
    a = math.fmod(angle_rad, _TWO_PI)
    return a + _TWO_PI if a < 0.0 else a


def geodetic_to_ecef(lat_rad: float, lon_rad: float, alt_m: float) -> tuple[float, float, float]:
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sl * sl)
    return (
        (n + alt_m) * cl * math.cos(lon_rad),
        (n + alt_m) * cl * math.sin(lon_rad),
        (n * (1.0 - WGS84_E2) + alt_m) * sl,
    )


_NEAR_POLE_RAD = math.radians(89.0)


def ecef_to_geodetic(x_m: float, y_m: float, z_m: float) -> tuple[float, float, float]:
    """ECEF -> (lat_rad, lon_rad, alt_m); Bowring's start and fixed-point refinement (sub-mm)."""
    lon = math.atan2(y_m, x_m)
    p = math.hypot(x_m, y_m)
    lat = math.atan2(z_m, p * (1.0 - WGS84_E2))
    alt = 0.0
    for _ in range(6):
        sl = math.sin(lat)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sl * sl)
        alt = p / math.cos(lat) - n if abs(lat) < _NEAR_POLE_RAD else z_m / sl - n * (1 - WGS84_E2)
        refined = math.atan2(z_m, p * (1.0 - WGS84_E2 * n / (n + alt)))
        if refined == lat:  # a fixed point: every further round gives these very values again
            break
        lat = refined
    return lat, lon, alt


@dataclass(frozen=True)
class GeoOrigin:
    """The geodetic origin of a local NED frame."""

    lat_rad: float
    lon_rad: float
    alt_m: float = 0.0

    @classmethod
    def from_degrees(cls, lat_deg: float, lon_deg: float, alt_m: float = 0.0) -> GeoOrigin:
        """The origin at WGS84 latitude/longitude [deg] and altitude [m] (files and configs say degrees)."""
        return cls(math.radians(lat_deg), math.radians(lon_deg), alt_m)

    def _ecef0(self) -> tuple[float, float, float]:
        return geodetic_to_ecef(self.lat_rad, self.lon_rad, self.alt_m)

    @functools.cached_property
    def _to_ecef(self) -> tuple[float, ...]:
        """The origin in ECEF and the NED -> ECEF rotation's terms, as ``to_geodetic`` multiplies
        them (the same products, so the same floats as computed afresh): a recorder converts
        every position it derives a map fix from."""
        x0, y0, z0 = self._ecef0()
        sl, cl = math.sin(self.lat_rad), math.cos(self.lat_rad)
        so, co = math.sin(self.lon_rad), math.cos(self.lon_rad)
        return x0, y0, z0, -sl * co, so, cl * co, -sl * so, co, cl * so, cl, sl

    @functools.cached_property
    def _to_ned(self) -> tuple[float, ...]:
        """The origin's ECEF position and the rotation's factors, computed once per origin (each
        product as ``to_ned`` associates it, so the result is the same to the bit)."""
        x0, y0, z0 = self._ecef0()
        sl, cl = math.sin(self.lat_rad), math.cos(self.lat_rad)
        so, co = math.sin(self.lon_rad), math.cos(self.lon_rad)
        return x0, y0, z0, -sl * co, sl * so, cl, -so, co, -cl * co, cl * so, sl

    def to_ned(self, lat_rad: float, lon_rad: float, alt_m: float = 0.0) -> tuple[float, float, float]:
        """Geodetic -> (north_m, east_m, down_m) relative to this origin."""
        x0, y0, z0, n_x, n_y, n_z, e_x, e_y, d_x, d_y, d_z = self._to_ned
        x, y, z = geodetic_to_ecef(lat_rad, lon_rad, alt_m)
        dx, dy, dz = x - x0, y - y0, z - z0
        north = n_x * dx - n_y * dy + n_z * dz
        east = e_x * dx + e_y * dy
        down = d_x * dx - d_y * dy - d_z * dz
        return north, east, down

    def to_geodetic(self, north_m: float, east_m: float, down_m: float = 0.0) -> tuple[float, float, float]:
        """(north_m, east_m, down_m) relative to this origin -> (lat_rad, lon_rad, alt_m)."""
        x0, y0, z0, n_x, e_x, d_x, n_y, e_y, d_y, cl, sl = self._to_ecef
        dx = n_x * north_m - e_x * east_m - d_x * down_m
        dy = n_y * north_m + e_y * east_m - d_y * down_m
        dz = cl * north_m - sl * down_m
        return ecef_to_geodetic(x0 + dx, y0 + dy, z0 + dz)
