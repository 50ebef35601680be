"""The ground station's side of the bus: what it hears (into the ``Fleet``) and what it asks.

* ``BusLink.attach`` subscribes to every vessel's state, solve record, mission status, vehicle
  status, NED origin, thrust command, energy budget, operating area, battery and GNSS fix, and
  watches every vessel's health tokens; each arrival updates the ``Fleet`` and calls
  ``on_change(vessel)`` (the stream's wake-up). Callbacks run on the transport's threads and do O(1)
  work: they never wait for a web client. A message stamped more than
  ``seaway.runtime.stamps.MAX_AHEAD_LIVE_S`` ahead of this machine's wall clock is dropped, counted
  and logged (``StampGate``): real time stamps with the wall clock and lockstep from t = 0, so
  neither comes ahead of it, and one that does would pose as the newest message for good and stretch
  the mission's metrics to its stamp (one state stamped 10^9 s ahead made them walk 10^10 grid
  points and take all the machine's memory). A key whose vessel is not a valid vessel name
  (``keys.check_vessel``: the API could never address it), or a new vessel when the fleet has no
  room (``Fleet``'s ``max_vessels``), is dropped, counted (``FleetView.vessels_refused``) and
  logged at most once a minute.
* ``ask`` sends one request and tells apart an answer (accepted or refused), no answer in time, and
  an error reply from the transport, which ``Bus.request`` folds into one refusal.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from pydantic_core import PydanticSerializationError
from seaway.contract import keys
from seaway.contract.messages import Message, MessageError, Reply
from seaway.runtime.bus import Bus
from seaway.runtime.bus_raw import Declared
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import StampBounds, StampGate

from seaway_groundstation.fleet import Fleet, Kind
from seaway_groundstation.views import CommandReply, Outcome

log = logging.getLogger("seaway_groundstation.gateway")

TOPICS: dict[Kind, keys.KeySpec] = {
    "state": keys.NAV_STATE,
    "solve": keys.SOLVE,
    "mission": keys.MISSION_STATUS,
    "vehicle": keys.VEHICLE_STATUS,
    "origin": keys.NAV_ORIGIN,
    "thrust": keys.THRUST,
    "energy": keys.MISSION_ENERGY,
    "area": keys.AREA_ACTIVE,
    "battery": keys.VEHICLE_BATTERY,
    "gnss": keys.GNSS,
}
"""What the ground station shows of each vessel, by the fleet's kind."""


def vessel_of(key: str) -> str | None:
    """``seaway/<vessel>/...`` -> ``<vessel>`` (None for a key outside Seaway's namespace, or
    whose vessel is not a valid vessel name)."""
    parts = key.split("/", 2)
    if len(parts) < 2 or parts[0] != keys.ROOT:
        return None
    try:
        return keys.check_vessel(parts[1])
    except keys.KeyNameError:
        return None


class BusLink:
    """Feeds the ``Fleet`` from the bus; see the module's description."""

    def __init__(self, bus: Bus, fleet: Fleet, clock: Callable[[], float] = time.monotonic,
                 on_change: Callable[[str], None] | None = None,
                 wall_ns: Callable[[], int] = time.time_ns) -> None:
        """``clock``: receive times [s, monotonic]; ``wall_ns``: the reference for stamps [ns since
        the Unix epoch]."""
        self.bus, self.fleet, self.clock, self.wall_ns = bus, fleet, clock, wall_ns
        self.stamps = StampGate("groundstation", log, StampBounds.live())
        self.on_change = on_change or (lambda _vessel: None)
        self._declared: list[Declared] = []
        self._refusals = RateLimitedLog(log, 60.0)

    def attach(self) -> None:
        """Declare the subscriptions and the health watch (call once, before serving)."""
        for kind, spec in TOPICS.items():
            self._declared.append(self.bus.subscribe(spec, callback=self._on_message(kind),
                                                     vessel="*"))
        self._declared.append(self.bus.watch_fleet_health(self._on_health))

    def _on_message(self, kind: Kind) -> Callable[[str, Any], None]:
        def handle(key: str, msg: Message) -> None:
            vessel = vessel_of(key)
            if vessel is None:
                self.fleet.refuse()
                self._refused(key[:200], "its vessel name is not valid")
                return
            if not self.stamps.admit(key, msg.stamp_ns, self.wall_ns()):
                return
            if not self.fleet.on_message(vessel, kind, msg, self.clock()):
                self._refused(key, f"no room for another vessel ({self.fleet.max_vessels} kept)")
                return
            self.on_change(vessel)

        return handle

    def _on_health(self, vessel: str, service: str, alive: bool) -> None:
        try:
            keys.check_vessel(vessel)
        except keys.KeyNameError:
            self.fleet.refuse()
            self._refused(f"health of {vessel[:200]!r}", "its vessel name is not valid")
            return
        before = self.fleet.refused
        if self.fleet.on_health(vessel, service, alive, self.clock()):
            self.on_change(vessel)
        elif self.fleet.refused != before:
            self._refused(f"health of {vessel!r}", f"no room for another vessel "
                                                   f"({self.fleet.max_vessels} kept)")

    def _refused(self, what: str, why: str) -> None:
        self._refusals.warning(why, "dropped %s: %s (%d dropped so far)", what, why, self.fleet.refused)

    def close(self) -> None:
        for d in self._declared:
            try:
                d.undeclare()
            except Exception:
                log.debug("undeclare failed", exc_info=True)
        self._declared.clear()


class UnsendableError(ValueError):
    """A request that cannot be encoded for the bus (nothing was sent); the text says why."""


def encode_request(spec: keys.KeySpec, request: Message) -> bytes:
    """``request``'s wire bytes; UnsendableError when the serializer gives up on it (a free-form
    document nested too deep, a number it cannot write) or the message refuses a non-finite
    number, so the caller answers 422 instead of a 500 and a traceback."""
    try:
        return request.encode()
    except (PydanticSerializationError, MessageError) as err:
        raise UnsendableError(f"the {spec.suffix} request cannot be encoded for the bus: {err}") from None


def ask(bus: Bus, spec: keys.KeySpec, request: Message, vessel: str, timeout_s: float) -> CommandReply:
    """Send ``request`` on ``spec`` of ``vessel`` and wait up to ``timeout_s`` [s] for the reply.

    Blocking (call it from a worker thread). The outcome says whether the service answered
    (``accepted``/``refused``), nobody did (``no_reply``), or the transport answered with an error
    (``error_reply``, e.g. a reply refused by access control). UnsendableError, before anything is
    sent, for a request that cannot be encoded (``encode_request``).
    """
    if spec.kind != "query" or type(request) is not spec.message:
        raise TypeError(f"{spec.suffix} does not take {type(request).__name__}")
    payload = encode_request(spec, request)
    key = spec.key(vessel)
    outcome: Outcome = "no_reply"
    reply = Reply.refuse(time.time_ns(), f"no reply from {key} within {timeout_s:g} s "
                                         "(is the service running?)")
    for r in bus.query_raw(key, payload, timeout_s):
        if r.error is not None:
            outcome, reply = "error_reply", Reply.refuse(time.time_ns(), f"error reply from {key}: {r.error}")
            break
        try:
            reply = Reply.decode(r.payload)
        except MessageError as err:
            outcome, reply = "error_reply", Reply.refuse(time.time_ns(), f"malformed reply from {key}: {err}")
            break
        outcome = "accepted" if reply.accepted else "refused"
        break
    return CommandReply(vessel=vessel, request=spec.suffix, outcome=outcome, accepted=reply.accepted,
                        reason=reply.reason, detail=reply.detail)
