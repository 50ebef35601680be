"""The figures every report and benchmark quotes: the paper's metrics of a run, and statistics.

The paper's metrics (shared/reproduction.md, "Metrics"), computed once, here, for the report of a
recording (``seaway report``) and for the in-process closed loop (``seaway_lab.closed_loop``, which
passes its simulator's ``SimTruth`` exactly as a recording carries it):

* **Travel time** [s]: from the start (the first state sample at or after the mission became active,
  else the first state sample) until the last circle of acceptance is entered. The active leg starts
  at P_0 -> P_1 and moves on each time the position enters the circle of the active waypoint P_i
  (``seaway.vessel.path.advance_leg``); entering the last waypoint's circle ends the run. A run that
  does not complete ends at its last state sample. Durations are differences of integer ``stamp_ns``.
* **Energy** [J]: integral over [start, end] of ``alpha (T1^2 + T2^2) + T^w`` (paper eq. 3). The
  propulsion part is the difference of ``SimTruth.energy_j`` (the simulator's own integral) when
  truth is given; otherwise the thrusts, each held from its stamp until the next one (zero-order
  hold), integrated with the vessel's alpha. The task part is ``T^w * (end - start)``. The other
  estimate is reported as a check.
* **Average cross-track error** [m]: the mean, over samples every ``sample_period_s`` (0.1 s) of
  [start, end), of the distance from the line P_{i-1} -> P_i of the active leg
  (``seaway.vessel.path.cross_track_m``), counting only samples outside every circle of acceptance.
  A sample is the newest state at or before the grid time. The end instant itself is not sampled:
  when the mission completes its position is inside the last circle anyway, and when it does not it
  is where the run stopped, not a stretch of it.

Everything here takes messages (or anything with the same fields) and returns numbers; nothing reads
a clock or a file.
"""

from __future__ import annotations

import math
import statistics
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Protocol

from seaway.contract import keys
from seaway.contract.units import NS_PER_S
from seaway.vessel.path import advance_leg, cross_track_m, inside_any_circle

MAX_GRID_SAMPLES = 2_000_000
"""The most samples of the cross-track grid one run's metrics walk: 55.6 h at the paper's 0.1 s. A
longer span between a run's first and last state is a wrong stamp (one state stamped 10^9 s ahead
asked for 10^10 samples, and all the machine's memory) or a recording of many runs, and is refused."""
CLOCK_STEP_GAP_NS = 3600 * NS_PER_S
"""A gap between two consecutive state samples of a run longer than this [ns] (an hour: a state
comes 10 times a second) is named in that refusal as a step of the clock they were stamped on."""

# -- statistics ---------------------------------------------------------------------------------------


def percentile(values: Sequence[float], q: float) -> float:
    """The q-th percentile (0-100), nearest-rank on sorted data; NaN for no data."""
    if not values:
        return math.nan
    s = sorted(values)
    k = max(0, min(len(s) - 1, math.ceil(q / 100.0 * len(s)) - 1))
    return s[k]


def median(values: Sequence[float]) -> float:
    """The median; NaN for no data."""
    return statistics.median(values) if values else math.nan


def rms(values: Sequence[float]) -> float:
    """Root mean square; NaN for no data."""
    return math.sqrt(sum(v * v for v in values) / len(values)) if values else math.nan


# -- the paper's metrics ------------------------------------------------------------------------------


class Pose(Protocol):
    """A state sample: ``SimTruth`` or ``StateEstimate`` (world frame, local NED)."""

    stamp_ns: int
    x_m: float
    y_m: float


class Thrust(Protocol):
    """A thrust sample: ``ThrustCommand`` or ``SimTruth`` [N]."""

    stamp_ns: int
    thrust_port_n: float
    thrust_starboard_n: float


@dataclass
class MissionMetrics:
    """The paper's metrics of one run (see the module docstring); energies [J], times [s], [m]."""

    completed: bool
    start_ns: int
    end_ns: int
    travel_time_s: float | None
    energy_j: float
    propulsion_energy_j: float
    task_energy_j: float
    energy_source: str
    energy_check_j: float | None
    energy_check_source: str
    avg_cross_track_m: float | None
    max_cross_track_m: float | None
    cross_track_samples: int
    legs_completed: int
    state_source: str
    state_samples: int
    series: dict[str, list[float]] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, Any]:
        """The metrics without the series (every other field is a number, a flag or a name: no
        copy; ``asdict`` deep-copied the series' ~20,000 floats only to drop them)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "series"}


def _legs(states: Sequence[Pose], start: int, waypoints: Sequence[tuple[float, float]], r: float
          ) -> tuple[list[int], int | None]:
    """Active leg index (i of P_i) after each state sample from ``start``; index of the final entry."""
    active = 1
    legs = [1] * len(states)
    end = None
    for k in range(start, len(states)):
        s = states[k]
        active = advance_leg(active, s.x_m, s.y_m, waypoints, r)
        legs[k] = min(active, len(waypoints) - 1)
        if active >= len(waypoints):
            end = k
            break
    return legs, end


def mission_metrics(
    states: Sequence[Pose],
    waypoints: Sequence[tuple[float, float]],
    coa_radius_m: float,
    task_power_w: float,
    *,
    alpha_w_per_n2: float | None = None,
    thrusts: Sequence[Thrust] | None = None,
    energy_j: Sequence[float] | None = None,
    mission_start_ns: int | None = None,
    sample_period_s: float = 0.1,
    state_source: str = "",
    thrust_source: str = "",
) -> MissionMetrics:
    """The paper's metrics of one run.

    ``states``: positions in stamp order (SimTruth or StateEstimate). ``energy_j``: cumulative propulsion
    energy per state sample (SimTruth.energy_j), if known. ``thrusts``: thrust samples in stamp order
    (SimTruth itself, or ThrustCommand). ``alpha_w_per_n2`` is needed for the thrust integral.
    """
    if len(waypoints) < 2:
        raise ValueError("need at least two waypoints")
    if not states:
        raise ValueError(f"no state samples ({keys.SIM_TRUTH.suffix} or {keys.NAV_STATE.suffix}) "
                         "in the recording")
    if energy_j is not None and len(energy_j) != len(states):
        raise ValueError("energy_j needs one value per state sample")
    wps = [(float(x), float(y)) for x, y in waypoints]
    stamps = [s.stamp_ns for s in states]
    start = 0 if mission_start_ns is None else bisect_right(stamps, mission_start_ns - 1)
    if start >= len(states):
        raise ValueError("no state sample after the mission started")
    legs, end = _legs(states, start, wps, coa_radius_m)
    last = end if end is not None else len(states) - 1
    t0, t1 = stamps[start], stamps[last]
    duration_s = (t1 - t0) / NS_PER_S
    period_ns = round(sample_period_s * NS_PER_S)
    if period_ns <= 0:
        raise ValueError(f"sample_period_s must be > 0 (at least 1 ns), got {sample_period_s}")
    if t1 - t0 > MAX_GRID_SAMPLES * period_ns:
        gap_ns, at = max((b - a, i) for i, (a, b) in enumerate(zip(stamps[start:last],
                                                                  stamps[start + 1:last + 1],
                                                                  strict=True)))
        step = (f"; the largest gap between two of them is {gap_ns / NS_PER_S:.6g} s, after "
                f"{(stamps[start + at] - t0) / NS_PER_S:.6g} s of the mission: the clock was "
                "stepped then (NTP or GPS time setting a computer without a real-time clock), "
                "which the recording does not say (a recorder that records steps says each, "
                "and the report bridges one forward)" if gap_ns > CLOCK_STEP_GAP_NS else "")
        raise ValueError(
            f"the state samples{f' ({state_source})' if state_source else ''} span "
            f"{duration_s:.6g} s from the mission's first to its last; at most "
            f"{MAX_GRID_SAMPLES * sample_period_s / 3600:.1f} h ({MAX_GRID_SAMPLES} samples of "
            f"{sample_period_s:g} s) are taken for one run: a stamp is wrong, or the recording "
            f"holds more than one run{step}")

    # Cross-track error on the sample grid over [t0, t1).
    xte: list[float] = []
    grid_t: list[float] = []
    grid_xte: list[float] = []
    k = start
    g = t0
    while g < t1:
        while k + 1 <= last and stamps[k + 1] <= g:
            k += 1
        s, leg = states[k], legs[k]
        inside = inside_any_circle(s.x_m, s.y_m, wps, coa_radius_m)
        e = cross_track_m(s.x_m, s.y_m, wps[leg - 1], wps[leg])
        grid_t.append((g - t0) / NS_PER_S)
        grid_xte.append(math.nan if inside else e)
        if not inside:
            xte.append(e)
        g += period_ns

    # Energy: the simulator's integral when present, the thrust integral otherwise (and as a check).
    thrust_j = None
    thrust_curve: list[float] = []
    if thrusts and alpha_w_per_n2 is not None:
        thrust_j, thrust_curve = _thrust_energy(thrusts, alpha_w_per_n2, t0, t1, stamps[start:last + 1])
    if energy_j is not None:
        propulsion = energy_j[last] - energy_j[start]
        source = f"{state_source} energy_j".strip()
        check, check_source = thrust_j, f"{thrust_source} thrust, zero-order hold".strip()
        curve = [energy_j[i] - energy_j[start] for i in range(start, last + 1)]
    elif thrust_j is not None:
        propulsion = thrust_j
        source = f"{thrust_source} thrust, zero-order hold".strip()
        check, check_source = None, ""
        curve = thrust_curve
    else:
        raise ValueError("cannot compute the energy: no energy_j and no thrusts with a known alpha "
                         "(give the vessel file)")
    task = task_power_w * duration_s
    series = {
        "t_s": [(stamps[i] - t0) / NS_PER_S for i in range(start, last + 1)],
        "x_m": [states[i].x_m for i in range(start, last + 1)],
        "y_m": [states[i].y_m for i in range(start, last + 1)],
        "energy_used_j": [curve[i] + task_power_w * (stamps[start + i] - t0) / NS_PER_S
                          for i in range(len(curve))],
        "grid_t_s": grid_t,
        "cross_track_m": grid_xte,
    }
    return MissionMetrics(
        completed=end is not None,
        start_ns=t0,
        end_ns=t1,
        travel_time_s=duration_s if end is not None else None,
        energy_j=propulsion + task,
        propulsion_energy_j=propulsion,
        task_energy_j=task,
        energy_source=source,
        energy_check_j=None if check is None else check + task,
        energy_check_source=check_source,
        avg_cross_track_m=(sum(xte) / len(xte)) if xte else None,
        max_cross_track_m=max(xte) if xte else None,
        cross_track_samples=len(xte),
        legs_completed=(legs[last] - 1) + (1 if end is not None else 0),
        state_source=state_source,
        state_samples=last - start + 1,
        series=series,
    )


def _thrust_energy(thrusts: Sequence[Thrust], alpha: float, t0: int, t1: int, at: Sequence[int]
                   ) -> tuple[float, list[float]]:
    """Integral of alpha (T1^2 + T2^2) over [t0, t1], each thrust held until the next one; also the
    running integral at the times ``at``."""
    ts = [c.stamp_ns for c in thrusts]
    power = [alpha * (c.thrust_port_n ** 2 + c.thrust_starboard_n ** 2) for c in thrusts]
    curve: list[float] = []
    total = 0.0
    t_prev = t0
    j = bisect_right(ts, t0) - 1  # the thrust in force at t0, if any
    p_cur = power[j] if j >= 0 else 0.0
    i = j + 1
    for t in [*at, t1]:
        while i < len(ts) and ts[i] <= t:
            total += p_cur * (ts[i] - t_prev) / NS_PER_S
            t_prev, p_cur = ts[i], power[i]
            i += 1
        curve.append(total + p_cur * (t - t_prev) / NS_PER_S)
    return curve[-1], curve[:-1]


# -- energy used, and how good the energy-to-finish prediction was (issue #17) -----------------------


class Drawn(Protocol):
    """A sample of the simulator's propulsion integral: ``SimTruth``."""

    stamp_ns: int
    energy_j: float


EnergyUsed = Sequence[tuple[int, float]]
"""(stamp [ns], energy used [J]) in time order; a difference of two is the energy used between."""

CHECK_TAIL_FRAC = 0.1
"""Predictions are judged until this fraction of the mission's time is left: closer to the end, a
few joules of misprediction are a large fraction of what is left, and nothing depends on them."""


def truth_energy_used(truth: Sequence[Drawn], task_power_w: float) -> list[tuple[int, float]]:
    """The energy used (paper eq. 3) at each simulator sample: its propulsion integral
    (``energy_j`` [J]) plus T^w t, ``task_power_w`` [W] times the stamp [s]. Only differences mean
    anything (the same energy the report's metrics integrate, ``mission_metrics``)."""
    return [(t.stamp_ns, t.energy_j + task_power_w * t.stamp_ns / NS_PER_S) for t in truth]


def energy_used_at(used: EnergyUsed, t_ns: int) -> float:
    """The energy used at ``t_ns`` [ns]: that of the newest sample at or before it (the first
    sample's before the first)."""
    i = bisect_right(used, t_ns, key=lambda u: u[0]) - 1
    return used[max(i, 0)][1]


@dataclass(frozen=True)
class PredictionPoint:
    """One prediction of the energy to finish against what finishing actually took [s, J]."""

    t_s: float
    predicted_j: float
    actual_j: float

    @property
    def error_frac(self) -> float:
        """(predicted - actual) / actual; NaN when nothing was left to use."""
        return (self.predicted_j - self.actual_j) / self.actual_j if self.actual_j > 0 else math.nan


@dataclass(frozen=True)
class PredictionCheck:
    """The energy to finish as predicted along a mission against the energy actually used.

    ``start``: the first prediction; ``half``: the first at or after half the mission's time;
    ``last_half_max_abs_error_frac``: the worst |error| of every prediction from there until
    ``CHECK_TAIL_FRAC`` of the mission is left."""

    points: list[PredictionPoint]
    start: PredictionPoint | None
    half: PredictionPoint | None
    last_half_max_abs_error_frac: float


def energy_prediction_check(predicted: Sequence[tuple[int, float]],
                            used: Sequence[tuple[int, float]], end_ns: int) -> PredictionCheck:
    """Compare predictions (stamp [ns], energy to finish [J]) with the energy actually used from
    each stamp to ``end_ns`` [ns], from ``used``: (stamp [ns], energy used since the start [J]),
    in time order, read as the newest sample at or before a time (the report's energy integral,
    or the simulator's ``energy_j`` plus T^w t: ``truth_energy_used``)."""

    def at(t_ns: int) -> float:
        return energy_used_at(used, t_ns)

    preds = [(s, p) for s, p in predicted if s <= end_ns and math.isfinite(p)]
    if not preds or not used:
        return PredictionCheck([], None, None, math.nan)
    t0 = preds[0][0]
    total = at(end_ns)
    points = [PredictionPoint((s - t0) / NS_PER_S, p, total - at(s)) for s, p in preds]
    half_ns = t0 + (end_ns - t0) / 2
    tail_ns = end_ns - CHECK_TAIL_FRAC * (end_ns - t0)
    half = next((pt for (s, _), pt in zip(preds, points, strict=True) if s >= half_ns), None)
    errs = [abs(pt.error_frac) for (s, _), pt in zip(preds, points, strict=True)
            if half_ns <= s <= tail_ns and math.isfinite(pt.error_frac)]
    return PredictionCheck(points, points[0], half, max(errs) if errs else math.nan)
