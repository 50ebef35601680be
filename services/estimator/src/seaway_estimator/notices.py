"""What the estimator's core tells its service to log: gated-out measurements and
re-initialisations (``EstimatorCore.take_notices``), and what it counts (``Counters``). The core
stays pure (no logging, no clock); the service decides the lines and their rate
(``seaway_estimator.node``)."""

from __future__ import annotations

from dataclasses import dataclass, field

PERSISTENT_REJECT_RUN = 5
"""Rejections in a row of one sensor from which its notices say ``persistent`` (a second of GNSS at
5 Hz): one outlier is noise, a run means the sensor and the filter disagree."""
MAX_NOTICES = 256
"""Notices kept until taken; older ones are dropped (a caller that never takes them, such as an
in-process study, must not grow the core)."""


@dataclass(frozen=True)
class Notice:
    """Something worth a log line: a measurement gated out, or the state (partly) re-initialised.

    ``kind``: ``gnss_rejected``, ``heading_rejected`` (``run``: rejections in a row so far),
    ``gnss_reinit``, ``heading_reinit`` (the state taken from the sensor after ``run`` rejections),
    ``time_jump``, ``divergence_reset`` (the whole state dropped), ``disturbance_reopened`` (a
    run of ``run`` rejections said the model is wrong: routine, the filter taking up what its model
    lacks; a boat that does not do as commanded is the motion fault's to say),
    ``withheld_reanchor`` (the state moved to the first fix after the autopilot was found
    withholding the thrust: routine),
    ``gnss_refused``, ``sog_refused``, ``yaw_rate_refused`` (what a message said is past what a
    receiver or the vessel can give, ``seaway_estimator.core_inputs``: the value and the bound),
    ``too_frequent`` (a sample closer to the last one used than its sensor's fastest rate allows),
    ``thrust_asymmetry`` (a thruster short of its command, ``seaway_estimator.asymmetry``) and
    ``thrust_asymmetry_cleared`` (routine).
    ``detail`` says by how much. ``routine``: expected in a normal run, an info line whatever the
    kind."""

    stamp_ns: int
    kind: str
    detail: str
    run: int = 0
    routine: bool = False

    @property
    def persistent(self) -> bool:
        """A run of rejections, or a re-initialisation that is not routine: worth a warning, not
        an info line."""
        if self.routine:
            return False
        return not self.kind.endswith("_rejected") or self.run >= PERSISTENT_REJECT_RUN


COUNTERS = (
    "gnss_accepted", "gnss_rejected", "gnss_no_fix", "gnss_reinit",
    "sog_accepted", "sog_rejected",
    "heading_accepted", "heading_rejected", "heading_reinit",
    "yaw_rate_accepted", "yaw_rate_rejected",
    "thrust_received", "late_applied", "too_old", "too_new", "refused_non_finite",
    "gnss_refused", "sog_refused", "yaw_rate_refused", "duplicates", "too_frequent",
    "status_received",
    "degraded_entered", "time_jumps", "divergence_resets", "disturbance_reopened", "resets",
    "motion_faults", "motion_anchored", "withheld_anchored", "thrust_asymmetries",
    "published",
    "publish_refused",
)


@dataclass
class Counters:
    """How often each of ``COUNTERS`` happened since the core was made (the service's stats line)."""

    values: dict[str, int] = field(default_factory=lambda: dict.fromkeys(COUNTERS, 0))

    def inc(self, name: str, n: int = 1) -> None:
        self.values[name] += n

    def __getitem__(self, name: str) -> int:
        return self.values[name]
