"""When the controller saves its mission checkpoint, how, and how a restarted one resumes it.

The file itself is ``checkpoint.py``'s. ``--state-file PATH`` keeps it: written whenever the
mission's progress changes and once a second of the service's own clock (simulated time in
lockstep, where a wall second can be a hundred periods), read at start, so that a controller
restarted mid-mission (the launcher restarts a crashed one) resumes the same mission at the same
leg, with its energy count and its energy budget's decision (a return home goes on as one), instead
of idling. A checkpoint saved before the run started (an earlier launch into the same run folder,
``seaway launch --run-dir``) is not resumed. Real time writes it durably (fsync) on a thread of its
own (``seaway.runtime.atomic.LatestWriter``: the control loop never waits for the disk), and the
last one before the process ends; lockstep writes it in the answer's turn, not durably.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

from seaway.contract.messages import MAX_REASON_CHARS
from seaway.runtime import atomic
from seaway.runtime.run import from_earlier_launch

from seaway_controller import checkpoint
from seaway_controller.core import ControllerCore
from seaway_controller.core_energy import BudgetDecision

log = logging.getLogger(__name__)

CHECKPOINT_PERIOD_NS = 1_000_000_000
"""An unchanged mission is re-saved this often (for its energy count), on the service's clock:
wall time live, simulated time in lockstep. What a restart can lose is the energy of this long."""
CHECKPOINT_CLOSE_S = 5.0
"""How long a stopping controller waits for its last checkpoint to be written (real time) [s]."""


class Checkpoints:
    """Saves the core's mission progress to ``path`` (None: keeps none)."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self._saved: tuple | None = None  # (mission id, leg, state, decision, hold) last written
        self._saved_at_ns: int | None = None  # when, on the service's clock
        self._writer: atomic.LatestWriter | None = None
        self._request: tuple[object, dict] | None = None  # (request, its JSON dump): made once
        self._home_saved: tuple[float, float] | None = None  # the vessel's home last written

    def durable(self) -> None:
        """Real time: write each checkpoint durably, on a thread of its own (an fsync can take a
        second beside another process's large write, and the control loop must not wait for it).
        Without this (lockstep) each is written at once, not durably (``checkpoint.save`` says
        why)."""
        if self.path is not None and self._writer is None:
            self._writer = atomic.LatestWriter(self.path, self._failed, "checkpoint")

    def save(self, core: ControllerCore, lock: threading.Lock, now_ns: int,
             force: bool = False) -> None:
        """Write the checkpoint if the progress changed, or ``CHECKPOINT_PERIOD_NS`` passed on the
        service's clock at ``now_ns`` (for the energy count; time going back is a new episode:
        saved too). ``lock`` guards ``core``."""
        if self.path is None:
            return
        with lock:
            progress, home = core.progress(), core.home
        if progress is None:
            if home is not None and home != self._home_saved:  # no mission: the home alone
                self._write(checkpoint.MissionCheckpoint(
                    saved_unix_ns=time.time_ns(), home_x_m=home[0], home_y_m=home[1]))
                self._home_saved = home
            return
        req, leg, state, energy = progress
        with lock:
            decision = core.decision()
            hold = core.missions.hold_point
        key = (req.mission_id, leg, state, decision, hold, home)
        last = self._saved_at_ns
        due = last is None or not 0 <= now_ns - last < CHECKPOINT_PERIOD_NS
        if not force and key == self._saved and not due:
            return
        if self._request is None or self._request[0] is not req:  # a request is never changed
            self._request = (req, req.model_dump(mode="json"))
        cp = checkpoint.MissionCheckpoint(
            request=self._request[1], active_leg=leg, state=state,  # type: ignore[arg-type]
            energy_used_j=energy, saved_unix_ns=time.time_ns(), returning=decision.returning,
            decision=decision.decision, decided_ns=decision.decided_ns,
            decision_reason=decision.reason[:MAX_REASON_CHARS],
            hold_x_m=None if hold is None else hold[0], hold_y_m=None if hold is None else hold[1],
            home_x_m=None if home is None else home[0], home_y_m=None if home is None else home[1])
        if not self._write(cp):
            return
        self._saved, self._saved_at_ns, self._home_saved = key, now_ns, home

    def _write(self, cp: checkpoint.MissionCheckpoint) -> bool:
        """Write ``cp`` (on the writer's thread in real time); False if it failed (logged)."""
        assert self.path is not None
        if self._writer is not None:
            self._writer.submit(checkpoint.encode(cp))
            return True
        try:
            checkpoint.save(self.path, cp, durable=False)
        except OSError as err:
            self._failed(err)
            return False
        return True

    def _failed(self, err: OSError) -> None:
        # The vessel keeps being controlled; only a restart would suffer.
        log.error("cannot write the mission checkpoint %s: %s", self.path, err)

    def close(self) -> None:
        """The last checkpoint given, written before the process ends."""
        if self._writer is not None and not self._writer.close(CHECKPOINT_CLOSE_S):
            log.error("the mission checkpoint %s was not written within %g s of the stop",
                      self.path, CHECKPOINT_CLOSE_S)


def resume(core: ControllerCore, path: Path, now_ns: int, run_file: str | Path | None = None
           ) -> None:
    """Take the vessel's home back and resume the checkpointed mission, if there is one in progress,
    when it was saved in this run (not before ``run_file`` was written:
    ``seaway.runtime.run.from_earlier_launch``); never fatal."""
    try:
        cp = checkpoint.load(path)
        if cp is None:
            return
        mission_id = (cp.request or {}).get("mission_id", "?")
        if from_earlier_launch(cp.saved_unix_ns, run_file):
            log.info("checkpoint %s: mission %s was saved before this run started (an earlier "
                     "launch into this folder); starting idle", path, mission_id)
            return
        if cp.home is not None:  # no arming will be heard again: the home is the saved one
            core.home = cp.home
            log.warning("home kept from %s: north %.1f m, east %.1f m", path, *cp.home)
        # A finished mission is taken up again only to go on holding station at its end.
        holding = cp.state == "complete" and cp.hold_point is not None
        if cp.state not in ("waiting", "active", "paused") and not holding:
            if cp.request is not None:
                log.info("checkpoint %s: mission %s was %s; starting idle", path, mission_id,
                         cp.state)
            return
        req = cp.mission_request()
    except checkpoint.CheckpointError as err:
        log.error("ignoring the mission checkpoint: %s", err)
        return
    decision = BudgetDecision(cp.returning, cp.decision, cp.decided_ns, cp.decision_reason)
    reply = core.restore(now_ns, req, cp.active_leg, cp.state, cp.energy_used_j, decision,
                         cp.hold_point)
    if reply.accepted:
        log.warning("resumed mission %r from %s at leg %d (%s), %.1f J used before the restart; "
                    "energy budget: %s%s", req.mission_id, path, cp.active_leg, cp.state,
                    cp.energy_used_j, cp.decision, " (returning home)" if cp.returning else "")
    else:
        log.error("could not resume mission %r from %s: %s", req.mission_id, path, reply.reason)
