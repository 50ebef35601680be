"""The estimator process: the bus around ``EstimatorCore``.

Inputs: ``sensors/gnss`` (GnssFix), ``sensors/attitude`` (Attitude), ``ctrl/thrust`` (ThrustCommand);
in lockstep they come in the sim's and the controller's bundles (``lockstep/sim``,
``lockstep/controller``: ``seaway.contract.bundle``). Outputs: ``nav/state`` (StateEstimate) and
``nav/origin`` (NavOrigin, once fixed, then at ``origin_rate_hz`` for late joiners), in lockstep in
its own bundle.

* Realtime (default): every 1/``publish_rate_hz`` of wall time, the inputs that arrived are fed to
  the core in stamp order and the state is predicted to now and published.
* Lockstep (``seaway.runtime.lockstep``): the estimator answers each period t_k of the sim once the
  sim's bundle (the samples due in (t_{k-1}, t_k]) and the thrust command the sim applied (in the
  controller's bundle) have arrived: the queued inputs stamped <= t_k are fed in stamp order, the
  state is predicted to t_k and published stamped exactly t_k, then the answer lists it. Nothing
  waits on a timeout. A new episode (the sim restarted, or loaded a scenario) re-initialises the
  core; a restarted estimator catches up from the sim's repeat of the current period.

In real time ``vehicle/status`` is an input too: while it says the autopilot withholds the thrust
(disarmed, no link, another mode), the core predicts with zero thrust.

Stamps (``seaway.runtime.stamps``): an input stamped further ahead of the service's time than the
bounds allow (a second ahead of the wall clock in real time; two periods ahead of t_k in lockstep),
or in real time older than ``max_gap_s``, is dropped before it reaches the core, counted, and
logged once: a stamp cannot make the core integrate into the future, nor hold an input for a time
that never comes.

Re-initialisation: a request on ``seaway/<vessel>/nav/reset`` (``NavResetRequest``) or SIGUSR1
(keeps the origin).
"""

from __future__ import annotations

import bisect
import logging
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import NavResetRequest, Reply
from seaway.runtime.clock import RateLoop
from seaway.runtime.lockstep import Member, Period
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.run import RunDescription
from seaway.runtime.service import base_parser, on_signals, parse, resolve_run, run_service
from seaway.runtime.stamps import StampBounds, StampGate
from seaway.simkit.scenario import load_scenario

from seaway_estimator.config import EstimatorConfig, load_estimator_config
from seaway_estimator.core import INPUT_KEYS, STATUS_KEY, EstimatorCore, EstimatorError
from seaway_estimator.replay import TraceWriter

log = logging.getLogger("seaway.estimator")
STATS_PERIOD_S = 10.0


_KIND_ORDER = {kind: i for i, kind in enumerate([*INPUT_KEYS, "status"])}
_SUFFIX = {**{kind: spec.suffix for kind, spec in INPUT_KEYS.items()}, "status": STATUS_KEY.suffix}


class Inbox:
    """Messages from Zenoh's threads, in arrival order, for the main loop."""

    def __init__(self) -> None:
        self._items: list[tuple[str, Any]] = []
        self._cond = threading.Condition()

    def put(self, kind: str, msg: Any) -> None:
        with self._cond:
            self._items.append((kind, msg))
            self._cond.notify_all()

    def take(self, timeout_s: float) -> list[tuple[str, Any]]:
        with self._cond:
            if not self._items:
                self._cond.wait(timeout_s)
            out, self._items = self._items, []
            return out


class EstimatorLoop:
    """Feeds the core, publishes, and serves resets; the bus-facing half of the service."""

    def __init__(self, core: EstimatorCore, bus: Any, recorder: TraceWriter | None = None) -> None:
        self.core = core
        self.bus = bus
        self.lock = threading.Lock()
        self.recorder = recorder
        self.pub_state = bus.publisher(keys.NAV_STATE)
        self.pub_origin = bus.publisher(keys.NAV_ORIGIN)
        self.pending: list[tuple[int, int, int, str, Any]] = []  # (stamp, kind order, seq, kind, msg)
        self._seq = 0
        self._origin_due_s = 0.0
        self.last_thrust_ns: int | None = None
        self.refused = 0
        self.repeats = 0
        self.last_stamp: dict[str, int] = {}  # per input kind, the newest stamp queued
        self.commands: dict[int, Any] = {}  # lockstep: commands by stamp, until a period uses one
        # Real time: a second ahead of the wall clock at most; no older than the filter can use.
        self.stamps = StampGate("estimator", log, StampBounds.live(core.config.max_gap_s))
        self.ratelog = RateLimitedLog(log)

    # -- inputs ----------------------------------------------------------------------------------

    def queue(self, kind: str, msg: Any, lockstep: bool = True, now_ns: int | None = None) -> None:
        """Queue an input for ``feed_pending``; a sample stamped as the last on its key is a repeat.

        ``now_ns`` (real time: the wall clock) bounds the stamp (``seaway.runtime.stamps``): an input
        outside the bounds is dropped here, counted and logged once. In lockstep the member admits
        inputs as they arrive (``Member.admit``) and ``on_period`` drops what is left too far ahead.

        A lockstep period repeated for a newcomer carries the same samples again: using one twice
        would count one measurement as two. In lockstep a command is held aside (the latest one per
        stamp) until a period says which one the sim applied (``on_period``); live, every command
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
                self.last_thrust_ns = max(msg.stamp_ns, self.last_thrust_ns or 0)
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
        if est is not None:
            out.append((keys.NAV_STATE, est))
        origin = self.core.nav_origin(t_ns)
        if origin is not None and now_s >= self._origin_due_s:
            out.append((keys.NAV_ORIGIN, origin))
            self._origin_due_s = now_s + 1.0 / self.core.config.origin_rate_hz
        return out

    def publish(self, t_ns: int, now_s: float) -> None:
        pubs = {keys.NAV_STATE: self.pub_state, keys.NAV_ORIGIN: self.pub_origin}
        for spec, msg in self.outputs(t_ns, now_s):
            pubs[spec].put(msg)

    def reset(self, keep_origin: bool, why: str) -> None:
        with self.lock:
            if self.recorder is not None:
                self.recorder.write("reset", keep_origin)
            self.core.reset(keep_origin=keep_origin)
            self.pending.clear()
            if not keep_origin:
                self._origin_due_s = 0.0
        log.info("estimator re-initialised (%s, keep_origin=%s)", why, keep_origin)

    def restart(self, t_ns: int) -> None:
        """A new lockstep episode at ``t_ns``: a fresh core, as in a freshly started estimator.

        Inputs already queued for the new episode (stamped <= ``t_ns``; the old one's are later)
        stay queued.
        """
        with self.lock:
            self.core = EstimatorCore(self.core.config)
            self.pending = [p for p in self.pending if p[0] <= t_ns]
            self.commands.clear()
            self.last_stamp = {}
            for stamp, _, _, kind, _ in self.pending:
                self.last_stamp[kind] = max(stamp, self.last_stamp.get(kind, stamp))
            self._origin_due_s = 0.0
            self.last_thrust_ns = None
        log.info("new lockstep episode at t = %.3f s: estimator started afresh", t_ns / 1e9)

    def on_reset_request(self, req: NavResetRequest) -> Reply:
        self.reset(req.keep_origin, f"request: {req.reason or 'no reason given'}")
        return Reply.accept(time.time_ns(), "re-initialising from the next measurements",
                            keep_origin=req.keep_origin)

    # -- lockstep --------------------------------------------------------------------------------

    def on_period(self, member: Member, period: Period, period_ns: int,
                  applied: Sequence[int] = ()) -> None:
        """Answer the lockstep period ``period``: the command the sim applied (its stamps in
        ``applied``) and the samples up to t_k fed in stamp order, the state at t_k published.

        Any other command held is dropped: an older one was never applied, and one stamped t_k or
        later cannot exist yet in this episode (it is a late one of an earlier episode)."""
        member.working(period)
        with self.lock:
            for stamp in applied:
                cmd = self.commands.get(stamp)
                if cmd is not None:
                    self._seq += 1
                    bisect.insort(self.pending, (stamp, _KIND_ORDER["thrust"], self._seq, "thrust", cmd))
            self.commands.clear()
            self.feed_pending(period.stamp_ns)
            # What is left waits for its period, unless no period can come for it this episode soon
            # enough (queued before the member knew its period, e.g. at start): dropped, counted.
            self.pending = [p for p in self.pending
                            if member.admit(_SUFFIX[p[3]], p[0], period.stamp_ns, period_ns)]
            out = self.outputs(period.stamp_ns, period.stamp_ns / 1e9)
        member.answer(period, period_ns, out)


def run_lockstep(loop: EstimatorLoop, bus: Any, inbox: Inbox, stop: threading.Event,
                 reset_signal: threading.Event, ready: Callable[[], None]) -> None:
    """The lockstep loop (``seaway.runtime.lockstep``): answer each period of the sim once complete.

    ``ready`` is called once the subscriptions are in place (it declares the health token, which
    makes the sim repeat its period for this newcomer)."""
    kinds = {spec.suffix: kind for kind, spec in INPUT_KEYS.items()}

    def on_input(key: str, msg: Any) -> None:
        suffix = key.split("/", 2)[2]
        if not member.admit(suffix, msg.stamp_ns):
            return  # stamped beyond any period to come soon: counted and logged by the member
        inbox.put(kinds[suffix], msg)  # first: what the ledger has seen is in the inbox
        member.saw(suffix, msg.stamp_ns)

    # The sensors come in the sim's bundle, which moves the estimator on; the command the sim
    # applied in the controller's, sent before the sim stepped (taken when the sim's comes).
    member = Member(bus, "estimator", watched=kinds, hears=("sim", "controller"),
                    passive=("controller",))
    member.deliver = on_input  # once ``member`` names it (on_input uses it)
    member.stamps = loop.stamps  # one count of dropped stamps (the stats line's), lockstep bounds
    restarts: list[Period] = []
    member.on_restart = lambda _before, now: restarts.append(now)
    answered: list[Period | None] = [None]
    step_lock = threading.Lock()

    def step() -> None:
        """Answer the current period if all it needs is in: on the bus's thread as the sim's bundle
        is taken (``Member.on_ready``), or from the loop (a passive bundle that came late, a reset)."""
        with step_lock:
            with member.changed:
                period = member.ledger.period
                tick = member.ledger.answer("sim")
                ready = member.ledger.complete(tick) and period != answered[0]
                restart = restarts[-1] if restarts else None
                restarts.clear()
            # After the ledger: everything it counted as seen is in the inbox by now.
            items = inbox.take(0.0)
            if restart is not None:
                loop.restart(restart.stamp_ns)
                answered[0] = None
            with loop.lock:
                for kind, msg in items:
                    loop.queue(kind, msg)
            if ready and tick is not None and period is not None:
                loop.on_period(member, period, tick.period_ns,
                               tick.consumed.get(keys.THRUST.suffix, []))
                answered[0] = period

    member.on_ready = step
    ready()
    member.join()
    version = 0
    stats_due = time.monotonic() + STATS_PERIOD_S
    while not stop.is_set():
        version = member.wait(version, 0.1)
        if reset_signal.is_set():
            reset_signal.clear()
            loop.reset(keep_origin=True, why="SIGUSR1")
        step()
        if time.monotonic() >= stats_due:
            stats_due += STATS_PERIOD_S
            log.info("estimator: %s", _stats_line(loop.core, loop))


def run_realtime(loop: EstimatorLoop, inbox: Inbox, ctx: Any, rate_hz: float,
                 reset_signal: threading.Event) -> None:
    """Real time: every 1/``rate_hz`` of wall time, feed what arrived in stamp order, publish now."""
    rate = RateLoop(1.0 / rate_hz, ctx.clock, ctx.stop)
    stats_due = time.monotonic() + STATS_PERIOD_S
    while rate.wait():
        if reset_signal.is_set():
            reset_signal.clear()
            loop.reset(keep_origin=True, why="SIGUSR1")
        items = inbox.take(0.0)
        now_ns = ctx.clock.now_ns()
        with loop.lock:
            for kind, msg in items:
                loop.queue(kind, msg, lockstep=False, now_ns=now_ns)
            loop.feed_pending(None)
            loop.publish(now_ns, time.monotonic())
        if time.monotonic() >= stats_due:
            stats_due += STATS_PERIOD_S
            log.info("estimator: %s", _stats_line(loop.core, loop))


def _stats_line(core: EstimatorCore, loop: EstimatorLoop | None = None) -> str:
    c = core.counters.values
    keys_ = ("gnss_accepted", "gnss_rejected", "gnss_no_fix", "heading_accepted", "heading_rejected",
             "degraded_entered", "refused_non_finite", "too_old", "too_new", "resets", "published")
    line = ", ".join(f"{k} {c[k]}" for k in keys_)
    dropped = loop.stamps.summary() if loop is not None else ""
    return line + (f"; stamps dropped: {dropped}" if dropped else "")


RUN_WIDE_CONFIG = ("vessel", "apply_dead_zone", "origin")  # what the run says, not the config file


def with_run(cfg: EstimatorConfig, run: RunDescription) -> EstimatorConfig:
    """The config with the run's model vessel, dead zone and NED origin.

    Those are run-wide facts (the controller and simulator must agree on them): a config file that
    sets them is refused, naming the fields, rather than silently overridden.
    """
    clash = sorted(set(RUN_WIDE_CONFIG) & cfg.model_fields_set)
    if clash:
        raise ConfigError(f"estimator config sets {', '.join(clash)}: these come from the run "
                          "(--run, or --vessel-file/--origin/--dead-zone/--scenario)")
    return cfg.model_copy(update={"vessel": run.model_vessel_file, "apply_dead_zone": run.dead_zone,
                                  "origin": run.origin})


def main(argv: Sequence[str] | None = None) -> int:
    ap = base_parser("estimator", f"EKF state and disturbance estimator: {keys.GNSS.suffix}, "
                                  f"{keys.ATTITUDE.suffix} -> {keys.NAV_STATE.suffix}")
    ap.add_argument("--config", default=None, help="estimator config file (TOML or JSON), or the "
                    "name of one in services/estimator/config (e.g. px4-sitl)")
    ap.add_argument("--record-inputs", default=None, metavar="FILE",
                    help="write every core call as JSON lines, for python -m seaway_estimator.replay")
    args = parse(ap, argv)
    run = resolve_run(args, "estimator", load_scenario)
    try:
        cfg = with_run(load_estimator_config(args.config), run)
    except ConfigError as err:
        print(f"seaway-estimator: {err}", file=sys.stderr)
        return 2
    lockstep = run.lockstep
    core = EstimatorCore(cfg)
    recorder = TraceWriter(args.record_inputs) if args.record_inputs else None
    reset_signal = threading.Event()
    with run_service("estimator", args, run=run) as ctx:
        loop = EstimatorLoop(core, ctx.bus, recorder)
        inbox = Inbox()
        ctx.bus.queryable(keys.NAV_RESET, loop.on_reset_request)
        on_signals((signal.SIGUSR1,), lambda _signum: reset_signal.set())
        log.info("estimator %s, vessel file %s", "lockstep" if lockstep
                 else f"realtime, publishing at {cfg.publish_rate_hz:g} Hz", cfg.vessel)
        try:
            if lockstep:
                run_lockstep(loop, ctx.bus, inbox, ctx.stop, reset_signal, ready=ctx.ready)
            else:
                for kind, spec in [*INPUT_KEYS.items(), ("status", STATUS_KEY)]:
                    ctx.bus.subscribe(spec, callback=lambda _k, m, kind=kind: inbox.put(kind, m))
                ctx.ready()
                run_realtime(loop, inbox, ctx, cfg.publish_rate_hz, reset_signal)
        finally:
            if recorder is not None:
                recorder.close()
            log.info("estimator final: %s", _stats_line(loop.core, loop))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
