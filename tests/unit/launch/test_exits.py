"""What follows a process's exit the launcher did not cause (``seaway.tools.launch.exits``): a
service's exit with code 0 nobody asked for is handled as a failure (it ran on as ``exited`` for
ever before); a finish (``stop_after``) and a helper's exit with 0 are not."""

from __future__ import annotations

from seaway.tools.launch.exits import after_exit
from seaway.tools.launch.profile import BackoffPolicy, ProcessSpec

BACKOFF = BackoffPolicy(initial_s=0.5, max_restarts=2)


def spec(name: str = "est", service: str | None = "estimator", restart: str = "on-failure"):
    return ProcessSpec(name=name, service=service, command=["x"], restart=restart)


def test_a_service_exiting_0_unasked_is_restarted_then_fails() -> None:
    first = after_exit(spec(), 0, 0, BACKOFF, frozenset())
    assert (first.state, first.delay_s) == ("backoff", 0.5)
    assert "code 0" in first.line and "asked" in first.line
    assert after_exit(spec(), 0, 2, BACKOFF, frozenset()).state == "failed"
    assert after_exit(spec(restart="never"), 0, 0, BACKOFF, frozenset()).state == "failed"


def test_a_finish_and_a_helper_exiting_0_are_exits() -> None:
    assert after_exit(spec("identify", "controller", "never"), 0, 0, BACKOFF,
                      frozenset({"identify"})).state == "exited"
    assert after_exit(spec("replay", None, "never"), 0, 0, BACKOFF, frozenset()).state == "exited"


def test_failures_are_as_before() -> None:
    assert after_exit(spec(), -9, 0, BACKOFF, frozenset()).state == "backoff"
    assert after_exit(spec(), 3, 2, BACKOFF, frozenset()).state == "failed"
    assert after_exit(spec("identify", "controller", "never"), 1, 0, BACKOFF,
                      frozenset({"identify"})).state == "failed"


def test_a_failure_for_good_says_whether_the_run_goes_on() -> None:
    required = after_exit(spec(), 1, 2, BACKOFF, frozenset())
    optional = after_exit(ProcessSpec(name="rec", service="recorder", command=["x"],
                                      required=False), 1, 2, BACKOFF, frozenset())
    assert required.state == optional.state == "failed"
    assert required.line != optional.line and "without" in optional.line
