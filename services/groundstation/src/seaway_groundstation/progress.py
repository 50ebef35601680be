"""The paper's metrics of a vessel's current mission, live, from what the ground station hears (pure).

``MissionTrack`` keeps the state estimates (``nav/state``) and thrust commands (``ctrl/thrust``) of
one vessel from the moment its ``mission/status`` says a mission became active until it completes
or is aborted; ``metrics`` hands them to ``seaway.vessel.metrics.mission_metrics``, the function
``seaway report`` applies to a recording, so the page shows the same figures the report will give,
computed from the estimate instead of the simulator's truth:

* travel time and average cross-track error (samples outside every circle of acceptance) exactly
  as the report defines them;
* energy: the thrust commands held until the next one, times alpha, plus T^w (the report's check
  figure when truth is recorded); only when the vessel's alpha is known.

Only what the metrics read of each sample is kept (``PoseSample``, ``ThrustSample``): a whole
``StateEstimate`` with its 81-number covariance (the estimator sends it at 20 Hz) took 4.2 kB, so a
track at its ``MAX_SAMPLES`` bound held 1.5 GB per vessel; a slim sample takes ~0.15 kB.

A new mission id, or the same mission started again (active after complete/aborted/idle), starts
a new track. Samples arrive slightly out of order (a state can come before the status computed from
it), so the last few states are kept to seed a new track with those at or after its start.
"""

from __future__ import annotations

import collections
from collections.abc import Sequence
from typing import Any, NamedTuple

from pydantic import BaseModel, Field
from seaway.contract import keys
from seaway.contract.messages import MissionStatus, StateEstimate, ThrustCommand
from seaway.vessel.metrics import mission_metrics

TRACKED_STATES = ("active", "paused")
"""Mission states during which samples are kept."""
SEED_SAMPLES = 20
"""States kept from before a mission's start, to seed its track (a state arrives before the status)."""
MAX_SAMPLES = 360_000
"""States (and as many thrusts) kept per mission: ten hours at 10 Hz; beyond, the track stops."""


class PoseSample(NamedTuple):
    """What the metrics read of a state estimate (``seaway.vessel.metrics.Pose``)."""

    stamp_ns: int
    x_m: float
    y_m: float


class ThrustSample(NamedTuple):
    """What the metrics read of a thrust command (``seaway.vessel.metrics.Thrust``) [N]."""

    stamp_ns: int
    thrust_port_n: float
    thrust_starboard_n: float


class MetricsView(BaseModel):
    """The paper's metrics of the current mission from the ground station's samples."""

    mission_id: str
    mission_state: str
    completed: bool = Field(description="the last circle of acceptance was entered")
    travel_time_s: float | None
    avg_cross_track_m: float | None = Field(description="mean distance from the active leg's line, "
                                                        "samples outside every circle [m]")
    max_cross_track_m: float | None
    cross_track_samples: int
    energy_j: float | None = Field(description="alpha (T1^2 + T2^2) + T^w over the travel time, from "
                                               "the thrust commands (None: the vessel's alpha unknown)")
    legs_completed: int
    state_samples: int
    truncated: bool = Field(description="the mission outlasted the samples kept; figures cover its start")
    source: str = (f"{keys.NAV_STATE.suffix} and {keys.THRUST.suffix} as the ground station "
                   "received them")


class MissionTrack:
    """One vessel's samples of its current mission; see the module's description."""

    def __init__(self, max_samples: int = MAX_SAMPLES) -> None:
        self.max_samples = max_samples
        self.mission_id: str | None = None
        self.state = "idle"
        self.start_ns: int | None = None
        self.states: list[PoseSample] = []
        self.thrusts: list[ThrustSample] = []
        self.truncated = False
        self._recent: collections.deque[PoseSample] = collections.deque(maxlen=SEED_SAMPLES)
        self._recent_thrust: collections.deque[ThrustSample] = collections.deque(maxlen=SEED_SAMPLES)

    def copy(self) -> MissionTrack:
        """A snapshot (the sample lists copied) to compute from while samples keep arriving."""
        out = MissionTrack(self.max_samples)
        out.mission_id, out.state, out.start_ns = self.mission_id, self.state, self.start_ns
        out.states, out.thrusts, out.truncated = list(self.states), list(self.thrusts), self.truncated
        return out

    @property
    def tracking(self) -> bool:
        return self.mission_id is not None and self.state in TRACKED_STATES

    def on_status(self, msg: MissionStatus) -> None:
        new_mission = msg.mission_id != self.mission_id
        restarted = msg.state == "active" and self.state not in TRACKED_STATES
        if msg.state == "active" and (new_mission or restarted):
            self.mission_id, self.start_ns, self.truncated = msg.mission_id, msg.stamp_ns, False
            self.states = [s for s in self._recent if s.stamp_ns >= msg.stamp_ns]
            self.thrusts = [t for t in self._recent_thrust if t.stamp_ns >= msg.stamp_ns]
        elif new_mission:  # a mission we never saw active (e.g. idle after a restart)
            self.mission_id, self.start_ns = msg.mission_id, None
            self.states, self.thrusts = [], []
        self.state = msg.state

    def on_state(self, msg: StateEstimate) -> None:
        sample = PoseSample(msg.stamp_ns, msg.x_m, msg.y_m)
        self._recent.append(sample)
        if self.tracking:
            self._keep(self.states, sample)

    def on_thrust(self, msg: ThrustCommand) -> None:
        sample = ThrustSample(msg.stamp_ns, msg.thrust_port_n, msg.thrust_starboard_n)
        self._recent_thrust.append(sample)
        if self.tracking:
            self._keep(self.thrusts, sample)

    def _keep(self, samples: list[Any], msg: Any) -> None:
        if samples and msg.stamp_ns < samples[-1].stamp_ns:
            return  # out of order or from an earlier episode: the metrics need stamp order
        if len(samples) >= self.max_samples:
            self.truncated = True
            return
        samples.append(msg)

    def metrics(self, waypoints_m: Sequence[tuple[float, float]], coa_radius_m: float,
                task_power_w: float, alpha_w_per_n2: float | None,
                sample_period_s: float = 0.1) -> MetricsView | None:
        """The metrics so far (None before the mission has a state sample)."""
        if self.mission_id is None or self.start_ns is None or not self.states or len(waypoints_m) < 2:
            return None
        states, thrusts = list(self.states), list(self.thrusts)
        with_energy = alpha_w_per_n2 is not None and bool(thrusts)
        m = mission_metrics(
            states, waypoints_m, coa_radius_m, task_power_w,
            alpha_w_per_n2=alpha_w_per_n2 if with_energy else None,
            thrusts=thrusts if with_energy else None,
            # Without alpha there is no energy to compute: zero propulsion keeps the other figures.
            energy_j=None if with_energy else [0.0] * len(states),
            mission_start_ns=self.start_ns, sample_period_s=sample_period_s,
            state_source=keys.NAV_STATE.suffix, thrust_source=keys.THRUST.suffix)
        return MetricsView(
            mission_id=self.mission_id, mission_state=self.state, completed=m.completed,
            travel_time_s=m.travel_time_s, avg_cross_track_m=m.avg_cross_track_m,
            max_cross_track_m=m.max_cross_track_m, cross_track_samples=m.cross_track_samples,
            energy_j=m.energy_j if with_energy else None, legs_completed=m.legs_completed,
            state_samples=m.state_samples, truncated=self.truncated)
