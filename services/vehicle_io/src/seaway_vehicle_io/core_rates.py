"""The core's telemetry rates: asking the autopilot for each message at its configured rate [Hz],
checking what arrives, and asking again after a reboot or a drop (the logic is in ``rates``).

Receive rates are counted per message over windows of at least ``RATE_WINDOW_S`` of monotonic
time, and reported in the status. A shortfall while the autopilot is starting (``Health.starting``:
ArduPilot streams below the rates asked, and LOCAL_POSITION_NED not at all, until its EKF has an
origin) is said at INFO; one still standing after the start is a drop (``rates.RateWatch``: within
``DROP_CONFIRM_S``), said as a warning.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from seaway_vehicle_io import rates as telemetry_rates
from seaway_vehicle_io.core_outputs import Now, Output, SendCommandLong, SendRequestDataStream
from seaway_vehicle_io.profile import Profile
from seaway_vehicle_io.rates import MAV_CMD_SET_MESSAGE_INTERVAL, RateCheck, RateWatch

if TYPE_CHECKING:
    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.core_link import LinkState
    from seaway_vehicle_io.timesync import BootTimeOffset

log = logging.getLogger("seaway.vehicle_io")

RATE_WINDOW_S = 2.0  # receive rates are counted over windows of at least this length


class RateRequests:
    """The rates part of ``VehicleIoCore``: owns the rate check and watch, and the receive rates
    measured (``rates_hz``) from the core's per-message ``counts``."""

    # read from the other parts
    cfg: VehicleIoConfig
    link: LinkState
    offset: BootTimeOffset
    counts: dict[str, int]
    autopilot_starting: Callable[[Now], bool]

    def _init_rates(self, start: Now) -> None:
        self.rate_check: RateCheck | None = None
        self.rate_watch: RateWatch | None = None  # the rates after the check (None: not asked)
        self._rates_redrop_ns: int | None = None  # when a drop was last asked again (None: none)
        self._rates_asked_resets = 0  # the reboots the time offset had seen by then
        self.rates_hz: dict[str, float] = {}
        self._rates_since_ns = start.mono_ns
        self._rates_quiet = False  # the shortfall standing was said at INFO, the autopilot starting

    def _request_rates(self, profile: Profile, now: Now) -> list[Output]:
        """At connection, after a reboot and on a drop: SET_MESSAGE_INTERVAL for every message at
        its configured rate. A standing shortfall stays in the status until the new check ends."""
        self.rate_check = None
        if not profile.requests_message_rates or not self.cfg.message_rates_hz:
            return []
        requests = telemetry_rates.plan(self.cfg.message_rates_hz)
        self.rate_check = RateCheck(requests, now.mono_ns)
        if self.rate_watch is None:
            self.rate_watch = RateWatch(requests)
        self._rates_asked_resets = self.offset.resets
        link = self.link
        assert link.target_system is not None and link.target_component is not None
        return [SendCommandLong(link.target_system, link.target_component,
                                MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                (float(r.msg_id), r.interval_us, 0.0, 0.0, 0.0, 0.0, 0.0))
                for r in requests]

    def _rate_check_tick(self, now: Now) -> list[Output] | None:
        """Advance the rate check; None when nothing changed, else what to send (maybe nothing)."""
        rc, link = self.rate_check, self.link
        if rc is None or not link.ok or link.profile is None or link.target_system is None:
            return None
        if self.offset.resets != self._rates_asked_resets:
            # A reboot (SYSTEM_TIME or every stamp going back) without the link dropping: the
            # autopilot forgot the intervals it was asked for and streams at its defaults.
            log.warning("autopilot rebooted: asking for the telemetry rates again")
            return self._request_rates(link.profile, now)
        if rc.all_accepted():
            rc.start_measuring(now.mono_ns, fallback=False)
            return []
        if rc.needs_fallback(now.mono_ns):
            streams = telemetry_rates.fallback_streams(rc.requests, link.profile.data_streams)
            log.warning("autopilot did not take SET_MESSAGE_INTERVAL (%d of %d accepted, refused "
                        "with %s): %s", rc.accepted, len(rc.requests), rc.refused or "no ACK",
                        f"asking with REQUEST_DATA_STREAM (streams {streams})" if streams else
                        f"{link.profile.name} has no stream-rate fallback: measuring what it sends")
            rc.start_measuring(now.mono_ns, fallback=True)
            assert link.target_component is not None
            return [SendRequestDataStream(link.target_system, link.target_component, sid, hz)
                    for sid, hz in sorted(streams.items())]
        if rc.phase == "measuring" and now.mono_ns >= rc.window_end_ns():
            short = rc.finish()
            if self.rate_watch is not None:
                self.rate_watch.checked(short)
            asked = ", ".join(f"{r.message} {r.rate_hz:g}" for r in rc.requests)
            how = "REQUEST_DATA_STREAM" if rc.fallback_used else "SET_MESSAGE_INTERVAL"
            if short:
                want = {r.message: r.rate_hz for r in rc.requests}
                said = ", ".join(f"{m} {hz:g} Hz of {want[m]:g} Hz" for m, hz in short.items())
                if self.autopilot_starting(now):
                    self._rates_quiet = True
                    log.info("telemetry below the requested rate (asked with %s) while the "
                             "autopilot starts: %s; a warning if it outlasts the start", how, said)
                else:
                    log.warning("telemetry BELOW the requested rate (asked with %s): %s; the "
                                "estimator may time out. Check the link's bandwidth and its "
                                "stream-rate parameters (ArduPilot SRn_*/MAVn_*)", how, said)
            else:
                log.info("telemetry at the requested rates (Hz: %s; asked with %s)", asked, how)
            return []
        return None

    def _update_rates(self, now: Now) -> list[Output]:
        """Close a rate window (at least RATE_WINDOW_S long); what to send if the telemetry the
        autopilot was asked for has dropped (``rates.RateWatch``)."""
        dt = (now.mono_ns - self._rates_since_ns) / 1e9
        if dt < RATE_WINDOW_S:  # a 1 Hz message needs a window of seconds to show a steady rate
            return []
        self.rates_hz = {k: round(v / dt, 2) for k, v in sorted(self.counts.items())}
        verdict = None
        rc, watch = self.rate_check, self.rate_watch
        if (rc is not None and watch is not None and rc.phase == "done"
                and self._rates_since_ns >= rc.window_end_ns()):  # a window after the check's
            verdict = watch.window(self.counts, self._rates_since_ns, now.mono_ns)
        self.counts.clear()
        self._rates_since_ns = now.mono_ns
        starting = self.autopilot_starting(now)
        want = {} if watch is None else {r.message: r.rate_hz for r in watch.requests}
        slow = ", ".join(f"{m} {hz:g} Hz of {want[m]:g} Hz"
                         for m, hz in ({} if watch is None else watch.short or {}).items())
        if verdict == "recovered":
            self._rates_redrop_ns = None
            log.info("telemetry back at the requested rates%s",
                     "" if self._rates_quiet else ": warning cleared")
            self._rates_quiet = False
        elif verdict == "drop" and self.link.profile is not None:
            self._rates_quiet = starting
            level = logging.INFO if starting else logging.WARNING
            last = self._rates_redrop_ns
            if last is None or now.mono_ns - last >= round(telemetry_rates.REREQUEST_EVERY_S * 1e9):
                self._rates_redrop_ns = now.mono_ns
                log.log(level, "telemetry DROPPED below the requested rate%s: %s; asking again",
                        " while the autopilot starts" if starting else "", slow)
                return self._request_rates(self.link.profile, now)
            log.log(level, "telemetry below the requested rate: %s (asked again less than %g s ago)",
                    slow, telemetry_rates.REREQUEST_EVERY_S)
        return []
