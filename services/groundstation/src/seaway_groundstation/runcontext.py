"""What the replay view needs of a recording beside its frames: the missions flown (in local metres)
and the run's report (``recordings.Library`` opens a recording with them)."""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from seaway.contract.messages import MessageError, MissionAccepted, MissionRequest
from seaway.vessel.frames import GeoOrigin

from seaway_groundstation import geo, journal

MAX_REPORT_BYTES = 256 << 10
"""A run's report/metrics.json shown at most [bytes]."""


def scenario(attachments: Mapping[str, bytes], notes: list[str]) -> tuple[str | None, GeoOrigin | None]:
    from seaway.recording import runinfo

    try:
        sc = runinfo.scenario_from_attachments(attachments)
    except Exception as err:  # a damaged attachment only costs the scenario's origin
        notes.append(f"the scenario attachment does not read: {err}")
        return None, None
    return (None, None) if sc is None else (sc.name, runinfo.scenario_origin(sc))


def _journal_folders(run_folder: Path, vessels: Iterable[str]) -> list[Path]:
    """Where the ground station's journal of a recording's run may be: its own folder, and for a
    fleet's vessel (``<run>/<vessel>/``, the launcher's layout) the run folder above, where the
    fleet's one ground station keeps it."""
    folders = [run_folder]
    if run_folder.name in set(vessels) and run_folder.parent != run_folder:
        folders.append(run_folder.parent)
    return folders


def missions(run_folder: Path | None, attachments: Mapping[str, bytes],
              origins: dict[str, GeoOrigin | None], scenario_name: str | None,
              notes: list[str], accepted: Sequence[tuple[str, MissionAccepted]] = ()
              ) -> list[geo.MissionPlanView]:
    """The missions flown, by id: what the controller recorded accepting (``mission/accepted``, in
    local metres; the latest of an id sent twice), else sent from the ground station (its journal),
    sent by the launcher (``mission.json``), else the recording's mission or scenario attachment."""
    from seaway.recording import runinfo

    any_origin = next((o for o in origins.values() if o is not None), None)
    found: dict[str, geo.MissionPlanView] = {}
    for _vessel, a in sorted(accepted, key=lambda va: va[1].accepted_ns, reverse=True):
        found.setdefault(a.mission_id, geo.MissionPlanView(
            mission_id=a.mission_id, waypoints_m=a.waypoints_m(), coa_radius_m=a.coa_radius_m,
            task_power_w=a.task_power_w, controller=a.controller,
            predict_disturbance=a.predict_disturbance, source="recording"))

    def add(req: MissionRequest, origin: GeoOrigin | None, source: str) -> None:
        try:
            found.setdefault(req.mission_id, geo.mission_plan(req, origin, source))
        except geo.NoOriginError as err:
            notes.append(f"mission {req.mission_id!r} is not drawn: {err}")

    if run_folder is not None:
        for folder in _journal_folders(run_folder, origins):
            for vessel, req in journal.accepted_missions(folder):
                if folder != run_folder and vessel not in origins:
                    continue  # the fleet's journal: another vessel's mission, not in this recording
                add(req, origins.get(vessel) or any_origin, "groundstation")
        launcher = run_folder / "mission.json"
        if launcher.is_file():
            try:
                add(MissionRequest.decode(launcher.read_bytes()), any_origin, "launcher")
            except (OSError, MessageError) as err:
                notes.append(f"mission.json does not read: {err}")
    try:
        m = runinfo.mission_from_attachments(attachments, any_origin)
    except Exception as err:
        notes.append(f"the recording's mission attachment does not read: {err}")
        m = None
    if m is not None:
        # The launcher names a scenario's mission after the scenario; a mission file has its own id.
        mission_id = scenario_name or ""
        found.setdefault(mission_id, geo.MissionPlanView(
            mission_id=mission_id, waypoints_m=list(m.waypoints), coa_radius_m=m.coa_radius_m,
            task_power_w=m.task_power_w, controller="", predict_disturbance=False, source="recording"))
    return list(found.values())


def report(run_folder: Path | None, notes: list[str]) -> dict[str, Any] | None:
    path = None if run_folder is None else run_folder / "report" / "metrics.json"
    if path is None or not path.is_file():
        return None
    try:
        if path.stat().st_size > MAX_REPORT_BYTES:
            notes.append("report/metrics.json is too large to show")
            return None
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        notes.append(f"report/metrics.json does not read: {err}")
        return None
    return doc if isinstance(doc, dict) else None
