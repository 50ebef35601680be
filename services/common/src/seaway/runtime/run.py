"""The run description: everything that must be the same in every process of one run, resolved once.

A run is one launch of a set of services (a profile). What they must agree on is here and nowhere
else: the run id, the vessel's key name, the vessel file the estimator, controller and vehicle_io
model (``model_vessel_file``), the one the simulator integrates (``plant_vessel_file``, which may
differ: the design's robustness test), the control period, the NED origin, the clock and, in
simulation, the scenario.

Who resolves it:

* the launcher, once, from the profile, the scenario and its own options; it writes ``run.json``
  into the run folder and hands every process ``--run run.json``;
* a service started by hand resolves it from the same flags every service has (``add_run_arguments``,
  ``resolve``), with the same defaults, so no service guesses a default another guesses differently.

Every service answers ``seaway/<vessel>/run/<service>`` with the description it was given and, when
it starts, asks the services already running for theirs: a difference in a run-wide field is an
error at start that names the field, both values and the other service (``check_peers``).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, model_validator

from seaway.contract import keys
from seaway.contract.config import ConfigError, ConfigModel, Origin, load_config, parse_config
from seaway.contract.units import s_to_ns
from seaway.runtime.argtypes import positive_float
from seaway.vessel.model import check_vessel_files

log = logging.getLogger("seaway.run")

CONTROL_PERIOD_S = 0.1
"""The control period [s]: the paper's dt (section V-A), one controller step and one lockstep
period. The only place this number is written; everything else takes it from the run."""

DEFAULT_VESSEL_FILE = "paper-sim"
"""The vessel file every service models when nothing names one (deploy/vessels/paper-sim.toml)."""

ClockMode = Literal["wall", "lockstep"]

# The fields every process of a run must agree on; ``run_id`` and ``scenario`` are informative.
RUN_WIDE_FIELDS = ("vessel", "model_vessel_file", "plant_vessel_file", "control_period_s", "origin",
                   "clock", "dead_zone")


class RunMismatchError(ConfigError):
    """Two processes of one run were told different run-wide facts."""


class RunDescription(ConfigModel):
    """Everything every process of one run must agree on (``run.json`` in the run folder)."""

    run_id: str = Field(min_length=1, max_length=128, description="unique name of this run")
    vessel: str = Field(min_length=1, description="vessel name: the key namespace seaway/<vessel>/...")
    model_vessel_file: str = Field(default=DEFAULT_VESSEL_FILE, min_length=1, description=(
        "vessel file (deploy/vessels name or path) the estimator, controller and vehicle_io model"))
    plant_vessel_file: str | None = Field(default=None, description=(
        "simulation only: the vessel file the simulator integrates; None: the model's"))
    control_period_s: float = Field(default=CONTROL_PERIOD_S, gt=0.0, le=1.0, description=(
        "control period [s]: one controller step, one lockstep period, the report's sample period"))
    origin: Origin | None = Field(default=None, description=(
        "local NED origin; None: the estimator takes its first good GNSS fix (a real boat)"))
    clock: ClockMode = Field(default="wall", description="'wall' (real time) or 'lockstep' (sim time)")
    dead_zone: bool = Field(default=False, description=(
        "the thrusters have the vessel file's dead zone (the estimator predicts with it)"))
    scenario: str | None = Field(default=None, description=(
        "simulation only: the scenario (name or path) the simulator runs; None on a boat"))

    @model_validator(mode="after")
    def _vessel_name(self) -> RunDescription:
        keys.check_vessel(self.vessel)
        return self

    @property
    def plant_vessel(self) -> str:
        """The vessel file the simulator integrates (the model's unless the run names another)."""
        return self.plant_vessel_file or self.model_vessel_file

    @property
    def lockstep(self) -> bool:
        return self.clock == "lockstep"

    @property
    def control_period_ns(self) -> int:
        return s_to_ns(self.control_period_s)

    def run_wide(self) -> dict[str, Any]:
        """The fields every process must agree on, as plain JSON values."""
        dumped = self.model_dump(mode="json")
        return {k: dumped[k] for k in RUN_WIDE_FIELDS}

    def differences(self, other: RunDescription) -> list[str]:
        """Each run-wide field in which ``other`` differs, as 'field: mine vs theirs'."""
        mine, theirs = self.run_wide(), other.run_wide()
        return [f"{k}: {mine[k]!r} here, {theirs[k]!r} there" for k in RUN_WIDE_FIELDS
                if mine[k] != theirs[k]]

    def encode(self) -> bytes:
        return self.model_dump_json().encode()

    def write(self, path: Path) -> Path:
        path.write_text(json.dumps(self.model_dump(mode="json"), indent=2) + "\n")
        return path


def started_ns(run_file: str | Path | None) -> int | None:
    """When the run started [ns since the Unix epoch]: when its description (``--run``) was written,
    which the launcher does once per launch, before it starts any process, and a restarted process
    reads again unchanged; None without one (a service started by hand from flags)."""
    if not run_file:
        return None
    return Path(run_file).stat().st_mtime_ns


def from_earlier_launch(saved_unix_ns: int, run_file: str | Path | None) -> bool:
    """Whether a state a process kept for its restart (saved at ``saved_unix_ns``) was kept before
    this run started: by an earlier launch into the same run folder (``seaway launch --run-dir``
    names one, and the run id is the folder's name), so it is not this run's to resume."""
    start = started_ns(run_file)
    return start is not None and saved_unix_ns < start


def new_run_id(label: str) -> str:
    """A run id from the wall time and a label, e.g. ``20261123-010203-sim-batch``."""
    return f"{time.strftime('%Y%m%d-%H%M%S')}-{label}"


def describe(*, vessel: str, run_id: str, clock: ClockMode = "wall", scenario: Any = None,
             scenario_ref: str | None = None, origin_from_scenario: bool = True,
             model_vessel_file: str | None = None, plant_vessel_file: str | None = None,
             control_period_s: float | None = None, origin: Origin | None = None,
             dead_zone: bool = False, simulated: bool = True, where: str = "run") -> RunDescription:
    """The one way a run description is made: by the launcher, and from a service's own flags.

    A ``scenario`` (a ``seaway.simkit.scenario.Scenario``, named ``scenario_ref`` as the simulator
    will load it) supplies the model vessel (its ``vessel``), the plant (its ``plant_vessel``, else
    ``vessel``), the dead zone and, unless ``origin_from_scenario`` is false (a boat), the origin, so
    the estimator shares the simulator's frame. Explicit values override it; None keeps the default.
    ``simulated=False`` (no simulator of ours in the run: ArduPilot's or PX4's SITL is the boat)
    takes only the model, origin and name from the scenario: its plant and dead-zone flag describe
    our simulator's hull, which is not there.
    A plant equal to the model is stored as None (no second model). ConfigError names a bad field,
    also of a vessel file (each is loaded here, so a bad one stops a launch, ``--check`` included,
    before any process starts).
    """
    fields: dict[str, Any] = {"run_id": run_id, "vessel": vessel, "clock": clock}
    if scenario is not None:
        fields.update(model_vessel_file=scenario.vessel, scenario=scenario_ref or scenario.name)
        if simulated:
            fields.update(plant_vessel_file=scenario.plant_vessel_file, dead_zone=scenario.dead_zone)
        if origin_from_scenario:
            fields["origin"] = scenario.origin
    overrides = {"model_vessel_file": model_vessel_file, "plant_vessel_file": plant_vessel_file,
                 "control_period_s": control_period_s, "origin": origin}
    fields.update({k: v for k, v in overrides.items() if v is not None})
    if dead_zone:
        fields["dead_zone"] = True
    if fields.get("plant_vessel_file") == fields.get("model_vessel_file", DEFAULT_VESSEL_FILE):
        fields["plant_vessel_file"] = None
    run = parse_config(fields, RunDescription, where)
    try:
        check_vessel_files(model=run.model_vessel_file, plant=run.plant_vessel_file)
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None
    return run


# ---------------------------------------------------------------------------------------------
# A service's flags
# ---------------------------------------------------------------------------------------------


def _origin_arg(text: str) -> Origin:
    try:
        parts = [float(p) for p in text.split(",")]
        if len(parts) not in (2, 3):
            raise ValueError
        return Origin(lat_deg=parts[0], lon_deg=parts[1], alt_m=parts[2] if len(parts) == 3 else 0.0)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--origin wants LAT,LON[,ALT] in degrees (|lat| <= 90, |lon| <= 180) and metres, "
            f"got {text!r}") from None


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """The flags every service takes to learn its run (the launcher passes only ``--run``)."""
    g = p.add_argument_group("run (what every process of the run must agree on)")
    g.add_argument("--run", default=None, metavar="FILE",
                   help="run description file written by the launcher; the flags below are then "
                        "not allowed")
    g.add_argument("--scenario", default=None,
                   help="simulation: take the vessel files, origin and dead zone from this scenario "
                        "(name in deploy/scenarios or a path)")
    g.add_argument("--vessel-file", default=None,
                   help=f"vessel file the services model (name in deploy/vessels or a path; "
                        f"default: the scenario's, else {DEFAULT_VESSEL_FILE})")
    g.add_argument("--plant-vessel-file", default=None,
                   help="simulation: vessel file the simulator integrates (default: the model's)")
    g.add_argument("--control-period-s", type=positive_float, default=None,
                   help=f"control period [s] (default {CONTROL_PERIOD_S})")
    g.add_argument("--origin", type=_origin_arg, default=None, metavar="LAT,LON[,ALT]",
                   help="local NED origin [deg, deg, m] (default: the scenario's; on a boat the first "
                        "good GNSS fix)")
    g.add_argument("--lockstep", action="store_true",
                   help="lockstep: the simulator owns time (batch simulation)")
    g.add_argument("--dead-zone", action="store_true",
                   help="the thrusters have the vessel file's dead zone (default: the scenario's flag)")


def resolve(args: argparse.Namespace, service: str,
            load_scenario: Any = None) -> RunDescription:
    """The run this process belongs to: ``--run FILE``, else its own flags (``add_run_arguments``).

    ``load_scenario`` (``seaway.simkit.scenario.load_scenario``) is passed by services that accept
    ``--scenario``; the runtime itself does not depend on the simulation kit. ConfigError on a bad
    file, a bad value, or flags given beside ``--run``.
    """
    flags = {"--scenario": args.scenario, "--vessel-file": args.vessel_file,
             "--plant-vessel-file": args.plant_vessel_file, "--control-period-s": args.control_period_s,
             "--origin": args.origin, "--lockstep": args.lockstep or None,
             "--dead-zone": args.dead_zone or None}
    if args.run:
        given = [flag for flag, value in flags.items() if value is not None]
        if given:
            raise ConfigError(f"{', '.join(given)} given beside --run {args.run}: the run description "
                              "says it all (edit the run file or drop --run)")
        run = load_config(args.run, RunDescription)
        if run.vessel != args.vessel:
            raise RunMismatchError(f"--vessel {args.vessel!r} but the run {args.run} is for vessel "
                                   f"{run.vessel!r}")
        return run
    scenario = None
    if args.scenario:
        if load_scenario is None:
            raise ConfigError(f"{service} takes no --scenario")
        scenario = load_scenario(args.scenario)
    return describe(vessel=args.vessel, run_id=new_run_id(service),
                    clock="lockstep" if args.lockstep else "wall", scenario=scenario,
                    scenario_ref=args.scenario, model_vessel_file=args.vessel_file,
                    plant_vessel_file=args.plant_vessel_file, control_period_s=args.control_period_s,
                    origin=args.origin, dead_zone=args.dead_zone, where=f"{service} run flags")


# ---------------------------------------------------------------------------------------------
# Agreement between processes
# ---------------------------------------------------------------------------------------------


def check_peers(run: RunDescription, service: str, peers: list[tuple[str, bytes]]) -> None:
    """Raise RunMismatchError if any peer's description differs from ``run`` in a run-wide field.

    ``peers`` are (key, payload) answers of ``seaway/<vessel>/run/*``; a payload that does not parse
    is reported as such (a process of another Seaway version, or not Seaway at all).
    """
    problems = []
    for key, payload in peers:
        other_service = key.rsplit("/", 1)[-1]
        if other_service == service:
            continue  # our own previous incarnation's answer cannot arrive; a twin is the launcher's
        try:
            other = RunDescription.model_validate_json(payload)
        except ValueError as err:
            problems.append(f"{other_service} answered an unreadable run description ({err})")
            continue
        diffs = run.differences(other)
        if diffs:
            problems.append(f"{other_service} (run {other.run_id}) was told otherwise: " + "; ".join(diffs))
    if problems:
        raise RunMismatchError(f"{service} (run {run.run_id}) disagrees with the services already "
                               f"running on vessel {run.vessel}: " + " | ".join(problems))


def announce(bus: Any, run: RunDescription, service: str, timeout_s: float = 2.0) -> Any:
    """Check ``run`` against the services already running on ``bus``, then answer for this one.

    Asks ``seaway/<vessel>/run/*`` of every running service (the query ends when all have answered,
    so nothing waits on a timeout unless a peer hangs) and raises RunMismatchError on a difference.
    Then declares this service's own answer and returns it (keep it: undeclared when the bus closes).
    ``bus`` is a ``seaway.runtime.bus.Bus`` (Zenoh or in-memory).
    """
    peers = [(r.key, r.payload) for r in bus.query_raw(keys.run_description_wildcard(run.vessel),
                                                        timeout_s=timeout_s, every=True)
             if r.error is None]
    check_peers(run, service, peers)
    payload = run.encode()
    return bus.queryable_raw(keys.run_description_key(run.vessel, service), lambda _request: payload)
