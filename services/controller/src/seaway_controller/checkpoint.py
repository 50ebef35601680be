"""The controller's mission checkpoint: what a restarted controller needs to carry on.

A controller killed mid-mission (a crash, the OOM killer, a launcher restart) must not forget the
mission nor start it again from P_0. The service writes this small JSON file atomically (temporary
file, fsync, rename) whenever the mission's progress changes and once a second for the energy
count; a new process given the same file resumes the mission at the same leg, with the energy
budget's decision (a return home stays a return home, a hold a hold), and where the vessel holds
station at rest (paused, or after the last waypoint), so that it goes on holding there rather than
drifting or idling. It keeps the vessel's home too (the operator's, or where the vessel was armed),
with or without a mission: a restarted controller hears no arming of a vessel armed already, and a
mission sent after the restart must still return there, not to where it happened to be accepted.
A checkpoint that cannot be read is reported and ignored: the controller then starts idle, as it
would without one.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

from pydantic import Field
from seaway.contract.config import ConfigModel
from seaway.contract.messages import EnergyDecision, MessageError, MissionRequest
from seaway.runtime import atomic
from seaway.vessel.frames import MAX_RANGE_M

CheckpointError = atomic.StateFileError
"""The checkpoint file exists but cannot be used; the text says why."""


class MissionCheckpoint(ConfigModel):
    """Mission progress as saved: the accepted request, the active leg, the state, the energy;
    and the vessel's home."""

    request: dict[str, Any] | None = Field(default=None, description="the accepted "
                                           "MissionRequest, as on the wire; None: no mission yet")
    active_leg: int = Field(default=0, ge=0, description="index i of the active waypoint P_i (0: "
                            "on the way to P_0)")
    state: Literal["idle", "waiting", "active", "paused", "complete", "aborted"] = "idle"
    energy_used_j: float = Field(default=0.0, ge=0)
    saved_unix_ns: int = Field(ge=0)
    returning: bool = Field(default=False, description="the mission is the energy budget's return home")
    decision: EnergyDecision = Field(default="none", description="the energy budget's decision")
    decided_ns: int | None = Field(default=None, ge=0, description="the period it was decided [ns]")
    decision_reason: str = Field(default="", description="why, as the budget said it")
    hold_x_m: float | None = Field(default=None, allow_inf_nan=False, description="where the "
                                   "vessel holds station at rest (paused, or complete), local NED "
                                   "north [m]; None: it does not hold (flying, or drifting)")
    hold_y_m: float | None = Field(default=None, allow_inf_nan=False, description="the hold point, "
                                   "local NED east [m]")
    home_x_m: float | None = Field(default=None, ge=-MAX_RANGE_M, le=MAX_RANGE_M,
                                   allow_inf_nan=False, description="the vessel's home, local NED "
                                   "north [m]; None: none yet")
    home_y_m: float | None = Field(default=None, ge=-MAX_RANGE_M, le=MAX_RANGE_M,
                                   allow_inf_nan=False, description="the vessel's home, east [m]")

    @property
    def home(self) -> tuple[float, float] | None:
        """The vessel's home (north, east) [m] as saved, if it had one."""
        if self.home_x_m is None or self.home_y_m is None:
            return None
        return (self.home_x_m, self.home_y_m)

    @property
    def hold_point(self) -> tuple[float, float] | None:
        """The saved hold point (north, east) [m], if the vessel held station."""
        if self.hold_x_m is None or self.hold_y_m is None:
            return None
        return (self.hold_x_m, self.hold_y_m)

    def mission_request(self) -> MissionRequest:
        if self.request is None:
            raise CheckpointError("no mission was saved")
        try:
            return MissionRequest.decode(json.dumps(self.request))
        except MessageError as err:
            raise CheckpointError(f"saved mission request is invalid: {err}") from None


def encode(checkpoint: MissionCheckpoint) -> str:
    """The file's text (what ``load`` reads back)."""
    return checkpoint.model_dump_json()


def save(path: Path, checkpoint: MissionCheckpoint, durable: bool = True) -> None:
    """Write ``checkpoint`` so that a reader sees the old file or the new one, never a mix
    (``seaway.runtime.atomic``).

    ``durable``: on disk before it counts (fsync), so that a power loss keeps it too. A simulation
    in lockstep passes False: a crashed process loses nothing the OS already has, and the fsync,
    every simulated second, cost the controller about 40 % of its time per period there. Real time
    writes its durable checkpoints through ``atomic.LatestWriter`` instead (the control loop must
    not wait for an fsync), with the same ``encode``."""
    atomic.write_text(path, encode(checkpoint), durable)


def load(path: Path) -> MissionCheckpoint | None:
    """The checkpoint at ``path``; None if there is none; CheckpointError if it is unusable."""
    return atomic.read_model(path, MissionCheckpoint)
