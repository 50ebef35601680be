"""``seaway bench lockstep``'s bookkeeping without the stack: authentication on and off alternate,
and both come out (table and JSON) with their ratio. The real runs are ``seaway bench lockstep``."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import pytest
from seaway_lab.bench import lockstep

# One period's marks, as offsets [ns] from the sim's answer: each stage's duration is distinct, so a
# stage measured between the wrong marks shows.
OFFSETS = {("sim", "sent", ""): 0, ("estimator", "arrived", "sim"): 60_000,
           ("estimator", "heard", "sim"): 100_000,
           ("estimator", "work", ""): 130_000, ("estimator", "sent", ""): 430_000,
           ("controller", "arrived", "estimator"): 510_000,
           ("controller", "heard", "estimator"): 530_000, ("controller", "work", ""): 570_000,
           ("controller", "sent", ""): 1_070_000, ("sim", "arrived", "controller"): 1_160_000,
           ("sim", "heard", "controller"): 1_170_000,
           ("recorder", "heard", "controller"): 1_250_000, ("recorder", "sent", ""): 1_650_000,
           ("sim", "heard", "recorder"): 1_700_000}


@pytest.fixture(autouse=True)
def no_floor_processes(monkeypatch: pytest.MonkeyPatch) -> None:
    """The floor's hand-over measure starts processes (``seaway bench handover``): a fixed figure."""
    monkeypatch.setattr(lockstep, "three_handovers_ms", lambda: 0.3)


def marks(period_ns: int, n: int = 50) -> dict[tuple[str, str, str], dict[int, int]]:
    """Marks of ``n`` periods of ``period_ns`` wall time each (stamps 0.1 s apart)."""
    out: dict[tuple[str, str, str], dict[int, int]] = {}
    for k in range(n):
        for mark, off in OFFSETS.items():
            out.setdefault(mark, {})[k * 100_000_000] = 10**12 + k * period_ns + off
    return out


def test_breakdown_measures_each_stage_between_its_own_marks() -> None:
    got = {name: {round(x, 9) for x in v} for name, v in lockstep.breakdown(marks(2_000_000)).items()}
    assert got["sim -> estimator: transport"] == {0.06}
    assert got["estimator: intake"] == {0.04}
    assert got["estimator -> controller: transport"] == {0.08}
    assert got["controller: intake"] == {0.02}
    assert got["controller -> sim: transport"] == {0.09}
    assert got["sim: intake of the controller's"] == {0.01}
    assert got["recorder -> sim: until taken"] == {0.05}
    assert got["estimator: wake-up"] == {0.03}
    assert got["estimator: filter and publish"] == {0.3}
    assert got["controller: solve and publish"] == {0.5}
    assert got["controller -> recorder: transport and intake"] == {0.18}
    assert got["recorder: write and flush"] == {0.4}
    # The sim waits for the recorder's answer to the period before (RECORDER_LAG), heard here 0.3 ms
    # before the controller's answer: no wait, and it publishes 0.83 ms after the controller's.
    assert got["sim: waiting for the recorder (its answer to the period before)"] == {0.0}
    assert got["sim: step and publish after the last answer"] == {0.83}
    assert got["period"] == {2.0}
    # 48 periods: the first (start) and the last (hold) are left out.
    assert all(len(v) == 48 for v in lockstep.breakdown(marks(2_000_000)).values())


def test_a_period_some_member_did_not_mark_is_left_out() -> None:
    m = marks(2_000_000)
    del m[("recorder", "sent", "")][10 * 100_000_000]
    assert len(lockstep.breakdown(m)["recorder: write and flush"]) == 47


def test_lockstep_alternates_auth_and_reports_both(monkeypatch: pytest.MonkeyPatch) -> None:
    order: list[bool] = []
    placed: list[frozenset[int] | None] = []

    def fake_run(run_dir: Path, auth: bool = True, cpus: frozenset[int] | None = None
                 ) -> dict[tuple[str, str, str], dict[int, int]]:
        order.append(auth)
        placed.append(cpus)
        return marks(5_000_000 if auth else 4_000_000)  # on costs 25 % more here

    monkeypatch.setattr(lockstep, "through_processes", fake_run)
    monkeypatch.setattr(lockstep, "run_closed_loop",
                        lambda *_a, **_k: SimpleNamespace(steps=49, travel_time_s=4.9))
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    res = lockstep.run(["--repeat", "2"])

    assert order == [True, False, True, False]
    # Every stack run placed alike: the chain apart given two CPUs (seaway launch --cpus).
    assert placed == [frozenset({0, 1})] * 4
    out = res.to_json()
    assert out["meta"]["stack placement"] == "chain on CPU 0, the rest on 1"
    names = set(lockstep.AUTH_FIGURES)
    for section in ("auth_on", "auth_off", "auth_overhead_ratio"):
        assert set(out[section]) == names
        assert all(math.isfinite(v) and v > 0 for v in out[section].values())
    assert out["auth_on"]["period_median_ms"] == pytest.approx(5.0)
    assert out["figures"]["through the processes, warm [s]"] == pytest.approx(48 * 0.005)
    assert out["auth_off"]["period_median_ms"] == pytest.approx(4.0)
    assert out["auth_overhead_ratio"]["wall_time_s"] == pytest.approx(1.25)
    ratio = out["targets"]["auth on / off, wall time"]
    assert ratio == {"target": "<= 1.1", "ok": False}
    assert not out["passed"]
    # The comparison with the in-process loop is the stack as it runs: authentication on.
    assert out["figures"]["through the processes, warm [s]"] == pytest.approx(out["auth_on"]["wall_time_s"])
    table = res.table()
    assert "auth on / off, period p99" in table and "through the processes, auth off [s]" in table


def test_lockstep_without_pinning_leaves_the_stack_to_the_kernel(monkeypatch: pytest.MonkeyPatch
                                                                 ) -> None:
    placed: list[frozenset[int] | None] = []

    def fake_run(run_dir: Path, auth: bool = True, cpus: frozenset[int] | None = None
                 ) -> dict[tuple[str, str, str], dict[int, int]]:
        placed.append(cpus)
        return marks(5_000_000)

    monkeypatch.setattr(lockstep, "through_processes", fake_run)
    monkeypatch.setattr(lockstep, "run_closed_loop",
                        lambda *_a, **_k: SimpleNamespace(steps=49, travel_time_s=4.9))
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    assert lockstep.run(["--no-pin"]).to_json()["meta"]["stack placement"] == "the kernel's"
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({3}))  # one CPU: no split
    assert lockstep.run([]).to_json()["meta"]["stack placement"] == "the kernel's"
    assert placed == [None] * 12  # by default three stack runs with authentication, three without


def test_the_auth_ratio_is_the_median_of_the_alternating_pairs(monkeypatch: pytest.MonkeyPatch
                                                               ) -> None:
    # The VM's speed drifts: the third pair ran on a slow minute with authentication off. Each run
    # with it on costs 20 % more than its neighbour off in two pairs of three; the ratio of the
    # settings' medians (4.2 / 5.0 ms) would hide that, the median of the pairs' ratios does not.
    periods_ns = iter([6_000_000, 5_000_000, 3_600_000, 3_000_000, 4_200_000, 6_000_000])
    monkeypatch.setattr(lockstep, "through_processes", lambda *_a, **_k: marks(next(periods_ns)))
    monkeypatch.setattr(lockstep, "run_closed_loop",
                        lambda *_a, **_k: SimpleNamespace(steps=49, travel_time_s=4.9))
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    res = lockstep.run(["--repeat", "3"])
    out = res.to_json()

    assert out["auth_on"]["period_median_ms"] == pytest.approx(4.2)  # each setting's own median
    assert out["auth_off"]["period_median_ms"] == pytest.approx(5.0)
    for name in lockstep.AUTH_FIGURES:
        assert out["auth_overhead_ratio"][name] == pytest.approx(1.2), name
    assert out["targets"]["auth on / off, wall time"] == {"target": "<= 1.1", "ok": False}
    note = next(f.note for f in res.figures if f.name == "auth on / off, period median")
    assert "median of 3 alternating pairs' ratios (0.700-1.200)" in note


def test_the_floor_is_the_in_process_period_plus_three_handovers(monkeypatch: pytest.MonkeyPatch
                                                                 ) -> None:
    ticks = iter(range(1000))  # each in-process run takes 1 s on this clock
    monkeypatch.setattr(lockstep.time, "perf_counter", lambda: float(next(ticks)))
    monkeypatch.setattr(lockstep, "through_processes", lambda *_a, **_k: marks(5_000_000))
    monkeypatch.setattr(lockstep, "run_closed_loop",
                        lambda *_a, **_k: SimpleNamespace(steps=50, travel_time_s=5.0))
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    res = lockstep.run(["--repeat", "1"])
    fig = res.to_json()["figures"]
    assert fig["in-process loop wall time [s]"] == pytest.approx(1.0)
    assert fig["floor: a period at the least [ms]"] == pytest.approx(20.0 + 0.3)  # 1 s / 50 + 0.3
    assert fig["floor: real-time factor at the least"] == pytest.approx(5.0 / (50 * 0.0203))
    assert fig["floor: ratio to the in process at the least"] == pytest.approx(20.3 / 20.0)
    note = next(f.note for f in res.figures if f.name == "floor: a period at the least [ms]")
    assert "plus three hand-overs at the least, 0.300 ms of CPU" in note
    # --no-floor: no measure, no floor rows.
    monkeypatch.setattr(lockstep, "three_handovers_ms", lambda: pytest.fail("measured"))
    res = lockstep.run(["--repeat", "1", "--no-floor"])
    assert not [f for f in res.figures if f.name.startswith("floor")]
