"""``seaway sitl ardupilot``: run ArduPilot Rover's own firmware (SITL) as the run's autopilot.

    seaway sitl ardupilot --run RUN_JSON --dir FOLDER [--instance N] [--no-boat-params]

The launcher's ``sitl-ardupilot`` profile runs this in place of Seaway's simulator: ArduPilot Rover
built for software-in-the-loop with its ``motorboat-skid`` physics (two thrusters), started at the
run's NED origin with the scenario's start heading, with ArduPilot's default parameters for that
frame plus what Seaway needs on a boat (``services/vehicle_io/config/ardupilot-boat.parm``,
docs/autopilots.md) and calm air for its simulation (``ardupilot-sitl.parm``: the motorboat
physics keeps the sailboat's sail, so ArduPilot's default wind would push the hull). vehicle_io
then connects to it as to any autopilot.

Where the firmware is: the folder named by ``$SEAWAY_ARDUPILOT_SITL``, else ``../shared/sitl/ardupilot``
beside the checkout when that exists. The folder holds ``ardurover`` (or a build tree with
``build/sitl/bin/ardurover``) and ArduPilot's default parameter files ``rover.parm``,
``motorboat.parm``, ``rover-skid.parm`` (or ``Tools/autotest/default_params/`` of the tree). Without
one the command says how to build it and exits 2.

Ports, all on 127.0.0.1 with the patched build of ../shared (a stock build listens on every
interface): SERIAL0 TCP ``5760 + 10 N`` (vehicle_io's link: ``serial0_url``), SERIAL1 ``+1``,
SERIAL2 ``+2`` (free for a ground station such as MAVProxy or QGroundControl).

The process is replaced by the firmware (``exec``), so the launcher's SIGINT and SIGKILL reach
ArduPilot itself and nothing is left behind.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from seaway.contract.config import ConfigError, load_config, repo_root
from seaway.runtime.argtypes import whole_number
from seaway.runtime.run import RunDescription

from seaway_vehicle_io import sitl_common, sitl_px4
from seaway_vehicle_io.config import CONFIG_DIR
from seaway_vehicle_io.sitl_common import SitlError, start_pose

ENV_FOLDER = "SEAWAY_ARDUPILOT_SITL"
FRAME = "motorboat-skid"
DEFAULT_PARAMS = ("rover.parm", "motorboat.parm", "rover-skid.parm")
"""ArduPilot's own defaults for the skid-steer motorboat (what ``sim_vehicle.py -f motorboat-skid``
loads), in this order: later files override earlier ones."""
BOAT_PARAMS = CONFIG_DIR / "ardupilot-boat.parm"
"""What Seaway needs on an ArduPilot boat (Two Paddles steering, no slew, radio failsafe on)."""
SIM_PARAMS = CONFIG_DIR / "ardupilot-sitl.parm"
"""SITL's own simulation parameters for Seaway's profiles (no wind on the sailboat physics' sail)."""
BASE_TCP_PORT = 5760
PORTS_PER_INSTANCE = 10
HOW_TO_GET = (
    "build ArduPilot Rover SITL (40-70 min on 2 cores: docs/autopilots.md, 'Building the SITL "
    "yourself') and set SEAWAY_ARDUPILOT_SITL to the folder holding ardurover and its default "
    "parameter files")


@dataclass(frozen=True)
class ArduPilotSitl:
    """A built ArduPilot Rover SITL: the binary and ArduPilot's default parameter files for the frame."""

    folder: Path
    binary: Path
    defaults: tuple[Path, ...]


def default_folder(env: Mapping[str, str], root: Path | None) -> Path | None:
    """``$SEAWAY_ARDUPILOT_SITL``, else ``<checkout>/../shared/sitl/ardupilot`` if it exists."""
    return sitl_common.default_folder(env, root, ENV_FOLDER, "ardupilot")


def find_firmware(folder: Path | None) -> ArduPilotSitl:
    """The firmware in ``folder`` (a flat folder like ../shared's, or an ArduPilot build tree)."""
    if folder is None:
        raise SitlError(f"no ArduPilot SITL: ${ENV_FOLDER} is not set and ../shared/sitl/ardupilot "
                        f"does not exist; {HOW_TO_GET}")
    binary = next((p for p in (folder / "ardurover", folder / "build" / "sitl" / "bin" / "ardurover")
                   if p.is_file() and os.access(p, os.X_OK)), None)
    if binary is None:
        raise SitlError(f"no executable ardurover in {folder} (nor in build/sitl/bin/ there); "
                        f"{HOW_TO_GET}")
    defaults = []
    for name in DEFAULT_PARAMS:
        found = next((p for p in (folder / name, folder / "Tools" / "autotest" / "default_params" / name)
                      if p.is_file()), None)
        if found is None:
            raise SitlError(f"ArduPilot's default parameter file {name} is missing from {folder} (and "
                            f"Tools/autotest/default_params/); copy it from the ArduPilot tree the "
                            f"binary was built from")
        defaults.append(found)
    return ArduPilotSitl(folder, binary, tuple(defaults))


def serial0_url(instance: int) -> str:
    """vehicle_io's link to SITL instance ``instance`` (its SERIAL0)."""
    return f"tcp:127.0.0.1:{BASE_TCP_PORT + PORTS_PER_INSTANCE * instance}"


def home_text(run: RunDescription) -> str:
    """ArduPilot's ``--home lat,lon,alt,yaw``: the run's NED origin and the scenario's start heading
    [deg, clockwise from north] (SITL starts at its home, so the scenario's start must be at the
    origin)."""
    pose = start_pose(run)
    o = pose.origin
    return f"{o.lat_deg:.7f},{o.lon_deg:.7f},{o.alt_m:g},{pose.yaw_deg:g}"


def command(sitl: ArduPilotSitl, home: str, instance: int,
            extra_params: tuple[Path, ...] = (BOAT_PARAMS, SIM_PARAMS)) -> list[str]:
    """The firmware's command line (run it in the folder that is to hold its eeprom and logs)."""
    if not 0 <= instance <= 99:
        raise SitlError(f"instance {instance} out of range: 0 to 99 (ports 5760 + 10 N)")
    for p in extra_params:
        if not p.is_file():
            raise SitlError(f"parameter file {p} not found")
    defaults = ",".join(str(p) for p in (*sitl.defaults, *extra_params))
    return [str(sitl.binary), "--model", FRAME, "--speedup", "1", f"-I{instance}", "--home", home,
            "--defaults", defaults, "--serial0", "tcp:0", "--serial1", "tcp:1", "--serial2", "tcp:2"]


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway sitl", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("firmware", choices=["ardupilot", "px4"],
                    help="which autopilot's SITL: ardupilot (Rover, motorboat-skid) or px4 (SIH "
                         "differential rover; its options: seaway sitl px4 --help)")
    ap.add_argument("--run", type=Path, required=True, help="the run description (run.json): its "
                    "origin is SITL's home, its scenario gives the start heading")
    ap.add_argument("--dir", type=Path, required=True,
                    help="folder for the firmware's eeprom and logs (made if missing)")
    ap.add_argument("--instance", type=whole_number(0), default=0,
                    help="SITL instance N: SERIAL0 on TCP 5760 + 10 N (default 0)")
    ap.add_argument("--no-boat-params", action="store_true",
                    help=f"ArduPilot's defaults only, without {BOAT_PARAMS.name} and {SIM_PARAMS.name}")
    ap.add_argument("--params", type=Path, action="append", default=[], metavar="FILE",
                    help="another parameter file, loaded last (e.g. SIM_WIND_SPD 3 for ArduPilot's "
                         "wind); repeatable")
    ap.add_argument("--print", action="store_true", help="print the command instead of running it")
    return ap


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["px4"]:
        return sitl_px4.main(argv[1:])
    args = parser().parse_args(argv)
    try:
        sitl = find_firmware(default_folder(os.environ, repo_root()))
        run = load_config(args.run, RunDescription)
        extra = () if args.no_boat_params else (BOAT_PARAMS, SIM_PARAMS)
        argv_fw = command(sitl, home_text(run), args.instance,
                          (*extra, *(p.resolve() for p in args.params)))
    except (ConfigError, OSError, ValueError) as err:
        print(f"seaway sitl: {err}", file=sys.stderr)
        return 2
    if args.print:
        print(" ".join(argv_fw))
        return 0
    args.dir.mkdir(parents=True, exist_ok=True)
    os.chdir(args.dir)
    print(f"seaway sitl: ArduPilot Rover SITL ({FRAME}) from {sitl.folder}, home {argv_fw[7]}, "
          f"vehicle_io's link {serial0_url(args.instance)}", flush=True)
    os.execv(argv_fw[0], argv_fw)
    return 0  # not reached


if __name__ == "__main__":
    raise SystemExit(main())
