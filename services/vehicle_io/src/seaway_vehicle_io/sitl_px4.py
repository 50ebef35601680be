"""``seaway sitl px4``: run PX4's own firmware (SITL, SIH differential rover) as the run's autopilot.

    seaway sitl px4 --run RUN_JSON --dir FOLDER --link-port PORT [--instance N] [--param NAME=VALUE]

The launcher's ``sitl-px4`` and ``identify-px4`` profiles run this in place of Seaway's simulator:
PX4 built for software-in-the-loop with its built-in SIH simulator, airframe 10046
(``sihsim_rover_differential``: PX4's ``rover_differential``, two reversible motors, Motor1 = right,
Motor2 = left), started at the run's NED origin (SIH's home, ``SIH_LOC_*``) with the parameters
Seaway needs (``services/vehicle_io/config/px4-boat.params``, then ``px4-sitl.params``, then each
``--param``; docs/autopilots.md C.11 and C.13). PX4 has no boat type and its SIH no initial heading:
the vehicle starts facing north, so the scenario must start heading north (``psi_rad = 0``).

Where the firmware is: the folder named by ``$SEAWAY_PX4_SITL``, else ``../shared/sitl/px4`` beside
the checkout when that exists; it holds ``bin/px4``, ``etc/`` (PX4's ROMFS) and ``test_data/``
(``../shared/sitl/px4/README.md`` says how it was built). Without one the command says how to build
it and exits 2. The binary is copied into ``FOLDER/bin`` next to a ``px4-<module>`` symlink per
module (PX4's start-up script runs every module through them; a copied build may have lost them).

Links. PX4's stock ``px4-rc.mavlink`` sends its onboard link to 14540 + N, which for instances above
9 becomes 14549 for all of them; this command puts a script of its own first on PX4's PATH in place
of it, which sets the parameters and starts three links, all bound to 127.0.0.1 (the build's patch):

- vehicle_io's: PX4 on 14580 + N, onboard mode, sending to ``--link-port`` (the launcher's
  ``{mavlink_port}``, where vehicle_io listens with ``udpin``);
- a ground station's: PX4 on 18570 + N sending to 14550 (QGroundControl's port, shared by all);
- the SIH display link: PX4 on 19450 + N sending HIL_ACTUATOR_CONTROLS (the motor outputs) and
  HIL_STATE_QUATERNION (the simulated truth) to 19410 + N.

Instances: N is taken from ``OWN_INSTANCES`` unless given, the first whose ports are free and whose
lock file (``LOCK_DIR``) no other process holds; the lock stays held by the firmware (its descriptor
survives the ``exec``) until it exits, so concurrent runs and tests never share one. Tests that run
PX4's stock script take theirs from ``STOCK_INSTANCES`` through the same ``free_instance``.

The process is replaced by the firmware (``exec``), so the launcher's SIGINT and SIGKILL reach PX4
itself and nothing is left behind.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import os
import shutil
import socket
import sys
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from seaway.contract.config import ConfigError, load_config, repo_root
from seaway.runtime.argtypes import whole_number
from seaway.runtime.run import RunDescription

from seaway_vehicle_io.config import CONFIG_DIR
from seaway_vehicle_io.sitl_common import SitlError, StartPose, default_folder, start_pose

ENV_FOLDER = "SEAWAY_PX4_SITL"
MODEL = "sihsim_rover_differential"
"""PX4_SIM_MODEL of airframe 10046, the SIH differential rover (a local patch of the build)."""
BOAT_PARAMS = CONFIG_DIR / "px4-boat.params"
"""What Seaway needs on a PX4 boat (no throttle slew, the roll stick at full scale)."""
SIM_PARAMS = CONFIG_DIR / "px4-sitl.params"
"""What Seaway's SITL profiles set on top (manual-control loss -> Hold, no flight log)."""

GCS_LOCAL, GCS_REMOTE = 18570, 14550  # + N for the local port; the remote is shared
API_LOCAL, API_REMOTE = 14580, 14540  # PX4's onboard link (stock remote: 14540 + N, N <= 9)
SIH_LOCAL, SIH_REMOTE = 19450, 19410
PAYLOAD_LOCAL, PAYLOAD_REMOTE, GIMBAL_LOCAL, GIMBAL_REMOTE = 14280, 14030, 13030, 13280
INSTANCE_PORT_BASES = (GCS_LOCAL, API_LOCAL, API_REMOTE, SIH_LOCAL, SIH_REMOTE, PAYLOAD_LOCAL,
                       PAYLOAD_REMOTE, GIMBAL_LOCAL, GIMBAL_REMOTE)
"""Every UDP port PX4's stock script binds or sends to, + N: an instance is free only if all are."""
STOCK_INSTANCES = range(1, 10)
"""Instances for PX4's own px4-rc.mavlink (its onboard link sends to 14540 + N only up to 9)."""
OWN_INSTANCES = range(10, 60)
"""Instances for this command's links script: 14580 + N from 14590 up, clear of the stock ones."""
LOCK_DIR = Path(tempfile.gettempdir()) / "seaway-px4-sitl"
"""Per-instance lock files, and each instance's short PX4_RUNTIME_DIR (a unix socket path)."""
HOW_TO_GET = ("build PX4 SITL with SIH (../shared/sitl/px4/README.md, 'Rebuild': PX4 release/1.18 "
              "and its five local patches, 5-8 min on 2 cores) and set SEAWAY_PX4_SITL to the folder "
              "holding bin/px4, etc/ and test_data/")


@dataclass(frozen=True)
class Px4SitlBuild:
    """A built PX4 SITL: the binary, its ROMFS (``etc``) and the test data folder."""

    folder: Path
    binary: Path
    etc: Path
    test_data: Path


def firmware_folder(env: Mapping[str, str], root: Path | None) -> Path | None:
    """``$SEAWAY_PX4_SITL``, else ``<checkout>/../shared/sitl/px4`` if it exists."""
    return default_folder(env, root, ENV_FOLDER, "px4")


def find_firmware(folder: Path | None) -> Px4SitlBuild:
    """The build in ``folder`` (``bin/px4``, ``etc/``, ``test_data/``); SitlError saying how to get
    one otherwise."""
    if folder is None:
        raise SitlError(f"no PX4 SITL: ${ENV_FOLDER} is not set and ../shared/sitl/px4 does not "
                        f"exist; {HOW_TO_GET}")
    binary = folder / "bin" / "px4"
    if not (binary.is_file() and os.access(binary, os.R_OK)):
        raise SitlError(f"no PX4 binary bin/px4 in {folder}; {HOW_TO_GET}")
    if not (folder / "etc" / "init.d-posix" / "rcS").is_file():
        raise SitlError(f"no PX4 start-up files (etc/init.d-posix/rcS) in {folder}; {HOW_TO_GET}")
    return Px4SitlBuild(folder, binary, folder / "etc", folder / "test_data")


def runnable_bin(build: Px4SitlBuild, into: Path) -> Path:
    """A bin folder PX4 can run from: the binary and a ``px4-<module>`` symlink per module (the
    start-up script calls modules through them), and PX4's shell helpers. Returns the binary."""
    into.mkdir(parents=True, exist_ok=True)
    exe = into / "px4"
    shutil.copy2(build.binary, exe)
    exe.chmod(0o755)
    for entry in (build.folder / "bin").iterdir():
        target = into / entry.name
        if entry.name == "px4" or target.exists() or target.is_symlink():
            continue
        if entry.suffix == ".sh":
            shutil.copy2(entry, target)
        elif entry.name.startswith("px4-"):
            target.symlink_to("px4")
    return exe


def read_params(path: Path) -> dict[str, float]:
    """A parameter file: ``NAME VALUE`` per line, ``#`` comments. SitlError naming the line."""
    out: dict[str, float] = {}
    for number, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        try:
            if len(parts) != 2:
                raise ValueError
            out[parts[0]] = float(parts[1])
        except ValueError:
            raise SitlError(f"{path}:{number}: want 'NAME VALUE', got {raw!r}") from None
    return out


def param_override(text: str) -> tuple[str, float]:
    """``NAME=VALUE`` from the command line."""
    name, sep, value = text.partition("=")
    try:
        if not sep or not name.strip():
            raise ValueError
        return name.strip().upper(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"want NAME=VALUE (e.g. NAV_RCL_ACT=1), got {text!r}") \
            from None


def udp_port_free(port: int) -> bool:
    """Whether UDP ``port`` can be bound on loopback now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def free_instance(instances: Iterable[int]) -> tuple[int, int]:
    """The first of ``instances`` whose lock this process gets and whose ports are all free:
    (instance, the lock's file descriptor: held until closed, or until every process it was
    passed to has exited). SitlError if none is."""
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    tried = list(instances)
    for n in tried:
        fd = os.open(LOCK_DIR / f"instance-{n}.lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        if all(udp_port_free(base + n) for base in INSTANCE_PORT_BASES):
            return n, fd
        os.close(fd)
    raise SitlError(f"no free PX4 SITL instance in {tried[0]}..{tried[-1]} (each locked in "
                    f"{LOCK_DIR} or with a port taken)")


def links_script(instance: int, link_port: int, params: Mapping[str, float]) -> str:
    """The ``px4-rc.mavlink`` PX4's start-up script sources (found first on its PATH): Seaway's
    parameters, then vehicle_io's, a ground station's and the SIH display link."""
    lines = ["#!/bin/sh",
             "# Written by `seaway sitl px4` in place of PX4's etc/init.d-posix/px4-rc.mavlink",
             "# (services/vehicle_io/src/seaway_vehicle_io/sitl_px4.py says why).",
             *(f"param set {name} {value:g}" for name, value in params.items()),
             f"mavlink start -x -u {GCS_LOCAL + instance} -r 4000000 -f",
             f"mavlink start -x -u {API_LOCAL + instance} -r 4000000 -f -m onboard -o {link_port}",
             f"mavlink start -x -u {SIH_LOCAL + instance} -r 400000 -m custom "
             f"-o {SIH_REMOTE + instance}",
             f"mavlink stream -r 200 -s HIL_ACTUATOR_CONTROLS -u {SIH_LOCAL + instance}",
             f"mavlink stream -r 25 -s HIL_STATE_QUATERNION -u {SIH_LOCAL + instance}", ""]
    return "\n".join(lines)


def environment(base: Mapping[str, str], pose: StartPose, runtime_dir: Path,
                script_dir: Path) -> dict[str, str]:
    """PX4's environment: the airframe, SIH's home, 127.0.0.1 only, and the links script first on
    PATH. SitlError for a start heading other than north (SIH has no initial heading)."""
    if min(pose.yaw_deg, 360.0 - pose.yaw_deg) > 0.01:
        raise SitlError(f"PX4's SIH starts facing north, but the scenario starts heading "
                        f"{pose.yaw_deg:g} deg: use a scenario with psi_rad = 0")
    o = pose.origin
    return {**base, "PX4_SIM_MODEL": MODEL, "PX4_RUNTIME_DIR": str(runtime_dir),
            "PX4_MAVLINK_BIND_ADDR": "127.0.0.1", "PX4_HOME_LAT": f"{o.lat_deg:.7f}",
            "PX4_HOME_LON": f"{o.lon_deg:.7f}", "PX4_HOME_ALT": f"{o.alt_m:g}",
            "PATH": f"{script_dir}{os.pathsep}{base.get('PATH', os.defpath)}"}


def command(exe: Path, build: Px4SitlBuild, instance: int, work_dir: Path) -> list[str]:
    """The firmware's command line: daemon mode, instance N, working folder ``work_dir``."""
    return [str(exe), "-d", "-i", str(instance), "-w", str(work_dir), "-t", str(build.test_data),
            str(build.etc)]


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway sitl px4", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, required=True, help="the run description (run.json): its "
                    "origin is SIH's home; its scenario must start at the origin heading north")
    ap.add_argument("--dir", type=Path, required=True,
                    help="folder for the firmware's parameters, dataman and logs (made if missing)")
    ap.add_argument("--link-port", type=whole_number(1, 65535), required=True,
                    help="UDP port on 127.0.0.1 PX4's onboard link sends to (vehicle_io's udpin)")
    ap.add_argument("--instance", type=whole_number(0, 99), default=None,
                    help=f"PX4 instance N, which must be free (default: the first free of "
                         f"{OWN_INSTANCES.start}..{OWN_INSTANCES.stop - 1})")
    ap.add_argument("--param", type=param_override, action="append", default=[],
                    metavar="NAME=VALUE", help="a PX4 parameter set after Seaway's; repeatable")
    ap.add_argument("--print", action="store_true", help="print the links script and the command "
                    "instead of running them (takes no instance lock)")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    lock_fd = None
    try:
        build = find_firmware(firmware_folder(os.environ, repo_root()))
        pose = start_pose(load_config(args.run, RunDescription))
        params = {**read_params(BOAT_PARAMS), **read_params(SIM_PARAMS), **dict(args.param)}
        if args.print:
            instance = OWN_INSTANCES.start if args.instance is None else args.instance
        else:  # a given instance is locked and checked as a chosen one is
            wanted = OWN_INSTANCES if args.instance is None else range(args.instance,
                                                                       args.instance + 1)
            instance, lock_fd = free_instance(wanted)
        runtime_dir = LOCK_DIR / f"run-{instance}"
        env = environment(os.environ, pose, runtime_dir, args.dir / "rc")
    except (ConfigError, OSError) as err:
        print(f"seaway sitl px4: {err}", file=sys.stderr)
        return 2
    script = links_script(instance, args.link_port, params)
    argv_fw = command(args.dir / "bin" / "px4", build, instance, args.dir.resolve())
    if args.print:
        print(script)
        print(" ".join(argv_fw))
        return 0
    (args.dir / "rc").mkdir(parents=True, exist_ok=True)
    (args.dir / "rc" / "px4-rc.mavlink").write_text(script)
    runnable_bin(build, args.dir / "bin")
    # A PX4 of this instance that died left its daemon socket and lock file: ours now.
    with contextlib.suppress(FileNotFoundError):
        shutil.rmtree(runtime_dir)
    runtime_dir.mkdir(parents=True)
    if lock_fd is not None:
        os.set_inheritable(lock_fd, True)  # held by PX4 itself after the exec
    os.chdir(args.dir)
    print(f"seaway sitl px4: PX4 SITL (SIH, {MODEL}) from {build.folder}, instance {instance}, "
          f"home {env['PX4_HOME_LAT']},{env['PX4_HOME_LON']},{env['PX4_HOME_ALT']} facing north; "
          f"onboard link 127.0.0.1:{API_LOCAL + instance} -> 127.0.0.1:{args.link_port}, SIH link "
          f"-> {SIH_REMOTE + instance}; {len(params)} parameters set", flush=True)
    os.execve(argv_fw[0], argv_fw, env)
    return 0  # not reached
