"""vehicle_io as a node of ``seaway.runtime.node``: the MAVLink link, its receive thread, the one
lock, and what the bus brings and asks for. The runtime (``LiveDriver``, on the wall clock) makes
the subscriptions and the request handlers, and runs the paced loop.

Threads, and why:

* **receive** (``_receive_loop``): the one MAVLink receive loop. It waits on the socket, decodes
  what arrived (a bounded batch per cycle, so a flood cannot keep it from handing heartbeats to
  the core, nor hold the lock for long) and hands each message, with the address it came from, to
  the core. It also reopens a transport that broke (TCP EOF, serial unplugged).
* **timer** (the runtime's paced loop, on the main thread): ``tick`` calls ``core.tick``, and the
  driver sleeps until ``core.next_wake_ns`` says something is due (MANUAL_CONTROL stream, watchdog
  deadline, heartbeat, status, retries), at most ``MAX_SLEEP_S`` (one stream period). A call into
  the core from another thread that makes something due sooner (a status held back by the pacing,
  ``status_pacing``) wakes it early (``sleep``).
* **bus callbacks** (``take``): a ThrustCommand is handled on arrival, on the transport's receive
  thread (``inline_inputs``; MANUAL_CONTROL goes out from the callback itself, which is what keeps bus-to-wire
  latency in the sub-millisecond range); arm and mode requests block their own callback thread
  while they wait for COMMAND_ACK; ``keys.AREA_ACTIVE`` and ``keys.NAV_ORIGIN`` feed the autopilot's fence
  (``fence_sync.py``) under the lock, and the timer loop drives its upload.

Shutting down (``finish``, once the loop ended): neutral thrust sent, the link closed, the receive
thread joined.

Every call into the core and every MAVLink send happens under ``self.lock``; the condition on that
lock wakes request handlers when an ACK has been processed. Bus publications are made after the
lock is released (no thread calls into the bus while holding it).
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import (
    ActiveArea,
    ArmRequest,
    Attitude,
    BatteryState,
    GnssFix,
    LocalPosition,
    MessageError,
    ModeRequest,
    NavOrigin,
    Reply,
    ThrustCommand,
    VehicleStatus,
)
from seaway.runtime.bus_typed import TypedPublisher
from seaway.runtime.node import LiveDriver, Node, Outputs
from seaway.runtime.ratelog import RateLimitedLog
from seaway.vessel.battery import BatteryParams
from seaway.vessel.frames import GeoOrigin

from seaway_vehicle_io.commands import MAV_CMD_COMPONENT_ARM_DISARM, MAV_RESULT_ACCEPTED
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.core import LockPeer, Now, Output, Publish, SendCommandLong, VehicleIoCore
from seaway_vehicle_io.link import LinkClosedError, MavlinkLink
from seaway_vehicle_io.mav import result_name
from seaway_vehicle_io.signing import SigningClock, SigningSetup
from seaway_vehicle_io.status_pacing import FlapWatch
from seaway_vehicle_io.thrust import ThrusterLimits

log = logging.getLogger("seaway.vehicle_io")
pacing_log = logging.getLogger("seaway.vehicle_io.status_pacing")
"""The statuses held back by the pacing (``status_pacing``): a flapping link or autopilot."""

REOPEN_DELAY_S = 1.0
OPEN_FAILURES_PER_LOG = 30
MAX_SLEEP_S = 0.05
IN_PROGRESS_WAIT_FACTOR = 5  # an IN_PROGRESS ACK extends the wait to 5 ACK timeouts
SHUTDOWN_NEUTRAL_PACKETS = 3


def now() -> Now:
    return Now(time.time_ns(), time.monotonic_ns())


class VehicleIoNode(Node):
    """vehicle_io on one MAVLink URL, a node of the wall clock only (no lockstep part)."""

    name = "vehicle_io"
    inline_inputs = frozenset({keys.THRUST})
    paced = True

    def __init__(self, cfg: VehicleIoConfig, limits: ThrusterLimits,
                 signing: SigningSetup | None = None, battery: BatteryParams | None = None,
                 origin: GeoOrigin | None = None) -> None:
        self.cfg = cfg
        self.stop = threading.Event()
        """The service's stop (the driver's, from ``attach``)."""
        t = now()
        # One signing clock for every link this process opens: its timestamp never goes back.
        self.signing = None if signing is None else SigningClock(signing, t.wall_ns, t.mono_ns)
        self.lock = threading.Lock()
        self.acks = threading.Condition(self.lock)
        self.core = VehicleIoCore(cfg, limits, t, None if signing is None else signing.key, battery)
        if origin is not None and self.core.fence is not None:
            self.core.fence.set_origin(origin)  # the run's; the published one, once heard, replaces it
        self.link: MavlinkLink | None = None
        self._requests_serial = threading.Lock()  # one COMMAND_LONG in flight at a time
        self._ratelog = RateLimitedLog(log)
        self._pacing_log = RateLimitedLog(pacing_log)
        self._flapping = FlapWatch()
        self._open_failures = 0
        self._publishers: dict[type, TypedPublisher] = {}
        self._receiver: threading.Thread | None = None
        self._wake_ns = 0  # monotonic
        self._sooner = threading.Event()  # set when another thread brought _wake_ns forward
        # The autopilot's fence needs the operating area and the NED origin; nothing else does.
        self.live_inputs = (keys.THRUST,) if self.core.fence is None else (
            keys.THRUST, keys.AREA_ACTIVE, keys.NAV_ORIGIN)

    # -- the runtime's hooks ---------------------------------------------------------------------

    def requests(self) -> Mapping[keys.KeySpec, Callable[[Any], Reply]]:
        return {keys.VEHICLE_ARM: self._on_arm, keys.VEHICLE_MODE: self._on_mode}

    def attach(self, driver: Any) -> None:
        assert isinstance(driver, LiveDriver), "vehicle_io runs on the wall clock only"
        self.stop = driver.stop
        bus = driver.out.bus
        # Typed publishers of its own (not ``out``'s, made on first use): the receive thread, the
        # request threads and the thrust callback publish too.
        self._publishers = {
            GnssFix: bus.publisher(keys.GNSS),
            Attitude: bus.publisher(keys.ATTITUDE),
            LocalPosition: bus.publisher(keys.LOCAL_POSITION),
            VehicleStatus: bus.publisher(keys.VEHICLE_STATUS),
            BatteryState: bus.publisher(keys.VEHICLE_BATTERY),
        }
        self._open_link()
        self._receiver = threading.Thread(target=self._receive_loop, name="mavlink-rx",
                                          daemon=True)
        self._receiver.start()

    def take(self, key: str, msg: Any, now_ns: int | None) -> None:
        if isinstance(msg, ThrustCommand):  # first: the latency path
            self._on_thrust(msg)
        elif isinstance(msg, ActiveArea):
            self._on_area(msg)
        elif isinstance(msg, NavOrigin):
            self._on_origin(msg)

    def tick(self, now_ns: int, out: Outputs) -> None:
        with self.lock:
            publish = self._send(self.core.tick(now()))
            self._wake_ns = self.core.next_wake_ns()
            held = self.core.status_pacer.held
        self._publish(publish)
        flapped = self._flapping.look(held, time.monotonic_ns())
        if flapped is not None:
            self._pacing_log.warning("held", "the vehicle's state changed faster than one status "
                                     "per %.0f ms: %d changes said later within a minute, with the "
                                     "latest state (a flapping link or autopilot?)",
                                     self.core.status_pacer.gap_ns / 1e6, flapped)

    def wake_s(self) -> float:
        """Until the core's next due work [s] (the driver waits at most ``MAX_SLEEP_S``)."""
        return (self._wake_ns - time.monotonic_ns()) / 1e9

    def sleep(self, timeout_s: float, stop: threading.Event) -> None:
        """Wait ``timeout_s`` [s], or less if another thread brought the core's next due work
        forward (``_wake_sooner``). ``stop`` is seen at the end of the wait: the driver's
        ``timeout_s`` is at most ``MAX_SLEEP_S``, so that is how late a stop is seen at most."""
        end_ns = time.monotonic_ns() + round(timeout_s * 1e9)
        while not stop.is_set():
            self._sooner.clear()  # before reading _wake_ns: a later set wakes the wait below
            remaining_ns = min(end_ns, self._wake_ns) - time.monotonic_ns()
            if remaining_ns <= 0:
                return
            self._sooner.wait(remaining_ns / 1e9)

    def _wake_sooner(self) -> None:
        """Called with ``self.lock`` held, after a call into the core off the timer thread: if the
        core now has work due before the timer wakes (a status held back by the pacing, due at the
        gap's end), wake the timer then rather than up to ``MAX_SLEEP_S`` later."""
        wake = self.core.next_wake_ns()
        if wake < self._wake_ns:
            self._wake_ns = wake
            self._sooner.set()

    def finish(self) -> None:
        self.stop.set()  # the receive thread and any waiting request end with it
        self._shutdown()
        if self._receiver is not None:
            self._receiver.join(2.0)

    def _shutdown(self) -> None:
        """Leave the thrusters at neutral rather than at the last command until the autopilot's
        loss failsafe notices the silence."""
        with self.lock:
            neutral = self.core.neutral_command()
            if neutral is not None and self.link is not None:
                self._send([neutral] * SHUTDOWN_NEUTRAL_PACKETS)
                log.info("sent neutral thrust before exiting")
            if self.link is not None:
                self.link.close()
                self.link = None
            if self.signing is not None and not self.signing.close():
                log.warning("MAVLink signing: the timestamp file %s was not written in time",
                            self.signing.setup.timestamp_file)
            if self.core.refusals.total:
                log.info("MAVLink refused during the run: %s (busiest: %s)",
                         self.core.refusals.by_reason, self.core.refusals.summary())
            if self.core.status_pacer.held:
                pacing_log.info("statuses held back by the pacing during the run: %d",
                                self.core.status_pacer.held)

    # -- MAVLink in --------------------------------------------------------------------------------

    def _open_link(self) -> bool:
        try:
            link = MavlinkLink(self.cfg.mavlink, self.cfg.source_system, self.cfg.source_component,
                               self.cfg.baud, udp_client_timeout_s=self.cfg.heartbeat_timeout_s,
                               signing=self.signing, bind_host=self.cfg.bind_host)
        except Exception as err:  # OSError, or pyserial's own SerialException
            self._open_failures += 1
            if self._open_failures % OPEN_FAILURES_PER_LOG == 1:  # the first, then every 30 s
                log.error("cannot open MAVLink %s: %s: %s (attempt %d; retrying every %.0f s)",
                          self.cfg.mavlink, type(err).__name__, err, self._open_failures,
                          REOPEN_DELAY_S)
            return False
        with self.lock:
            self.link = link
            self.core.set_source_policy(link.policy)
            # A reopened transport keeps the lock the core holds (TCP: the same peer).
            locked = self.core.link
            link.lock_peer(locked.target_address if locked.ok else None)
        self._open_failures = 0
        expected = link.policy.expected_address
        log.info("MAVLink %s open on %s (we are system %d component %d%s); the autopilot may "
                 "speak from %s", self.cfg.mavlink, link.local_address(), self.cfg.source_system,
                 self.cfg.source_component, ", signing" if link.signing else "",
                 "any address until its first HEARTBEAT locks the link" if expected is None
                 else f"{expected[0]}:{expected[1]} only")
        return True

    def _receive_loop(self) -> None:
        while not self.stop.is_set():
            link = self.link
            if link is None:
                if not self._open_link():
                    self.stop.wait(REOPEN_DELAY_S)
                continue
            try:
                if not link.wait_readable(MAX_SLEEP_S):
                    continue
                received = link.read_available()
            except LinkClosedError as err:
                if self.stop.is_set():
                    return  # closed by the shutdown, not broken
                self._drop_link(link, err)
                continue
            except Exception as err:  # anything unexpected from the transport: reopen, never die
                log.exception("MAVLink receive failed")
                self._drop_link(link, err)
                continue
            if not received.messages and not received.refused:
                continue
            publish: list[Publish] = []
            with self.lock:
                if received.refused:
                    self.core.on_refused_datagrams(received.refused, now())
                for msg, address in received.messages:
                    try:
                        publish += self._send(self.core.on_mavlink(msg, now(), address))
                    except Exception:  # a bug for one message must not end the receive loop
                        self._ratelog.exception(("handling", msg.get_type()), "handling %s failed",
                                                msg.get_type())
                self._wake_sooner()  # once per batch, not per message
                self.acks.notify_all()
            self._publish(publish)

    def _drop_link(self, link: MavlinkLink, err: Exception) -> None:
        log.warning("MAVLink transport broke: %s; reopening", err)
        with self.lock:
            if self.link is link:
                self.link = None
        link.close()
        self.stop.wait(REOPEN_DELAY_S)

    # -- outputs ---------------------------------------------------------------------------------------

    def _send(self, outputs: list[Output]) -> list[Publish]:
        """Send the MAVLink outputs in order; return the publications for ``_publish``.

        Called with ``self.lock`` held. Publishing happens after the lock is released, so that no
        thread ever calls into the bus while holding the lock that the bus's receive thread takes
        in the thrust callback (and the in-memory bus delivers in the publishing thread itself).
        """
        publish: list[Publish] = []
        for out in outputs:
            if isinstance(out, Publish):
                publish.append(out)
            elif isinstance(out, LockPeer):
                if self.link is not None:
                    self.link.lock_peer(out.address)
            elif self.link is not None:
                try:
                    self.link.send(out)
                except LinkClosedError as err:
                    self._ratelog.warning("send", "send failed: %s", err)
                except Exception:  # an output that cannot be packed must not end the loop
                    self._ratelog.exception(("packing", type(out).__name__), "sending %s failed",
                                            type(out).__name__)
        return publish

    def _publish(self, publish: list[Publish]) -> None:
        for out in publish:
            try:
                self._publishers[type(out.message)].put(out.message)
            except MessageError as err:  # never happens for validated messages; never crash
                log.error("not published: %s", err)

    # -- bus in ------------------------------------------------------------------------------------------

    def _on_thrust(self, cmd: ThrustCommand) -> None:
        """ThrustCommand handled on the transport's own receive thread (``inline_inputs``).

        A plain callback subscription hands each sample to a Python thread of its own first; that
        extra wake-up is most of the tail latency from bus to wire on a loaded machine. The handler
        is short (map, one sendto) and takes only ``self.lock``, which nobody holds for long.
        Latest-only by construction: each command replaces the previous one in the core. Malformed
        payloads are counted in the bus's stats and dropped, as on every typed subscription.
        """
        with self.lock:
            publish = self._send(self.core.on_thrust(cmd, now()))
            self._wake_sooner()
        self._publish(publish)

    def _on_area(self, area: ActiveArea) -> None:
        with self.lock:
            if self.core.fence is not None:
                self.core.fence.set_area(area)

    def _on_origin(self, origin: NavOrigin) -> None:
        with self.lock:
            if self.core.fence is not None:
                self.core.fence.set_origin(GeoOrigin(origin.lat_rad, origin.lon_rad, origin.alt_m))

    def _on_arm(self, req: ArmRequest) -> Reply:
        what = "arm" if req.arm else "disarm"
        log.info("request: %s%s", what, " (forced)" if req.force else "")
        return self._command(lambda: self.core.arm_command(req.arm, req.force), None)

    def _on_mode(self, req: ModeRequest) -> Reply:
        log.info("request: mode %s", req.mode)
        return self._command(lambda: self.core.mode_command(req.mode), req.mode)

    def _command(self, build: Callable[[], SendCommandLong | str], mode: str | None) -> Reply:
        """Send a COMMAND_LONG, resend on timeout, and turn the COMMAND_ACK into a Reply."""
        with self._requests_serial:
            with self.lock:
                cmd = build()
                if isinstance(cmd, str):
                    log.warning("request refused: %s", cmd)
                    return Reply.refuse(time.time_ns(), cmd)
                self.core.commands.begin(cmd.command, cmd.target_system)
            name = self.core.command_name(cmd.command)
            sent_mono_ns = time.monotonic_ns()
            result, attempts = self._send_and_wait(cmd)
            why: list[str] = []
            if (result is not None and result != MAV_RESULT_ACCEPTED
                    and cmd.command == MAV_CMD_COMPONENT_ARM_DISARM):
                why = self._refusal_texts(sent_mono_ns)
            with self.lock:
                self.core.commands.finish(cmd.command)
                status = None
                if result == MAV_RESULT_ACCEPTED:
                    self.core.command_accepted(cmd.command, cmd.params, mode)
                    # Not paced (``status_pacing``): it goes out before the reply, because the
                    # requester acts on the status once it has the reply (the launcher asks the
                    # controller to resume after a mode change, refused while the status says the
                    # thrust is withheld); and its rate is the requests', one at a time, each
                    # waiting for the autopilot's ACK: no flood the autopilot can make alone.
                    # Saying the latest state, it also says whatever the pacing held back.
                    status = Publish(self.core.status(now()))
                    self.core.status_pacer.said()
            if status is not None:
                self._publish([status])
            detail = {"command": name, "attempts": attempts,
                      "target_system": cmd.target_system}
            if result is None:
                reason = (f"no COMMAND_ACK for {name} after {attempts} attempt(s) of "
                          f"{self.cfg.command_ack_timeout_s:g} s (or the link was lost)")
                log.warning("request failed: %s", reason)
                return Reply.refuse(time.time_ns(), reason, result="TIMEOUT", **detail)
            rname = result_name(result)
            if result == MAV_RESULT_ACCEPTED:
                log.info("%s accepted by the autopilot", name)
                return Reply.accept(time.time_ns(), f"{name} ACCEPTED", result=rname, **detail)
            said = f" ({'; '.join(why)})" if why else ""
            with self.lock:  # refusing while it starts is the expected answer (Health.starting)
                starting = self.core.autopilot_starting(now())
            log.log(logging.INFO if starting else logging.WARNING, "%s refused by the autopilot%s: "
                    "%s%s", name, " while it starts" if starting else "", rname, said)
            if why:
                detail["autopilot_text"] = why
            return Reply.refuse(time.time_ns(), f"{name} refused by the autopilot: {rname}{said}",
                                result=rname, **detail)

    def _refusal_texts(self, since_mono_ns: int) -> list[str]:
        """The autopilot's own reason for a refused arm (ArduPilot: STATUSTEXT "PreArm: ...";
        PX4: EVENTs), waiting up to ``statustext_grace_s`` for it to be complete: it may arrive
        after the ACK."""
        deadline = time.monotonic_ns() + round(self.cfg.statustext_grace_s * 1e9)
        with self.acks:  # the receive loop notifies after each batch of messages
            if not self.core.explains_refusals():
                return []
            while True:
                texts, complete = self.core.refusal_texts(since_mono_ns)
                remaining = (deadline - time.monotonic_ns()) / 1e9
                if complete or remaining <= 0 or self.stop.is_set():
                    return texts
                self.acks.wait(remaining)

    def _send_and_wait(self, cmd: SendCommandLong) -> tuple[int | None, int]:
        timeout_ns = round(self.cfg.command_ack_timeout_s * 1e9)
        attempts = 0
        for confirmation in range(self.cfg.command_attempts):
            with self.acks:
                pending = self.core.commands.state(cmd.command)
                if pending is None or self.stop.is_set():
                    return None, attempts  # abandoned: the link was lost meanwhile
                self._send([dataclasses.replace(cmd, confirmation=confirmation)])
                attempts += 1
                deadline = time.monotonic_ns() + timeout_ns
                extended = False
                while True:
                    pending = self.core.commands.state(cmd.command)
                    if pending is None:
                        return None, attempts
                    if pending.result is not None:
                        return pending.result, attempts
                    if pending.in_progress and not extended:
                        # The autopilot is working on it: wait longer, and never resend meanwhile.
                        deadline += (IN_PROGRESS_WAIT_FACTOR - 1) * timeout_ns
                        extended = True
                    remaining = (deadline - time.monotonic_ns()) / 1e9
                    if remaining <= 0 or self.stop.is_set():
                        break
                    self.acks.wait(remaining)
                if extended:
                    return None, attempts
        return None, attempts
