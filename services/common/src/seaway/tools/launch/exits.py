"""What the supervisor makes of a process's exit that it did not cause (``Supervisor.poll``).

A failure (a code other than 0) is restarted after its back-off (``restart = "on-failure"``), at
most ``max_restarts`` times, then counts as failed. A code of 0 is a finish only for a process that
may finish: the profile's ``stop_after`` (a replay, an identification flight) or one without a
health token (a helper). A service, one with a health token, runs until the launcher stops it, so
its exit with 0 unasked (a ``kill`` from outside, a service that returned from its loop) is no
finish: it is handled as a failure. Before, it was written down as ``exited`` and the run went on
without it for ever: a required estimator gone, and in lockstep the whole stack waiting on it.
"""

from __future__ import annotations

from dataclasses import dataclass

from seaway.tools.launch.profile import BackoffPolicy, ProcessSpec

UNASKED = "without being asked to stop (a service runs until the launcher stops it)"
"""Said of a service's exit with code 0 that nobody asked for."""


@dataclass(frozen=True)
class AfterExit:
    """What follows an exit: the process's next ``state`` (``backoff``, ``exited`` or ``failed``),
    the wait before its restart [s] (``backoff`` only) and the line the launcher prints."""

    state: str
    delay_s: float | None
    line: str


def unasked_finish(spec: ProcessSpec, code: int, finishes: frozenset[str]) -> bool:
    """Whether ``code`` 0 of ``spec``'s process is a service's exit nobody asked for (``finishes``:
    the processes that may finish, the profile's ``stop_after``)."""
    return code == 0 and spec.service is not None and spec.name not in finishes


def after_exit(spec: ProcessSpec, code: int, restarts_so_far: int, backoff: BackoffPolicy,
               finishes: frozenset[str]) -> AfterExit:
    """The outcome of an exit with ``code`` while the launcher was not stopping the run."""
    unasked = unasked_finish(spec, code, finishes)
    how = f"exited with code {code}" + (f" {UNASKED}" if unasked else "")
    if not (code != 0 or unasked):
        return AfterExit("exited", None, f"launcher: {spec.name} exited (code {code})")
    if spec.restart == "on-failure" and restarts_so_far < backoff.max_restarts:
        delay_s = backoff.delay_s(restarts_so_far)
        return AfterExit("backoff", delay_s,
                         f"launcher: {spec.name} {how}; restarting in {delay_s:.1f} s (restart "
                         f"{restarts_so_far + 1} of at most {backoff.max_restarts})")
    why = ("not restarted: restart = \"never\"" if spec.restart == "never" else
           f"not restarted again: {backoff.max_restarts} restarts (backoff.max_restarts) used")
    then = ("the run ends" if spec.required else
            "the run goes on without it (the profile does not require it)")
    return AfterExit("failed", None, f"launcher: {spec.name} failed: {how}; {why}; {then}")
