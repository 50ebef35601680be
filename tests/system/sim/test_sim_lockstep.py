"""Lockstep as real processes: the protocol's order, determinism, stale commands, holding, SIGTERM."""

from __future__ import annotations

import itertools
import json
import signal
import sys
import threading

import pytest
from seaway.contract import bundle, keys
from seaway.contract.messages import ClockTick, ThrustCommand
from seaway.runtime.bus import Bus

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system

PERIOD_NS = 100_000_000
VESSEL = "vessel1"


class Recorder:
    """Every sample on seaway/vessel1/** in arrival order: (key suffix, decoded JSON)."""

    def __init__(self, bus: Bus) -> None:
        self.samples: list[tuple[str, dict]] = []
        self._lock = threading.Lock()
        bus.subscribe_raw(f"seaway/{VESSEL}/**", self._on)

    def _on(self, sample) -> None:
        # A lockstep bundle stands for the samples it carries (seaway.contract.bundle), in order.
        parts = (bundle.unpack(sample.key, sample.payload) if sample.encoding == bundle.ENCODING
                 else [(sample.key, sample.payload, sample.encoding)])
        for key, payload, _encoding in parts:
            suffix = key.split("/", 2)[2]
            if suffix.startswith(("health/", "lockstep/")):
                continue
            with self._lock:
                self.samples.append((suffix, json.loads(payload)))

    def of(self, suffix: str) -> list[dict]:
        with self._lock:
            return [d for k, d in self.samples if k == suffix]

    def snapshot(self) -> list[tuple[str, dict]]:
        with self._lock:
            return list(self.samples)


def start_lockstep(procs, env, name: str, *args: str):
    p = procs.start([str(BIN / "seaway-sim"), "--lockstep", *args], env, name)
    wait_for(lambda: "lockstep: period" in procs.log(p), 20, what=f"{name} up")
    return p


def start_responder(procs, env, name: str):
    p = procs.start([sys.executable, "-m", "seaway_lab.responder", "--port-n", "30",
                     "--starboard-n", "20"], env, name)
    wait_for(lambda: "READY" in procs.log(p), 20, what=f"{name} ready")
    return p


def lockstep_run(procs, env, tag: str, periods: int) -> tuple[dict[int, dict], list, float]:
    """Run lake in lockstep against the instant responder until ``periods`` truths were seen."""
    with Bus.open(VESSEL) as bus:
        rec = Recorder(bus)
        sim = start_lockstep(procs, env, f"sim-{tag}", "--scenario", "lake",
                             "--stall-repeat-s", "0.3")
        resp = start_responder(procs, env, f"responder-{tag}")
        wait_for(lambda: len(rec.of("sim/truth")) > periods + 2, 30,
                 what=f"{periods} lockstep periods")
        stop_s = procs.stop(sim, signal.SIGTERM)
        procs.stop(resp, signal.SIGTERM)
        samples = rec.snapshot()
    truths = {d["stamp_ns"]: d for k, d in samples if k == "sim/truth"}
    return truths, samples, stop_s


def test_lockstep_is_deterministic_ordered_and_stops_on_sigterm(procs, zenoh_env):
    n = 120
    a, samples, stop_a = lockstep_run(procs, zenoh_env, "a", n)
    b, _, stop_b = lockstep_run(procs, zenoh_env, "b", n)

    # Two runs of the same scenario: identical truth at every common period, bit for bit.
    # (t_0 may be published before this test's subscriber is matched; from t_1 on nothing is
    # lost, because the sim waits for the responder, which starts after this subscriber.)
    common = sorted(set(a) & set(b))
    upto_n = [t for t in common if 0 < t <= n * PERIOD_NS]
    assert upto_n == [k * PERIOD_NS for k in range(1, n + 1)]
    assert all(a[t] == b[t] for t in common)
    assert a[n * PERIOD_NS]["x_m"] > 1.0  # it did move (30 N / 20 N on paper-boat)

    # The protocol's order for every period: sensors due in (t_{k-1}, t_k], then truth, then
    # disturbance, then the battery at whole seconds (battery.REPORT_HZ), and the clock tick t_k
    # last.
    samples = [(k, d) for k, d in samples if k != "ctrl/thrust"]  # the responder's, not the sim's
    ticks = [i for i, (k, _) in enumerate(samples) if k == "sim/clock"]
    for prev, i in itertools.pairwise(ticks):
        t_k = samples[i][1]["stamp_ns"]
        if t_k == samples[prev][1]["stamp_ns"] or t_k == 0:
            continue  # a tick republished while waiting carries no new outputs
        block = samples[prev + 1:i]
        kinds = [k for k, _ in block]
        if t_k % 1_000_000_000 == 0:
            assert kinds[-1] == "vehicle/battery", (t_k, kinds)
            block, kinds = block[:-1], kinds[:-1]
        assert kinds[-2:] == ["sim/truth", "sim/disturbance"], (t_k, kinds)
        assert all(k in ("sensors/gnss", "sensors/attitude") for k in kinds[:-2])
        assert [d["stamp_ns"] for k, d in block if k == "sensors/attitude"] == [
            t_k - PERIOD_NS // 2, t_k]  # 20 Hz
        gnss = [d["stamp_ns"] for k, d in block if k == "sensors/gnss"]
        assert gnss == ([t_k] if t_k % (2 * PERIOD_NS) == 0 else [])  # 5 Hz, no dropouts in lake
        assert samples[i][1]["lockstep"] is True
        assert all(d["stamp_ns"] == t_k for k, d in block[-2:])
    gnss = [d for k, d in samples if k == "sensors/gnss"]
    assert gnss and all(d["vel_n_mps"] is not None for d in gnss)
    assert stop_a < 2.0 and stop_b < 2.0


def test_lockstep_ignores_stale_commands_and_holds_without_commands(procs, zenoh_env):
    with Bus.open(VESSEL) as bus:
        rec = Recorder(bus)
        pub = bus.publisher(keys.THRUST)
        sim = start_lockstep(procs, zenoh_env, "sim", "--scenario", "paper-c1",
                             "--stall-repeat-s", "0.3")

        def command(stamp_ns: int) -> None:
            pub.put(ThrustCommand(stamp_ns=stamp_ns, thrust_port_n=5.0, thrust_starboard_n=5.0))

        # t_0: nobody answered, so the sim holds and repeats the period every 0.3 s (the safety net
        # for a newcomer whose subscriptions were late).
        wait_for(lambda: len(rec.of("sim/clock")) >= 2, 10, what="the tick republished")
        assert {d["stamp_ns"] for d in rec.of("sim/clock")} == {0}
        # The held period is republished whole (for late joiners): the same samples, same stamps.
        wait_for(lambda: sum(d["stamp_ns"] == 0 for d in rec.of("sensors/gnss")) >= 2, 5,
                 what="the t_0 GNSS sample republished")
        first_fixes = [d for d in rec.of("sensors/gnss") if d["stamp_ns"] == 0]
        assert all(d == first_fixes[0] for d in first_fixes)
        command(0)
        wait_for(lambda: any(d["stamp_ns"] == PERIOD_NS for d in rec.of("sim/truth")), 10,
                 what="the step to t_1")
        command(0)  # stale now: must not step
        wait_for(lambda: sum(d["stamp_ns"] == PERIOD_NS for d in rec.of("sim/clock")) >= 3, 10,
                 what="t_1 held and republished")
        assert max(d["stamp_ns"] for d in rec.of("sim/truth")) == PERIOD_NS
        command(PERIOD_NS)
        wait_for(lambda: any(d["stamp_ns"] == 2 * PERIOD_NS for d in rec.of("sim/truth")), 10,
                 what="the step to t_2")
        held = [ClockTick.model_validate(d) for d in rec.of("sim/clock")]
        assert all(t.lockstep for t in held)
    assert procs.stop(sim, signal.SIGTERM) < 2.0
    log = procs.log(sim)
    assert "repeating t = 0.000 s (stalled" in log and "repeating t = 0.100 s (stalled" in log
