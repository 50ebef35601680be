"""``seaway mission check``: the check before a mission, at the desk (``seaway.mission_check``:
the controller's own, the one it applies on acceptance).

    seaway mission check deploy/missions/lake-square.toml [--json]
    seaway mission check lake --battery-j 298000
    seaway mission check mission.toml --area lake-area.plan

What it checks against: a scenario's own vessel file, battery (its ``[battery]``, else full) and
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

from seaway.area.files import run_area
from seaway.area.model import AreaError
from seaway.contract.config import ConfigError
from seaway.contract.messages import MessageError, MissionRequest
from seaway.mission_check import MissionCheckUnavailableError, check_mission
from seaway.runtime.argtypes import non_negative_float
from seaway.simkit.scenario import Scenario, load_mission_source, load_scenario
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


def desk_check(what: str, battery_j: float | None = None, area_file: str | None = None,
               force: bool = False) -> dict:
    """The check of the mission ``what`` names, at the desk, as ``--json`` prints it.
    ConfigError/AreaError/MessageError when something cannot be read."""
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
    ap.add_argument("what", help="mission file (.toml, .json) or scenario (name or file)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--battery-j", type=non_negative_float, default=None, metavar="J",
                    help="usable energy in the battery [J] (default: the scenario's, else full)")
    ap.add_argument("--area", default=None, metavar="FILE",
                    help="the operating area (.toml [area], .plan geoFence, .geojson)")
    ap.add_argument("--force", action="store_true",
                    help="check as the controller would a forced mission (energy only warns)")
    args = ap.parse_args(argv)
    try:
        out = desk_check(args.what, args.battery_j, args.area, args.force)
    except (ConfigError, AreaError, MessageError, OSError, MissionCheckUnavailableError) as err:
        print(f"seaway mission check: {err}", file=sys.stderr)
        return EXIT_UNREADABLE
    print(json.dumps(out) if args.json else show(out))
    return EXIT_OK if out["verdict"] == "ok" else EXIT_REFUSED
