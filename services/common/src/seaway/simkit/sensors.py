"""Sensor synthesis for simulated runs: GNSS, heading and yaw rate from the true state, seeded.

Pure (no clock, no bus, no global randomness), so the simulator's core (``seaway_sim.core.SimCore``,
stepped by the service and by the in-process closed loop) produces the same samples from the same
scenario and seed, bit for bit. Every random draw comes from its own stream,
``numpy.random.Generator(PCG64([seed, STREAM, k]))``, one per quantity, so that changing one
noise level never shifts another's draws.

What is modelled (``seaway.simkit.scenario.SensorNoise`` gives the numbers, all 1-sigma, white):

* GNSS at ``gnss_rate_hz``: position = truth + N(0, gnss_std_m) north and east [m], converted to
  WGS84 through the scenario origin (``seaway.vessel.frames.GeoOrigin``, exact through ECEF); velocity over
  ground (SOG, NED) = R(psi) [u, v] + current (paper eq. 2) + N(0, sog_std_mps) per axis [m/s].
  Dropouts: outages start as a Poisson process of rate ``gnss_dropout_rate_per_s`` and last
  ``gnss_dropout_duration_s``; a fix due inside an outage is not produced (``None``).
* Attitude at ``attitude_rate_hz``: heading = psi + N(0, heading_std_rad), wrapped to (-pi, pi];
  yaw rate = r + N(0, yaw_rate_std_radps). A 3-DOF surface vessel has no roll or pitch: both are 0.

The scenario's scheduled sensor faults (``seaway.simkit.faults``: GNSS dropouts, position jumps, a
heading bias) are applied on top, at the scenario's time (``t_ns - since_ns``).

Sample instants are ``i * period`` from the simulation epoch (t = 0), in integer nanoseconds, so a
sensor's schedule never drifts and is the same whatever step the simulator takes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from seaway.contract.config import Origin
from seaway.contract.messages import Attitude, GnssFix
from seaway.contract.units import NS_PER_S
from seaway.simkit.faults import SensorFaults
from seaway.simkit.scenario import SensorNoise
from seaway.vessel.frames import GeoOrigin, wrap_pi

GPS_FIX_TYPE_3D = 3  # MAVLink GPS_FIX_TYPE_3D_FIX
SIMULATED_SATELLITES = 12

# Stream identifiers: fixed forever, so that recorded runs stay reproducible across versions.
_STREAM = 0x5E45
_GNSS_NORTH, _GNSS_EAST, _SOG_N, _SOG_E, _HEADING, _YAW_RATE, _DROPOUT = range(7)


def period_ns(rate_hz: float) -> int:
    """Sample period of a sensor running at ``rate_hz`` [ns], rounded to whole nanoseconds."""
    return round(NS_PER_S / rate_hz)


def instants_in(period: int, after_ns: int, upto_ns: int) -> list[int]:
    """Sample instants ``i * period`` with ``after_ns < t <= upto_ns`` [ns]."""
    first = after_ns // period + 1
    last = upto_ns // period
    return [i * period for i in range(first, last + 1)]


def origin_of(origin: Origin) -> GeoOrigin:
    """The scenario's geodetic origin as a ``GeoOrigin`` (degrees -> radians)."""
    return GeoOrigin.from_degrees(origin.lat_deg, origin.lon_deg, origin.alt_m)


class _Normal:
    """One seeded stream of N(0, std) draws; std 0 draws nothing (and so costs nothing)."""

    def __init__(self, seed: int, stream: int, std: float) -> None:
        self.std = std
        self._rng = np.random.Generator(np.random.PCG64([seed, _STREAM, stream]))

    def draw(self) -> float:
        return self.std * float(self._rng.standard_normal()) if self.std > 0 else 0.0


class GnssDropouts:
    """Poisson outages: starts at rate ``rate_per_s``, each lasting ``duration_s``.

    ``active(t_ns)`` must be asked with non-decreasing times (the simulator's order).
    """

    def __init__(self, seed: int, rate_per_s: float, duration_s: float) -> None:
        self._rng = np.random.Generator(np.random.PCG64([seed, _STREAM, _DROPOUT]))
        self.rate_per_s = rate_per_s
        self.duration_ns = round(duration_s * NS_PER_S)
        self._start_ns = self._next_start(0) if rate_per_s > 0 and self.duration_ns > 0 else None

    def _next_start(self, after_ns: int) -> int:
        return after_ns + round(float(self._rng.exponential(1.0 / self.rate_per_s)) * NS_PER_S)

    def active(self, t_ns: int) -> bool:
        while self._start_ns is not None and t_ns >= self._start_ns + self.duration_ns:
            self._start_ns = self._next_start(self._start_ns + self.duration_ns)
        return self._start_ns is not None and t_ns >= self._start_ns


class SensorSuite:
    """The simulated vessel's sensors for one scenario (noise levels, origin, seed)."""

    def __init__(self, noise: SensorNoise, origin: Origin, seed: int, faults: Sequence[object] = (),
                 since_ns: int = 0) -> None:
        """``faults``: the scenario's scheduled faults, timed from ``since_ns`` (the sim time at
        which the scenario started) [ns]."""
        self.noise = noise
        self.origin = origin_of(origin)
        self.gnss_period_ns = period_ns(noise.gnss_rate_hz)
        self.attitude_period_ns = period_ns(noise.attitude_rate_hz)
        self._north = _Normal(seed, _GNSS_NORTH, noise.gnss_std_m)
        self._east = _Normal(seed, _GNSS_EAST, noise.gnss_std_m)
        self._sog_n = _Normal(seed, _SOG_N, noise.sog_std_mps)
        self._sog_e = _Normal(seed, _SOG_E, noise.sog_std_mps)
        self._heading = _Normal(seed, _HEADING, noise.heading_std_rad)
        self._yaw_rate = _Normal(seed, _YAW_RATE, noise.yaw_rate_std_radps)
        self.dropouts = GnssDropouts(seed, noise.gnss_dropout_rate_per_s,
                                     noise.gnss_dropout_duration_s)
        self.faults = SensorFaults(faults, self.gnss_period_ns)
        self.since_ns = since_ns

    def gnss_lost(self, t_ns: int) -> bool:
        """Whether no fix is produced at sim time ``t_ns``: a random or a scheduled dropout."""
        return self.dropouts.active(t_ns) or self.faults.gnss_lost(t_ns - self.since_ns)

    def gnss(self, t_ns: int, x: Sequence[float], current_ne: Sequence[float],
             epoch_ns: int = 0) -> GnssFix | None:
        """A fix of state ``x`` = [u, v, r, x, y, psi] at sim time ``t_ns``, or None in a dropout.

        ``t_ns`` is time since the sim epoch (it drives the dropout schedule); the fix is stamped
        ``epoch_ns + t_ns``.
        """
        if self.gnss_lost(t_ns):
            return None
        u, v, _, north, east, psi = x
        c, s = math.cos(psi), math.sin(psi)
        jump_north, jump_east = self.faults.position_offset_m(t_ns - self.since_ns)
        noisy_north = north + self._north.draw() + jump_north
        noisy_east = east + self._east.draw() + jump_east
        lat, lon, _ = self.origin.to_geodetic(noisy_north, noisy_east, 0.0)
        return GnssFix(
            stamp_ns=epoch_ns + t_ns,
            lat_rad=lat,
            lon_rad=lon,
            # The vessel floats: report the origin's altitude, never the ECEF round-trip residue.
            alt_m=self.origin.alt_m,
            fix_type=GPS_FIX_TYPE_3D,
            vel_n_mps=u * c - v * s + current_ne[0] + self._sog_n.draw(),
            vel_e_mps=u * s + v * c + current_ne[1] + self._sog_e.draw(),
            horizontal_std_m=self.noise.gnss_std_m,
            satellites=SIMULATED_SATELLITES,
        )

    def attitude(self, t_ns: int, x: Sequence[float], epoch_ns: int = 0) -> Attitude:
        """Heading and yaw rate of state ``x`` at sim time ``t_ns`` (stamped ``epoch_ns + t_ns``);
        roll and pitch are 0 (3-DOF)."""
        return Attitude(
            stamp_ns=epoch_ns + t_ns,
            roll_rad=0.0,
            pitch_rad=0.0,
            yaw_rad=wrap_pi(x[5] + self._heading.draw()
                            + self.faults.heading_bias_rad(t_ns - self.since_ns)),
            roll_rate_radps=0.0,
            pitch_rate_radps=0.0,
            yaw_rate_radps=x[2] + self._yaw_rate.draw(),
        )
