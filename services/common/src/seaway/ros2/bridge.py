"""``seaway-ros2`` (``seaway ros2 bridge``): Seaway's state as ROS 2 topics over rmw_zenoh.

Inputs (Seaway's bus, read only): ``nav/state``, ``sensors/gnss``, ``mission/accepted``,
``ctrl/solve``, ``ctrl/thrust``, ``vehicle/battery``, ``vehicle/status`` and the services' health
tokens. Outputs (a second Zenoh session, the ROS 2 side): the topics of ``seaway.ros2.face`` in
rmw_zenoh's wire format (``seaway.ros2.rmw``): CDR payloads with their attachment, and liveliness
tokens for the node ``/<vessel>/seaway_bridge`` and each of its publishers, so that ``ros2 topic
list`` and ``ros2 node info`` find them. ``/diagnostics`` once a second.

The ROS 2 side is a Zenoh peer that connects to ``--ros2-connect`` (``rmw_zenohd``'s default
``tcp/127.0.0.1:7447``), without Seaway's credentials: it is ROS's network, not Seaway's bus.
Read only by default: the bridge subscribes to nothing there, so nothing a ROS 2 node sends reaches
Seaway. With ``--ros2-writes`` it also subscribes (with rmw_zenoh's subscription tokens) to the
topics of ``seaway.ros2.writes`` and sends what they ask, a mission or its pause/resume/abort, as
the request an operator sends, under its own identity: Zenoh's access control and the controller
decide (docs/ros2.md). Requests are sent one at a time from a worker thread, never from Zenoh's
callback; samples beyond ``WRITE_QUEUE`` waiting are dropped and counted.

A Seaway message that does not decode is dropped and counted by the bus (``bus.stats``); one that
cannot be converted is dropped and counted here (``dropped``); a ROS 2 sample that is not a request
is dropped and counted (``seaway.ros2.writes.WriteStats``, in ``/diagnostics``), each logged at a
limited rate.
"""

from __future__ import annotations

import argparse
import logging
import os
import queue
import threading
import time
from collections.abc import Sequence
from typing import Any

import zenoh

from seaway.contract import keys
from seaway.contract import messages as m
from seaway.ros2 import cdr, convert, face, rmw, writes
from seaway.runtime.argtypes import whole_number
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.service import base_parser, parse, run_service
from seaway.vessel.model import VesselParams, load_vessel

log = logging.getLogger("seaway.ros2")
SERVICE = "ros2"
NODE_NAME = "seaway_bridge"
DIAGNOSTICS_PERIOD_S = 1.0
CDR_ENCODING = "application/cdr"
WRITE_QUEUE = 16
"""ROS 2 samples waiting for their request to be sent; more are dropped (``busy``)."""
REQUEST_TIMEOUT_S = 5.0


def ros_session(connect: Sequence[str], listen: Sequence[str] = ()) -> zenoh.Session:
    """A Zenoh peer on ROS 2's network as rmw_zenoh's default session config has it: peer mode,
    multicast scouting off, connecting to the router (``connect``); ``listen`` endpoints too."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", _json_list(connect))
    conf.insert_json5("listen/endpoints", _json_list(listen))
    return zenoh.open(conf)


def _json_list(items: Sequence[str]) -> str:
    return "[" + ",".join(f'"{i}"' for i in items) + "]"


class RosNode:
    """One ROS 2 node on a Zenoh session: its token, and a publisher (token, key, sequence) per
    topic. ``publish`` is thread-safe."""

    def __init__(self, session: zenoh.Session, domain: int, namespace: str, name: str) -> None:
        self.session = session
        self.node = rmw.Node(domain, str(session.info.zid()), 0, namespace, name)
        self._entities: list[Any] = [session.liveliness().declare_token(self.node.token())]
        self._pubs: dict[str, tuple[Any, bytes, list[int]]] = {}
        self._lock = threading.Lock()
        self.published = 0
        self._next_id = 1

    def _entity_id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    def advertise(self, topic: str, type_name: str) -> None:
        fq = rmw.qualify(self.node.namespace, topic)
        token = self.node.publisher_token(self._entity_id(), fq, type_name)
        pub = self.session.declare_publisher(rmw.topic_key(self.node.domain, fq, type_name),
                                             encoding=zenoh.Encoding(CDR_ENCODING))
        self._entities += [pub, self.session.liveliness().declare_token(token)]
        self._pubs[topic] = (pub, rmw.gid(token), [1])

    def subscribe(self, topic: str, type_name: str, callback: Any) -> None:
        """Subscribe to ``topic`` as rmw_zenoh does: the topic's key and a subscription token
        (so ``ros2 topic info`` counts it); ``callback(payload bytes)`` per sample."""
        fq = rmw.qualify(self.node.namespace, topic)
        token = self.node.subscription_token(self._entity_id(), fq, type_name)
        sub = self.session.declare_subscriber(rmw.topic_key(self.node.domain, fq, type_name),
                                              lambda sample: callback(sample.payload.to_bytes()))
        self._entities += [sub, self.session.liveliness().declare_token(token)]

    def publish(self, topic: str, type_name: str, value: dict[str, Any]) -> None:
        pub, gid, seq = self._pubs[topic]
        payload = cdr.encode(type_name, value)
        with self._lock:
            n = seq[0]
            seq[0] += 1
            pub.put(payload, attachment=rmw.attachment(n, time.time_ns(), gid))
            self.published += 1

    def close(self) -> None:
        for e in reversed(self._entities):
            e.undeclare()
        self._entities.clear()


class Bridge:
    """The bus-facing half: Seaway messages in, ROS 2 samples out."""

    def __init__(self, node: RosNode, vessel: VesselParams, vessel_name: str) -> None:
        self.node, self.vessel, self.vessel_name = node, vessel, vessel_name
        self.health = face.Health()
        self.dropped = 0
        self.ratelog = RateLimitedLog(log)
        self.writes: writes.Writes | None = None
        self._writes_lock = threading.Lock()
        self._pending: queue.Queue[tuple[keys.KeySpec, m.Request]] = queue.Queue(WRITE_QUEUE)
        for t in face.TOPICS:
            node.advertise(t.name, t.type_name)
        node.advertise(face.DIAGNOSTICS_TOPIC, face.rt.DIAGNOSTIC_ARRAY.name)

    def on_message(self, suffix: str, msg: m.Message) -> None:
        topic = face.BY_SUFFIX[suffix]
        try:
            type_name, value = face.ros_message(topic, msg, self.vessel)
            self.node.publish(topic.name, type_name, value)
        except (cdr.CdrError, ValueError) as err:
            self.dropped += 1
            self.ratelog.warning(("convert", suffix), "dropped %s: not convertible to %s: %s",
                                 suffix, topic.type_name, err)

    def publish_diagnostics(self, stamp_ns: int) -> None:
        type_name, value = self.health.message(stamp_ns, self.vessel_name)
        if self.writes is not None:
            with self._writes_lock:
                counts = self.writes.stats.values()
            value["status"].append({
                "level": convert.OK, "name": "seaway ros2 writes",
                "message": f"{counts['sent']} requests sent, {counts['dropped']} samples dropped",
                "hardware_id": self.vessel_name,
                "values": [{"key": k, "value": v} for k, v in counts.items()]})
        self.node.publish(face.DIAGNOSTICS_TOPIC, type_name, value)

    # -- writes (--ros2-writes) ----------------------------------------------------------------

    def enable_writes(self) -> writes.Writes:
        """Subscribe to the topics ROS 2 may write (``seaway.ros2.writes``)."""
        self.writes = writes.Writes()
        for inbound in writes.INBOUND:
            self.node.subscribe(inbound.name, inbound.type_name,
                                lambda payload, t=inbound.name: self.on_ros_sample(t, payload))
        return self.writes

    def on_accepted(self, accepted: m.MissionAccepted) -> None:
        if self.writes is not None:
            with self._writes_lock:
                self.writes.on_accepted(accepted)

    def on_ros_sample(self, topic: str, payload: bytes) -> None:
        """A sample from ROS 2 (Zenoh's thread): its request queued, or dropped and counted."""
        assert self.writes is not None
        with self._writes_lock:
            try:
                spec, request = self.writes.request(topic, payload, time.time_ns())
            except writes.DroppedError as drop:
                self.ratelog.warning(("ros2 write", drop.kind), "dropped a sample on %s (%s): %s",
                                     topic, drop.kind, drop)
                return
            try:
                self._pending.put_nowait((spec, request))
            except queue.Full:
                self.writes.stats.dropped["busy"] = self.writes.stats.dropped.get("busy", 0) + 1
                self.ratelog.warning(("ros2 write", "busy"), "dropped a sample on %s: %d requests "
                                     "already waiting", topic, WRITE_QUEUE)

    def send_requests(self, bus: Any, stop: threading.Event) -> None:
        """The worker: each queued request sent and its reply counted, until ``stop``."""
        while not stop.is_set():
            try:
                spec, request = self._pending.get(timeout=0.2)
            except queue.Empty:
                continue
            reply = bus.request(spec, request, timeout_s=REQUEST_TIMEOUT_S)
            assert self.writes is not None
            with self._writes_lock:
                self.writes.on_reply(reply)
            if reply.accepted:
                log.info("from ROS 2: %s %s accepted: %s", spec.suffix, _what(request), reply.reason)
            else:
                self.ratelog.warning(("ros2 refused", spec.suffix), "from ROS 2: %s %s REFUSED: %s",
                                     spec.suffix, _what(request), reply.reason)


def _what(request: m.Request) -> str:
    if isinstance(request, m.MissionCommand):
        return request.command
    if isinstance(request, m.MissionRequest):
        return f"{request.mission_id} ({len(request.waypoints)} waypoints)"
    return type(request).__name__


def parser() -> argparse.ArgumentParser:
    p = base_parser(SERVICE, "Seaway's state as ROS 2 topics over rmw_zenoh (read only unless "
                    "--ros2-writes).",
                    prog="seaway-ros2")
    p.add_argument("--ros2-connect", action="append", default=None, metavar="ENDPOINT",
                   help=f"Zenoh endpoint of ROS 2's router, rmw_zenohd (default {rmw.DEFAULT_ROUTER}; "
                        "repeat for several)")
    p.add_argument("--ros2-listen", action="append", default=[], metavar="ENDPOINT",
                   help="also listen for ROS 2 peers on this Zenoh endpoint")
    p.add_argument("--ros2-domain", type=whole_number(0, rmw.ROS_DOMAIN_MAX),
                   default=os.environ.get("ROS_DOMAIN_ID", "0"),
                   help=f"ROS_DOMAIN_ID, 0-{rmw.ROS_DOMAIN_MAX} (default $ROS_DOMAIN_ID or 0)")
    p.add_argument("--ros2-namespace", default=None, metavar="NS",
                   help="the node's namespace (default /<vessel>, made a valid ROS name)")
    p.add_argument(face.WRITES_FLAG, action="store_true",
                   help=f"also take a mission (nav_msgs/Path on <ns>/{writes.SET_PATH.name}) and "
                        f"its pause/resume/abort (std_msgs/String on <ns>/{writes.COMMAND.name}) "
                        "from ROS 2, sent as an operator's requests under this process's identity; "
                        "the stack's access rules must let it ask them (docs/ros2.md)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(parser(), argv)
    namespace = args.ros2_namespace or f"/{rmw.ros_name(args.vessel)}"
    try:
        rmw.check_name(namespace, "--ros2-namespace")
    except rmw.RosNameError as err:
        print(f"seaway-ros2: {err}", flush=True)
        return 2
    with run_service(SERVICE, args) as ctx:
        vessel = load_vessel(ctx.run.model_vessel_file)
        session = ros_session(args.ros2_connect or [rmw.DEFAULT_ROUTER], args.ros2_listen)
        node = RosNode(session, int(args.ros2_domain), namespace, NODE_NAME)
        bridge = Bridge(node, vessel, ctx.vessel)
        for t in face.TOPICS:
            ctx.bus.subscribe(t.spec, callback=lambda _k, msg, s=t.spec.suffix: bridge.on_message(s, msg))
        ctx.bus.subscribe(keys.VEHICLE_STATUS, callback=lambda _k, s: bridge.health.on_status(s))
        ctx.bus.watch_health(bridge.health.on_token)
        worker = None
        if args.ros2_writes:
            bridge.enable_writes()
            ctx.bus.subscribe(keys.MISSION_ACCEPTED, callback=lambda _k, a: bridge.on_accepted(a))
            worker = threading.Thread(target=bridge.send_requests, args=(ctx.bus, ctx.stop),
                                      name="ros2-writes", daemon=True)
            worker.start()
            log.info("ROS 2 writes ON: %s", ", ".join(f"{namespace.rstrip('/')}/{i.name} -> "
                                                      f"{i.spec.suffix}" for i in writes.INBOUND))
        ctx.ready()
        log.info("ROS 2 node %s/%s on domain %d, zid %s, connecting to %s", namespace.rstrip("/"),
                 NODE_NAME, node.node.domain, node.node.zid, ", ".join(args.ros2_connect or
                                                                       [rmw.DEFAULT_ROUTER]))
        while not ctx.stop.wait(DIAGNOSTICS_PERIOD_S):
            bridge.publish_diagnostics(ctx.clock.now_ns())
        if worker is not None:
            worker.join(timeout=REQUEST_TIMEOUT_S + 1)
        log.info("published %d ROS 2 samples, dropped %d", node.published, bridge.dropped)
        if bridge.writes is not None:
            log.info("ROS 2 writes: %s", bridge.writes.stats.values())
        node.close()
        session.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
