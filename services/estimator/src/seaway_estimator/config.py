"""The estimator's configuration: defaults, a file (TOML or JSON; unknown fields are errors), flags.

Made by ``seaway.runtime.config`` (``--config FILE`` or the name of a shipped one, then the flags
of the fields marked ``Flag``). ``vessel``, ``apply_dead_zone`` and ``origin`` are the run's
(``seaway_estimator.main.with_run``), never the file's.

Every standard deviation is 1-sigma in the unit its name carries. Process noise is given as the
standard deviation a quantity accumulates over one second of white noise (``..._per_sqrt_s``), so
``q = std**2`` is the continuous spectral density and ``Q = q * dt`` its discrete form.

Gates are chi-square thresholds on the normalised innovation squared ``nu' S^-1 nu``; the defaults
are the 0.9999 quantiles (2 degrees of freedom for position and velocity over ground, 1 for heading
and yaw rate), so a healthy filter rejects about one good sample in 10,000.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field
from seaway.contract.config import ConfigModel, Origin, load_config, named_file
from seaway.contract.messages import MAX_GNSS_STD_M
from seaway.runtime.config import Flag
from seaway.runtime.run import DEFAULT_VESSEL_FILE

from seaway_estimator.mismatch import MismatchConfig

CHI2_2DOF_9999 = 18.42
CHI2_1DOF_9999 = 15.14


class EstimatorConfig(ConfigModel):
    # -- model and inputs ----------------------------------------------------------------------
    vessel: str = Field(default=DEFAULT_VESSEL_FILE, description="vessel file name (deploy/vessels) or "
                        "path; the service takes it from the run")
    apply_dead_zone: bool = Field(default=False, description="apply the vessel's thrust dead zone "
                                  "to commanded thrust (the real boat's 10 N)")
    thrust_timeout_s: float = Field(default=1.0, gt=0, description="a thrust command older than "
                                    "this is assumed replaced by zero thrust (vehicle_io's watchdog)")
    disturbance_frame: Literal["world", "body"] = Field(
        default="world", description="frame of the random walk of the disturbance force: 'world' "
        "(wind, current, conditions #3-#5) or 'body' (condition #2); yaw moment is always body. "
        "Published values are always body frame")
    max_step_s: float = Field(default=0.05, gt=0, le=1.0, description="prediction substep [s]")
    # -- publishing ----------------------------------------------------------------------------
    publish_rate_hz: float = Field(default=20.0, gt=0, le=200, description="NavState rate in real "
                                   "time [Hz] (lockstep answers once per control period)")
    origin_rate_hz: float = Field(default=1.0, gt=0, le=50, description="NavOrigin repeat rate")
    origin: Origin | None = Field(default=None, description="fixed NED origin; None: the first good GNSS fix")
    # -- measurement noise (used unless a message reports its own) ------------------------------
    gnss_std_m: float = Field(default=0.3, gt=0, le=MAX_GNSS_STD_M, description="GNSS horizontal "
                              "position std [m]; at most 100 m (a fix worse than that is no fix)")
    use_reported_gnss_std: bool = Field(default=True, description="use GnssFix.horizontal_std_m "
                                        "when present (floored at gnss_std_min_m; a fix reporting "
                                        "more than 100 m is refused)")
    gnss_std_min_m: float = Field(default=0.02, gt=0, le=10.0, description="floor of a reported "
                                  "GNSS horizontal std [m]; at most 10 m (a floor above that "
                                  "discards what every real receiver reports)")
    min_fix_type: int = Field(default=3, ge=2, le=8, description="MAVLink GPS_FIX_TYPE accepted")
    sog_std_mps: float = Field(default=0.05, gt=0, le=5.0, description="GNSS velocity over "
                               "ground std per axis [m/s]; at most 5 m/s (the vessels' own speed: "
                               "beyond it the velocity says nothing)")
    heading_std_rad: float = Field(default=0.01745, gt=0, le=math.pi, description="heading std "
                                   "[rad]; at most pi (half a turn: any heading)")
    yaw_rate_std_radps: float = Field(default=0.005, gt=0, le=1.0, description="yaw rate std "
                                      "[rad/s]; at most 1 rad/s (a gyro worse than that is none)")
    # -- process noise ------------------------------------------------------------------------
    # Upper bounds: each well past any vessel in deploy/vessels (thrust up to 200 N a thruster,
    # speeds of a few m/s), well inside what the filter's float arithmetic carries (a std of
    # 1e200 squared overflows building the core; 1e200-1e300 leave the filter without an estimate).
    accel_surge_std_per_sqrt_s: float = Field(default=0.02, gt=0, le=10.0,
                                              description="[m/s^2 sqrt(s)]; at most 10")
    accel_sway_std_per_sqrt_s: float = Field(default=0.02, gt=0, le=10.0,
                                             description="[m/s^2 sqrt(s)]; at most 10")
    accel_yaw_std_per_sqrt_s: float = Field(default=0.01, gt=0, le=10.0,
                                            description="[rad/s^2 sqrt(s)]; at most 10")
    position_std_per_sqrt_s: float = Field(default=0.005, gt=0, le=10.0, description="unmodelled "
                                           "drift (e.g. current) [m/sqrt(s)]; at most 10")
    heading_std_per_sqrt_s: float = Field(default=0.001, gt=0, le=1.0,
                                          description="[rad/sqrt(s)]; at most 1")
    force_std_per_sqrt_s: float = Field(default=0.003, gt=0, le=100.0, description="disturbance "
                                        "force random walk [N/sqrt(s)]; at most 100")
    moment_std_per_sqrt_s: float = Field(default=0.0005, gt=0, le=100.0, description="disturbance "
                                         "yaw moment random walk [N m/sqrt(s)]; at most 100")
    # -- initial uncertainty -------------------------------------------------------------------
    init_speed_std_mps: float = Field(default=0.3, gt=0, le=10.0, description="u, v when no SOG "
                                      "[m/s]; at most 10 m/s")
    init_yaw_rate_std_radps: float = Field(default=0.05, gt=0, le=math.pi, description="r at "
                                           "initialisation [rad/s]; at most pi")
    init_force_std_n: float = Field(default=0.3, gt=0, le=1000.0, description="disturbance force "
                                    "other than a current's (wind, a towed load) [N]; at most "
                                    "1000 N (over twice the strongest vessel's full thrust)")
    init_current_std_mps: float = Field(default=0.3, ge=0, le=5.0, description="the water current "
                                        "the filter may start in [m/s]: the model has no current, so "
                                        "it holds a drift c by the force D c that balances the "
                                        "damping D (X_u, Y_v); the initial force std adds that. At "
                                        "most 5 m/s, the strongest tidal races (and the scenarios' "
                                        "bound)")
    init_moment_std_nm: float = Field(default=0.03, gt=0, le=1000.0, description="disturbance yaw "
                                      "moment at initialisation [N m]; at most 1000 N m")
    init_max_skew_s: float = Field(default=1.0, gt=0, le=10.0, description="the first fix and the "
                                   "first heading must be this close in time to initialise [s]; "
                                   "at most 10 s (the vessel moves meanwhile)")
    # -- robustness ------------------------------------------------------------------------------
    gate_gnss: float = Field(default=CHI2_2DOF_9999, gt=0, description="chi-square, 2 dof")
    gate_sog: float = Field(default=CHI2_2DOF_9999, gt=0, description="chi-square, 2 dof")
    gate_heading: float = Field(default=CHI2_1DOF_9999, gt=0, description="chi-square, 1 dof")
    gate_yaw_rate: float = Field(default=CHI2_1DOF_9999, gt=0, description="chi-square, 1 dof")
    gnss_reject_reinit_count: int = Field(default=25, ge=2, description="this many GNSS positions "
                                          "rejected in a row means the filter, not the GNSS, is "
                                          "wrong: re-initialise the position from the fix")
    heading_reject_reinit_count: int = Field(default=40, ge=2, description="the same for heading")
    reject_run_reopen_count: int = Field(default=5, ge=2, description="this many yaw rates, or "
                                         "velocities over ground, rejected in a row mean the model "
                                         "is wrong (a thruster lost, a tow): the disturbance's "
                                         "variance is re-opened by a thruster's full thrust (and "
                                         "moment) and the sample tried again")
    gnss_timeout_s: float = Field(default=2.0, gt=0, description="no accepted GNSS position for "
                                  "this long sets `degraded`")
    heading_timeout_s: float = Field(default=1.0, gt=0, description="no accepted heading for this "
                                     "long sets `degraded`")
    late_tolerance_s: float = Field(default=0.5, ge=0, description="a measurement stamped up to "
                                    "this much before the filter's time is applied with a "
                                    "first-order delay correction; older ones are refused")
    max_gap_s: float = Field(default=30.0, gt=0, description="a time step longer than this is not "
                             "integrated: the filter re-initialises from the next measurements")
    max_position_std_m: float = Field(default=1000.0, gt=0, le=100_000.0, description="beyond this "
                                      "the filter drops its state and re-initialises [m]; at most "
                                      "100 km (scenarios start within it of the origin; above, the "
                                      "filter never gives up on a lost state)")
    mismatch: MismatchConfig = Field(default_factory=MismatchConfig, description="the motion fault "
                                     "detector (``seaway_estimator.mismatch``): the vessel does not "
                                     "do what the commanded thrust says")
    # -- the process ---------------------------------------------------------------------------
    state_file: Annotated[Path | None, Flag(metavar="FILE")] = Field(
        default=None, description="keep the NED origin taken from the first fix here, and start "
        "from it after a restart in the same run (seaway_estimator.origin_file); unused when the "
        "run fixes the origin")
    record_inputs: Annotated[Path | None, Flag(metavar="FILE")] = Field(
        default=None, description="write every core call as JSON lines, for python -m "
                                  "seaway_estimator.replay (None: do not)")


CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
"""The shipped configs (``px4-sitl.toml``: a vessel whose model leaves large residuals)."""


def load_estimator_config(path: str | Path | None) -> EstimatorConfig:
    """The config file at ``path`` (TOML or JSON), or ``CONFIG_DIR/<name>.toml``, or the defaults."""
    if path is None:
        return EstimatorConfig()
    return load_config(named_file(CONFIG_DIR, path, "estimator config", "services/estimator/config/"),
                       EstimatorConfig)
