"""The manoeuvre flown on the simulator's core in process, recorded as a vessel's run would be.

``fly_in_sim`` steps ``seaway_sim.core.SimCore`` (the plant, disturbances and sensors of a scenario:
the same code the ``sim`` service runs) one control period at a time, commanding the manoeuvre's
thrust at each tick, and writes an MCAP recording with the keys a recorder on the bus would store:
``ctrl/thrust`` (the commands), ``sensors/gnss`` and ``sensors/attitude`` (what the fit reads) and
``sim/truth`` (for comparison only). Log times are the simulator's time (epoch 0), as in lockstep.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from seaway.contract import keys
from seaway.contract.messages import Message, ThrustCommand
from seaway.contract.units import NS_PER_S, s_to_ns
from seaway.runtime.run import CONTROL_PERIOD_S
from seaway.simkit.scenario import Scenario, SensorNoise
from seaway.vessel.model import VesselParams
from seaway_recorder.core import RecordingWriter
from seaway_sim.core import SimCore

from seaway_lab.identify.manoeuvre import Manoeuvre

IDENTIFY_METADATA = "seaway.identify"
"""The recording's metadata record naming the manoeuvre and the vessel it was flown on."""
SOURCE = "identify"


@dataclass
class SimRun:
    path: Path
    duration_s: float
    messages: int


def calm_scenario(vessel: str, noise: SensorNoise, seed: int = 1, dead_zone: bool = False,
                  thruster_lag: bool = False) -> Scenario:
    """Calm water (no disturbance) with the given sensors: the sim's own vessel as it is."""
    return Scenario(name="identify", seed=seed, vessel=vessel, sensors=noise, dead_zone=dead_zone,
                    thruster_lag=thruster_lag)


def _put(w: RecordingWriter, vessel: str, spec: keys.KeySpec, msg: Message) -> None:
    w.write(spec.key(vessel), msg.encode(), f"application/json;{msg.SCHEMA}", msg.stamp_ns)


def fly_in_sim(scenario: Scenario, plant: VesselParams, manoeuvre: Manoeuvre, out: Path,
               vessel_name: str = "sim", tick_s: float = CONTROL_PERIOD_S) -> SimRun:
    """Fly ``manoeuvre`` on ``plant`` in ``scenario`` and record it to ``out`` (MCAP)."""
    sim = SimCore(scenario, plant)
    tick_ns = s_to_ns(tick_s)
    meta = {"vessel": plant.name, "scenario": scenario.name, "level_n": f"{manoeuvre.level_n:g}",
            "reverse_level_n": f"{manoeuvre.reverse_level_n or manoeuvre.level_n:g}",
            "sensors": json.dumps(scenario.sensors.model_dump()), "where": "in-process simulator"}
    w = RecordingWriter(out, foxglove=False, metadata={IDENTIFY_METADATA: meta})
    w.open(0)
    n_ticks = int(manoeuvre.duration_s / tick_s) + 1
    for k in range(n_ticks + 1):
        t_ns = k * tick_ns
        if k > 0:
            sim.advance(thrust, tick_ns)  # noqa: F821 - set below at k = 0
        samples = sim.take_samples()
        for att in samples.attitude:
            _put(w, vessel_name, keys.ATTITUDE, att)
        for fix in samples.gnss:
            if fix is not None:
                _put(w, vessel_name, keys.GNSS, fix)
        _put(w, vessel_name, keys.SIM_TRUTH, sim.truth())
        thrust = manoeuvre.thrust_n(t_ns / NS_PER_S)
        _put(w, vessel_name, keys.THRUST, ThrustCommand(stamp_ns=sim.stamp_ns, thrust_port_n=thrust[0],
                                                        thrust_starboard_n=thrust[1], source=SOURCE,
                                                        seq=k))
    files = w.close(sim.stamp_ns)
    return SimRun(Path(files[0]), sim.t_ns / NS_PER_S, w.stats.messages)
