"""``seaway launch PROFILE``: start a profile, show a live status line, stop everything on Ctrl-C.

    seaway launch sim                      # the default: the simulated vessel and every service
    seaway launch sim --scenario paper-c1  # another scenario
    seaway launch boat --vessel boat1      # on the boat's computer
    seaway launch sim-batch --controller nmpc --predict-disturbance --task-power-w 2
    seaway launch fleet                    # several simulated vessels and one ground station
    seaway launch fleet --vessels a,b,c    # these three

A profile that lists ``vessels`` (a fleet, ``deploy/profiles/fleet.toml``) runs each of its
per-vessel processes once per vessel (``profile.instances``), ``--vessels`` choosing them; every
other profile runs one vessel, ``--vessel``. The launcher makes the start-up requests (mode,
arming, the mission), watches readiness and liveness, shows the status and writes the run
description, the mission sent, the recording and the report per vessel: in the run folder for one
vessel, in ``<run folder>/<vessel>/`` for several (``vessel_dir``).

When a ground station is among the processes, the launcher prints its page's address once all are
ready (``ground station: http://127.0.0.1:8321/#token=...``, from ``<run
folder>/groundstation/address.json``, ``seaway.tools.launch.address``), and again if it restarts:
open it in a browser on this machine. The token is in that line and in the address file only.

The mission options (--controller, --predict-disturbance, --task-power-w) change the scenario's
mission that the launcher sends; with no mission to send they are refused. The run folder is
``--run-dir``, else ``runs/<time>-<profile>``, and when a mission is sent
``runs/<time>-<profile>-<scenario>-<controller>[-tauD]`` (``-tauD``: the mission predicts with the
estimated disturbance), with ``-2``, ``-3``, ... added if that folder exists already; a ``--run-dir``
that holds an earlier launch's recording is refused (exit 2). The mission sent
is written to ``mission.json`` in the run folder, and the final report takes it from there.

Ctrl-C (or SIGTERM) stops every process in order, the recorder last, then prints the status table
and the run's report. A second Ctrl-C shortens each process's grace before SIGKILL, but still stops
them in order and lets the recorder finish its file; one during the report skips the report (and
says how to make it later).

Exit code: 0 after a clean stop (Ctrl-C, SIGTERM, or the mission completed with
``stop_when_complete``); 1 when a required process failed or could not start; 2 for a bad profile.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from rich.console import Console

from seaway.contract import keys
from seaway.contract.access import AccessError
from seaway.contract.config import ConfigError, deploy_path, repo_root
from seaway.contract.messages import (
    CONTROLLER_NAMES,
    MAX_TASK_POWER_W,
    ArmRequest,
    MessageError,
    MissionRequest,
    ModeRequest,
    Reply,
)
from seaway.runtime import cpus, memory, refusals
from seaway.runtime import run as runs
from seaway.runtime.argtypes import positive_float
from seaway.runtime.bus import Bus, RuntimeEnvError
from seaway.runtime.credentials import ENV_CREDENTIALS, NONE, CredentialsError
from seaway.runtime.lockstep import CHAIN
from seaway.runtime.private import PRIVATE_UMASK
from seaway.runtime.service import (
    DEFAULT_VESSEL,
    ENV_VESSEL,
    dump_stacks_on_signal,
    on_stop_signals,
)
from seaway.runtime.zenoh_bus import ENV_CONFIG, use_lockstep_runtime
from seaway.simkit.scenario import load_scenario
from seaway.tools.launch import address, authority, recording_source
from seaway.tools.launch.mission_end import MissionEnd, MissionsTaken
from seaway.tools.launch.profile import Instance, Profile, instances, load_profile, substitute
from seaway.tools.launch.resume import RESUME_WAIT_S, LinkTender
from seaway.tools.launch.status_line import StatusLine
from seaway.tools.launch.supervisor import Supervised, Supervisor, default_echo
from seaway.vessel.energy_prediction import known_poor


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway launch", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("profile", help="profile name (deploy/profiles/<name>.toml) or path")
    ap.add_argument("--vessel", default=None,
                    help=f"the vessel of a one-vessel profile (default ${ENV_VESSEL} or "
                         f"{DEFAULT_VESSEL})")
    ap.add_argument("--vessels", type=_vessel_list, default=None, metavar="V1,V2,...",
                    help="a fleet profile's vessels (default: the profile's 'vessels')")
    ap.add_argument("--scenario", default=None, help="scenario name or path (profile's default)")
    ap.add_argument("--run-dir", type=Path, default=None,
                    help="default runs/<time>-<profile>, or runs/<time>-<profile>-<scenario>-"
                         "<controller>[-tauD] when a mission is sent")
    ap.add_argument("--no-mission", action="store_true", help="do not send the scenario's mission")
    ap.add_argument("--tiles", default=None, metavar="URL|DIR|FILE",
                    help="the ground station's map tiles: an http(s) URL template with {z}/{x}/{y}, "
                         "a folder <z>/<x>/<y>.png or an MBTiles file (*.mbtiles) it serves itself "
                         "(default: the profile's tiles, else none: a metric grid, offline)")
    ap.add_argument("--controller", choices=CONTROLLER_NAMES, default=None,
                    help="fly the mission with this controller (default: the mission's)")
    ap.add_argument("--predict-disturbance", action=argparse.BooleanOptionalAction, default=None,
                    help="the mission predicts with the estimator's tau_d instead of tau_d = 0 "
                         "(the paper's); default: the mission's")
    ap.add_argument("--task-power-w", type=_task_power, default=None, metavar="W",
                    help=f"the mission's task power T^w [W], in (0, {MAX_TASK_POWER_W:g}] "
                         "(default: the mission's)")
    ap.add_argument("--stay", action="store_true", help="keep running after the mission completes")
    ap.add_argument("--resume-wait", type=positive_float, default=RESUME_WAIT_S, metavar="S",
                    help="real time: how long a mission paused by a restart of vehicle_io or the sim "
                         "may wait for the autopilot (armed) before the run ends it (default "
                         f"{RESUME_WAIT_S:g} s; seaway.tools.launch.resume)")
    ap.add_argument("--verbose", action="store_true", help="show every process's output")
    ap.add_argument("--no-report", action="store_true",
                    help="skip the final report (metrics, plots) after the stop; make it later with "
                         "'seaway report RUN_DIR' (a study reads each recording itself)")
    ap.add_argument("--recording", type=Path, default=None, help="recording for the replay profile")
    ap.add_argument("--control-period-s", type=positive_float, default=None,
                    help=f"the run's control period [s] (default {runs.CONTROL_PERIOD_S})")
    ap.add_argument("--cpus", type=_cpu_list, default=None, metavar="LIST",
                    help="run the whole stack (this launcher, every process it starts, their "
                         "threads) on these CPUs only, e.g. 0 or 0-1,4; in lockstep with two or "
                         "more, the sim, estimator and controller on the lowest, the rest on the "
                         "others (default: wherever the kernel puts them; seaway.runtime.cpus says "
                         "when it pays)")
    ap.add_argument("--check", action="store_true", help="validate the profile and exit")
    return ap


def _cpu_list(text: str) -> frozenset[int]:
    try:
        return cpus.parse_cpus(text)
    except cpus.CpuSetError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _task_power(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of watts") from None
    if not math.isfinite(value) or not 0 < value <= MAX_TASK_POWER_W:
        # The mission's own bound (contract.messages), said before anything starts.
        raise argparse.ArgumentTypeError(f"{text!r}: the task power must be finite, in (0, "
                                         f"{MAX_TASK_POWER_W:g}] W")
    return value


def _vessel_list(text: str) -> list[str]:
    names = [v.strip() for v in text.split(",")]
    if not all(names):
        raise argparse.ArgumentTypeError(f"{text!r}: vessel names separated by commas, none empty")
    return names


def launch_vessels(args: argparse.Namespace, profile: Profile) -> list[str]:
    """The vessels this launch runs: a fleet profile's (``--vessels``, else its list), else the one
    of ``--vessel`` (else ``$SEAWAY_VESSEL``, else the default). ConfigError for the option that
    does not fit the profile."""
    if profile.vessels is None:
        if args.vessels is not None:
            raise ConfigError(f"--vessels: profile {profile.name} runs one vessel (--vessel); "
                              "--vessels is for a fleet profile (one that lists 'vessels', e.g. "
                              "fleet)")
        return [args.vessel or os.environ.get(ENV_VESSEL) or DEFAULT_VESSEL]
    if args.vessel is not None:
        raise ConfigError(f"--vessel: profile {profile.name} runs the vessels it lists "
                          f"({', '.join(profile.vessels)}); choose them with --vessels V1,V2")
    return list(args.vessels or profile.vessels)


def vessel_dir(run_dir: Path, vessel: str, vessels: list[str]) -> Path:
    """A vessel's folder in the run folder: the run folder itself for a launch of one vessel,
    ``<run_dir>/<vessel>`` for several (its run.json, mission.json, recording, report, events)."""
    return run_dir if len(vessels) == 1 else run_dir / vessel


def tiles_for(tiles: str | None) -> str | None:
    """The ground station's tiles as its process needs them: a URL as it is, a file or folder as an
    absolute path (the ground station checks it, and refuses what it cannot serve)."""
    if not tiles or tiles.startswith(("http://", "https://")):
        return tiles or None
    return str(Path(tiles).expanduser().resolve())


def free_udp_ports(n: int) -> list[int]:
    """``n`` distinct UDP ports free on loopback now (``{mavlink_port}``: each simulated
    autopilot of a fleet listens on its own)."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks.append(s)
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def supervised(plan: list[Instance], vessels: list[str], run_dir: Path,
               common: dict[str, str]) -> list[Supervised]:
    """The processes of ``plan`` with their commands' placeholders filled in: ``common`` (the
    launch's) and each one's vessel's ``{vessel}``, ``{run}``, ``{vessel_dir}``,
    ``{mavlink_port}`` (a free UDP port per vessel) and ``{vessel_index}`` (its place in
    ``vessels``, from 0). ConfigError for an unknown placeholder."""
    ports = dict(zip(vessels, free_udp_ports(len(vessels)), strict=True))
    out = []
    for inst in plan:
        folder = vessel_dir(run_dir, inst.vessel, vessels)
        values = {**common, "vessel": inst.vessel, "run": str(folder / recording_source.RUN_FILE),
                  "vessel_dir": str(folder if inst.per_vessel or len(vessels) == 1 else run_dir),
                  "mavlink_port": str(ports[inst.vessel]),
                  "vessel_index": str(vessels.index(inst.vessel))}
        out.append(Supervised(inst.spec, substitute(inst.spec.command, values), inst.vessel,
                              folder if inst.per_vessel else None))
    return out


MISSION_OPTIONS = ("controller", "predict_disturbance", "task_power_w")
"""The launch options that change the mission sent (refused when no mission is sent)."""


def profile_path(name_or_path: str) -> Path:
    """The profile file the launcher runs (what ``{profile}`` stands for in a command)."""
    p = Path(name_or_path)
    return p if p.suffix in (".toml", ".json") else deploy_path("profiles", f"{name_or_path}.toml")


def resolve_run(args: argparse.Namespace, profile: Profile, scenario: str,
                run_id: str, vessel: str | None = None) -> runs.RunDescription:
    """The run description of ``vessel`` (default: the launch's one vessel), resolved once here
    and handed to its processes as ``--run``; a fleet's vessels differ only in their name.

    A simulated run takes the model and plant vessel files, origin and dead zone from the scenario;
    the profile's ``vessel_file`` replaces the model, and ``origin_from_scenario = false`` (a boat)
    leaves the origin to the estimator's first GNSS fix. A profile without our simulator (the
    autopilot's own SITL) has no plant vessel file; a replay (``--recording``) of our simulator's
    run is described as that run was. ConfigError on a bad scenario or value.
    """
    vessel = vessel or launch_vessels(args, profile)[0]
    return runs.describe(vessel=vessel, run_id=run_id, clock=profile.clock,
                         scenario=load_scenario(scenario) if scenario else None,
                         scenario_ref=scenario or None,
                         origin_from_scenario=profile.origin_from_scenario,
                         model_vessel_file=profile.vessel_file,
                         # A replay's sensors were made by our simulator on the scenario's hull
                         # (its dead zone, which the estimator predicts with), as in the recording.
                         simulated=(any(p.service == "sim" for p in profile.processes)
                                    or args.recording is not None),
                         control_period_s=args.control_period_s, where="launch")


def run_dir_name(profile: str, scenario: str, mission: MissionRequest | None,
                 stamp: str | None = None) -> str:
    """``<time>-<profile>``, and ``-<scenario>-<controller>[-tauD]`` after it when a mission is sent
    (``-tauD``: the mission predicts with the estimated disturbance)."""
    parts = [stamp or time.strftime("%Y%m%d-%H%M%S"), Path(profile).stem]
    if mission is not None:
        parts += [Path(scenario).stem[:40] or "mission", mission.controller]
        if mission.predict_disturbance:
            parts.append("tauD")
    return re.sub(r"[^A-Za-z0-9._-]", "_", "-".join(parts))


def _run_dir(args: argparse.Namespace, scenario: str = "", mission: MissionRequest | None = None,
             stamp: str | None = None) -> Path:
    """``--run-dir``, else a new folder under ``runs/`` named by ``run_dir_name`` (made unique)."""
    if args.run_dir is not None:
        return args.run_dir
    base = (repo_root() or Path.cwd()) / "runs"
    name = run_dir_name(args.profile, scenario, mission, stamp)
    path, n = base / name, 1
    while path.exists():
        n += 1
        path = base / f"{name}-{n}"
    return path


def earlier_recordings(run_dir: Path, vessels: list[str]) -> list[Path]:
    """The recordings an earlier launch left where this one would write its own (the run folder,
    or each vessel's folder in it): none for a fresh folder.

    A recorder never overwrites (``recording.restart-001.mcap`` goes beside), and the report and
    the study read every recording of a folder: missions of two launches, often with the same
    ids, would pass for one run's."""
    folders = dict.fromkeys(vessel_dir(run_dir, v, vessels) for v in vessels)
    return sorted(p for f in folders if f.is_dir() for p in f.glob("*.mcap"))


def _mission_request(scenario_name: str, args: argparse.Namespace | None = None
                     ) -> MissionRequest | None:
    """The scenario's mission as the launcher sends it, with the launch's mission options applied;
    None if the scenario has none. ConfigError if the options make it invalid."""
    sc = load_scenario(scenario_name)
    if sc.mission is None:
        return None
    try:
        return sc.mission.to_request(time.time_ns(), mission_id=sc.name,
                                     controller=getattr(args, "controller", None),
                                     predict_disturbance=getattr(args, "predict_disturbance", None),
                                     task_power_w=getattr(args, "task_power_w", None))
    except MessageError as err:
        raise ConfigError(f"scenario {sc.name}: mission: {err}") from None


def _mission_options(args: argparse.Namespace) -> list[str]:
    """The mission options given on the command line, spelled as flags."""
    return [f"--{o.replace('_', '-')}" for o in MISSION_OPTIONS if getattr(args, o) is not None]


REPORT_TIMEOUT_S = 120.0  # the final report is skipped (with the command to make it) past this
LINK_WAIT_S = 20.0  # how long the start-up requests wait for vehicle_io's autopilot link


def _required_failure(sup: Supervisor) -> str | None:
    """Notice exits now; the failure of a required process, with its log's tail, else None."""
    sup.poll()
    failed = sup.failed_required()
    if not failed:
        return None
    return (f"required process(es) failed: {', '.join(failed)}\n"
            + "\n".join(sup.log_tail(name) for name in failed))


def _operator_requests(bus: Bus, profile: Profile, stop: threading.Event, vessel: str,
                       label: str = "", failure: Callable[[], str | None] = lambda: None) -> bool:
    """The profile's start-up mode and arming of ``vessel``, as explicit requests with their
    replies shown (each line begins with ``label``: a fleet's ``<vessel>: ``).

    vehicle_io is ready when it serves requests, which can be before it has heard the autopilot;
    so the requests wait for a VehicleStatus with the link up, as an operator would. ``failure``
    is asked while waiting: a required process that failed meanwhile (the autopilot's SITL, say)
    ends the wait with its reason instead of a timeout.
    """
    if not (profile.mode_on_start or profile.arm_on_start):
        return True
    status = bus.subscribe(keys.VEHICLE_STATUS, mode="latest", vessel=vessel)
    deadline = time.monotonic() + LINK_WAIT_S
    while True:
        msg = status.get(0.5)
        if msg is not None and msg.link_ok:
            break
        if stop.is_set():
            return True  # stopping anyway: not a failure of the start
        failed = failure()
        if failed:
            print(f"\nseaway launch: {failed}", file=sys.stderr, flush=True)
            return False
        if time.monotonic() > deadline:
            print(f"{label}no autopilot link reported by vehicle_io within {LINK_WAIT_S:g} s; "
                  "not sending mode or arming", flush=True)
            return False
    status.undeclare()
    if profile.mode_on_start:
        reply = bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                                mode=profile.mode_on_start),
                            timeout_s=10.0, vessel=vessel)
        print(f"{label}mode {profile.mode_on_start}: "
              f"{'accepted' if reply.accepted else 'REFUSED: ' + reply.reason}", flush=True)
        if not reply.accepted:
            return False
    if profile.arm_on_start:
        return _arm(bus, profile.arm_wait_s, stop, vessel, label, failure)
    return True


ARM_RETRY_S = 5.0  # between arming requests while the autopilot refuses (profile.arm_wait_s)


def _arm(bus: Bus, wait_s: float, stop: threading.Event, vessel: str, label: str,
         failure: Callable[[], str | None]) -> bool:
    """Ask to arm; while refused, ask again every ``ARM_RETRY_S`` for up to ``wait_s``, printing each
    new reason once (an autopilot still converging says why, and the reason changes as it does)."""
    t0 = time.monotonic()
    said = ""
    while True:
        reply = bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                            timeout_s=10.0, vessel=vessel)
        waited = time.monotonic() - t0
        if reply.accepted:
            print(f"{label}arm: accepted" + (f" after {waited:.0f} s" if said else ""), flush=True)
            return True
        if stop.is_set() or waited + ARM_RETRY_S > wait_s:
            print(f"{label}arm: REFUSED: {reply.reason}"
                  + (f" (asked for {waited:.0f} s)" if wait_s else ""), flush=True)
            return stop.is_set()
        failed = failure()
        if failed:
            print(f"\nseaway launch: {failed}", file=sys.stderr, flush=True)
            return False
        if reply.reason != said:
            print(f"{label}arm: not yet ({reply.reason}); asking again every {ARM_RETRY_S:g} s for "
                  f"up to {wait_s:g} s", flush=True)
            said = reply.reason
        if stop.wait(ARM_RETRY_S):
            return True


def show_groundstations(sup: Supervisor, run_dir: Path, shown: dict[str, int]) -> None:
    """Print the page's address of each ground station that became ready since the last call
    (``shown``: process name -> the pid whose address was printed), read from the address file it
    wrote before it declared itself ready. A file of another pid is a leftover, not its address."""
    for name, sp in sup.procs.items():
        if sp.spec.service != "groundstation" or sp.state != "ready" or shown.get(name) == sp.pid:
            continue
        shown[name] = sp.pid or 0
        try:
            where = address.read(run_dir)
        except address.AddressError as err:
            print(f"ground station: no address ({err}); see {sup.logs / f'{name}.log'}", flush=True)
            continue
        if where.pid != sp.pid:
            print(f"ground station: {address.address_path(run_dir)} is from process {where.pid}, "
                  f"not the running {sp.pid} (was it started with --run-dir {run_dir}?)", flush=True)
            continue
        print(f"ground station: {where.page}", flush=True)




def _check_mission(mission: MissionRequest | None, scenario: str) -> int:
    """``--check``: the mission sent checked as the controller checks it (``seaway mission
    check``), against the scenario; 0 ok (or no mission), 1 refused, 2 unreadable."""
    if mission is None or not scenario:
        return 0
    from seaway.tools import mission_check_cli

    try:
        out = mission_check_cli.check_request(mission, load_scenario(scenario))
    except (ConfigError, ValueError, RuntimeError) as err:
        print(f"seaway launch: mission check: {err}", file=sys.stderr)
        return 2
    print(mission_check_cli.show(out))
    return 0 if out["verdict"] == "ok" else 1

def _rally_points(scenario: str) -> tuple[tuple[float, float], ...]:
    """The rally points of ``scenario``'s operating area (local NED, m); none without one."""
    if not scenario:
        return ()
    area = load_scenario(scenario).operating_area()
    return () if area is None else tuple(r.position_m for r in area.rally_points)

def main(argv: list[str]) -> int:
    # First, before any thread: the launcher lives as long as the run and is off the control path
    # (seaway.runtime.memory says why its memory grew without it).
    memory.cap_malloc_arenas()
    args = parser().parse_args(argv)
    # Everything the launch writes (run folder, recording, logs, registry, credentials) and what its
    # processes write is the user's alone: 0600 files, 0700 folders (seaway.runtime.private).
    os.umask(PRIVATE_UMASK)
    if args.cpus is not None:  # first: every thread and process started later inherits it
        try:
            cpus.pin_threads(0, args.cpus)
        except OSError as err:  # e.g. a container that forbids it: said, nothing started
            print(f"seaway launch: --cpus {cpus.format_cpus(args.cpus)}: this process cannot be "
                  f"kept on those CPUs: {err}", file=sys.stderr)
            return 2
    dump_stacks_on_signal()
    try:
        profile: Profile = load_profile(args.profile)
    except ConfigError as err:
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    takes = recording_source.takes_recording([spec.command for spec in profile.processes])
    if problem := recording_source.recording_problem(profile.name, takes, args.recording):
        print(f"seaway launch: {problem}", file=sys.stderr)
        return 2
    try:
        # A replay's estimator and controller need the recorded run's scenario (its model, origin
        # and mission): without one they wait for a mission that never comes.
        scenario = (args.scenario or (recording_source.recorded_scenario(args.recording) if takes
                                      else profile.scenario) or "")
        mission = (_mission_request(scenario, args) if profile.mission_on_start and scenario
                   and not args.no_mission else None)
    except ConfigError as err:
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    given = _mission_options(args)
    if mission is None and given:
        why = ("--no-mission was given" if args.no_mission
               else f"profile {profile.name} sends no mission" if not profile.mission_on_start
               else "the profile names no scenario and --scenario was not given" if not scenario
               else f"scenario {scenario} has no [mission]")
        print(f"seaway launch: {', '.join(given)}: option(s) of the mission sent, but this launch "
              f"sends no mission ({why})", file=sys.stderr)
        return 2
    run_dir = _run_dir(args, scenario, mission)
    try:
        vessels = launch_vessels(args, profile)
        plan = instances(profile, vessels)
        runs_of = {v: resolve_run(args, profile, scenario, run_dir.name, v) for v in vessels}
    except (ConfigError, ValueError) as err:
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    if held := earlier_recordings(run_dir, vessels):
        shown = ", ".join(str(p) for p in held[:3]) + (", ..." if len(held) > 3 else "")
        print(f"seaway launch: --run-dir {run_dir} holds an earlier launch's recording ({shown}); "
              f"a launch needs a run folder of its own: give a new --run-dir, leave it out "
              f"(a fresh folder under runs/), or move those away", file=sys.stderr)
        return 2
    common = {"scenario": scenario, "run_dir": str(run_dir),
              "profile": str(profile_path(args.profile)), "recording": str(args.recording or ""),
              "mavlink_key": str(authority.mavlink_key_path(run_dir.name))}
    try:
        procs = supervised(plan, vessels, run_dir, common)
    except ConfigError as err:
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    if args.check:
        print(f"profile {profile.name}: {len(procs)} processes"
              + (f" for vessels {', '.join(vessels)}" if len(vessels) > 1 else "") + ", valid"
              + (f"; mission {mission.mission_id} ({_describe_mission(mission)})"
                 if mission is not None else ""))
        return _check_mission(mission, scenario)

    try:
        auth = authority.credentials_for(profile, run_dir.name)
        if not profile.zenoh_config:
            # The default peer config meets on one rendezvous endpoint: one stack per endpoint.
            # A deployment config (boat, shore) names its own endpoints, in its own namespace.
            authority.claim(auth, profile, run_dir, ",".join(vessels))
    except (authority.StackInUseError, CredentialsError, AccessError) as err:
        if "auth" in locals():
            auth.release()
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    try:
        return _launch(args, profile, scenario, mission, run_dir, runs_of, procs, auth)
    finally:
        auth.release()


def _launch(args: argparse.Namespace, profile: Profile, scenario: str, mission: MissionRequest | None,
            run_dir: Path, runs_of: dict[str, runs.RunDescription], procs: list[Supervised],
            auth: authority.Authority) -> int:
    """Start the stack, make the profile's requests, watch it until done; stop it."""
    vessels = list(runs_of)
    run = runs_of[vessels[0]]  # the run-wide facts, the same for every vessel of the launch
    if run.lockstep:
        use_lockstep_runtime()  # the launcher's own Zenoh, and so its processes' (zenoh_bus says why)
    placement, split = None, None
    if run.lockstep and args.cpus is not None and (split := cpus.split_chain(args.cpus)):
        # The chain on a CPU of its own; the launcher, and so what it starts but the chain (the
        # recorder), on the others (seaway.runtime.cpus says why).
        cpus.pin_threads(0, split[1])
        placement = dict.fromkeys(CHAIN, split[0])
    env = dict(os.environ)
    env[ENV_VESSEL] = vessels[0]  # each process gets its own vessel's (Supervisor.spawn)
    tiles = tiles_for(args.tiles or profile.tiles)
    if tiles is not None:
        env[address.ENV_TILES] = tiles
    # Every child is a process of this stack: the stack's credentials (or the explicit opt-out).
    env[ENV_CREDENTIALS] = str(auth.credentials.folder) if auth.credentials else NONE
    # Children find their commands next to the interpreter running the launcher (the venv).
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    if profile.zenoh_config:
        env[ENV_CONFIG] = str(deploy_path("zenoh", profile.zenoh_config))
    folders = {v: vessel_dir(run_dir, v, vessels) for v in vessels}
    mission_files: dict[str, Path | None] = dict.fromkeys(vessels)
    for v, folder in folders.items():
        folder.mkdir(parents=True, exist_ok=True)
        runs_of[v].write(folder / recording_source.RUN_FILE)
        if mission is not None:
            mission_files[v] = folder / "mission.json"
            mission_files[v].write_text(mission.model_dump_json(indent=2) + "\n")
    sup = Supervisor(procs, run_dir, env, profile.backoff, default_echo, args.verbose, run.clock,
                     placement)
    stop = threading.Event()
    _install_stop_signals(stop, sup)
    label = {v: f"{v}: " if len(vessels) > 1 else "" for v in vessels}
    print(f"seaway launch {profile.name}: vessel{'s' if len(vessels) > 1 else ''} "
          f"{', '.join(vessels)}, run folder {run_dir}", flush=True)
    print(f"run {run.run_id}: model {run.model_vessel_file}"
          + (f", plant {run.plant_vessel_file}" if run.plant_vessel_file else "")
          + f", period {run.control_period_s:g} s, clock {run.clock}"
          + (f", scenario {run.scenario}" if run.scenario else "")
          + (f", CPUs {cpus.format_cpus(args.cpus)}" if args.cpus is not None else "")
          + (f" (the lockstep chain on {cpus.format_cpus(split[0])}, the rest on "
             f"{cpus.format_cpus(split[1])})" if split else ""), flush=True)
    for note in auth.notes:
        print(note, flush=True)

    # The launcher holds the rendezvous port first: links refused there are counted here. It hears
    # the navigation state every period, so in lockstep it counts drops alone (refusals module).
    refusals.watch("launcher", full=not run.lockstep)
    try:
        bus = Bus.open(vessels[0], env.get(ENV_CONFIG), identity="launcher",
                       credentials=auth.credentials or NONE)
    except RuntimeEnvError as err:  # before any process started: nothing to stop
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    problem = authority.rendezvous_problem(auth, bus)
    if problem is not None:  # before any process started: none of them could link
        bus.close()
        print(f"seaway launch: {problem}", file=sys.stderr)
        return 2
    authority.register(auth)  # now that this session holds the rendezvous port (authority says why)
    refusals.serve(bus, "launcher")
    code = 0
    t0 = time.monotonic()
    taken = MissionsTaken(vessels)
    try:
        # The launcher's own token on each vessel (``seaway health`` lists it); not one of the
        # processes it supervises, so the supervisor does not hear it. A shore launcher's would be
        # the boat's to refuse: it declares none.
        bus.watch_fleet_health(lambda v, service, alive: service != "launcher"
                               and sup.on_health(v, service, alive))
        if profile.side != "shore":
            for v in vessels:
                bus.declare_alive("launcher", vessel=v)
        # What the processes must keep publishing (liveness): heard here, so a hung one is seen.
        sup.watch_on(bus)
        status = StatusLine(vessels, lockstep=run.lockstep, commands=mission is None)
        status.watch(bus)
        taken.watch(bus)  # which vessels' controllers take a mission (the launcher's or another's)
        ending = MissionEnd(vessels, mission, None if not run.lockstep
                            else round(run.control_period_s * 1e9), _rally_points(scenario))
        ending.watch(bus)
        error = sup.start_all(stop)
        if error:
            print(f"seaway launch: {error}", file=sys.stderr)
            code = 1 if not stop.is_set() else 0
            return code
        print(sup.status_table(), flush=True)
        print(f"all ready in {time.monotonic() - t0:.1f} s", flush=True)
        shown: dict[str, int] = {}
        show_groundstations(sup, run_dir, shown)
        for v in vessels:
            if not _operator_requests(bus, profile, stop, v, label[v], lambda: _required_failure(sup)):
                code = 1
                return code
        refused = []
        for v in vessels:
            if mission is None or stop.is_set():
                break
            reply = bus.request(keys.MISSION_SET, mission, timeout_s=10.0, vessel=v)
            for line in mission_reply_lines(mission, reply):
                print(f"{label[v]}{line}", flush=True)
            if not reply.accepted:
                refused.append(v)
        if refused and profile.stop_when_complete and not args.stay:
            # A batch run ends when its mission does: one refused never will.
            print(f"seaway launch: the mission was refused ({', '.join(refused)}); nothing to "
                  "fly (seaway mission check says why before a launch)", file=sys.stderr, flush=True)
            code = 1
            return code
        t_run = time.monotonic()
        tender = None if mission is None or run.lockstep else LinkTender(
            bus, sup, vessels, mission, profile.mode_on_start, args.resume_wait)
        while not stop.wait(0.2):
            sup.poll()
            show_groundstations(sup, run_dir, shown)  # again after a restart: a new address
            failed = sup.failed_required()
            if failed:
                print(f"\nseaway launch: required process(es) failed: {', '.join(failed)}",
                      file=sys.stderr)
                for name in failed:
                    print(sup.log_tail(name), file=sys.stderr)
                code = 1
                break
            status.show(time.monotonic() - t_run)
            taken.look()
            ended = tender.step(time.monotonic(), label) if tender is not None else None
            if ended:  # a mission paused by a link restart that could not be resumed
                status.show(time.monotonic() - t_run, final=True)
                print(f"\nseaway launch: {ended}", file=sys.stderr, flush=True)
                code = 1
                break
            if profile.stop_after and sup.procs[profile.stop_after].state == "exited":
                status.show(time.monotonic() - t_run, final=True)
                print(f"{profile.stop_after} finished", flush=True)
                break
            # Completion counts only for the mission this launcher sent (and, by the access rules,
            # only from the controller), bounded and borne out by the navigation state
            # (mission_end), on every vessel: a status of some other mission stops nothing.
            if profile.stop_when_complete and not args.stay and ending.over(time.time_ns()):
                status.show(time.monotonic() - t_run, final=True)
                print("mission complete", flush=True)
                break
        else:
            status.show(time.monotonic() - t_run, final=True)
    finally:
        # The run is over, whatever ended it: from here on a Ctrl-C hurries the stop and skips the
        # report (after a completed mission the first Ctrl-C only set ``stop``: the report went on).
        stop.set()
        print("stopping...", flush=True)
        t_stop = time.monotonic()
        flown = taken.look()
        sup.stop_all()
        bus.close()
        print(sup.status_table())
        print(f"stopped in {time.monotonic() - t_stop:.1f} s; logs in {run_dir / 'logs'}",
              flush=True)
        hurried = sup.hurried
        for v in vessels:
            if len(vessels) > 1:
                print(f"\n{v}:", flush=True)
            if sup.hurried > hurried:  # a Ctrl-C during an earlier vessel's report skips the rest
                print(f"(report skipped: Ctrl-C; make it with: seaway report {folders[v]})")
                continue
            _final_report(folders[v], scenario, mission_files[v], sup, make=not args.no_report,
                          idle_vessel=None if v in flown else v)
    return code


def _install_stop_signals(stop: threading.Event, sup: Supervisor) -> None:
    """SIGINT or SIGTERM stops the run (``stop``); every further Ctrl-C hurries the stop: shorter
    graces, the same order, the recorder's file finished, and the report skipped if it is running."""

    def act(signum: int) -> None:  # on_stop_signals' own thread, not in a handler
        if not stop.is_set():
            stop.set()
            return
        if signum == signal.SIGINT:
            sup.hurry()  # no printing here: the main thread may be inside a write to the terminal

    on_stop_signals(act)


def mission_reply_lines(mission: MissionRequest, reply: Reply) -> list[str]:
    """What the launcher prints of the controller's reply to the mission it sent; a warning below
    an acceptance when the controller's energy prediction is known to be poor, so that the 'to
    finish' and 'to home' on the status line are not read as more than they are."""
    # An acceptance can carry news too (its solver is still being made, say).
    said = ("accepted" + ("" if reply.reason in ("", "mission started") else f" ({reply.reason})")
            if reply.accepted else "REFUSED: " + reply.reason)
    lines = [f"mission {mission.mission_id}: {said} ({_describe_mission(mission)})"]
    if reply.accepted and (poor := known_poor(mission.controller)):
        lines.append(f"WARNING: {poor}")
    return lines


def _describe_mission(mission: MissionRequest) -> str:
    """What the mission options chose, e.g. ``nmpc, predicting the estimated tau_d, T^w 1 W``."""
    return (f"{mission.controller}, "
            + ("predicting the estimated tau_d" if mission.predict_disturbance else "tau_d = 0")
            + f", T^w {mission.task_power_w:g} W")


def _final_report(run_dir: Path, scenario: str, mission_file: Path | None = None,
                  sup: Supervisor | None = None, make: bool = True,
                  idle_vessel: str | None = None) -> None:
    """The run's metrics (from its recording, by ``seaway report``) and where the recording is;
    with ``make`` False (``--no-report``) only where the recording is, and how to make the report.

    The report takes the mission from ``mission_file`` (what the launcher sent, options applied)
    when there is one, else from what the recording holds. An ``idle_vessel`` (one the launcher
    sent no mission and whose controller accepted none either: a fleet's vessel the operator left
    idle) gets no report, and that is said. The report runs in a session of its own, so that a Ctrl-C
    reaches only the launcher, which then stops it and says how to make it later."""
    recordings = sorted(run_dir.glob("*.mcap"))
    if not recordings:
        return
    print(f"recording: {', '.join(str(r) for r in recordings)}", flush=True)
    if idle_vessel is not None and mission_file is None:
        # The report would judge the scenario's path, which the vessel was never sent (a fleet's
        # missions come from the operator).
        print(f"(no report: vessel {idle_vessel} flew no mission in this run)", flush=True)
        return
    seaway = shutil.which("seaway", path=str(Path(sys.executable).parent)) or "seaway"
    cmd = [seaway, "report", str(run_dir), "--out", str(run_dir / "report")]
    if scenario:
        cmd += ["--scenario", scenario]
    if mission_file is not None:
        cmd += ["--mission", str(mission_file)]
    if not make:
        print(f"(report skipped: --no-report; make it with: {' '.join(cmd)})", flush=True)
        return
    hurried = sup.hurried if sup is not None else 0
    console = Console(file=sys.stdout)  # the real stdout: fd 1 is the refusal counter's pipe
    # (seaway.runtime.refusals). The report's output is kept until it is done, then shown whole, so
    # that the progress line and the report's table do not tear each other.
    with tempfile.TemporaryFile("w+") as out:
        try:
            sys.stdout.flush()
            proc = subprocess.Popen(cmd, start_new_session=True, stdout=out, stderr=subprocess.STDOUT)
        except OSError as err:
            print(f"(no report: {err})")
            return
        t0 = time.monotonic()
        if not console.is_terminal:
            print("making the report (metrics, plots) ...", flush=True)
        with console.status("making the report (metrics, plots) ...") as shown:
            while proc.poll() is None:
                skipped = sup is not None and sup.hurried > hurried
                if skipped or time.monotonic() - t0 > REPORT_TIMEOUT_S:
                    proc.kill()
                    proc.wait()
                    shown.stop()
                    why = "Ctrl-C" if skipped else f"it took over {REPORT_TIMEOUT_S:g} s"
                    print(f"(report skipped: {why}; make it with: {' '.join(cmd)})", flush=True)
                    return
                shown.update(f"making the report (metrics, plots): {time.monotonic() - t0:4.0f} s")
                time.sleep(0.05)
        out.seek(0)
        sys.stdout.write(out.read())
        sys.stdout.flush()
