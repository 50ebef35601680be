"""Bench progress (``seaway_lab.bench.progress``): on stderr whether a terminal or not, with an
estimate of the time left; and how ``seaway bench controller`` counts its work for it. Time is a
fake clock here: nothing depends on the machine's speed."""

from __future__ import annotations

import io

import pytest
from seaway_lab.bench.controller import _Work
from seaway_lab.bench.progress import HEARTBEAT_S, Progress, duration_text, eta_s


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_eta_assumes_the_pace_so_far() -> None:
    assert eta_s(0, 10, 5.0) is None  # no pace yet
    assert eta_s(2, 10, 30.0) == pytest.approx(120.0)  # 15 s a unit, 8 left
    assert eta_s(2.5, 10, 10.0) == pytest.approx(30.0)  # parts of a unit count
    assert eta_s(10, 10, 99.0) == 0.0 and eta_s(11, 10, 99.0) == 0.0


def test_durations_read_as_a_person_would_say_them() -> None:
    assert [duration_text(s) for s in (None, 0.4, 42.0, 185.0, 3720.0)] == [
        "?",
        "0 s",
        "42 s",
        "3 min 05 s",
        "1 h 02 min",
    ]


def test_not_on_a_terminal_a_line_per_step_and_a_heartbeat_within_a_long_one() -> None:
    clock, out = Clock(), io.StringIO()
    p = Progress(4, out=out, clock=clock, tty=False)
    clock.t += 1.0
    p.show(0.1, "c1 flying")  # within a step: nothing yet (a log is not a redraw)
    assert out.getvalue() == ""
    clock.t += 59.0
    p.step(1, "c1 done")
    clock.t += HEARTBEAT_S + 1
    p.show(1.5, "c2 flying")  # a long step: one line so the log is not silent
    p.show(1.6, "c2 flying")  # and not another right after
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and "\r" not in out.getvalue()
    assert lines[0].startswith(" 25% ETA 3 min 00 s") and lines[0].endswith("| c1 done")
    assert "1 min 00 s elapsed" in lines[0]
    assert lines[1].startswith(" 38% ETA") and lines[1].endswith("| c2 flying")


def test_on_a_terminal_one_line_rewritten_then_cleared() -> None:
    clock, out = Clock(), io.StringIO()
    p = Progress(2, out=out, clock=clock, tty=True)
    for _ in range(3):
        clock.t += 1.0
        p.show(0.5, "working")
    p.close()
    text = out.getvalue()
    assert text.count("\r") == 4 and "\n" not in text and text.endswith("\r\x1b[K")


def test_disabled_shows_nothing() -> None:
    out = io.StringIO()
    p = Progress(2, enabled=False, out=out, tty=False)
    p.step(1, "x")
    p.close()
    assert out.getvalue() == ""


def test_the_controller_bench_counts_flying_then_ipopt_and_learns_their_shares() -> None:
    clock = Clock()
    work = _Work(repeats=2, clock=clock)
    assert work.flying(0, 0.0) == 0.0
    assert work.flying(1, 0.5) == pytest.approx(0.5 * 0.75)  # a guessed half for flying
    assert work.flying(1, 3.0) == pytest.approx(0.5)  # a run longer than the paper's: clamped
    clock.t += 10.0
    work.flown()
    assert work.solving(5, 10) == pytest.approx(0.75)
    clock.t += 30.0
    work.solved()
    assert work.done == 1.0 and work.fly_share == pytest.approx(0.25)  # 10 s of 40 s
    assert work.flying(2, 0.0) == pytest.approx(1.25)
    assert work.solving(10, 10) == pytest.approx(2.0)
