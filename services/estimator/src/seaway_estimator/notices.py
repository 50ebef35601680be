"""What the estimator's core tells its service to log: gated-out measurements and
re-initialisations (``EstimatorCore.take_notices``). The core stays pure (no logging, no clock);
the service decides the lines and their rate (``seaway_estimator.node``)."""

from __future__ import annotations

from dataclasses import dataclass

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
    run of ``run`` rejections said the model is wrong), ``withheld_reanchor`` (the state moved to
    the first fix after the autopilot was found withholding the thrust: routine, not a warning).
    ``detail`` says by how much."""

    stamp_ns: int
    kind: str
    detail: str
    run: int = 0

    @property
    def persistent(self) -> bool:
        """A run of rejections, or a re-initialisation: worth a warning, not an info line."""
        if self.kind == "withheld_reanchor":
            return False
        return not self.kind.endswith("_rejected") or self.run >= PERSISTENT_REJECT_RUN
