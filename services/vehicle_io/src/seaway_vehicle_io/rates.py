"""Telemetry rates vehicle_io asks the autopilot for, and the start-up check that they arrive.

Why: ArduPilot streams its telemetry at the rates of the link's stream-rate parameters (``SRn_*``,
``MAVn_*`` from 4.7), 1 Hz by default on Rover, and the estimator needs attitude and position
faster than that (its heading timeout is 1 s; the controller runs at 10 Hz). So at every connection
vehicle_io asks for each message it uses with ``MAV_CMD_SET_MESSAGE_INTERVAL`` (511; param1 =
message id, param2 = interval [us]), and then measures what arrives.

Fallback: when the autopilot refuses or ignores the command (no ACCEPTED ACK within
``ACK_TIMEOUT_S``), ``REQUEST_DATA_STREAM`` is sent for the stream groups holding those messages.
ArduPilot maps that message onto the stream-rate parameters of the link it arrives on
(``GCS_MAVLINK::handle_request_data_stream`` sets ``streamRates[...]``), which spares us knowing
which serial port (which ``SRn_``/``MAVn_``) we are on.

Check: from ``SETTLE_S`` after the request (or the fallback) for ``WINDOW_S``, every requested
message is counted; one arriving at less than ``TOLERANCE`` of its requested rate is a shortfall,
reported by name with its measured rate. The whole check ends within about 3 s of connecting
(1 s more when the fallback is needed), inside the 5 s the start-up verdict has.

Watch: the rates can fall later. An autopilot that reboots forgets every interval asked of it and
streams at its defaults again (1 Hz on Rover), and it may reboot fast enough that the link never
drops. So after the check, ``RateWatch`` keeps measuring over the status windows: a shortfall that
stands for ``DROP_CONFIRM_S`` is a drop (the core asks again, at most every ``REREQUEST_EVERY_S``),
and a window with every message at its rate clears the shortfall (the status field and the log say
so). The core also asks again at once when it sees the autopilot reboot (``timesync``).

All pure: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

from seaway_vehicle_io.mav import mavlink

MAV_CMD_SET_MESSAGE_INTERVAL = 511
MAV_RESULT_ACCEPTED = 0

ACK_TIMEOUT_S = 1.0  # no ACCEPTED ACK for every request by then: fall back to stream rates
SETTLE_S = 0.5  # the autopilot's scheduler needs a moment to adopt a new interval
WINDOW_S = 2.5  # a 1 Hz message is counted at least twice whatever its phase
TOLERANCE = 0.8  # a message arriving at >= 80 % of its requested rate is "at the rate"
MAX_RATE_HZ = 50.0
DROP_CONFIRM_S = 4.0  # a shortfall standing this long (two status windows) is a drop, not jitter
REREQUEST_EVERY_S = 10.0  # a drop the last request did not cure is asked again at most this often

TELEMETRY = frozenset({"ATTITUDE", "GLOBAL_POSITION_INT", "GPS_RAW_INT", "LOCAL_POSITION_NED",
                       "SYS_STATUS", "BATTERY_STATUS"})
"""The telemetry messages the core interprets (``core.VehicleIoCore._HANDLERS``): what may be asked for."""

DEFAULT_RATES_HZ = {
    "ATTITUDE": 10.0,  # heading and yaw rate at the control rate (10 Hz); heading timeout 1 s
    "GLOBAL_POSITION_INT": 5.0,  # the GNSS fix the estimator corrects with
    "GPS_RAW_INT": 5.0,  # qualifies each fix (fix type, accuracy): as fast as the fix
    "LOCAL_POSITION_NED": 5.0,
    "SYS_STATUS": 1.0,  # battery
    "BATTERY_STATUS": 1.0,
}


@dataclass(frozen=True)
class RateRequest:
    """One message wanted at ``rate_hz`` [Hz]."""

    message: str
    msg_id: int
    rate_hz: float

    @property
    def interval_us(self) -> float:
        """SET_MESSAGE_INTERVAL's param2 [us]."""
        return 1e6 / self.rate_hz


def message_id(name: str) -> int:
    """MAVLink message name -> id; ValueError naming the message if the dialect has none."""
    msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None)
    if not isinstance(msg_id, int):
        raise ValueError(f"{name!r} is not a MAVLink message")
    return msg_id


def plan(rates_hz: Mapping[str, float],
         handled: frozenset[str] = TELEMETRY) -> tuple[RateRequest, ...]:
    """The requests for ``rates_hz`` (message name -> Hz), in a stable order.

    ``handled``: the messages vehicle_io interprets; asking for anything else would only load the
    link. Raises ValueError naming the message or rate that is wrong and what is allowed.
    """
    out = []
    for name, rate in sorted(rates_hz.items()):
        if name not in handled:
            raise ValueError(f"message_rates_hz: vehicle_io does not use {name!r}; it uses "
                             f"{', '.join(sorted(handled))}")
        if not (math.isfinite(rate) and 0.0 < rate <= MAX_RATE_HZ):
            raise ValueError(f"message_rates_hz[{name!r}] = {rate}: must be in (0, {MAX_RATE_HZ:g}] Hz")
        out.append(RateRequest(name, message_id(name), float(rate)))
    return tuple(out)


def fallback_streams(requests: tuple[RateRequest, ...],
                     stream_of: Mapping[str, int]) -> dict[int, int]:
    """REQUEST_DATA_STREAM stream id -> rate [Hz, whole, rounded up]: the fastest rate wanted of
    any message in that stream group. Messages the profile maps to no stream are left out."""
    streams: dict[int, int] = {}
    for r in requests:
        stream = stream_of.get(r.message)
        if stream is not None:
            streams[stream] = max(streams.get(stream, 0), math.ceil(r.rate_hz))
    return streams


def shortfalls(requests: tuple[RateRequest, ...], counts: Mapping[str, int],
               window_s: float, tolerance: float = TOLERANCE, slack: int = 0) -> dict[str, float]:
    """Message -> measured rate [Hz] for each requested message that arrived below
    ``tolerance`` x its requested rate over ``window_s``; {} when all did. ``slack`` messages
    more may be missing (a window not aligned with a slow message's phase)."""
    short = {}
    for r in requests:
        count = counts.get(r.message, 0)
        if count + slack < tolerance * r.rate_hz * window_s - 1e-9:
            short[r.message] = round(count / window_s, 2)
    return short


Phase = Literal["requesting", "measuring", "done"]


@dataclass
class RateCheck:
    """One connection's rate request and check (a small state machine driven by the core)."""

    requests: tuple[RateRequest, ...]
    sent_mono_ns: int
    phase: Phase = "requesting"
    accepted: int = 0
    refused: list[int] = field(default_factory=list)  # MAV_RESULT of each refusal
    fallback_used: bool = False
    window_start_ns: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    result: dict[str, float] | None = None

    def on_ack(self, result: int) -> None:
        """A COMMAND_ACK for SET_MESSAGE_INTERVAL (ArduPilot answers each in order)."""
        if self.phase != "requesting":
            return
        if result == MAV_RESULT_ACCEPTED:
            self.accepted += 1
        else:
            self.refused.append(result)

    def needs_fallback(self, now_ns: int) -> bool:
        """True once a request was refused, or the ACKs are overdue."""
        if self.phase != "requesting":
            return False
        if self.refused:
            return True
        return now_ns - self.sent_mono_ns >= round(ACK_TIMEOUT_S * 1e9)

    def all_accepted(self) -> bool:
        return self.phase == "requesting" and self.accepted >= len(self.requests)

    def start_measuring(self, now_ns: int, fallback: bool) -> None:
        self.phase = "measuring"
        self.fallback_used = fallback
        self.window_start_ns = now_ns + round(SETTLE_S * 1e9)
        self.counts.clear()

    def window_end_ns(self) -> int:
        return self.window_start_ns + round(WINDOW_S * 1e9)

    def count(self, message: str, now_ns: int) -> None:
        if self.phase == "measuring" and self.window_start_ns <= now_ns < self.window_end_ns():
            self.counts[message] = self.counts.get(message, 0) + 1

    def finish(self) -> dict[str, float]:
        self.phase = "done"
        self.result = shortfalls(self.requests, self.counts, WINDOW_S)
        return self.result

    def next_due_ns(self) -> int | None:
        """When the check next has something to decide (None: finished)."""
        if self.phase == "requesting":
            return self.sent_mono_ns + round(ACK_TIMEOUT_S * 1e9)
        if self.phase == "measuring":
            return self.window_end_ns()
        return None


Verdict = Literal["drop", "recovered"]


@dataclass
class RateWatch:
    """The rates as they keep arriving after a check (pure; time in monotonic nanoseconds).

    ``short`` is the standing shortfall (message -> measured Hz) the status reports: None before
    the first check ends, {} when every message is at its rate."""

    requests: tuple[RateRequest, ...]
    short: dict[str, float] | None = None
    since_ns: int | None = None  # start of the first window of the shortfall now standing

    def checked(self, result: Mapping[str, float]) -> None:
        """A rate check ended with ``result`` (``RateCheck.finish``): that is the standing state."""
        self.short = dict(result)
        self.since_ns = None

    def window(self, counts: Mapping[str, int], start_ns: int, end_ns: int) -> Verdict | None:
        """Messages counted over [start_ns, end_ns): "drop" once a shortfall has stood for
        ``DROP_CONFIRM_S`` (then it is the standing one, and the confirmation starts over),
        "recovered" when a standing shortfall is gone, else None."""
        window_s = (end_ns - start_ns) / 1e9
        if window_s <= 0:
            return None
        short = shortfalls(self.requests, counts, window_s, slack=1)
        if not short:
            self.since_ns = None
            if self.short:
                self.short = {}
                return "recovered"
            return None
        if self.since_ns is None:
            self.since_ns = start_ns
        if end_ns - self.since_ns >= round(DROP_CONFIRM_S * 1e9):
            self.short = short
            self.since_ns = None
            return "drop"
        return None
