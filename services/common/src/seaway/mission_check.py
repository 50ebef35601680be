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
