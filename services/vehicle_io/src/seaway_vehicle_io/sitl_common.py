"""What ``seaway sitl`` shares between autopilots: where a firmware is, and where the run starts it.

Each autopilot's SITL module (``sitl.py`` for ArduPilot, ``sitl_px4.py``) finds its build with
``default_folder`` and places the vehicle with ``start_pose``; their errors are ``SitlError``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from seaway.contract.config import ConfigError, Origin
from seaway.runtime.run import RunDescription
from seaway.simkit.scenario import load_scenario


class SitlError(ConfigError):
    """The firmware or its files cannot be found, or the run cannot place it."""


@dataclass(frozen=True)
class StartPose:
    """Where a SITL starts: the run's NED origin, at rest, heading ``yaw_deg`` [deg, clockwise from
    north, in [0, 360)]."""

    origin: Origin
    yaw_deg: float


def default_folder(env: Mapping[str, str], root: Path | None, env_name: str,
                   shared_name: str) -> Path | None:
    """``$<env_name>``, else ``<checkout>/../shared/sitl/<shared_name>`` if it exists."""
    if env.get(env_name):
        return Path(env[env_name])
    shared = root.parent / "shared" / "sitl" / shared_name if root is not None else None
    return shared if shared is not None and shared.is_dir() else None


def start_pose(run: RunDescription) -> StartPose:
    """The run's NED origin and the scenario's start heading; SitlError if the scenario does not
    start at rest at the origin (a SITL starts at its home) or the run has no origin."""
    if run.origin is None:
        raise SitlError("the run has no NED origin (origin_from_scenario = false?): SITL needs one "
                        "for its home; use a scenario with an [origin]")
    yaw_deg = 0.0
    if run.scenario:
        start = load_scenario(run.scenario).start
        if math.hypot(start.x_m, start.y_m) > 0.01 or start.u_mps != 0.0:
            raise SitlError(f"scenario {run.scenario}: SITL starts at rest at the origin, but the "
                            f"scenario starts at x {start.x_m:g} m, y {start.y_m:g} m, "
                            f"u {start.u_mps:g} m/s")
        yaw_deg = math.degrees(start.psi_rad) % 360.0
    return StartPose(run.origin, yaw_deg)
