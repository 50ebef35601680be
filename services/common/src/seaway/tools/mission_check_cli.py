"""``seaway mission check``: the check before a mission, at the desk (``seaway.mission_check``:
the controller's own, the one it applies on acceptance).

    seaway mission check deploy/missions/lake-square.toml [--json]
    seaway mission check lake --battery-j 298000
    seaway mission check mission.toml --area lake-area.plan
    seaway mission check survey.plan --task-power-w 250

A QGroundControl ``.plan`` or a GeoJSON mission (``seaway.mission_files``) brings its own operating
area and rally points (``--area`` replaces them) and acceptance radius; what it does not give
(``--coa-radius-m``, ``--task-power-w``) is the default scenario's mission's, and said in a note.

With ``--live`` it checks against the running vessel (``--vessel`` in a fleet): its state and
disturbance estimate, its energy budget's battery, reserve and home, the operating area its
controller enforces and its origin, as heard on the bus within ``--timeout``; the model is the
running stack's (its run description), or ``--vessel-file``.

At the desk, what it checks against: a scenario's own vessel file, battery (its ``[battery]``, else full) and
operating area; a mission file against those of the default scenario (the ``sim`` profile's),
with the mission file's own area if ``--area`` gives one. ``--battery-j`` replaces the battery's
usable energy left. At the desk there is no vessel: the vessel is taken at rest at P_0, calm.

Prints the figures and the verdict (``--json``: one object, ``{"verdict": "ok"|"refused",
"reasons": [...], ...}``). Exit status 0 ok, 1 refused, 2 a file that cannot be read (or a bad
command line).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from seaway import json_files, mission_files
from seaway.area.files import run_area
from seaway.area.model import AreaError
from seaway.contract.config import ConfigError
from seaway.contract.messages import MessageError, MissionRequest
from seaway.mission_check import MissionCheckUnavailableError, check_live, check_mission
from seaway.runtime.argtypes import non_negative_float, positive_float
from seaway.simkit.scenario import Scenario, load_mission_source, load_scenario
from seaway.tools import request_cli
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

EXIT_OK, EXIT_REFUSED, EXIT_UNREADABLE = 0, 1, 2
DEFAULT_PROFILE = "sim"
"""The profile whose scenario a mission file is checked against (its vessel, battery, area)."""


def default_scenario() -> Scenario:
    """The default scenario: the ``sim`` profile's."""
    from seaway.tools.launch.profile import load_profile

    name = load_profile(DEFAULT_PROFILE).scenario
    if not name:
        raise ConfigError(f"profile {DEFAULT_PROFILE} names no scenario")
    return load_scenario(name)


def foreign_mission(path: Path) -> mission_files.ImportedPath | None:
    """The mission of a QGroundControl ``.plan`` or a GeoJSON file (``.geojson``, or a ``.json``
    that is one), or None for Seaway's own mission and scenario files. ConfigError naming the file
    when it is one of those and cannot be read."""
    if path.suffix not in (".plan", ".geojson", ".json"):
        return None
    try:
        doc = mission_files.load_json(json_files.read_bytes(path), str(path))
    except OSError as err:
        raise ConfigError(f"{path}: cannot read: {err.strerror}") from None
    except (json_files.JsonFileError, mission_files.PlanError) as err:
        raise ConfigError(str(err)) from None
    if path.suffix == ".json" and not (isinstance(doc, dict) and (
            doc.get("fileType") == "Plan" or isinstance(doc.get("type"), str))):
        return None  # Seaway's own mission or scenario as JSON
    try:
        return mission_files.parse_document(doc)
    except mission_files.PlanError as err:
        raise ConfigError(f"{path}: {err}") from None


def foreign_request(path: Path, imported: mission_files.ImportedPath, against: Scenario,
                    coa_radius_m: float | None, task_power_w: float | None,
                    ) -> tuple[MissionRequest, list[str]]:
    """The request for an imported path: the command line's values, then the file's, then the
    default scenario's mission's (each of those named in the notes returned)."""
    params = {**imported.hints}
    if not params.get("mission_id"):
        params["mission_id"] = path.stem[:64]
    if coa_radius_m is not None:
        params["coa_radius_m"] = coa_radius_m
    if task_power_w is not None:
        params["task_power_w"] = task_power_w
    notes = []
    for name in ("coa_radius_m", "task_power_w"):
        if name not in params:
            if against.mission is None:
                raise ConfigError(f"{path}: gives no {name} and scenario {against.name!r} has no "
                                  f"[mission] to take it from; give --{name.replace('_', '-')}")
            params[name] = getattr(against.mission, name)
            notes.append(f"{name} {params[name]:g} from scenario {against.name}'s mission "
                         f"(the {imported.source} file gives none)")
    try:
        return mission_files.mission_request(imported, params, time.time_ns()), notes
    except mission_files.PlanError as err:
        raise ConfigError(f"{path}: {err}") from None


def desk_check(what: str, battery_j: float | None = None, area_file: str | None = None,
               force: bool = False, coa_radius_m: float | None = None,
               task_power_w: float | None = None) -> dict:
    """The check of the mission ``what`` names, at the desk, as ``--json`` prints it.
    ConfigError/AreaError/MessageError when something cannot be read."""
    imported = foreign_mission(Path(what))
    if imported is not None:
        against = default_scenario()
        req, notes = foreign_request(Path(what), imported, against, coa_radius_m, task_power_w)
        if force:
            req = req.model_copy(update={"force": True})
        if area_file is None and imported.area is not None:
            area_file = what  # the file's own geoFence and rallyPoints
            # Not what a flight keeps to: the controller enforces its run's area, and an import
            # sends the mission only. Said, so the file's fence is not taken for that one.
            notes.append(f"checked against the file's own operating area, not scenario "
                         f"{against.name}'s; a flight keeps to its run's area (the scenario's "
                         "[area], or the controller's --area), which this file does not set")
        out = check_request(req, against, battery_j, area_file)
        out["notes"] = [*notes, *out["notes"]]
        return out
    spec, scenario = load_mission_source(what)
    against = scenario if scenario is not None else default_scenario()
    req = spec.to_request(time.time_ns(), mission_id=spec.mission_id or against.name)
    if force:
        req = req.model_copy(update={"force": True})
    return check_request(req, against, battery_j, area_file)


def check_request(req: MissionRequest, against: Scenario, battery_j: float | None = None,
                  area_file: str | None = None) -> dict:
    """The check of ``req`` against ``against``'s vessel, battery (``battery_j`` if given, else
    its ``[battery]``, else full) and area (``area_file`` if given), as ``--json`` prints it."""
    vessel = load_vessel(against.vessel)
    o = against.origin
    origin = GeoOrigin.from_degrees(o.lat_deg, o.lon_deg, o.alt_m)
    area, area_source = run_area(against, area_file, origin)
    if battery_j is None:
        battery_j = against.battery.start_j(vessel.battery)
    home = (against.start.x_m, against.start.y_m)
    out = check_mission(req, vessel, origin=origin, battery_j=battery_j, area=area,
                        home=home).to_dict()
    out.update(vessel=against.vessel, against=f"scenario {against.name}",
               area_source=area_source or None)
    return out


LIVE_LISTEN_S = 1.5
"""How long the live check listens once the vessel's state has come [s]: the area and the origin
are said once a second."""


def live_request(what: str, coa_radius_m: float | None, task_power_w: float | None,
                 force: bool) -> tuple[MissionRequest, list[str]]:
    """The request a live check checks: a .plan or GeoJSON file's, or a mission or scenario
    file's ``[mission]``."""
    imported = foreign_mission(Path(what))
    if imported is not None:
        req, notes = foreign_request(Path(what), imported, default_scenario(), coa_radius_m,
                                     task_power_w)
    else:
        spec, scenario = load_mission_source(what)
        req, notes = spec.to_request(time.time_ns(), mission_id=spec.mission_id or (
            scenario.name if scenario is not None else Path(what).stem)), []
    return (req.model_copy(update={"force": True}) if force else req), notes


def running_model(vessel_file: str | None) -> str:
    """The model vessel file of the stack this command speaks to (its run description), unless
    ``vessel_file`` names one. ConfigError when neither is known."""
    if vessel_file is not None:
        return vessel_file
    from seaway.contract.config import parse_config, read_document
    from seaway.runtime import stacks
    from seaway.runtime.run import RunDescription
    from seaway.runtime.zenoh_bus import rendezvous_endpoint

    entry = stacks.lookup(rendezvous_endpoint())
    run_file = Path(entry.run_dir) / "run.json" if entry is not None else None
    if run_file is None or not run_file.is_file():
        raise ConfigError("no running stack's run description found here to take the vessel model "
                          "from; give --vessel-file")
    return parse_config(read_document(run_file), RunDescription, str(run_file)).model_vessel_file


def live_check(args: argparse.Namespace) -> dict | None:
    """The check of ``args.what`` against the running vessel; None if no vessel was chosen (a
    fleet without ``--vessel``: ``vessel_choice`` has said so). ConfigError when its state does
    not come within ``args.timeout``."""
    from seaway.contract import keys
    from seaway.runtime.bus import Bus
    from seaway.tools import vessel_choice
    from seaway.tools.request_cli import DEFAULT_VESSEL

    req, notes = live_request(args.what, args.coa_radius_m, args.task_power_w, args.force)
    model = running_model(args.vessel_file)
    with Bus.open(args.vessel or DEFAULT_VESSEL, args.zenoh_config) as bus:
        vessel = vessel_choice.resolve(bus, args.vessel, "seaway mission check")
        if vessel is None:
            return None
        heard = {spec: bus.subscribe(spec, vessel=vessel) for spec in (
            keys.NAV_STATE, keys.NAV_ORIGIN, keys.MISSION_ENERGY, keys.AREA_ACTIVE)}
        if heard[keys.NAV_STATE].get(args.timeout) is None:
            raise ConfigError(f"no {keys.NAV_STATE.suffix} from vessel {vessel} within "
                              f"{args.timeout:g} s: is it running? (without --live: at the desk)")
        time.sleep(LIVE_LISTEN_S)
        state, origin_msg, energy, area = (heard[s].latest() for s in (
            keys.NAV_STATE, keys.NAV_ORIGIN, keys.MISSION_ENERGY, keys.AREA_ACTIVE))
    origin = None if origin_msg is None else GeoOrigin(origin_msg.lat_rad, origin_msg.lon_rad,
                                                       origin_msg.alt_m)
    out = check_live(req, load_vessel(model), origin=origin, state=state, energy=energy, area=area,
                     battery_j=args.battery_j)
    out.update(vessel=model, against=f"vessel {vessel}",
               area_source=area.source if area is not None else None)
    out["notes"] = [*notes, *out["notes"]]
    return out


def show(out: dict) -> str:
    def fig(k: str, unit: str, fmt: str = ".0f") -> str:
        v = out.get(k)
        return "-" if v is None else f"{v:{fmt}} {unit}"

    lines = [
        f"mission {out['mission_id'] or '(unnamed)'}: checked against {out['against']} "
        f"(vessel {out['vessel']}, area {out['area_source'] or 'none'})",
        f"  path length              {fig('path_length_m', 'm', '.1f')}",
        f"  predicted time           {fig('predicted_time_s', 's')} "
        f"at {fig('cruise_speed_mps', 'm/s', '.2f')}",
        f"  energy for the mission   {fig('energy_mission_j', 'J')}",
        f"  energy home from the end {fig('energy_home_from_last_j', 'J')}",
        f"  battery                  {fig('battery_j', 'J')}, after {fig('battery_after_j', 'J')}, "
        f"reserve {fig('reserve_j', 'J')}",
        f"  operating area           {out['area']}",
        *[f"  note: {n}" for n in out["notes"]],
        f"verdict: {out['verdict'].upper()}",
        *[f"  - {r}" for r in out["reasons"]],
    ]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="seaway mission check", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", help="mission file (.toml, .json, QGroundControl .plan, GeoJSON) or "
                    "scenario (name or file)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--battery-j", type=non_negative_float, default=None, metavar="J",
                    help="usable energy in the battery [J] (default: the scenario's, else full)")
    ap.add_argument("--area", default=None, metavar="FILE",
                    help="the operating area (.toml [area], .plan geoFence, .geojson)")
    ap.add_argument("--live", action="store_true",
                    help="check against the running vessel's live state, battery and area")
    ap.add_argument("--vessel-file", default=None, metavar="NAME",
                    help="with --live: the vessel model (default: the running stack's)")
    request_cli.add_request_arguments(ap, "vessel's state (with --live)")
    ap.add_argument("--force", action="store_true",
                    help="check as the controller would a forced mission (energy only warns)")
    ap.add_argument("--coa-radius-m", type=positive_float, default=None, metavar="M",
                    help="r_COA of a .plan or GeoJSON mission (default: the file's, else the "
                    "default scenario's)")
    ap.add_argument("--task-power-w", type=positive_float, default=None, metavar="W",
                    help="T^w of a .plan or GeoJSON mission (default: the default scenario's)")
    args = ap.parse_args(argv)
    if args.live and args.area is not None:
        ap.error("--area is for the desk: live, the area is the one the controller enforces")
    try:
        if args.live:
            out = live_check(args)
            if out is None:
                return EXIT_UNREADABLE
        else:
            out = desk_check(args.what, args.battery_j, args.area, args.force, args.coa_radius_m,
                             args.task_power_w)
    except (ConfigError, AreaError, MessageError, OSError, MissionCheckUnavailableError) as err:
        print(f"seaway mission check: {err}", file=sys.stderr)
        return EXIT_UNREADABLE
    print(json.dumps(out) if args.json else show(out))
    return EXIT_OK if out["verdict"] == "ok" else EXIT_REFUSED
