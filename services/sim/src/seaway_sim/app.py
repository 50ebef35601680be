"""What both of the sim's loops share: the core behind a lock, scenario loading, truth outputs.

The ``sim/scenario`` queryable runs on a Zenoh thread while a loop steps the core; the lock makes a
scenario swap happen between two steps, never inside one. ``generation`` counts swaps, so a loop
waiting on something (lockstep waits for a thrust command) can notice that the world changed.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path

from seaway.contract import keys
from seaway.contract.config import ConfigError, deploy_path
from seaway.contract.messages import ClockTick, Message, Reply, ScenarioRequest
from seaway.runtime.bus import Bus
from seaway.runtime.run import RunDescription
from seaway.simkit.faults import ThrusterFaults
from seaway.simkit.scenario import Scenario, load_scenario, parse_scenario
from seaway.vessel.model import VesselParams, load_vessel

from seaway_sim import kept
from seaway_sim.battery import SimPack
from seaway_sim.core import SimCore

log = logging.getLogger("seaway_sim")


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

    The scenario must keep the run's model (the estimator and the controller cannot change theirs)
    and its [battery] must fit the plant's pack."""
    scenario = parse_scenario(document, where, scenario_base())
    vessel = load_vessel(scenario.plant_vessel_file)
    model = load_vessel(scenario.vessel)
    if run is not None and model != load_vessel(run.model_vessel_file):
        raise ConfigError(f"scenario {scenario.name} models vessel {scenario.vessel!r} but this "
                          f"run's services model {run.model_vessel_file!r}: start a new run for it")
    SimPack.of(scenario, vessel)
    ThrusterFaults(scenario.faults, (-vessel.reverse_max_n, vessel.thrust_max_n))  # a stuck thrust fits
    return scenario, vessel, model


class SimApp:
    """The core, its lock, the truth publishers and the scenario request handler."""

    def __init__(self, bus: Bus, core: SimCore, lockstep: bool, run: RunDescription | None = None,
                 model: VesselParams | None = None, state_file: Path | None = None) -> None:
        self.bus = bus
        self.run = run
        self.state_file = state_file
        """Where each scenario loaded over the bus is kept for a restarted sim (``seaway_sim.kept``);
        None: not kept."""
        self.core = core
        self.lockstep = lockstep
        self.lock = threading.Lock()
        self.generation = 0
        self.model = model or load_vessel(core.scenario.vessel)
        """The vessel the services model: its limits are vehicle I/O's, whose output stage the
        lockstep sim applies to the controller's demand (``thrusters.output_stage``)."""
        self.on_load: list[Callable[[Scenario, VesselParams], None]] = []
        self.before_load: Callable[[], str] | None = None
        """Lockstep: called under ``lock`` before a load, so the loop publishes nothing more; waits
        until the current episode's last period is answered and on disk, and returns a note for the
        reply ('' if nothing to say)."""
        self.after_load: Callable[[int, int], str] | None = None
        """Lockstep: called with the new (episode, stamp [ns]) once a load is done, before the
        reply; waits until the stack is in the new episode and returns a note for the reply ('' if
        nothing to say) (``Lockstep.await_episode``)."""
        self.pubs = {spec: bus.publisher(spec)
                     for spec in (keys.SIM_TRUTH, keys.SIM_DISTURBANCE, keys.SIM_CLOCK)}
        bus.queryable(keys.SIM_SCENARIO, self.handle_scenario)

    def handle_scenario(self, request: ScenarioRequest) -> Reply:
        """Load the scenario document in ``request`` (action ``load``), or restart the current
        scenario (action ``restart``): the request says which (``ScenarioRequest``).

        A document that does not validate, or names a vessel file that does not, is refused with
        the validation text; the running scenario is then untouched.
        """
        try:
            if request.action == "restart":
                scenario, vessel, model = self.core.scenario, self.core.vessel, self.model
            else:
                assert request.scenario is not None  # ScenarioRequest checks it
                scenario, vessel, model = world_of(request.scenario, "scenario request", self.run)
        except ConfigError as err:
            log.warning("scenario request refused: %s", err)
            return Reply.refuse(self.core.stamp_ns, str(err))
        with self.lock:
            before = self.before_load() if self.before_load is not None else ""
            # Lockstep: a new episode, time restarts at 0 (seaway.runtime.lockstep); real time goes on.
            self.core.load(scenario, vessel, restart_time=self.lockstep)
            self.model = model
            self.generation += 1
            for hook in self.on_load:
                hook(scenario, vessel)
            stamp, episode = self.core.stamp_ns, self.generation
        what = "restarted" if request.action == "restart" else "loaded"
        log.info("scenario %s %s (seed %d, vessel %s)", scenario.name, what, scenario.seed,
                 vessel.name)
        if request.action == "load":
            before += self._keep(scenario, request.scenario)
        note = before + (self.after_load(episode, stamp) if self.after_load is not None else "")
        return Reply.accept(stamp, f"scenario {scenario.name} {what}{note}", name=scenario.name,
                            seed=scenario.seed, vessel=vessel.name)

    def _keep(self, scenario: Scenario, document: dict | None) -> str:
        """Keep a loaded scenario's document for a restarted sim (``state_file``); a note for the
        reply if it could not be kept (the load stands: it is flying)."""
        if self.state_file is None or document is None:
            return ""
        try:
            kept.save(self.state_file, kept.KeptScenario(name=scenario.name, document=document,
                                                         saved_unix_ns=time.time_ns()))
        except OSError as err:
            log.error("scenario %s not kept in %s: %s; a restarted sim would fly the run's",
                      scenario.name, self.state_file, err)
            return f"; not kept for a restart ({self.state_file}: {err})"
        return ""

    def truth_outputs(self, real_time_factor: float | None,
                      battery: bool = False) -> list[tuple[keys.KeySpec, Message]]:
        """SIM_TRUTH, SIM_DISTURBANCE, in lockstep VEHICLE_BATTERY if ``battery`` (a report is due:
        ``battery.report_due_at``), and SIM_CLOCK last, at the core's current time (lock held).

        The battery is the sim's own only in lockstep, where no autopilot speaks: in real time the
        simulated PX4 reports it over MAVLink and vehicle_io publishes it, as on a boat."""
        out: list[tuple[keys.KeySpec, Message]] = [(keys.SIM_TRUTH, self.core.truth()),
                                                   (keys.SIM_DISTURBANCE, self.core.disturbance())]
        if self.lockstep and battery:
            out.append((keys.VEHICLE_BATTERY, self.core.battery()))
        out.append((keys.SIM_CLOCK, ClockTick(stamp_ns=self.core.stamp_ns, lockstep=self.lockstep,
                                              real_time_factor=real_time_factor)))
        return out

    def publish_truth(self, real_time_factor: float | None) -> None:
        """Publish ``truth_outputs`` in that order (lock held)."""
        for spec, msg in self.truth_outputs(real_time_factor):
            pub = self.pubs.get(spec)
            if pub is None:
                pub = self.pubs[spec] = self.bus.publisher(spec)
            pub.put(msg)
