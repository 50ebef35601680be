"""The sim as a node of ``seaway.runtime.node``: the core behind a lock, scenario loading, outputs.

In lockstep it is the clock (``seaway.runtime.lockstep_clock.LockstepClock``): each period it
publishes the sensor samples due, the truth, the disturbance, the battery when a report is due
(``battery.report_due_at``) and the clock (``outputs``), and applies the controller's command over
the period through vehicle I/O's output stage (``advance``). On the wall clock it is driven over
its PX4-like MAVLink endpoint (``seaway_sim.realtime``), ticking every ``--step``.

The ``sim/scenario`` request runs on a bus thread while the loop steps the core; the lock makes a
scenario swap happen between two steps, never inside one. ``episode`` counts swaps, so a loop
waiting on something (lockstep waits for a thrust command) can notice that the world changed.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import ClockTick, Message, Reply, ScenarioRequest, ThrustCommand
from seaway.runtime.lockstep_clock import ClockNode
from seaway.runtime.node import LiveDriver, Outputs
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.run import RunDescription
from seaway.simkit.scenario import Scenario
from seaway.vessel.model import VesselParams, load_vessel
from seaway.vessel.thrusters import absurd_thrust, output_pair

from seaway_sim import kept
from seaway_sim.battery import report_due_at
from seaway_sim.core import SimCore
from seaway_sim.world import world_of

log = logging.getLogger("seaway_sim")
_refusals = RateLimitedLog(log, every_s=60.0)


class SimNode(ClockNode):
    """The core, its lock, its outputs, the scenario request handler; the live half when given."""

    name = "sim"

    def __init__(self, core: SimCore, lockstep: bool, run: RunDescription | None = None,
                 model: VesselParams | None = None, state_file: Path | None = None) -> None:
        self.run = run
        self.state_file = state_file
        """Where each scenario loaded over the bus is kept for a restarted sim (``seaway_sim.kept``);
        None: not kept."""
        self.core = core
        self.lockstep = lockstep
        self.lock = threading.Lock()
        self.episode = 0
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
        nothing to say) (``LockstepClock.await_episode``)."""
        self.refused_commands = 0
        """Lockstep: absurd demands (``thrusters.absurd_thrust``) replaced by neutral, as vehicle I/O
        refuses them."""
        self.live: Any = None
        """Real time: the MAVLink half (``seaway_sim.realtime.Realtime``), given by ``main``."""
        self.out: Outputs | None = None

    def requests(self) -> dict[keys.KeySpec, Callable[[Any], Reply]]:
        return {keys.SIM_SCENARIO: self.handle_scenario}

    def attach(self, driver: Any) -> None:
        if isinstance(driver, LiveDriver):
            self.out = driver.out
            self.driver = driver
            if self.live is not None:
                self.live.start(driver.stop)

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
            self.episode += 1
            for hook in self.on_load:
                hook(scenario, vessel)
            stamp, episode = self.core.stamp_ns, self.episode
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
        """Real time: publish ``truth_outputs`` in that order (lock held)."""
        assert self.out is not None, "publish_truth is the real-time node's"
        self.out.put_all(self.truth_outputs(real_time_factor))

    # -- the lockstep clock (seaway.runtime.lockstep_clock) ------------------------------------

    def time_ns(self) -> int:
        return self.core.stamp_ns

    def outputs(self, period_ns: int) -> list[tuple[keys.KeySpec, Message]]:
        """The sensor samples due in (t_{k-1}, t_k] (at k = 0: those at t = 0) on GNSS and
        ATTITUDE, each stamped with its own sample instant (a fix due inside a dropout is not
        published); then SIM_TRUTH, SIM_DISTURBANCE, VEHICLE_BATTERY when a report is due and
        SIM_CLOCK, stamped t_k (lock held)."""
        samples = self.core.take_samples()
        out: list[tuple[keys.KeySpec, Message]] = [(keys.GNSS, f) for f in samples.gnss
                                                   if f is not None]
        out += [(keys.ATTITUDE, a) for a in samples.attitude]
        out += self.truth_outputs(None, battery=report_due_at(self.core.stamp_ns, period_ns))
        return out

    def advance(self, cmd: ThrustCommand, period_ns: int) -> None:
        """Apply ``cmd`` (T1 port, T2 starboard [N]) for one period through vehicle I/O's output
        stage, which the sim stands in for here (saturation, dead-zone compensation), and so
        through its refusal of an absurd demand: neutral for the period, never full power by
        saturation (lock held)."""
        demand = (cmd.thrust_port_n, cmd.thrust_starboard_n)
        if (why := absurd_thrust(*demand, self.model)) is not None:
            self.refused_commands += 1
            _refusals.log("absurd", logging.WARNING, "refused an absurd thrust command (%s); "
                          "neutral applied; %d refused so far", why, self.refused_commands)
            demand = (0.0, 0.0)
        self.core.advance(output_pair(*demand, self.model), period_ns)

    # -- real time (seaway_sim.realtime) -------------------------------------------------------

    def tick(self, now_ns: int, out: Outputs) -> None:
        """Real time: advance the world to now and send what fell due (``Realtime.tick``)."""
        with self.lock:
            self.live.tick(self.driver.loop.tick)

    def finish(self) -> None:
        if self.live is not None:
            self.live.close()
