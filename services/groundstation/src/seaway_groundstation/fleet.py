"""The fleet as the ground station knows it, built from bus messages (pure: time is passed in).

Inputs, each with the receive time ``now_s`` (a monotonic clock [s]):

* ``on_health(vessel, service, alive)``: health tokens ``seaway/<vessel>/health/<service>``;
* ``on_message(vessel, kind, msg)``: the latest state, solve record, mission status, vehicle status,
  NED origin, thrust command, energy budget, operating area, battery and GNSS fix of each vessel
  (``KINDS``); states, thrusts and
  statuses also feed
  the vessel's ``MissionTrack`` (the paper's metrics of its current mission, ``progress.py``);
* ``record_mission(vessel, request, source)``: a mission this ground station sent and had accepted
  (or learned from the launcher), kept by id so the map can draw the one the vessel flies.

Outputs: ``view`` / ``views`` (``VesselView`` with the age of each message, for GET requests),
``changes`` (the stream's JSON frames: what changed since a client's last frame, latest only) and
``metrics`` (the current mission's metrics so far).

A vessel is known once a service other than the ground station itself declares health on it or it
publishes a message; it stays known (and goes stale) after its services stop. At most
``max_vessels`` are kept: a new name beyond that takes the place of the vessel silent longest, if
one has been silent ``forget_after_s`` with no service's health token, else it is refused (counted
in ``refused``). Before, every name heard was kept for good: 20 000 names a publisher made up took
150 MB, a 7 MB first frame to every stream client and a 1 s stall of the event loop per
``GET /api/vessels``. Thread-safe: bus callbacks write from transport threads while the web server
reads.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass, field
from typing import Any, Literal

from pydantic import BaseModel
from seaway.contract.messages import (
    Message,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    StateEstimate,
    ThrustCommand,
)
from seaway.vessel.frames import GeoOrigin

from seaway_groundstation import geo
from seaway_groundstation.progress import MetricsView, MissionTrack
from seaway_groundstation.views import CommandNote, FleetView, Timed, VesselView

Kind = Literal["state", "solve", "mission", "vehicle", "origin", "thrust", "energy", "area", "battery",
               "gnss"]
KINDS: tuple[Kind, ...] = ("state", "solve", "mission", "vehicle", "origin", "thrust", "energy", "area",
                           "battery", "gnss")
MAX_MISSIONS = 32
"""Missions remembered per vessel (by id), the most recent kept."""
COMMAND = "command"
"""The stream's kind of the latest request relayed to the vessel (``CommandNote``); not a bus
message, so not in ``KINDS`` nor in the vessel's view."""
HEALTH = "health"
"""The stream's pseudo-kind for a change of a vessel's services."""
IGNORED_SERVICES = ("groundstation",)
"""Services whose health token alone does not make a vessel: the ground station's own."""
MAX_VESSELS = 64
"""Vessels kept at once by default (a fleet here is a few boats)."""
FORGET_AFTER_S = 60.0
"""How long a vessel without any service's health token must have been silent before a new name
may take its place [s]."""


class Entry:
    """One latest message with its receive time and change number; its JSON is made once."""

    __slots__ = ("_json", "message", "received_s", "seq")

    def __init__(self, message: BaseModel, received_s: float, seq: int) -> None:
        self.message, self.received_s, self.seq = message, received_s, seq
        self._json: str | None = None

    def json(self) -> str:
        if self._json is None:  # a benign race: two threads may both compute the same text
            self._json = self.message.model_dump_json()
        return self._json


@dataclass
class _Vessel:
    services: set[str] = field(default_factory=set)
    entries: dict[str, Entry] = field(default_factory=dict)
    heard_s: float | None = None
    health_seq: int = 0
    last_mission: MissionRequest | None = None
    missions: dict[str, tuple[MissionRequest, str]] = field(default_factory=dict)
    track: MissionTrack = field(default_factory=MissionTrack)

    @property
    def known(self) -> bool:
        return bool(self.services - set(IGNORED_SERVICES)) or bool(self.entries)


class Fleet:
    """Latest messages per vessel and kind; see the module's description."""

    def __init__(self, stale_after_s: float = 2.0, default_origin: GeoOrigin | None = None,
                 max_vessels: int = MAX_VESSELS, forget_after_s: float = FORGET_AFTER_S) -> None:
        """``forget_after_s`` [s]: see the module's description."""
        if stale_after_s <= 0 or max_vessels < 1 or forget_after_s < 0:
            raise ValueError(f"need stale_after_s > 0, max_vessels >= 1 and forget_after_s >= 0, got "
                             f"{stale_after_s}, {max_vessels}, {forget_after_s}")
        self.stale_after_s = stale_after_s
        self.default_origin = default_origin
        """The NED origin for a vessel that has published none (the run's)."""
        self.max_vessels, self.forget_after_s = max_vessels, forget_after_s
        self.refused = 0
        """Messages and health changes dropped: their vessel was new and there was no room."""
        self.forgotten = 0
        """Vessels forgotten to make room for a new name (their stream clients drop their keys)."""
        self._lock = threading.Lock()
        self._vessels: dict[str, _Vessel] = {}
        self._seq = 0

    # -- inputs -------------------------------------------------------------------------------------

    def _vessel(self, vessel: str, now_s: float) -> _Vessel | None:
        """The vessel's record, made if there is room (None: refused, counted); hold the lock."""
        v = self._vessels.get(vessel)
        if v is None:
            if len(self._vessels) >= self.max_vessels and not self._forget_one(now_s):
                self.refused += 1
                return None
            v = self._vessels[vessel] = _Vessel()
        return v

    def _forget_one(self, now_s: float) -> bool:
        """Forget the vessel silent longest if it has been for ``forget_after_s`` and no service
        of it declares health (a live vessel is never forgotten); hold the lock."""
        idle = [(v.heard_s if v.heard_s is not None else -math.inf, name)
                for name, v in self._vessels.items()
                if not (v.services - set(IGNORED_SERVICES))
                and (v.heard_s is None or now_s - v.heard_s >= self.forget_after_s)]
        if not idle:
            return False
        del self._vessels[min(idle)[1]]
        self.forgotten += 1
        return True

    def refuse(self) -> None:
        """Count a message or health change dropped before it reached the fleet (a vessel name
        that is not valid)."""
        with self._lock:
            self.refused += 1

    def names(self) -> set[str]:
        """Every vessel name held (known or not yet)."""
        with self._lock:
            return set(self._vessels)

    def on_health(self, vessel: str, service: str, alive: bool, now_s: float) -> bool:
        """A health token appeared or went away; True if the vessel's services changed (False
        too when the vessel was refused for want of room)."""
        with self._lock:
            v = self._vessel(vessel, now_s)
            if v is None:
                return False
            before = set(v.services)
            (v.services.add if alive else v.services.discard)(service)
            if v.services == before:
                return False
            self._seq += 1
            v.health_seq, v.heard_s = self._seq, now_s
            return True

    def on_message(self, vessel: str, kind: Kind, msg: Message, now_s: float) -> bool:
        """The latest message of ``kind`` from ``vessel``, received at ``now_s``; False if the
        vessel was refused for want of room (the message is dropped)."""
        if kind not in KINDS:
            raise ValueError(f"unknown kind {kind!r}; known: {', '.join(KINDS)}")
        with self._lock:
            v = self._vessel(vessel, now_s)
            if v is None:
                return False
            self._seq += 1
            v.entries[kind] = Entry(msg, now_s, self._seq)
            v.heard_s = now_s
            if isinstance(msg, StateEstimate):
                v.track.on_state(msg)
            elif isinstance(msg, ThrustCommand):
                v.track.on_thrust(msg)
            elif isinstance(msg, MissionStatus):
                v.track.on_status(msg)
        return True

    def on_command(self, vessel: str, note: CommandNote, now_s: float) -> None:
        """A request relayed to ``vessel`` and its answer: streamed to every client as ``command``."""
        with self._lock:
            v = self._vessel(vessel, now_s)
            if v is None:
                return
            self._seq += 1
            v.entries[COMMAND] = Entry(note, now_s, self._seq)

    def record_mission(self, vessel: str, request: MissionRequest, source: str = "groundstation") -> None:
        """Remember a mission of ``vessel``: sent from here (the last one, for export and start
        again) or learned elsewhere (``source``, e.g. the launcher's), by its id for the map."""
        with self._lock:
            v = self._vessels.get(vessel)  # a vessel seen (the endpoints check): never refused
            if v is None:
                return
            if source == "groundstation":
                v.last_mission = request
            v.missions.pop(request.mission_id, None)
            v.missions[request.mission_id] = (request, source)
            while len(v.missions) > MAX_MISSIONS:
                v.missions.pop(next(iter(v.missions)))

    # -- queries ------------------------------------------------------------------------------------

    def knows(self, vessel: str) -> bool:
        with self._lock:
            v = self._vessels.get(vessel)
            return v is not None and v.known

    def vessels(self) -> list[str]:
        """The known vessels, sorted by name."""
        with self._lock:
            return sorted(name for name, v in self._vessels.items() if v.known)

    def services(self, vessel: str) -> set[str]:
        with self._lock:
            v = self._vessels.get(vessel)
            return set(v.services) if v else set()

    def last_mission(self, vessel: str) -> MissionRequest | None:
        with self._lock:
            v = self._vessels.get(vessel)
            return v.last_mission if v else None

    def origin(self, vessel: str) -> NavOrigin | None:
        """The vessel's published NED origin, if one was received."""
        with self._lock:
            v = self._vessels.get(vessel)
            e = v.entries.get("origin") if v else None
            return e.message if e is not None else None  # type: ignore[return-value]

    def geo_origin(self, vessel: str) -> GeoOrigin | None:
        """The vessel's NED origin: published, else the run's (``default_origin``), else None."""
        return geo.geo_origin(self.origin(vessel)) or self.default_origin

    def active_mission_id(self, vessel: str) -> str | None:
        """The mission id the vessel's latest status names (None: no status, or idle)."""
        with self._lock:
            v = self._vessels.get(vessel)
            e = v.entries.get("mission") if v else None
        if e is None or not isinstance(e.message, MissionStatus) or e.message.state == "idle":
            return None
        return e.message.mission_id

    def mission(self, vessel: str, mission_id: str) -> tuple[MissionRequest, str] | None:
        """A remembered mission of ``vessel`` by id, with where it was learned."""
        with self._lock:
            v = self._vessels.get(vessel)
            return v.missions.get(mission_id) if v else None

    def active_plan(self, vessel: str) -> geo.MissionPlanView | None:
        """The mission the vessel flies, in metres, if the ground station knows its waypoints."""
        mission_id = self.active_mission_id(vessel)
        known = None if mission_id is None else self.mission(vessel, mission_id)
        if known is None:
            return None
        try:
            return geo.mission_plan(known[0], self.geo_origin(vessel), known[1])
        except geo.NoOriginError:
            return None

    def metrics(self, vessel: str, alpha_w_per_n2: float | None,
                sample_period_s: float = 0.1) -> MetricsView | None:
        """The paper's metrics of the vessel's current mission so far (None: no mission known with
        its waypoints, or no sample yet)."""
        plan = self.active_plan(vessel)
        with self._lock:
            v = self._vessels.get(vessel)
            if v is None or plan is None or v.track.mission_id != plan.mission_id:
                return None
            track = v.track.copy()  # bus threads go on appending to the original
        return track.metrics(plan.waypoints_m, plan.coa_radius_m, plan.task_power_w, alpha_w_per_n2,
                                sample_period_s)

    def _timed(self, e: Entry | None, now_s: float) -> Timed[Any] | None:
        if e is None:
            return None
        age = max(0.0, now_s - e.received_s)
        return Timed[type(e.message)](age_s=age, stale=age > self.stale_after_s,  # type: ignore[misc]
                                      message=e.message)

    def view(self, vessel: str, now_s: float) -> VesselView | None:
        """The vessel's view at ``now_s``, or None if it is not known."""
        with self._lock:
            v = self._vessels.get(vessel)
            if v is None or not v.known:
                return None
            entries, services = dict(v.entries), sorted(v.services)
            heard, last_mission = v.heard_s, v.last_mission
        heard_age = None if heard is None else max(0.0, now_s - heard)
        return VesselView(
            vessel=vessel, services=services, simulated="sim" in services,
            last_heard_age_s=heard_age,
            stale=heard_age is None or heard_age > self.stale_after_s,
            last_mission=last_mission, active_mission=self.active_plan(vessel),
            geo=geo.frame_view(self.geo_origin(vessel)),
            **{kind: self._timed(entries.get(kind), now_s) for kind in KINDS},
        )

    def views(self, now_s: float) -> FleetView:
        out = [v for v in (self.view(name, now_s) for name in self.vessels()) if v is not None]
        return FleetView(stale_after_s=self.stale_after_s, vessels=out, max_vessels=self.max_vessels,
                         vessels_refused=self.refused, vessels_forgotten=self.forgotten)

    # -- the stream ---------------------------------------------------------------------------------

    def changes(self, seen: dict[tuple[str, str], int], vessels: frozenset[str] | None,
                now_s: float) -> list[str]:
        """JSON frames, one per vessel with something new since ``seen`` (updated in place).

        ``vessels``: only these (None: every known vessel). A frame is
        ``{"vessel", "services", "stale_after_s", "updates": {kind: {"age_s", "stale", "message"}}}``
        with only the kinds that changed; ``updates`` is empty when only the services changed.
        Only the latest message of each kind is ever sent, never a backlog.
        """
        picked: list[tuple[str, list[str], list[tuple[str, Entry]]]] = []
        with self._lock:
            for name, v in self._vessels.items():
                if not v.known or (vessels is not None and name not in vessels):
                    continue
                new = [(k, e) for k, e in v.entries.items() if e.seq > seen.get((name, k), 0)]
                health_new = v.health_seq > seen.get((name, HEALTH), 0)
                if not new and not health_new:
                    continue
                for k, e in new:
                    seen[(name, k)] = e.seq
                seen[(name, HEALTH)] = v.health_seq
                picked.append((name, sorted(v.services), new))
        frames = []
        for name, services, new in picked:
            parts = []
            for kind, e in new:
                age = max(0.0, now_s - e.received_s)
                parts.append(f'{json.dumps(kind)}:{{"age_s":{age:.4f},'
                             f'"stale":{"true" if age > self.stale_after_s else "false"},'
                             f'"message":{e.json()}}}')
            frames.append(f'{{"vessel":{json.dumps(name)},"services":{json.dumps(services)},'
                          f'"stale_after_s":{self.stale_after_s},"updates":{{{",".join(parts)}}}}}')
        return frames
