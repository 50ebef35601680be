"""The controller service's configuration: defaults, a file (TOML or JSON), flags.

Made by ``seaway.runtime.config``: the defaults below, then ``--config FILE`` (unknown fields are
errors), then a flag per field (``--solver``, ``--max-state-age-s``, ...). The vessel model, the
control period (also the OCP's dt), the origin and the clock are the run's (``seaway.runtime.run``),
not settings of the controller. ``seaway_controller.main`` turns this and the run into the core's
``ControllerConfig``, defined here too: the core's own settings.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field
from seaway.contract.config import ConfigModel
from seaway.runtime.config import Flag
from seaway.vessel.guidance import LosGains

from seaway_controller import costs
from seaway_controller.hold import HoldGains
from seaway_controller.mission import MissionLimits
from seaway_controller.ocp import ControllerKind, OcpSpec
from seaway_controller.solvers import SOLVER_KINDS

SolverChoice = Literal[SOLVER_KINDS]  # type: ignore[valid-type]  # built from the solver registry

MAX_STATE_AGE_S = 2.0
"""The oldest state the controller may steer on [s]: at 2 m/s a 2 s old state is 4 m off, past a
waypoint's reach."""


class ControllerServiceConfig(ConfigModel):
    """What the controller service runs with, besides the run's facts."""

    solver: Annotated[SolverChoice, Flag()] = Field(
        default="generated",
        description="generated: compiled SQP (fast); ipopt: plain IPOPT (reference)")
    predict_disturbance: Annotated[bool, Flag()] = Field(
        default=False,
        description="predict with the estimator's tau_d instead of tau_d = 0 (the paper's)")
    max_state_age_s: Annotated[float, Flag()] = Field(
        default=0.5, gt=0, le=MAX_STATE_AGE_S,
        description="real time: older states give zero thrust [s]; at most 2 s: an older state "
                    "puts the vessel metres from where it is, and vehicle_io refuses thrust "
                    "stamped over thrust_max_age_s (1 s by default) old anyway")
    plan_reuse_steps: Annotated[int, Flag()] = Field(
        default=3, ge=0,
        description="fallback 1: periods of failed solves flown on the last good plan")
    los_steps: Annotated[int, Flag()] = Field(
        default=600, ge=0,
        description="fallback 2: periods of line-of-sight guidance after that, before zero thrust")
    state_file: Annotated[Path | None, Flag()] = Field(
        default=None, description="mission checkpoint: resume from it at start, keep it up to date")
    max_range_m: Annotated[float, Flag()] = Field(
        default=MissionLimits.max_range_m, gt=0,
        description="operating area: waypoints within this distance of the origin [m]")
    controller_module: Annotated[list[str], Flag(metavar="FILE|MODULE")] = Field(
        default_factory=list,
        description="a controller of one's own: a .py file or an importable module that registers "
                    "it (seaway_controller.controllers.load_module)")
    area: Annotated[Path | None, Flag()] = Field(
        default=None,
        description="the operating area to enforce (.toml [area], .plan geoFence, .geojson); "
                    "default: the run's scenario's [area], else none")


@dataclass(frozen=True)
class ControllerConfig:
    """The controller's settings (paper values by default: H = 10, dt = 0.1 s, n = 2)."""

    horizon: int = 10
    dt_s: float = 0.1
    profile_n: float = 2.0
    solver: str = "generated"
    """'generated' (fast SQP, compiled C) or 'ipopt' (plain IPOPT, the reference)."""
    plan_reuse_steps: int = 3
    los_steps: int = 600
    solve_budget_s: float | None = 0.1
    """A solve slower than this is late and not applied (None: never late, for replayable runs)."""
    predict_disturbance: bool = False
    """Make every mission predict with the estimate's tau_d (beyond the paper, which predicts with
    tau_d = 0), whatever its request says; False leaves it to each mission's ``predict_disturbance``."""
    los: LosGains = field(default_factory=LosGains)
    hold: HoldGains = field(default_factory=HoldGains)
    limits: MissionLimits = field(default_factory=MissionLimits)
    nmpc: costs.NmpcWeights = field(default_factory=costs.NmpcWeights)

    def spec(self, kind: ControllerKind) -> OcpSpec:
        return OcpSpec(kind, self.horizon, self.dt_s, self.profile_n, nmpc=self.nmpc)
