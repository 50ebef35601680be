"""The vessel does not do what it is told: the estimator's motion fault (``StateEstimate.motion_fault``,
``seaway_estimator.mismatch``) in the controller.

Flying a mission on a vessel that does not follow its thrust (aground, a thruster stuck, held by
friction) only pretends: the estimate dead-reckons along the track, the energy count rises. So an
active mission is paused while the latest estimate carries a motion fault, with the fault named in
``MissionStatus.reason``, the thrust zeroed (a paused mission drifts: no grinding on a shoal, no
spinning on one thruster), and a resume is refused while the fault lasts, saying which. Once the
estimator clears it, the operator may resume (a mission is never resumed by itself).

Pure: the latest estimate in, a reason out.
"""

from __future__ import annotations

from seaway.contract.messages import MOTION_FAULT_TEXT, StateEstimate

from seaway_controller.mission import MissionManager


def motion_fault_reason(state: StateEstimate | None) -> str | None:
    """The estimate's motion fault for a person (its name, what it means, the evidence), or None."""
    if state is None or state.motion_fault is None:
        return None
    detail = f" ({state.motion_fault_detail})" if state.motion_fault_detail else ""
    return f"motion fault {state.motion_fault}: {MOTION_FAULT_TEXT[state.motion_fault]}{detail}"


def pause_on_motion_fault(missions: MissionManager, state: StateEstimate) -> str | None:
    """Pause ``missions``' active mission if ``state`` carries a motion fault: the reason it was
    paused with, or None if nothing changed."""
    why = motion_fault_reason(state)
    if why is None or not missions.hold(f"paused by the controller: {why}; resume once the "
                                        "estimator clears it"):
        return None
    return missions.reason


def resume_refusal(state: StateEstimate | None) -> str | None:
    """Why a paused mission may not be resumed now (a motion fault lasts), or None."""
    why = motion_fault_reason(state)
    return None if why is None else f"cannot resume: {why}; the mission stays paused"
