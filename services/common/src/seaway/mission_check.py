"""The check before a mission, for the callers outside the controller: ``seaway mission check``,
``seaway launch --check`` and the ground station's API.

The check itself is the controller's (``seaway_controller.mission_check``): the controller applies
it on acceptance, and its energy figures are the energy budget's own model. One package does not
import another service's (``tests/contract/test_keys.py``), so this finds it through the entry
point group ``seaway.mission_check`` that ``seaway-controller`` registers (as ``seaway bench``
finds the lab's benchmarks). Its result is a ``MissionCheck``; ``to_dict()`` is the ``--json``
form, ``{"verdict": "ok"|"refused", "reasons": [...], ...}``.
"""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any

GROUP = "seaway.mission_check"
NAME = "check_mission"


class MissionCheckUnavailableError(RuntimeError):
    """The controller's package (which holds the check) is not installed here."""


def check_mission(*args: Any, **kwargs: Any) -> Any:
    """``seaway_controller.mission_check.check_mission(req, vessel, ...)``, found through the
    entry point; MissionCheckUnavailableError if seaway-controller is not installed."""
    found = [ep for ep in entry_points(group=GROUP) if ep.name == NAME]
    if not found:
        raise MissionCheckUnavailableError(
            f"the mission check comes with the seaway-controller package (entry point group "
            f"{GROUP!r}), which is not installed here")
    return found[0].load()(*args, **kwargs)


def check_live(req: Any, vessel: Any, *, origin: Any, state: Any = None, energy: Any = None,
               area: Any = None, battery_j: float | None = None) -> dict[str, Any]:
    """The check of ``req`` against what a running vessel says, as ``--json`` prints it: its
    navigation state (``StateEstimate``: where it is, the disturbance estimate), its energy
    budget (``EnergyBudget``: the battery left unless ``battery_j`` is given, the reserve, home),
    the operating area the controller enforces (``ActiveArea``) and the origin (``GeoOrigin``).
    Each may be None (not heard, or stale): the check then takes the desk's default for it."""
    if battery_j is None and energy is not None:
        battery_j = energy.battery_remaining_j
    return check_mission(
        req, vessel, origin=origin, state=state, battery_j=battery_j,
        reserve_j=energy.reserve_j if energy is not None else None,
        area=area.to_area() if area is not None else None,
        home=(energy.home_x_m, energy.home_y_m) if energy is not None else None).to_dict()
