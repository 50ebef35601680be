"""The check before a mission in the API (``POST /missions/check?vessel=V``): the
controller's own check (``seaway.mission_check``, the one it applies on acceptance)
against the vessel's live state as this ground station knows it.

What it takes from the vessel, each only while fresh (not stale): the navigation state (where it
is, the disturbance estimate), the energy budget's battery left and reserve, the origin; the
operating area the controller enforces (``area/active``). With no fresh state it checks at the
desk: the vessel at rest at P_0, calm. The vessel model is the run's (``Settings.model_vessel_file``).
"""

from __future__ import annotations

from typing import Any

from pydantic import Field
from seaway.contract.messages import ActiveArea, EnergyBudget, MissionRequest, StateEstimate
from seaway.mission_check import check_live
from seaway.vessel.model import load_vessel

from seaway_groundstation.bodies import MissionBody
from seaway_groundstation.fleet import Fleet


class MissionCheckBody(MissionBody):
    """A mission to check (nothing is sent): waypoints and parameters as for sending, and the
    options only the check has."""

    battery_j: float | None = Field(default=None, ge=0, le=1e9, description="usable energy in "
                                    "the battery [J]; default the vessel's last energy budget's")


def live_check(req: MissionRequest, fleet: Fleet, vessel: str | None, now_s: float,
               model_vessel_file: str, battery_j: float | None = None) -> dict[str, Any]:
    """The check of ``req`` against ``vessel`` as ``fleet`` knows it at ``now_s`` (module doc)."""
    view = fleet.view(vessel, now_s) if vessel is not None else None
    state = energy = area = None
    if view is not None:
        if view.area is not None:  # the area in force, however long since it was said
            area = view.area.message
        if view.state is not None and not view.state.stale:
            state = view.state.message
        if view.energy is not None and not view.energy.stale:
            energy = view.energy.message
    state = state if isinstance(state, StateEstimate) else None
    energy = energy if isinstance(energy, EnergyBudget) else None
    area = area if isinstance(area, ActiveArea) else None
    out = check_live(
        req, load_vessel(model_vessel_file),
        origin=fleet.geo_origin(vessel) if vessel is not None else fleet.default_origin, state=state,
        energy=energy, area=area, battery_j=battery_j)
    against = "the desk" if vessel is None else f"vessel {vessel}" + ("" if state else " (desk)")
    out.update(vessel=model_vessel_file, against=against,
               area_source=area.source if area is not None else None)
    return out
