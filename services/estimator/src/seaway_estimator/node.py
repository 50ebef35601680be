"""The estimator as a node of ``seaway.runtime.node``: the bus-facing half of ``EstimatorCore``.

Inputs: ``sensors/gnss`` (GnssFix), ``sensors/attitude`` (Attitude), ``ctrl/thrust`` (ThrustCommand);
in lockstep they come in the sim's and the controller's bundles (``lockstep/sim``,
``lockstep/controller``: ``seaway.contract.bundle``). Outputs: ``nav/state`` (StateEstimate) and
``nav/origin`` (NavOrigin, once fixed, then at ``origin_rate_hz`` for late joiners), in lockstep in
its own bundle.

* Real time: every 1/``publish_rate_hz`` of wall time (``tick``), the inputs that arrived stamped
  up to now are fed to the core in stamp order (a later one waits for its time) and the state is
  predicted to now and published.
* Lockstep: the estimator answers each period t_k of the sim once the sim's bundle (the samples due
  in (t_{k-1}, t_k]) and the thrust command the sim applied (in the controller's bundle) have
  arrived (``answer``): the queued inputs stamped <= t_k are fed in stamp order, the state is
  predicted to t_k and published stamped exactly t_k. Nothing waits on a timeout. A new episode (the
  sim restarted, or loaded a scenario) re-initialises the core (``restart``); a restarted estimator
  catches up from the sim's repeat of the current period.

In real time ``vehicle/status`` is an input too: while it says the autopilot withholds the thrust
(disarmed, no link, another mode), the core predicts with zero thrust.

Stamps (``seaway.runtime.stamps``): an input stamped further ahead of the service's time than the
bounds allow (a second ahead of the wall clock in real time; two periods ahead of t_k in lockstep),
or in real time older than ``max_gap_s``, is dropped before it reaches the core, counted, and
logged once: a stamp cannot make the core integrate into the future, nor hold an input for a time
that never comes.

Re-initialisation: a request on ``seaway/<vessel>/nav/reset`` (``NavResetRequest``) or SIGUSR1
(keeps the origin; ``request_reset``).
"""

from __future__ import annotations

import bisect
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import NavResetRequest, Reply
from seaway.runtime.node import Answer, MemberSpec, Node, Outputs, Period, PeriodAt
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import StampBounds, StampGate
from seaway.vessel.frames import GeoOrigin

from seaway_estimator.core import INPUT_KEYS, STATUS_KEY, EstimatorCore, EstimatorError
from seaway_estimator.replay import TraceWriter

log = logging.getLogger("seaway.estimator")
STATS_PERIOD_S = 10.0

_KIND_ORDER = {kind: i for i, kind in enumerate([*INPUT_KEYS, "status"])}
_SUFFIX = {**{kind: spec.suffix for kind, spec in INPUT_KEYS.items()}, "status": STATUS_KEY.suffix}
_KIND = {suffix: kind for kind, suffix in _SUFFIX.items()}

MEMBER = MemberSpec("estimator", needs=("sim",),
                    inputs=frozenset(spec.suffix for spec in INPUT_KEYS.values()),
                    hears=("sim", "controller"), passive=("controller",))
"""In lockstep the sensors come in the sim's bundle, which moves the estimator on; the command the
sim applied in the controller's, sent before the sim stepped (taken when the sim's comes)."""


class EstimatorNode(Node):
    """Feeds the core, answers each period or tick, and serves resets (``seaway.runtime.node``)."""

    name = "estimator"
    member = MEMBER
    live_inputs = (*INPUT_KEYS.values(), STATUS_KEY)

    def __init__(self, core: EstimatorCore, recorder: TraceWriter | None = None,
                 keep_origin: Callable[[GeoOrigin], None] | None = None) -> None:
        self.core = core
        self.keep_origin = keep_origin
        """Called with each origin the core takes from a fix (``origin_file.save``), else None."""
        self._kept: GeoOrigin | None = core.origin  # configured or kept already: nothing to keep
        self.lock = threading.Lock()
        self.recorder = recorder
        self.reset_requested = threading.Event()  # SIGUSR1: re-initialise, keeping the origin
        self._stats_due = time.monotonic() + STATS_PERIOD_S
        self.pending: list[tuple[int, int, int, str, Any]] = []  # (stamp, kind order, seq, kind, msg)
        self._seq = 0
        self._origin_due_s = 0.0
        self.refused = 0
        self.repeats = 0
        self.last_stamp: dict[str, int] = {}  # per input kind, the newest stamp queued
        self.commands: dict[int, Any] = {}  # lockstep: commands by stamp, until a period uses one
        # Real time: a second ahead of the wall clock at most; no older than the filter can use.
        bounds = StampBounds.live(core.config.max_gap_s)
        self.stamps = StampGate("estimator", log, bounds)
        self._ahead_ns = bounds.ahead_ns
        self.ratelog = RateLimitedLog(log)

    # -- inputs ----------------------------------------------------------------------------------

    def queue(self, kind: str, msg: Any, lockstep: bool = True, now_ns: int | None = None) -> None:
        """Queue an input for ``feed_pending``; a sample stamped as the last on its key is a repeat.

        ``now_ns`` (real time: the wall clock) bounds the stamp (``seaway.runtime.stamps``): an input
        outside the bounds is dropped here, counted and logged once. In lockstep the member admits
        inputs as they arrive (``Member.admit``) and ``answer`` drops what is left too far ahead.

        A lockstep period repeated for a newcomer carries the same samples again: using one twice
        would count one measurement as two. In lockstep a command is held aside (the latest one per
        stamp) until a period says which one the sim applied (``answer``); live, every command
        counts (a controller may send a zero command with the stamp of its last state).
        """
        if not self.stamps.admit(_SUFFIX[kind], msg.stamp_ns, now_ns):
            return
        if kind == "thrust" and lockstep:
            self.commands[msg.stamp_ns] = msg
            return
        last = self.last_stamp.get(kind)
        if kind != "thrust" and msg.stamp_ns == last:
            self.repeats += 1
            return
        self.last_stamp[kind] = msg.stamp_ns if last is None else max(last, msg.stamp_ns)
        self._seq += 1
        bisect.insort(self.pending, (msg.stamp_ns, _KIND_ORDER[kind], self._seq, kind, msg))

    def feed(self, kind: str, msg: Any) -> None:
        """One core call, recorded; a refused input is logged and counted, never fatal."""
        if self.recorder is not None:
            self.recorder.write(kind, msg)
        try:
            if kind == "gnss":
                self.core.on_gnss(msg)
            elif kind == "attitude":
                self.core.on_attitude(msg)
            elif kind == "status":
                before = self.core.thrust_withheld
                self.core.on_vehicle_status(msg)
                if self.core.thrust_withheld != before:
                    log.info("the autopilot %s: predicting with %s", "applies the commanded thrust"
                             if self.core.thrust_withheld is None else
                             f"withholds the thrust ({self.core.thrust_withheld})",
                             "the commanded thrust" if self.core.thrust_withheld is None
                             else "zero thrust")
            else:
                self.core.on_thrust(msg)
        except EstimatorError as err:
            self.refused += 1
            self.ratelog.warning(("refused", kind), "refused %s input: %s", kind, err)
        self.log_notices()

    def log_notices(self) -> None:
        """Log what the core gated out or re-initialised (``seaway_estimator.notices``): a lone
        rejection at INFO, a run of them and every re-initialisation at WARNING, each kind at most
        once per ``LOG_EVERY_S`` of wall time (the line says how many were held back)."""
        for n in self.core.take_notices():
            level = logging.WARNING if n.persistent else logging.INFO
            run = f" ({n.run} in a row)" if n.run else ""
            self.ratelog.log((n.kind, n.persistent), level, "estimator %s at t = %.3f s: %s%s",
                             n.kind.replace("_", " "), n.stamp_ns / 1e9, n.detail, run)

    def feed_pending(self, upto_ns: int | None) -> None:
        """Feed queued messages stamped <= ``upto_ns`` (all if None) in stamp order."""
        n = len(self.pending) if upto_ns is None else bisect.bisect_right(
            self.pending, (upto_ns, 99, 1 << 62))
        batch, self.pending = self.pending[:n], self.pending[n:]
        for _, _, _, kind, msg in batch:
            self.feed(kind, msg)

    # -- outputs ---------------------------------------------------------------------------------

    def outputs(self, t_ns: int, now_s: float) -> list[tuple[keys.KeySpec, Any]]:
        """The state predicted to ``t_ns`` (once initialised) and, at ``origin_rate_hz`` of
        ``now_s`` (wall seconds live, sim seconds in lockstep), the origin. Lock held."""
        if self.recorder is not None:
            self.recorder.write("tick", t_ns)
        out: list[tuple[keys.KeySpec, Any]] = []
        try:
            est = self.core.predict_to(t_ns)
        except EstimatorError as err:
            self.ratelog.warning("publish", "cannot publish at %d: %s", t_ns, err)
            return out
        self.log_notices()
        if self.keep_origin is not None and self.core.origin is not self._kept:
            self._kept = self.core.origin
            if self._kept is not None:  # taken from a fix: once a run, again after a reset
                self.keep_origin(self._kept)
        if est is not None:
            out.append((keys.NAV_STATE, est))
        origin = self.core.nav_origin(t_ns) if now_s >= self._origin_due_s else None
        if origin is not None:  # the message made only when due: most periods have none
            out.append((keys.NAV_ORIGIN, origin))
            self._origin_due_s = now_s + 1.0 / self.core.config.origin_rate_hz
        return out

    def reset(self, keep_origin: bool, why: str) -> None:
        with self.lock:
            if self.recorder is not None:
                self.recorder.write("reset", keep_origin)
            self.core.reset(keep_origin=keep_origin)
            self.pending.clear()
            if not keep_origin:
                self._origin_due_s = 0.0
        log.info("estimator re-initialised (%s, keep_origin=%s)", why, keep_origin)

    def restart(self, period: Period) -> None:
        """A new lockstep episode at ``period``: a fresh core, as in a freshly started estimator.

        Inputs already queued for the new episode (stamped <= t_k; the old one's are later) stay
        queued.
        """
        t_ns = period.stamp_ns
        with self.lock:
            self.core = EstimatorCore(self.core.config)
            self.pending = [p for p in self.pending if p[0] <= t_ns]
            self.commands.clear()
            self.last_stamp = {}
            for stamp, _, _, kind, _ in self.pending:
                self.last_stamp[kind] = max(stamp, self.last_stamp.get(kind, stamp))
            self._origin_due_s = 0.0
        log.info("new lockstep episode at t = %.3f s: estimator started afresh", t_ns / 1e9)

    def on_reset_request(self, req: NavResetRequest) -> Reply:
        self.reset(req.keep_origin, f"request: {req.reason or 'no reason given'}")
        return Reply.accept(time.time_ns(), "re-initialising from the next measurements",
                            keep_origin=req.keep_origin)

    # -- the node (seaway.runtime.node) ---------------------------------------------------------

    def requests(self) -> dict[keys.KeySpec, Callable[[Any], Reply]]:
        return {keys.NAV_RESET: self.on_reset_request}

    def take(self, key: str, msg: Any, now_ns: int | None) -> None:
        """An input: queued (``queue``); ``now_ns`` the wall clock in real time, None in lockstep."""
        with self.lock:
            self.queue(_KIND[key.split("/", 2)[2]], msg, lockstep=now_ns is None, now_ns=now_ns)

    def answer(self, at: PeriodAt) -> Answer:
        """Answer the lockstep period ``at.period``: the command the sim applied (listed in its
        answer's ``consumed``) and the samples up to t_k fed in stamp order, the state at t_k.

        Any other command held is dropped: an older one was never applied, and one stamped t_k or
        later cannot exist yet in this episode (it is a late one of an earlier episode)."""
        tick = at.answers["sim"]
        applied = tick.consumed.get(keys.THRUST.suffix, [])
        t_ns = at.period.stamp_ns
        with self.lock:
            for stamp in applied:
                cmd = self.commands.get(stamp)
                if cmd is not None:
                    self._seq += 1
                    bisect.insort(self.pending, (stamp, _KIND_ORDER["thrust"], self._seq, "thrust", cmd))
            self.commands.clear()
            self.feed_pending(t_ns)
            # What is left waits for its period, unless no period can come for it this episode soon
            # enough (queued before the member knew its period, e.g. at start): dropped, counted.
            self.pending = [p for p in self.pending if at.admit(_SUFFIX[p[3]], p[0])]
            return Answer(self.outputs(t_ns, t_ns / 1e9))

    def tick(self, now_ns: int, out: Outputs) -> None:
        """Real time: feed what arrived stamped up to now in stamp order, publish the state at now.

        An input stamped after now (up to ``MAX_AHEAD_LIVE_S`` ahead: the stamp gate drops later
        ones) waits for its time, as in lockstep: fed now, it would move the filter ahead of the
        clock, and until the clock caught up every estimate at now and every measurement stamped
        now would be too old (a fix 0.9 s ahead cost 0.4 s of nav/state and 16 measurements)."""
        with self.lock:
            self.drop_ahead(now_ns)
            self.feed_pending(now_ns)
            out.put_all(self.outputs(now_ns, time.monotonic()))

    def drop_ahead(self, now_ns: int) -> None:
        """Real time: drop the queued inputs stamped further ahead of ``now_ns`` than the stamp gate
        admits (counted and logged as it counts them). Each was admitted against the clock of its
        arrival, so only a clock stepped back since (NTP or GPS time) leaves any: left queued, an
        hour-old fix would be fused as a current one once the clock came round to its stamp."""
        limit_ns = now_ns + self._ahead_ns
        if not self.pending or self.pending[-1][0] <= limit_ns:
            return
        n = bisect.bisect_right(self.pending, (limit_ns, 99, 1 << 62))
        ahead, self.pending = self.pending[n:], self.pending[:n]
        for stamp, _, _, kind, _ in ahead:
            self.stamps.admit(_SUFFIX[kind], stamp, now_ns)  # refuses it: counted and logged
        self.last_stamp = {k: v for k, v in self.last_stamp.items() if v <= limit_ns}

    def idle(self) -> None:
        """At each wake of the driver: a SIGUSR1's reset, and the stats line every
        ``STATS_PERIOD_S``."""
        if self.reset_requested.is_set():
            self.reset_requested.clear()
            self.reset(keep_origin=True, why="SIGUSR1")
        if time.monotonic() >= self._stats_due:
            self._stats_due += STATS_PERIOD_S
            log.info("estimator: %s", stats_line(self.core, self))


def stats_line(core: EstimatorCore, loop: EstimatorNode | None = None) -> str:
    """The counters a crew reads in the log every ``STATS_PERIOD_S`` and at exit: what was used,
    gated out, refused, and what the filter did about it (``seaway_estimator.notices``)."""
    c = core.counters.values
    keys_ = ("gnss_accepted", "gnss_rejected", "gnss_no_fix", "heading_accepted", "heading_rejected",
             "sog_rejected", "yaw_rate_rejected", "disturbance_reopened", "motion_faults",
             "thrust_asymmetries",
             "degraded_entered", "refused_non_finite", "gnss_refused", "sog_refused",
             "yaw_rate_refused", "duplicates", "too_frequent", "too_old", "too_new", "resets", "published")
    line = ", ".join(f"{k} {c[k]}" for k in keys_)
    dropped = loop.stamps.summary() if loop is not None else ""
    return line + (f"; stamps dropped: {dropped}" if dropped else "")
