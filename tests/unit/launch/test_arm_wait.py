"""The launcher's arming request with ``arm_wait_s``: asked again while the autopilot refuses (an EKF
still converging), each new reason said once, and given up with the last reason when the time is up."""

from __future__ import annotations

import threading

import pytest
from seaway.contract.messages import Reply
from seaway.tools.launch import startup_requests as launch


class Autopilot:
    """Answers arming requests from a script of replies (the last one repeats)."""

    def __init__(self, *replies: Reply) -> None:
        self.replies = list(replies)
        self.asked = 0

    def request(self, spec, request, timeout_s: float, vessel: str) -> Reply:
        self.asked += 1
        return self.replies[min(self.asked, len(self.replies)) - 1]


REFUSED_EKF = Reply(stamp_ns=1, accepted=False, reason="FAILED (Arm: Accels inconsistent)")
REFUSED_GYRO = Reply(stamp_ns=1, accepted=False, reason="FAILED (Arm: Gyros inconsistent)")
ACCEPTED = Reply(stamp_ns=1, accepted=True, reason="ACCEPTED")


@pytest.fixture(autouse=True)
def quick_retries(monkeypatch) -> None:
    monkeypatch.setattr(launch, "ARM_RETRY_S", 0.01)


def test_it_asks_again_until_accepted_saying_each_new_reason_once(capsys) -> None:
    ap = Autopilot(REFUSED_EKF, REFUSED_EKF, REFUSED_GYRO, ACCEPTED)
    assert launch._arm(ap, 60.0, threading.Event(), "v1", "", lambda: None)  # type: ignore[arg-type]
    out = capsys.readouterr().out.splitlines()
    assert ap.asked == 4
    assert [line.split(" (")[0] for line in out] == ["arm: not yet", "arm: not yet",
                                                     "arm: accepted after 0 s"]
    assert "Accels inconsistent" in out[0] and "Gyros inconsistent" in out[1]


def test_without_a_wait_one_refusal_fails_the_start(capsys) -> None:
    ap = Autopilot(REFUSED_EKF, ACCEPTED)
    assert not launch._arm(ap, 0.0, threading.Event(), "v1", "", lambda: None)  # type: ignore[arg-type]
    assert ap.asked == 1 and capsys.readouterr().out == "arm: REFUSED: FAILED (Arm: Accels inconsistent)\n"


def test_it_gives_up_with_the_last_reason_when_the_wait_is_over(capsys) -> None:
    ap = Autopilot(REFUSED_GYRO)
    assert not launch._arm(ap, 0.05, threading.Event(), "v1", "b1: ", lambda: None)  # type: ignore[arg-type]
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith("b1: arm: REFUSED: FAILED (Arm: Gyros inconsistent) (asked for ")


def test_a_required_process_failing_meanwhile_ends_the_wait_with_its_reason(capsys) -> None:
    ap = Autopilot(REFUSED_EKF)
    failures = iter([None, "required process(es) failed: sitl\n    no executable ardurover"])
    assert not launch._arm(ap, 60.0, threading.Event(), "v1", "", lambda: next(failures))  # type: ignore[arg-type]
    assert ap.asked == 2 and "failed: sitl" in capsys.readouterr().err


def test_a_stop_while_waiting_is_not_a_failed_start() -> None:
    stop = threading.Event()
    stop.set()
    assert launch._arm(Autopilot(REFUSED_EKF), 60.0, stop, "v1", "", lambda: None)  # type: ignore[arg-type]
