"""Replay: recorded inputs give the same outputs, bit for bit; a committed recording still does.

``data/trace_c4.jsonl`` is 15 s of condition #4 with realistic sensor noise, a 20 m GNSS outlier at
5 s, a GNSS outage from 8 s to 11 s and a re-initialisation request at 12 s, as the estimator was fed
it (``seaway_estimator.replay`` format). ``data/trace_c4_expected.json`` holds every 10th output of
that replay (state, disturbance, covariance diagonal, degraded). Regenerate both after an intended
change of the estimator with ``python -m tests.unit.estimator.test_replay``.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from seaway.contract.units import NS_PER_S
from seaway.simkit.scenario import load_scenario
from seaway_estimator.core import EstimatorCore
from seaway_estimator.replay import decode_entry, encode_entry, read_trace, replay, write_trace
from seaway_lab.closed_loop import REALISTIC_NOISE, run_estimator_loop

DATA = Path(__file__).with_name("data")
TRACE = DATA / "trace_c4.jsonl"
EXPECTED = DATA / "trace_c4_expected.json"
S = NS_PER_S


def record() -> tuple[list, list[bytes]]:
    """A fresh recording: the entries fed and the outputs the live run published."""
    def gnss(t, fix):
        if 8 * S <= t < 11 * S:
            return None
        if t == 5 * S:
            return fix.model_copy(update={"lat_rad": fix.lat_rad + 20.0 / 6.37e6})  # ~20 m north
        return fix

    run = run_estimator_loop(load_scenario("paper-c4"), EstimatorCore(), 15.0, REALISTIC_NOISE,
                             gnss_filter=gnss, record_trace=True)
    # The re-initialisation request is part of the recording: split the run's entries at 12 s.
    entries = []
    for kind, value in run.trace:
        if kind == "tick" and value == 12 * S:
            entries.append(("reset", True))
        entries.append((kind, value))
    return entries, [s.est.encode() for s in run.samples]


def summary(outputs: list[bytes]) -> list:
    out = []
    for b in outputs[::10]:
        d = json.loads(b)
        if d is None:
            out.append(None)
            continue
        cov = d["covariance"]
        out.append([d["stamp_ns"], d["u_mps"], d["v_mps"], d["r_radps"], d["x_m"], d["y_m"],
                    d["psi_rad"], d["tau_d_surge_n"], d["tau_d_sway_n"], d["tau_d_yaw_nm"],
                    d["degraded"], [cov[i * 10] for i in range(9)]])
    return out


def test_replaying_a_recording_reproduces_the_live_outputs_exactly() -> None:
    run = run_estimator_loop(load_scenario("paper-c4"), EstimatorCore(), 8.0, REALISTIC_NOISE,
                             record_trace=True)
    live = [s.est.encode() for s in run.samples]
    # Through the JSON-lines form, as a file would carry it.
    entries = [decode_entry(encode_entry(k, v)) for k, v in run.trace]
    replayed = [b for b in replay(entries) if b != b"null"]
    assert replayed == live and len(live) > 100


def test_the_committed_recording_replays_identically_twice_and_matches_its_outputs() -> None:
    entries = list(read_trace(TRACE))
    first, second = replay(entries), replay(entries)
    assert first == second  # bit for bit
    core = EstimatorCore()
    replay(entries, core=core)
    assert core.counters["gnss_rejected"] == 1 and core.counters["resets"] == 1
    assert core.counters["degraded_entered"] >= 1
    assert b"null" in first  # after the reset, until re-initialised
    expected = json.loads(EXPECTED.read_text())
    got = summary(first)
    assert len(got) == len(expected)
    for g, e in zip(got, expected, strict=True):
        if e is None or g is None:
            assert g == e
            continue
        assert g[0] == e[0] and g[10] == e[10]
        # Identical on the machine that recorded it; a different BLAS may differ in the last bits.
        for a, b in zip([*g[1:10], *g[11]], [*e[1:10], *e[11]], strict=True):
            assert math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), (g[0], a, b)


if __name__ == "__main__":
    DATA.mkdir(exist_ok=True)
    trace, _ = record()
    n = write_trace(TRACE, trace)
    EXPECTED.write_text(json.dumps(summary(replay(list(read_trace(TRACE))))) + "\n")
    print(f"wrote {n} entries to {TRACE} ({TRACE.stat().st_size:,} bytes) and {EXPECTED}",
          file=sys.stderr)
