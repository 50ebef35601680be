"""The sim's worlds: a scenario and its vessels, by name or from a document sent over the bus."""

from __future__ import annotations

from pathlib import Path

from seaway.contract.config import ConfigError, deploy_path
from seaway.runtime.run import RunDescription
from seaway.simkit.faults import ThrusterFaults
from seaway.simkit.scenario import Scenario, load_scenario, parse_scenario
from seaway.vessel.model import VesselParams, load_vessel

from seaway_sim.battery import SimPack


def load_world(name_or_path: str) -> tuple[Scenario, VesselParams]:
    """A scenario by name (deploy/scenarios) or path, and its plant's vessel file. ConfigError."""
    scenario = load_scenario(name_or_path)
    return scenario, load_vessel(scenario.plant_vessel_file)


def scenario_base() -> Path:
    """Where ``file =`` entries of a scenario sent over the bus resolve: deploy/scenarios."""
    try:
        return deploy_path("scenarios")
    except ConfigError:
        return Path.cwd()


def world_of(document: dict, where: str, run: RunDescription | None
             ) -> tuple[Scenario, VesselParams, VesselParams]:
    """(scenario, plant vessel, model vessel) of a scenario document sent over the bus (or kept
    from one: ``seaway_sim.kept``); ConfigError naming ``where`` and what is wrong.

    The scenario must keep the run's model (the estimator and the controller cannot change theirs),
    and its [battery] must fit the plant's pack (its disturbances together stay within what one may
    be: ``seaway.simkit.scenario.disturbance_sums``)."""
    scenario = parse_scenario(document, where, scenario_base())
    vessel = load_vessel(scenario.plant_vessel_file)
    model = load_vessel(scenario.vessel)
    if run is not None and model != load_vessel(run.model_vessel_file):
        raise ConfigError(f"scenario {scenario.name} models vessel {scenario.vessel!r} but this "
                          f"run's services model {run.model_vessel_file!r}: start a new run for it")
    SimPack.of(scenario, vessel)
    ThrusterFaults(scenario.faults, (-vessel.reverse_max_n, vessel.thrust_max_n))  # a stuck thrust fits
    return scenario, vessel, model


