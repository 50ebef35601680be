"""The core's read of the autopilot's parameters: its loss failsafe and its thrust mapping.

After connecting (and again when the autopilot finished starting, and when it arms) vehicle_io
reads the parameters its profile names, asking each under every name it has had (PARAM_VALUE
values decoded by the profile, in the parameter's own units). The answers give the assessment of
what the autopilot does if vehicle_io dies, and the mapping from thrust to its axes (e.g.
ArduPilot's RC calibration and dead zone). Retries are timed on the monotonic clock.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from seaway_vehicle_io.conversions import FieldError
from seaway_vehicle_io.core_outputs import Now, Output, SendParamRequestRead
from seaway_vehicle_io.profile import FailsafeAssessment, Profile

if TYPE_CHECKING:
    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.core_link import LinkState
    from seaway_vehicle_io.fence_sync import FenceSync

log = logging.getLogger("seaway.vehicle_io")


@dataclass
class ParamCheck:
    """The start-up read of the autopilot's loss-failsafe parameters.

    ``wanted`` are the names the assessment uses; ``alternatives`` the names each is asked under
    (a parameter renamed between firmware versions is asked under all its names at once, and the
    first answer settles it: no waiting for a name the firmware does not have)."""

    wanted: tuple[str, ...] = ()
    alternatives: dict[str, tuple[str, ...]] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)
    answered_as: dict[str, str] = field(default_factory=dict)
    attempts: dict[str, int] = field(default_factory=dict)
    last_sent_mono_ns: int = 0
    not_before_mono_ns: int = 0
    """No requests before this (monotonic ns): a read restarted while another was in progress
    asks no sooner than that one would have asked again (``_start_param_check``)."""
    done: bool = False
    assessment: FailsafeAssessment | None = None

    def names_for(self, wanted: str) -> tuple[str, ...]:
        return self.alternatives.get(wanted, (wanted,))

    def wanted_for(self, name: str) -> str | None:
        """The assessment's name for a PARAM_VALUE's ``name`` (None: not asked for)."""
        if name in self.wanted:
            return name
        return next((w for w, names in self.alternatives.items() if name in names), None)


class ParamRead:
    """The parameter part of ``VehicleIoCore``: owns the read (``params``) and the thrust mapping
    made from it (``mapper``: (L, R) -> axes; None until made)."""

    # read from the other parts
    cfg: VehicleIoConfig
    link: LinkState
    fence: FenceSync | None

    def _init_params(self) -> None:
        self.params = ParamCheck()
        self.mapper: Any = None  # (L, R) -> axes for this autopilot's parameters; None: not yet

    def _on_param_value(self, msg: Any, now: Now) -> list[Output]:
        pc = self.params
        name = str(msg.param_id).rstrip("\x00")
        if self.fence is not None and self.link.profile is not None:
            value = self.link.profile.decode_param(msg.param_value, msg.param_type)
            if value == value and abs(value) != float("inf"):
                fence_out: list[Output] = list(self.fence.on_param_value(name, value, now.mono_ns))
                if fence_out:
                    return fence_out
        wanted = pc.wanted_for(name)
        if pc.done or wanted is None or self.link.profile is None:
            return []
        value = self.link.profile.decode_param(msg.param_value, msg.param_type)
        if value != value or value in (float("inf"), float("-inf")):
            raise FieldError("PARAM_VALUE", "param_value", msg.param_value, "not finite")
        pc.values[wanted] = value
        pc.answered_as[wanted] = name
        if len(pc.values) == len(pc.wanted):
            self._finish_param_check()
        return []

    def _armed_now(self, now: Now | None = None) -> None:
        """The vessel just armed (its ACK or HEARTBEAT, whichever came first): read the thrust
        mapping's parameters again before thrust matters.

        Read after start-up, a value can still be a boot-time one: measured on Rover SITL, RC1_DZ
        read 0 even after the mode left INITIALISING (its 30 us default came with the first RC
        input, seconds later), so the port paddle lost its dead-zone compensation, 30 us or about
        1 N in 25, and the boat turned steadily to port. The mapping in use stays until the new one
        is made."""
        profile = self.link.profile
        if (profile is None or not profile.mapping_needs_params or not self.cfg.check_failsafe_params
                or not self.params.done):
            return
        line = "autopilot armed: reading its parameters again (the thrust mapping's)"
        if now is None:  # an accepted arm request: one per request, never a flood
            log.info("%s", line)
        else:  # a HEARTBEAT saying armed: as often as the autopilot flaps it
            self._log_change(now, "armed", logging.INFO, line)
        self._start_param_check(profile)

    def _start_param_check(self, profile: Profile) -> None:
        """(Re)start the parameter read; the mapping in use stays until the new one is made.

        A read restarted while one is in progress keeps that one's pace: its requests go out no
        sooner than the old read would have asked again. An autopilot flapping between its
        start-up mode and another, or armed and disarmed, restarts the read at every flap; at
        10,000 flaps a second each tick sent the whole set, 480 PARAM_REQUEST_READ a second, more
        than a 57,600 baud radio carries beside MANUAL_CONTROL. A read that finished, the usual
        case at the end of start-up and at arming, is no pace to keep: the new one asks at once."""
        old = self.params
        pc = ParamCheck(
            wanted=profile.failsafe_params if self.cfg.check_failsafe_params else (),
            alternatives=dict(profile.param_alternatives),
            done=not self.cfg.check_failsafe_params)
        if not old.done:
            next_ns = (old.last_sent_mono_ns + round(self.cfg.param_timeout_s * 1e9)
                       if old.attempts else 0)
            pc.not_before_mono_ns = max(old.not_before_mono_ns, next_ns)
        self.params = pc

    def _param_requests(self, now: Now) -> list[Output]:
        pc, link = self.params, self.link
        if pc.done or not pc.wanted or not link.ok or link.target_system is None:
            return []
        if pc.attempts and now.mono_ns < pc.last_sent_mono_ns + round(self.cfg.param_timeout_s * 1e9):
            return []
        if now.mono_ns < pc.not_before_mono_ns:
            return []
        missing = [p for p in pc.wanted if p not in pc.values]
        exhausted = [p for p in missing if pc.attempts.get(p, 0) >= self.cfg.param_attempts]
        if exhausted and len(exhausted) == len(missing):
            self._finish_param_check()
            return []
        assert link.target_component is not None
        out: list[Output] = []
        for p in missing:
            if pc.attempts.get(p, 0) < self.cfg.param_attempts:
                pc.attempts[p] = pc.attempts.get(p, 0) + 1
                out.extend(SendParamRequestRead(link.target_system, link.target_component, name)
                           for name in pc.names_for(p))
        pc.last_sent_mono_ns = now.mono_ns
        return out

    def _finish_param_check(self) -> None:
        pc = self.params
        assert self.link.profile is not None
        pc.done = True
        missing = ["/".join(pc.names_for(p)) for p in pc.wanted if p not in pc.values]
        a = self.link.profile.assess_failsafe(pc.values, self.cfg.source_system,
                                              self.cfg.rc_receiver)
        pc.assessment = a
        self.mapper = self.link.profile.mapper(pc.values)
        level = logging.INFO if a.verdict in ("stops", "takes_over") else logging.WARNING
        log.log(level, "if vehicle_io dies, the autopilot %s: %s", {
            "stops": "STOPS the thrusters", "takes_over": "TAKES OVER (does not simply stop)",
            "none": "DOES NOT STOP the thrusters", "unknown": "may or may not stop the thrusters",
        }[a.verdict], a.summary)
        if missing:
            log.warning("parameters not reported by the autopilot: %s", ", ".join(missing))
        for w in a.warnings:
            log.warning("autopilot configuration: %s", w)
        for b in a.blocking:
            log.error("autopilot configuration BLOCKS thrust (neutral only): %s", b)
