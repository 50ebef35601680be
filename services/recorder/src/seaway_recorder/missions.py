"""Which missions a recording ran, and what describes each: the report's missions.

A report must be about the mission actually flown, not the one the scenario names: an operator
may have sent another one to the live stack (``seaway mission FILE``, the ground station), or
several in a row. The controller's ``mission/status`` messages say which missions ran (their
``mission_id``), when, and how far each got. Its ``mission/accepted`` messages say what each one
was: the waypoints in local NED, r_COA, T^w and the controller, as it accepted them. They are the
first source of a mission's waypoints (``choose``); a recording made before the controller
published them (or one that missed them) falls back to a document: the ``--mission`` file, the
run's ``mission.json``, the recording's ``mission/*`` or ``scenario/*`` attachment. A document is
used for a mission only if it fits what the controller reported while flying it: the same number
of waypoints, and the controller's distance to the active waypoint
(``MissionStatus.distance_to_waypoint_m``, from the state it acted on) found again from the
document's waypoints. A mission with neither is reported from the controller's own figures, and the
report says that its waypoints are not in the recording.
"""

from __future__ import annotations

import bisect
import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field

from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, MissionStatus, StateEstimate
from seaway.recording.runinfo import Mission, mission_from_accepted

FIT_MEDIAN_M = 0.25
"""A document fits a flown mission when the median |distance to the active waypoint from the
document - the controller's| over the mission's statuses is at most this: exact in lockstep (the
same state), within a period's travel in real time (the state a status was computed from is the
newest before it)."""


RESENT_AFTER_NS = 1_000_000_000
"""An acceptance of a mission's id this long after its first active status is the same id sent
again while it flew (the controller restarts it): its metrics are measured from that acceptance.
Shorter gaps are the same acceptance seen through real time's lag (a status is stamped with the
state it was computed from, which may predate the acceptance by a period or two)."""


@dataclass
class MissionRun:
    """One mission the controller flew: a stretch of statuses with one ``mission_id`` that went
    active, from its first status to the next mission's first (stamps, ns)."""

    mission_id: str
    start_ns: int
    end_ns: int | None
    statuses: list[MissionStatus] = field(default_factory=list)

    @property
    def last(self) -> MissionStatus:
        return self.statuses[-1]

    def controller_reported(self) -> dict[str, object]:
        """What the controller itself said last about this mission."""
        s = self.last
        return {"state": s.state, "mission_id": s.mission_id, "active_leg": s.active_leg,
                "waypoint_count": s.waypoint_count, "energy_used_j": s.energy_used_j,
                "energy_to_go_j": s.energy_to_go_j, "leg_energy_to_go_j": s.leg_energy_to_go_j,
                "reason": getattr(s, "reason", "")}


def mission_runs(statuses: Sequence[MissionStatus]) -> list[MissionRun]:
    """The missions flown, in order, from statuses in stamp order (an id that never went active
    is not a mission flown: the idle controller's statuses; nor is one active at one instant only,
    unless there is no other)."""
    runs: list[MissionRun] = []
    current: MissionRun | None = None
    for s in statuses:
        if current is None or s.mission_id != current.mission_id:
            if current is not None:
                current.end_ns = s.stamp_ns
            current = MissionRun(s.mission_id, s.stamp_ns, None)
            runs.append(current)
        current.statuses.append(s)
    flown = [r for r in runs if any(s.state == "active" for s in r.statuses)]
    # A mission accepted in the last, held period of an episode (the world restarted before time
    # moved on) was not flown in it: it has one active stamp. Such a one counts only if alone.
    moved = [r for r in flown if len({s.stamp_ns for s in r.statuses if s.state == "active"}) > 1]
    return moved or flown


@dataclass(frozen=True)
class Candidate:
    """A mission document and the id it names (None: a document without one)."""

    mission: Mission
    mission_id: str | None


def fit(doc: Mission, run: MissionRun, states: Sequence[StateEstimate]) -> tuple[bool, str]:
    """Whether ``doc`` describes ``run`` (see the module docstring), and how that was judged."""
    counts = {s.waypoint_count for s in run.statuses if s.waypoint_count}
    if counts and counts != {len(doc.waypoints)}:
        return False, (f"{len(doc.waypoints)} waypoints, the controller flew "
                       f"{', '.join(map(str, sorted(counts)))}")
    stamps = [s.stamp_ns for s in states]
    diffs = []
    for s in run.statuses:
        if s.state != "active" or s.distance_to_waypoint_m is None:
            continue
        if not 0 <= s.active_leg < len(doc.waypoints):
            return False, f"the controller flew to waypoint {s.active_leg}, which it does not have"
        i = bisect.bisect_right(stamps, s.stamp_ns) - 1  # the newest state at the status
        if i < 0:
            continue
        x, y = doc.waypoints[s.active_leg]
        d = math.hypot(states[i].x_m - x, states[i].y_m - y)
        diffs.append(abs(d - s.distance_to_waypoint_m))
    if not diffs:
        return True, "no distances to check it against"
    med = statistics.median(diffs)
    if med > FIT_MEDIAN_M:
        return False, (f"its waypoints are {med:.2f} m (median) off the controller's distances to "
                       "the active waypoint")
    return True, f"checked against the controller's distances ({len(diffs)} statuses)"


def acceptances(msgs: Sequence[MissionAccepted]) -> list[MissionAccepted]:
    """Each acceptance once (real time re-publishes it every second: the same ``accepted_ns``), in
    the order accepted."""
    seen: dict[tuple[str, int], MissionAccepted] = {}
    for a in msgs:
        seen.setdefault((a.mission_id, a.accepted_ns), a)
    return sorted(seen.values(), key=lambda a: a.accepted_ns)


@dataclass(frozen=True)
class Choice:
    """What describes a flown mission: the mission (None: nothing does), how that was decided, and
    from which status stamp its metrics are measured [ns]."""

    mission: Mission | None
    how: str
    start_ns: int


def choose(run: MissionRun, accepted: Sequence[MissionAccepted], candidates: Sequence[Candidate],
           states: Sequence[StateEstimate]) -> Choice:
    """The mission ``run`` flew: the controller's recorded acceptance of its id (the last one
    before the run ended), else a fitting document (``match``). ``accepted`` as ``acceptances``
    returns them. The recorded mission is what the controller flew by construction; it is still
    checked against the controller's distances, and the check is reported."""
    active = [s.stamp_ns for s in run.statuses if s.state == "active"]
    start = min(active) if active else run.start_ns
    mine = [a for a in accepted if a.mission_id == run.mission_id
            and (run.end_ns is None or a.accepted_ns <= run.end_ns)]
    if not mine:
        doc, how = match(run, candidates, states)
        return Choice(doc, how, start)
    chosen = mine[-1]
    mission = mission_from_accepted(chosen, f"recorded {keys.MISSION_ACCEPTED.suffix}")
    notes = []
    # Sent again while it flew: measured from the last flight. A restarted controller's resumption
    # of its checkpoint is the same flight going on.
    sent = [a for a in mine if not a.resumed]
    if sent and sent[-1].accepted_ns > start + RESENT_AFTER_NS:
        chosen = sent[-1]
        start = min((t for t in active if t >= chosen.accepted_ns), default=chosen.accepted_ns)
        notes.append(f"sent again at {chosen.accepted_ns / 1e9:.3f} s under the same id: "
                     "measured from then")
    flight = MissionRun(run.mission_id, start, run.end_ns,
                        [s for s in run.statuses if s.stamp_ns >= start])
    ok, how = fit(mission, flight, states)
    notes.insert(0, f"the controller's own record of it ({how})" if ok else
                 f"the controller's own record of it, although it does not fit its statuses: {how}")
    return Choice(mission, "; ".join(notes), start)


def match(run: MissionRun, candidates: Sequence[Candidate], states: Sequence[StateEstimate]
          ) -> tuple[Mission | None, str]:
    """The document for ``run`` and why: one with its id that fits, else any that fits (the same
    mission sent under another id), else None with what was tried."""
    tried = []
    ordered = sorted(candidates, key=lambda c: c.mission_id != run.mission_id)
    for c in ordered:
        ok, how = fit(c.mission, run, states)
        if ok:
            same = c.mission_id in (None, run.mission_id)
            note = how if same else f"{how}; its id is {c.mission_id!r}, not {run.mission_id!r}"
            return c.mission, note
        tried.append(f"{c.mission.source}: {how}")
    why = "; ".join(tried) if tried else "no mission document given or attached"
    return None, why
