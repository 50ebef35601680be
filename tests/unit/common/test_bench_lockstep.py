"""``seaway bench lockstep``'s bookkeeping without the stack: the mission delimited by the sim's
marks, composed and through the processes in turn, the ratios to each other and to the MPC solves,
authentication on and off alternating, both out (table and JSON) with their ratio. The real runs are
``seaway bench lockstep`` (and its smoke test, tests/system/launch/test_bench_lockstep.py)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

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
           ("sim", "heard", "recorder"): 1_700_000, ("sim", "work", ""): 1_750_000}


def marks(period_ns: int, n: int = 50) -> lockstep.Marks:
    """Marks of ``n`` periods of ``period_ns`` wall time each (stamps 0.1 s apart): the sim steps
    from each (its ``work``) 1.75 ms after its answer."""
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


def test_the_mission_runs_from_the_sim_s_first_step_to_its_last_answer() -> None:
    m = marks(2_000_000)
    # The sim's answer for t_0 waited 3 s for the mission to be accepted, then it stepped.
    m[("sim", "sent", "")][0] -= 3_000_000_000
    span = lockstep.mission_span(m)
    assert span.simulated_s == pytest.approx(4.9)  # 49 steps of 0.1 s, t_0 to t_49
    assert span.wall_s == pytest.approx(49 * 0.002 - 0.00175)  # not the wait, not t_0's answer
    # Each period after the first step, the sim's answer to its next: 48 of them, none the wait.
    assert lockstep.periods_ms(m) == pytest.approx([2.0] * 48)
    with pytest.raises(ValueError, match="SEAWAY_LOCKSTEP_TRACE"):
        lockstep.mission_span({("sim", "sent", ""): {0: 1}})


def flight(period_ns: int, solve_s: float = 0.001) -> lockstep.Flight:
    return lockstep.Flight(marks(period_ns), [solve_s] * 49)


SETTINGS = {True: "composed", False: "processes"}


def test_lockstep_flies_composed_then_processes_on_then_off(monkeypatch: pytest.MonkeyPatch) -> None:
    order: list[tuple[bool, bool]] = []
    placed: list[frozenset[int] | None] = []
    periods = {(True, True): 400_000, (False, True): 5_000_000, (False, False): 4_000_000}

    def fake_fly(run_dir: Path, composed: bool, auth: bool = True,
                 cpus: frozenset[int] | None = None, scenario: str = "paper-c1") -> lockstep.Flight:
        order.append((composed, auth))
        placed.append(cpus)
        return flight(periods[composed, auth], 0.0001)  # on costs 25 % more than off here

    monkeypatch.setattr(lockstep, "fly", fake_fly)
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    res = lockstep.run(["--repeat", "2"])

    assert order == [(True, True), (False, True), (False, False)] * 2
    # Every stack run placed alike: the chain apart given two CPUs (seaway launch --cpus); the
    # composed run is one process, left to the kernel.
    assert placed == [None, frozenset({0, 1}), frozenset({0, 1})] * 2
    out = res.to_json()
    assert out["meta"]["stack placement"] == "chain on CPU 0, the rest on 1"
    assert sys.executable in out["meta"]["python"]  # the figures depend on the interpreter's build
    fig = out["figures"]
    wall = {k: 49 * p / 1e9 - 0.00175 for k, p in periods.items()}
    assert fig["simulated time [s]"] == pytest.approx(4.9)
    assert fig["composed: wall time [s]"] == pytest.approx(wall[True, True])
    assert fig["composed: real-time factor"] == pytest.approx(4.9 / wall[True, True])
    assert fig["composed: period median [ms]"] == pytest.approx(0.4)
    assert fig["MPC solves"] == 49
    assert fig["MPC solves alone: sum [s]"] == pytest.approx(49 * 0.0001)
    assert fig["MPC solves alone: real-time factor"] == pytest.approx(4.9 / (49 * 0.0001))
    assert fig["MPC solve median [ms]"] == pytest.approx(0.1)
    assert fig["composed / MPC solves alone"] == pytest.approx(wall[True, True] / (49 * 0.0001))
    assert fig["processes: wall time [s]"] == pytest.approx(wall[False, True])
    assert fig["processes: real-time factor"] == pytest.approx(4.9 / wall[False, True])
    assert fig["processes / composed"] == pytest.approx(wall[False, True] / wall[True, True])
    # The targets: composed >= 200x real time (274x here) and <= 2x its solves (3.6x), processes
    # >= 60x (20x).
    assert out["targets"]["composed: real-time factor"] == {"target": ">= 200", "ok": True}
    assert out["targets"]["composed / MPC solves alone"] == {"target": "<= 2", "ok": False}
    assert out["targets"]["processes: real-time factor"] == {"target": ">= 60", "ok": False}
    # Where a period goes, both ways.
    assert fig["composed: controller: solve and publish, median [ms]"] == pytest.approx(0.5)
    assert fig["processes: recorder: write and flush, median [ms]"] == pytest.approx(0.4)
    names = set(lockstep.AUTH_FIGURES)
    for section in ("auth_on", "auth_off", "auth_overhead_ratio"):
        assert set(out[section]) == names
        assert all(math.isfinite(v) and v > 0 for v in out[section].values())
    assert out["auth_on"]["period_median_ms"] == pytest.approx(5.0)
    assert out["auth_off"]["period_median_ms"] == pytest.approx(4.0)
    assert out["auth_overhead_ratio"]["period_median_ms"] == pytest.approx(1.25)
    assert out["targets"]["auth on / off, wall time"] == {"target": "<= 1.1", "ok": False}
    assert not out["passed"]
    assert fig["processes: wall time [s]"] == pytest.approx(out["auth_on"]["wall_time_s"])
    table = res.table()
    assert "auth on / off, period p99" in table and "processes, auth off: wall time [s]" in table


def test_lockstep_without_pinning_leaves_the_stack_to_the_kernel(monkeypatch: pytest.MonkeyPatch
                                                                 ) -> None:
    placed: list[frozenset[int] | None] = []

    def fake_fly(run_dir: Path, composed: bool, auth: bool = True,
                 cpus: frozenset[int] | None = None, scenario: str = "paper-c1") -> lockstep.Flight:
        placed.append(cpus)
        return flight(5_000_000)

    monkeypatch.setattr(lockstep, "fly", fake_fly)
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    assert lockstep.run(["--no-pin"]).to_json()["meta"]["stack placement"] == "the kernel's"
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({3}))  # one CPU: no split
    assert lockstep.run([]).to_json()["meta"]["stack placement"] == "the kernel's"
    assert placed == [None] * 12  # by default two rounds: composed, auth on, auth off


def test_the_ratios_are_medians_of_neighbours(monkeypatch: pytest.MonkeyPatch) -> None:
    # The VM's speed drifts: the third round ran on a slow minute for the composed run and the run
    # with authentication off. In two rounds of three the processes with authentication on cost
    # 20 % more than the run off after them and 3x the composed run before them; the ratio of the
    # settings' medians (4.2 / 5.0 ms) would hide that, the median of the neighbours' ratios does not.
    periods_ns = iter([2_000_000, 6_000_000, 5_000_000, 1_200_000, 3_600_000, 3_000_000,
                       3_000_000, 4_200_000, 6_000_000])
    # Each round: composed (its solves timed with its waits for the GIL), auth on, auth off.
    solves_s = iter([0.003, 0.001, 0.002, 0.003, 0.0005, 0.0005, 0.003, 0.002, 0.001])
    monkeypatch.setattr(lockstep, "fly",
                        lambda *_a, **_k: flight(next(periods_ns), next(solves_s)))
    monkeypatch.setattr(lockstep.cpusets, "allowed", lambda: frozenset({0, 1}))
    res = lockstep.run(["--repeat", "3"])
    out = res.to_json()

    assert out["auth_on"]["period_median_ms"] == pytest.approx(4.2)  # each setting's own median
    assert out["auth_off"]["period_median_ms"] == pytest.approx(5.0)
    for name in ("period_median_ms", "period_p99_ms"):
        assert out["auth_overhead_ratio"][name] == pytest.approx(1.2), name
    assert out["targets"]["auth on / off, wall time"] == {"target": "<= 1.1", "ok": False}
    note = next(f.note for f in res.figures if f.name == "auth on / off, period median")
    assert "median of 3 alternating pairs' ratios (0.700-1.200)" in note
    wall = {p: 49 * p / 1e9 - 0.00175 for p in (2_000_000, 1_200_000, 3_000_000, 6_000_000,
                                                3_600_000, 4_200_000)}
    fig = out["figures"]
    processes_over_composed = sorted([wall[6_000_000] / wall[2_000_000],
                                      wall[3_600_000] / wall[1_200_000],
                                      wall[4_200_000] / wall[3_000_000]])
    assert fig["processes / composed"] == pytest.approx(processes_over_composed[1])
    # Each composed run over the solves of its round's runs through the processes (the median of
    # the two: 0.0735, 0.0245 and 0.0735 s), not its own (0.147 s) nor another round's.
    over = sorted([wall[2_000_000] / 0.0735, wall[1_200_000] / 0.0245, wall[3_000_000] / 0.0735])
    assert fig["composed / MPC solves alone"] == pytest.approx(over[1])
    assert fig["MPC solves alone: sum [s]"] == pytest.approx(0.0735)
    assert fig["composed: its solves, sum [s]"] == pytest.approx(0.147)
