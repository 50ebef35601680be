"""CPU sets (``seaway.runtime.cpus``): the kernel's list format, the split between parallel stacks,
and pinning every thread of a process."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest
from seaway.runtime import cpus

FOUR = frozenset({0, 1, 2, 3})


def test_a_cpu_set_is_written_in_the_kernels_list_format() -> None:
    assert cpus.format_cpus({0, 1, 2, 5}) == "0-2,5"
    assert cpus.format_cpus([3]) == "3"
    assert cpus.format_cpus({7, 0, 1, 3, 4}) == "0-1,3-4,7"
    assert cpus.format_cpus(()) == ""


@pytest.mark.parametrize("text, expected", [
    ("0", {0}), ("0,2", {0, 2}), ("0-3", FOUR), (" 1-2 , 0 ", {0, 1, 2}), ("3,3", {3}),
])
def test_a_cpu_list_is_read(text: str, expected: set[int]) -> None:
    assert cpus.parse_cpus(text, FOUR) == expected
    assert cpus.parse_cpus(cpus.format_cpus(expected), FOUR) == expected  # and written back


@pytest.mark.parametrize("text, says", [
    ("", r"'' is not a CPU number or a range like 0-3 \(allowed here: 0-3\)"),
    ("a", r"'a' is not a CPU number"),
    ("1-", r"'1-' is not a CPU number"),
    ("3-1", r"'3-1' is not a range of CPU numbers from low to high"),
    ("-1", r"'-1' is not a CPU number"),
    ("4", r"CPU 4 cannot be used by this process \(allowed here: 0-3\)"),
    ("0-99999999999", r"CPU 99999999999 cannot be used"),  # refused before a set is made of it
])
def test_a_bad_cpu_list_says_what_is_wrong_and_what_is_allowed(text: str, says: str) -> None:
    with pytest.raises(cpus.CpuSetError, match=says):
        cpus.parse_cpus(text, FOUR)


def test_a_cpu_this_process_may_not_use_is_refused() -> None:
    with pytest.raises(cpus.CpuSetError, match=r"CPU 1 cannot be used .*allowed here: 0,2"):
        cpus.parse_cpus("0-1", frozenset({0, 2}))


def test_cpus_are_split_evenly_between_stacks_in_runs_of_neighbours() -> None:
    assert cpus.partition(frozenset({0, 1}), 2) == [{0}, {1}]
    assert cpus.partition(frozenset(range(5)), 2) == [{0, 1, 2}, {3, 4}]
    assert cpus.partition(frozenset({0, 2, 5, 7}), 3) == [{0, 2}, {5}, {7}]
    assert cpus.partition(FOUR, 1) is None  # one stack: nothing to split
    assert cpus.partition(frozenset({0, 1}), 3) is None  # a CPU would carry two stacks
    for n in range(2, 9):
        groups = cpus.partition(frozenset(range(8)), n)
        assert groups is not None and len(groups) == n
        assert frozenset().union(*groups) == frozenset(range(8))
        assert max(map(len, groups)) - min(map(len, groups)) <= 1


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs to pin to one")
def test_a_lockstep_chain_gets_the_first_cpu_and_the_rest_the_others() -> None:
    assert cpus.split_chain(frozenset({0, 1})) == (frozenset({0}), frozenset({1}))
    assert cpus.split_chain(frozenset({5, 2, 7})) == (frozenset({2}), frozenset({5, 7}))
    assert cpus.split_chain(frozenset({3})) is None  # one CPU: all share it
    assert cpus.split_chain(frozenset()) is None
    from seaway.runtime.lockstep import CHAIN

    assert CHAIN == ("sim", "estimator", "controller")  # the recorder writes beside the chain


def test_pinning_a_process_pins_every_thread_it_has_and_what_it_starts_later() -> None:
    # In a child, so the test process keeps its own affinity. A thread started before the pin is
    # pinned too (the kernel sets one thread at a time); one started after inherits it, and so
    # does a process started after.
    code = textwrap.dedent("""
        import os, subprocess, sys, threading
        from seaway.runtime import cpus
        target = frozenset({max(os.sched_getaffinity(0))})
        seen = {}
        gate = threading.Event()
        def before():
            gate.wait()
            seen["before"] = os.sched_getaffinity(0)
        t = threading.Thread(target=before)
        t.start()
        n = cpus.pin_threads(0, target)
        gate.set()
        t.join()
        after = threading.Thread(target=lambda: seen.update(after=os.sched_getaffinity(0)))
        after.start()
        after.join()
        child = subprocess.run([sys.executable, "-c", "import os; print(sorted(os.sched_getaffinity(0)))"],
                               capture_output=True, text=True, check=True).stdout.strip()
        print(n >= 2, seen["before"] == target, seen["after"] == target,
              os.sched_getaffinity(0) == target, child == str(sorted(target)))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True"] * 5


def test_pinning_a_process_that_is_gone_is_an_error() -> None:
    p = subprocess.Popen(["true"])
    p.wait()
    with pytest.raises(ProcessLookupError):
        cpus.pin_threads(p.pid, frozenset(os.sched_getaffinity(0)))


def test_a_launcher_the_system_will_not_pin_says_so_and_starts_nothing(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    from seaway.tools.launch import main as launch

    def refuse(pid: int, cpu_set: frozenset[int]) -> int:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(cpus, "pin_threads", refuse)
    first = min(os.sched_getaffinity(0))
    code = launch.main(["sim-batch", "--cpus", str(first), "--run-dir", str(tmp_path / "run")])
    assert code == 2
    assert (f"seaway launch: --cpus {first}: this process cannot be kept on those CPUs: "
            "[Errno 1] Operation not permitted") in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
