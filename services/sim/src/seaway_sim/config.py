"""The simulator's configuration: defaults, a file (TOML or JSON), flags.

Made by ``seaway.runtime.config``: the defaults below, then ``--config FILE`` (unknown fields are
errors), then a flag per field (``--state-file``, ``--mavlink``, ``--step``, ``--param``, ...). The
scenario, the vessel files, the control period and the clock are the run's (``seaway.runtime.run``),
not settings of the simulator. The MAVLink fields matter in real time only: lockstep speaks none.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

from pydantic import Field, field_validator
from seaway.contract.config import ConfigError, ConfigModel
from seaway.contract.messages import MAX_STAMP_NS
from seaway.runtime.config import Flag
from seaway.runtime.lockstep_clock import STALL_REPEAT_S

from seaway_sim.mavlink_link import DEFAULT_ENDPOINT

DEFAULT_STEP_S = 0.01  # real-time tick: the plant's internal RK4 step, 100 Hz
START_SPACING_M = 5.0
"""How far apart [m] the vessels of a fleet start (``--start-slot``): east of the scenario's start,
one slot each, clear of each other's circle of acceptance and of their glyphs on the map."""


def parse_params(items: Sequence[str]) -> tuple[tuple[str, float], ...]:
    """``NAME=VALUE`` items -> overrides; the autopilot's ParamStore checks names, types, ranges."""
    out = []
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out.append((name.strip(), float(value)))
        except ValueError:
            raise ConfigError(f"--param wants NAME=VALUE with a number, got {item!r}") from None
    return tuple(out)


class SimConfig(ConfigModel):
    """What the simulator runs with, besides the run's facts."""

    state_file: Annotated[Path | None, Flag(metavar="PATH")] = Field(
        default=None,
        description="keep each scenario loaded over the bus in PATH, and start with the one kept "
                    "there, if any, instead of the run's: a sim the launcher restarts flies on in "
                    "the water it was given (seaway_sim.kept)")
    stall_repeat_s: Annotated[float, Flag()] = Field(
        default=STALL_REPEAT_S, gt=0,
        description="lockstep: wall seconds without progress after which the sim repeats its "
                    "period, a safety net [s]")
    until_s: Annotated[float | None, Flag(metavar="S")] = Field(
        default=None, gt=0, le=MAX_STAMP_NS / 1e9,
        description="lockstep: fly no period past S s of simulated time; the clock holds at the "
                    "last period at or before S (seaway launch --max-mission-s passes it)")
    mavlink: Annotated[str, Flag()] = Field(
        default=DEFAULT_ENDPOINT, min_length=1,
        description="real time: where the simulated autopilot listens")
    step_s: Annotated[float, Flag("--step")] = Field(
        default=DEFAULT_STEP_S, gt=0, description="real time: plant and MAVLink tick [s]")
    sysid: Annotated[int, Flag()] = Field(
        default=1, ge=1, le=255, description="real time: MAVLink system id")
    signing_key_file: Annotated[Path | None, Flag(metavar="PATH")] = Field(
        default=None,
        description="real time: MAVLink 2 signing key file (64 hex characters): sign everything "
                    "sent and reject unsigned or wrongly signed messages, as PX4 with a key does. "
                    "Create one with: python -m seaway.mavlink.signing PATH")
    start_slot: Annotated[int, Flag(metavar="N")] = Field(
        default=0, ge=0, le=64,
        description=f"start N x {START_SPACING_M:g} m east of the scenario's start (the fleet "
                    "profile gives each vessel its own slot, so none starts on another); the "
                    "scenario's operating area must hold it (default 0: the scenario's start)")
    px4_params: Annotated[list[str], Flag("--param", metavar="NAME=VALUE")] = Field(
        default_factory=list,
        description="real time: set a simulated PX4 parameter at boot, e.g. NAV_RCL_ACT=1")

    @field_validator("px4_params")
    @classmethod
    def _check_params(cls, items: list[str]) -> list[str]:
        try:
            parse_params(items)
        except ConfigError as err:
            raise ValueError(str(err).removeprefix("--param ")) from None
        return items
