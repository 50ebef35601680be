"""The files and facts that let a recording rebuild its run: attachments in, mission and vessel out.

Attachments are named ``<role>/<file name>``; the roles are ``scenario``, ``scenario-data`` (files a
scenario refers to, by their path relative to it), ``vessel``, ``profile``, ``mission``, ``zenoh`` and
``config`` (``ROLES``). The recorder writes them (``seaway_recorder.attachments`` makes them from
files); the report, replay and the ground station's replay view read them back here:

* the mission (waypoints, circle of acceptance, T^w): a ``mission/*`` attachment (a MissionRequest
  JSON document, or a TOML/JSON file with the scenario's ``[mission]`` fields at its top level or under
  ``mission``), else the ``[mission]`` table of the ``scenario/*`` attachment. These are documents,
  the fallback: a recording of a controller that publishes ``mission/accepted`` holds each mission
  it flew (``mission_from_accepted``; ``missions.choose`` prefers those);
* the vessel (alpha for the energy): the ``vessel/*`` attachment, else the vessel the scenario names.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from seaway.contract.config import ConfigError, deploy_path, parse_config
from seaway.contract.messages import MessageError, MissionAccepted, MissionRequest
from seaway.runtime.run import RunDescription
from seaway.simkit.scenario import Scenario, parse_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import VesselParams, load_vessel

ROLES = ("run", "scenario", "scenario-data", "vessel", "plant-vessel", "profile", "mission", "zenoh",
         "config")
RUN_ATTACHMENT = "run/run.json"  # the run description (seaway.runtime.run) every recording carries


# -- the files a name stands for (deploy/scenarios, deploy/profiles, deploy/vessels) ----------------


def scenario_path(name_or_path: str) -> Path:
    p = Path(name_or_path)
    if p.suffix not in (".toml", ".json"):
        p = deploy_path("scenarios", f"{name_or_path}.toml")
    return p


def profile_path(name_or_path: str) -> Path:
    p = Path(name_or_path)
    return p if p.suffix in (".toml", ".json") else deploy_path("profiles", f"{name_or_path}.toml")


def vessel_path(name_or_path: str, relative_to: Path | None = None) -> Path:
    p = Path(name_or_path)
    if p.suffix in (".toml", ".json"):
        return p if p.is_absolute() or relative_to is None else relative_to / p
    return deploy_path("vessels", f"{name_or_path}.toml")


# -- reading back -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Mission:
    """Waypoints P_0..P_N in local NED metres, r_COA and T^w."""

    waypoints: tuple[tuple[float, float], ...]
    coa_radius_m: float
    task_power_w: float
    source: str = ""
    controller: str | None = None
    """The controller that flew it, when the source says (a recorded ``mission/accepted``)."""
    predict_disturbance: bool | None = None

    def __post_init__(self) -> None:
        if len(self.waypoints) < 2:
            raise ValueError("a mission needs at least two waypoints (P_0 and P_1)")
        if not self.coa_radius_m > 0:
            raise ValueError("coa_radius_m must be > 0")


def _decode(name: str, data: bytes) -> dict[str, Any]:
    text = data.decode("utf-8")
    if name.endswith(".toml"):
        return tomllib.loads(text)
    doc = json.loads(text)
    if not isinstance(doc, dict):
        raise ValueError(f"{name}: the top level must be an object")
    return doc


def mission_from_request(req: MissionRequest, origin: GeoOrigin | None, source: str) -> Mission:
    pts = []
    for i, w in enumerate(req.waypoints):
        if w.x_m is not None and w.y_m is not None:
            pts.append((w.x_m, w.y_m))
        elif w.lat_deg is not None and w.lon_deg is not None:
            if origin is None:
                raise ValueError(f"{source}: waypoint {i} is geodetic and no origin is known")
            n, e, _ = origin.to_ned(math.radians(w.lat_deg), math.radians(w.lon_deg), origin.alt_m)
            pts.append((n, e))
        else:
            raise ValueError(f"{source}: waypoint {i} has neither x_m/y_m nor lat_deg/lon_deg")
    return Mission(tuple(pts), req.coa_radius_m, req.task_power_w, source)


def mission_from_accepted(msg: MissionAccepted, source: str) -> Mission:
    """The mission a controller accepted (``mission/accepted``): already in local NED metres."""
    return Mission(tuple(msg.waypoints_m()), msg.coa_radius_m, msg.task_power_w, source,
                   msg.controller, msg.predict_disturbance)


def mission_from_document(doc: dict[str, Any], origin: GeoOrigin | None, source: str) -> Mission:
    """A MissionRequest document, a scenario, or a ``[mission]``-style table."""
    if "waypoints" in doc:
        try:
            req = MissionRequest.decode(json.dumps({"stamp_ns": 0, **doc}))
        except MessageError as err:
            raise ValueError(f"{source}: {err}") from None
        return mission_from_request(req, origin, source)
    table = doc.get("mission", doc)
    if not isinstance(table, dict) or "waypoints_m" not in table:
        raise ValueError(f"{source}: no mission (waypoints or waypoints_m) in it")
    wps = tuple((float(x), float(y)) for x, y in table["waypoints_m"])
    return Mission(wps, float(table["coa_radius_m"]), float(table.get("task_power_w", 0.0)), source)


def mission_id_of(doc: dict[str, Any], default: str | None = None) -> str | None:
    """The ``mission_id`` a mission document names: a MissionRequest's, a ``[mission]`` table's,
    else a scenario's name (the launcher sends a scenario's mission under it); else ``default``."""
    table = doc.get("mission") if isinstance(doc.get("mission"), dict) else doc
    mid = table.get("mission_id") or (doc.get("name") if table is not doc else None)
    return str(mid) if mid else default


def _named(atts: Mapping[str, bytes], prefix: str) -> list[str]:
    """The attachments' names under ``prefix``, in the recording's order (names only: an
    attachment is read when looked up, so the others are never read)."""
    return [name for name in atts if name.startswith(prefix)]


def missions_from_attachments(atts: Mapping[str, bytes], origin: GeoOrigin | None
                              ) -> list[tuple[Mission, str | None]]:
    """Every mission document attached (``mission/*``, then the ``scenario/*`` ``[mission]``),
    each with the id it names; documents that are not missions are left out."""
    out = []
    for prefix in ("mission/", "scenario/"):
        for name in _named(atts, prefix):
            doc = _decode(name, atts[name])
            if prefix == "scenario/" and not doc.get("mission"):
                continue
            try:
                out.append((mission_from_document(doc, origin, f"attachment {name}"),
                            mission_id_of(doc)))
            except (ValueError, KeyError, TypeError):
                continue
    return out


def scenario_from_attachments(atts: Mapping[str, bytes]) -> Scenario | None:
    for name in _named(atts, "scenario/")[:1]:
        doc = _decode(name, atts[name])
        # Grid files come along as scenario-data/ attachments; the report needs only the mission
        # and origin, so the disturbances are dropped rather than resolved here.
        doc = {k: v for k, v in doc.items() if k != "disturbances"}
        return parse_scenario(doc, f"attachment {name}")
    return None


def mission_from_attachments(atts: Mapping[str, bytes], origin: GeoOrigin | None) -> Mission | None:
    for name in _named(atts, "mission/")[:1]:
        return mission_from_document(_decode(name, atts[name]), origin, f"attachment {name}")
    for name in _named(atts, "scenario/"):
        doc = _decode(name, atts[name])
        if doc.get("mission"):
            return mission_from_document(doc, origin, f"attachment {name}")
    return None


def run_from_attachments(atts: Mapping[str, bytes]) -> RunDescription | None:
    """The run description the recording was made under (None for recordings made before it)."""
    data = atts.get(RUN_ATTACHMENT)
    return None if data is None else parse_config(_decode(RUN_ATTACHMENT, data), RunDescription,
                                                 f"attachment {RUN_ATTACHMENT}")


def vessel_from_attachments(atts: Mapping[str, bytes]) -> VesselParams | None:
    for name in _named(atts, "vessel/")[:1]:
        return parse_config(_decode(name, atts[name]), VesselParams, f"attachment {name}")
    return None


def scenario_origin(s: Scenario) -> GeoOrigin:
    return GeoOrigin.from_degrees(s.origin.lat_deg, s.origin.lon_deg, s.origin.alt_m)


def load_vessel_for(scenario: Scenario | None) -> VesselParams | None:
    if scenario is None:
        return None
    try:
        return load_vessel(scenario.vessel)
    except (ConfigError, OSError):
        return None
