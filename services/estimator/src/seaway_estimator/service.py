"""The estimator process: the bus around ``EstimatorCore``.

Inputs: ``sensors/gnss`` (GnssFix), ``sensors/attitude`` (Attitude), ``ctrl/thrust`` (ThrustCommand),
and in ``--lockstep`` ``sim/clock`` (ClockTick). Outputs: ``nav/state`` (StateEstimate) and
``nav/origin`` (NavOrigin, once fixed, then at ``origin_rate_hz`` for late joiners).

* Realtime (default): every 1/``publish_rate_hz`` of wall time, the inputs that arrived are fed to
  the core in stamp order and the state is predicted to now and published.
* Lockstep: data-driven. On each ClockTick t_k, every sensor message stamped <= t_k is fed in stamp
  order (later ones wait for their tick), the state is predicted to t_k and published stamped
  exactly t_k. Thrust commands are fed as they arrive (the controller's answer to t_k applies from
  t_k). Zenoh does not order messages across keys, so a tick may overtake what it closes: the tick
  waits (at most ``LOCKSTEP_WAIT_S``) for the thrust command answering the previous tick, once a
  controller has been heard, and for any sensor sample its own period says is due. A tick earlier
  than the previous one means the simulation restarted: the core resets.

Re-initialisation: a request on ``seaway/<vessel>/nav/reset`` (``NavResetRequest``) or SIGUSR1
(keeps the origin).
"""

from __future__ import annotations

import bisect
import collections
import logging
import signal
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import ClockTick, NavResetRequest, Reply
from seaway.runtime.clock import RateLoop
from seaway.runtime.run import RunDescription
from seaway.runtime.service import base_parser, parse, resolve_run, run_service
from seaway.simkit.scenario import load_scenario

from seaway_estimator.config import EstimatorConfig, load_estimator_config
from seaway_estimator.core import INPUT_KEYS, EstimatorCore, EstimatorError
from seaway_estimator.replay import TraceWriter

log = logging.getLogger("seaway.estimator")
STATS_PERIOD_S = 10.0
LOCKSTEP_WAIT_S = 0.2  # longest wait for a thrust command or sensor sample a tick lacks


_KIND_ORDER = {kind: i for i, kind in enumerate(INPUT_KEYS)}


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
        self._origin_due = 0.0
        self._last_tick: int | None = None
        self.last_thrust_ns: int | None = None
        self.refused = 0
        self.repeats = 0
        self.thrust_waits_timed_out = 0
        self.thrust_warn_due = 0.0
        self.sensor_waits_timed_out = 0
        # Per sensor: [last stamp, shortest period seen] (ns), to know what a tick still lacks.
        self.schedule: dict[str, list[Any]] = {}

    # -- inputs ----------------------------------------------------------------------------------

    def queue(self, kind: str, msg: Any) -> None:
        sched = self.schedule.get(kind)
        if kind != "thrust" and sched is not None and msg.stamp_ns == sched[0]:
            # The same sample again (a lockstep sim republishes a held period): using it twice
            # would count one measurement as two.
            self.repeats += 1
            return
        if sched is None:
            self.schedule[kind] = [msg.stamp_ns, None]
        elif msg.stamp_ns > sched[0]:
            sched[1] = msg.stamp_ns - sched[0] if sched[1] is None else min(sched[1],
                                                                             msg.stamp_ns - sched[0])
            sched[0] = msg.stamp_ns
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
            else:
                self.core.on_thrust(msg)
                self.last_thrust_ns = max(msg.stamp_ns, self.last_thrust_ns or 0)
        except EstimatorError as err:
            self.refused += 1
            log.warning("refused %s input: %s", kind, err)

    def feed_pending(self, upto_ns: int | None) -> None:
        """Feed queued messages stamped <= ``upto_ns`` (all if None) in stamp order."""
        n = len(self.pending) if upto_ns is None else bisect.bisect_right(
            self.pending, (upto_ns, 99, 1 << 62))
        batch, self.pending = self.pending[:n], self.pending[n:]
        for _, _, _, kind, msg in batch:
            self.feed(kind, msg)

    # -- outputs ---------------------------------------------------------------------------------

    def publish(self, t_ns: int) -> None:
        if self.recorder is not None:
            self.recorder.write("tick", t_ns)
        try:
            est = self.core.predict_to(t_ns)
        except EstimatorError as err:
            log.warning("cannot publish at %d: %s", t_ns, err)
            return
        if est is not None:
            self.pub_state.put(est)
        now = time.monotonic()
        origin = self.core.nav_origin(t_ns)
        if origin is not None and now >= self._origin_due:
            self.pub_origin.put(origin)
            self._origin_due = now + 1.0 / self.core.config.origin_rate_hz

    def reset(self, keep_origin: bool, why: str) -> None:
        with self.lock:
            if self.recorder is not None:
                self.recorder.write("reset", keep_origin)
            self.core.reset(keep_origin=keep_origin)
            self.pending.clear()
            if not keep_origin:
                self._origin_due = 0.0
        log.info("estimator re-initialised (%s, keep_origin=%s)", why, keep_origin)

    def on_reset_request(self, req: NavResetRequest) -> Reply:
        self.reset(req.keep_origin, f"request: {req.reason or 'no reason given'}")
        return Reply.accept(time.time_ns(), "re-initialising from the next measurements",
                            keep_origin=req.keep_origin)

    # -- lockstep --------------------------------------------------------------------------------

    def awaits_thrust(self, tick: ClockTick) -> bool:
        """Whether the command answering the previous tick is still on its way.

        The sim steps from t_k only once it has a command stamped >= t_k, but that command reaches
        us on another path than the sim's next tick, so it can arrive after it. Once a controller
        has been heard, the tick waits for it (bounded by ``LOCKSTEP_WAIT_S``).
        """
        return (self.last_thrust_ns is not None and self._last_tick is not None
                and tick.stamp_ns > self._last_tick and self.last_thrust_ns < self._last_tick)

    def awaits_sensor(self, tick: ClockTick) -> str | None:
        """A sensor whose next sample (by its own period) is due by this tick but not here yet.

        Messages on different keys may arrive in a different order than they were published, so a
        tick can overtake the samples it closes. Samples never sent (a simulated dropout) cost
        one bounded wait each: ``skip_expected`` moves the expectation on.
        """
        for kind, (last, period) in self.schedule.items():
            if period is not None and last + period <= tick.stamp_ns:
                return kind
        return None

    def skip_expected(self, kind: str) -> None:
        last, period = self.schedule[kind]
        self.schedule[kind] = [last + period, period]

    def on_tick(self, tick: ClockTick) -> None:
        t = tick.stamp_ns
        if self._last_tick is not None and t < self._last_tick:
            self.reset(keep_origin=False, why=f"simulation time went back to {t} ns")
        self._last_tick = t
        with self.lock:
            self.feed_pending(t)
            self.publish(t)


def _stats_line(core: EstimatorCore) -> str:
    c = core.counters.values
    keys_ = ("gnss_accepted", "gnss_rejected", "gnss_no_fix", "heading_accepted", "heading_rejected",
             "degraded_entered", "refused_non_finite", "too_old", "resets", "published")
    return ", ".join(f"{k} {c[k]}" for k in keys_)


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
    ap.add_argument("--config", default=None, help="estimator config file (TOML or JSON)")
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
        for kind, spec in INPUT_KEYS.items():
            ctx.bus.subscribe(spec, callback=lambda _k, m, kind=kind: inbox.put(kind, m))
        if lockstep:
            ctx.bus.subscribe(keys.SIM_CLOCK, callback=lambda _k, m: inbox.put("tick", m))
        ctx.bus.queryable(keys.NAV_RESET, loop.on_reset_request)
        ctx.ready()
        signal.signal(signal.SIGUSR1, lambda *_: reset_signal.set())
        log.info("estimator %s, publishing %s, vessel file %s",
                 f"lockstep on {keys.SIM_CLOCK.suffix}" if lockstep else "realtime",
                 "per tick" if lockstep else f"at {cfg.publish_rate_hz:g} Hz", cfg.vessel)
        stats_due = time.monotonic() + STATS_PERIOD_S
        ticks: collections.deque[tuple[ClockTick, float]] = collections.deque()
        rate = None if lockstep else RateLoop(1.0 / cfg.publish_rate_hz, ctx.clock, ctx.stop)
        try:
            while not ctx.stop.is_set():
                if reset_signal.is_set():
                    reset_signal.clear()
                    loop.reset(keep_origin=True, why="SIGUSR1")
                if rate is not None:
                    if not rate.wait():
                        break
                    items = inbox.take(0.0)
                    with loop.lock:
                        for kind, msg in items:
                            loop.queue(kind, msg)
                        loop.feed_pending(None)
                        loop.publish(ctx.clock.now_ns())
                else:
                    for kind, msg in inbox.take(0.01 if ticks else 0.1):
                        if kind == "tick":
                            ticks.append((msg, time.monotonic() + LOCKSTEP_WAIT_S))
                        with loop.lock:
                            if kind == "thrust":
                                loop.feed(kind, msg)
                            elif kind != "tick":
                                loop.queue(kind, msg)
                    while ticks:
                        tick, deadline = ticks[0]
                        late = time.monotonic() >= deadline
                        if loop.awaits_thrust(tick):
                            if not late:
                                break
                            loop.thrust_waits_timed_out += 1
                            if time.monotonic() >= loop.thrust_warn_due:  # one line, not a flood
                                loop.thrust_warn_due = time.monotonic() + STATS_PERIOD_S
                                log.warning("no thrust command for t = %d ns within %.1f s; "
                                            "predicting with the last one (%d times so far)",
                                            loop._last_tick, LOCKSTEP_WAIT_S,
                                            loop.thrust_waits_timed_out)
                        sensor = loop.awaits_sensor(tick)
                        while sensor is not None and late:
                            loop.sensor_waits_timed_out += 1
                            loop.skip_expected(sensor)
                            sensor = loop.awaits_sensor(tick)
                        if sensor is not None:
                            break
                        ticks.popleft()
                        loop.on_tick(tick)
                if time.monotonic() >= stats_due:
                    stats_due += STATS_PERIOD_S
                    log.info("estimator: %s", _stats_line(core))
        finally:
            if recorder is not None:
                recorder.close()
            log.info("estimator final: %s", _stats_line(core))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
