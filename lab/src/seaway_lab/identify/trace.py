"""What a fit needs from a run, and the checks that refuse a run that cannot support one.

A ``Trace`` holds, as numpy arrays on one time axis (seconds from the first thrust command):

* the thrust commands (T1 port, T2 starboard) [N], at their log time: when the recorder, like
  vehicle_io, received them (a command's stamp is that of the state it was computed from);
* the GNSS velocity over ground, NED (north, east) [m/s], at each fix's stamp;
* the heading psi [rad] (clockwise from north, unwrapped) and the yaw rate r [rad/s], at each
  attitude sample's stamp.

These are the raw sensors (``sensors/gnss``, ``sensors/attitude``), not the estimator's
``nav/state``: the estimator predicts with a vessel model, and a fit must not see the model it
replaces. The same keys come from vehicle_io on a real vessel and from the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from seaway.contract import keys
from seaway.contract.messages import Attitude, GnssFix, ThrustCommand
from seaway.contract.units import NS_PER_S

MIN_DURATION_S = 60.0
"""Shortest run a fit accepts: a few surge steps and one turn each way take about a minute."""
MIN_SURGE_LEVELS = 3
"""Distinct surge levels (both thrusters ahead, held ``SURGE_HOLD_S`` or more) a fit needs: steady
speeds at three levels or more, and the steps between them."""
SURGE_HOLD_S = 1.5
"""A surge level counts when held this long: several surge time constants of a small boat."""
TURN_HOLD_S = 5.0
"""A turn is a thrust difference of a fifth of the largest command or more, held this long."""
COAST_HOLD_S = 3.0
"""Coasting is both thrusters at zero for this long after moving."""


class IdentifyError(ValueError):
    """A recording or request a fit cannot use; the text names what is missing and what is needed."""


@dataclass
class Trace:
    """Sensors and commands of one run on one time axis [s] (see the module docstring)."""

    cmd_t_s: np.ndarray
    cmd_n: np.ndarray
    """(n, 2): T1 port, T2 starboard [N]."""
    gnss_t_s: np.ndarray
    vel_ne_mps: np.ndarray
    """(n, 2): velocity over ground, north and east [m/s]."""
    att_t_s: np.ndarray
    psi_rad: np.ndarray
    """Heading, unwrapped (continuous through +-pi) [rad]."""
    r_radps: np.ndarray
    source: str = ""

    @property
    def duration_s(self) -> float:
        ends = [a[-1] for a in (self.cmd_t_s, self.gnss_t_s, self.att_t_s) if len(a)]
        starts = [a[0] for a in (self.cmd_t_s, self.gnss_t_s, self.att_t_s) if len(a)]
        return float(min(ends) - max(starts)) if len(ends) == 3 else 0.0

    def heading_at(self, t_s: np.ndarray) -> np.ndarray:
        """Heading at ``t_s`` [rad], linear between attitude samples."""
        return np.interp(t_s, self.att_t_s, self.psi_rad)

    def body_velocity(self, current_ne: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """(n, 2) body velocity through the water (u, v) at the GNSS instants: R(psi)^T (SOG - current)."""
        psi = self.heading_at(self.gnss_t_s)
        n = self.vel_ne_mps[:, 0] - current_ne[0]
        e = self.vel_ne_mps[:, 1] - current_ne[1]
        c, s = np.cos(psi), np.sin(psi)
        return np.column_stack([c * n + s * e, -s * n + c * e])

    def command_at(self, t_s: np.ndarray) -> np.ndarray:
        """(n, 2) the command in force at each ``t_s`` (held from its time to the next) [N]."""
        i = np.searchsorted(self.cmd_t_s, t_s, side="right") - 1
        out = self.cmd_n[np.clip(i, 0, None)].copy()
        out[i < 0] = 0.0
        return out


def from_messages(thrust: list[tuple[int, ThrustCommand]], gnss: list[GnssFix],
                  attitude: list[Attitude], source: str = "") -> Trace:
    """A trace from decoded messages; ``thrust`` as (log time ns, command) pairs.

    Raises ``IdentifyError`` naming each stream that is empty or unusable.
    """
    missing = []
    if not thrust:
        missing.append(f"no thrust commands ({keys.THRUST.suffix})")
    fixes = [f for f in gnss if f.vel_n_mps is not None and f.vel_e_mps is not None]
    if not gnss:
        missing.append(f"no GNSS fixes ({keys.GNSS.suffix})")
    elif not fixes:
        missing.append(f"GNSS fixes ({keys.GNSS.suffix}) carry no velocity over ground "
                       "(vel_n_mps, vel_e_mps): the fit needs it")
    if not attitude:
        missing.append(f"no attitude samples ({keys.ATTITUDE.suffix}: heading and yaw rate)")
    if missing:
        raise IdentifyError(f"{source or 'the recording'}: " + "; ".join(missing))
    thrust = sorted(thrust, key=lambda p: p[0])
    fixes.sort(key=lambda f: f.stamp_ns)
    att = sorted(attitude, key=lambda a: a.stamp_ns)
    t0 = thrust[0][0]

    def secs(ns: list[int]) -> np.ndarray:
        return (np.asarray(ns, dtype=np.int64) - t0) / NS_PER_S

    return Trace(
        cmd_t_s=secs([t for t, _ in thrust]),
        cmd_n=np.array([[c.thrust_port_n, c.thrust_starboard_n] for _, c in thrust], dtype=float),
        gnss_t_s=secs([f.stamp_ns for f in fixes]),
        vel_ne_mps=np.array([[f.vel_n_mps, f.vel_e_mps] for f in fixes], dtype=float),
        att_t_s=secs([a.stamp_ns for a in att]),
        psi_rad=np.unwrap(np.array([a.yaw_rad for a in att], dtype=float)),
        r_radps=np.array([a.yaw_rate_radps for a in att], dtype=float),
        source=source,
    )


def from_recording(path: str | Path, vessel: str | None = None) -> Trace:
    """The trace of a recording (an MCAP file or a run folder) of one vessel."""
    from seaway.recording.reader import decode_vessel, open_paths

    files = open_paths([path])
    wanted = (keys.THRUST.suffix, keys.GNSS.suffix, keys.ATTITUDE.suffix)
    dec = decode_vessel(files, vessel, suffixes=wanted)
    thrust = list(zip(dec.log_ns.get(keys.THRUST.suffix, []), dec.get(keys.THRUST.suffix),
                      strict=True))
    return from_messages(thrust, dec.get(keys.GNSS.suffix),  # type: ignore[arg-type]
                         dec.get(keys.ATTITUDE.suffix), source=str(path))  # type: ignore[arg-type]


def _held_runs(mask: np.ndarray, t_s: np.ndarray) -> list[float]:
    """Durations of the runs of consecutive True in ``mask`` (samples at ``t_s``) [s]."""
    out, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        if start is not None and (not m or i == len(mask) - 1):
            out.append(float(t_s[i] - t_s[start]))
            start = None
    return out


def problems(trace: Trace) -> list[str]:
    """What the run lacks for a fit (empty when it can support one), each naming what is needed."""
    out = []
    if trace.duration_s < MIN_DURATION_S:
        out.append(f"too short: {trace.duration_s:.1f} s of thrust commands, GNSS and attitude "
                   f"together, at least {MIN_DURATION_S:g} s needed")
    grid = np.arange(trace.cmd_t_s[0], trace.cmd_t_s[-1], 0.1)
    if len(grid) < 2:
        return [*out, "no thrust command sequence (a single command)"]
    cmd = trace.command_at(grid)
    peak = float(np.max(np.abs(cmd))) if cmd.size else 0.0
    if peak <= 0:
        return [*out, "the thrust commands are all zero: nothing moved the vessel"]
    surge = cmd.sum(axis=1)
    diff = cmd[:, 0] - cmd[:, 1]
    levels = set()
    for lev in np.unique(np.round(surge / (0.05 * peak))):
        held = _held_runs((np.round(surge / (0.05 * peak)) == lev) & (np.abs(diff) < 0.05 * peak)
                          & (lev > 0), grid)
        if held and max(held) >= SURGE_HOLD_S - 1e-9:
            levels.add(lev)
    if len(levels) < MIN_SURGE_LEVELS:
        out.append(f"no surge steps: {len(levels)} distinct forward thrust level(s) held "
                   f"{SURGE_HOLD_S:g} s or more with both thrusters equal, at least "
                   f"{MIN_SURGE_LEVELS} needed")
    for name, mask in (("to starboard (T1 port > T2 starboard)", diff > 0.2 * peak),
                       ("to port (T2 starboard > T1 port)", diff < -0.2 * peak)):
        held = _held_runs(mask, grid)
        if not held or max(held) < TURN_HOLD_S:
            out.append(f"no turn {name} held {TURN_HOLD_S:g} s or more (a thrust difference of "
                       f"at least a fifth of the largest command)")
    moved = np.cumsum(np.abs(cmd).sum(axis=1)) > 0
    coast = _held_runs((np.abs(cmd).sum(axis=1) == 0) & moved, grid)
    if not coast or max(coast) < COAST_HOLD_S:
        out.append(f"no coasting: both thrusters at zero for {COAST_HOLD_S:g} s or more after moving")
    return out


def check(trace: Trace) -> None:
    """Raise ``IdentifyError`` listing everything the run lacks for a fit."""
    bad = problems(trace)
    if bad:
        raise IdentifyError(f"{trace.source or 'the run'} cannot be used for a fit: " + "; ".join(bad)
                            + " (fly `seaway identify run`'s manoeuvre: surge steps, turns both "
                            "ways, coasting)")
