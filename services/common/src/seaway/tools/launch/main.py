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

``--max-mission-s S`` ends a run whose mission has not ended S seconds after it was sent (simulated
time in lockstep, the wall clock in real time): a batch run whose vessel cannot finish (a current
stronger than its thrust, a waypoint it cannot reach) stops instead of running on. In lockstep the
sim's clock holds at the last control period at or before S (its ``--until-s``), so the recording
ends there however fast the run goes; in real time the launcher stops the run at its first look
(five a second) after S. The run is stopped in order and its report made, as after Ctrl-C.

A process the profile does not require (the ground station; in real time the recorder too: a card
gone read-only must not end a boat's control loop) that fails for good is left out, and the run
goes on without it: the launcher says so at once and again at the end.

Exit code: 0 after a clean stop (Ctrl-C, SIGTERM, or the mission completed with
``stop_when_complete``); 1 when a required process failed or could not start; 2 for a bad profile
or option; 3 when ``--max-mission-s`` ran out; 4 after an otherwise clean stop of a run that went on
without a process that failed for good (a recording that ends early).
"""

# The docstring above is ``seaway launch --help``. This module holds the options and everything
# decided before a process starts (the profile, scenario, mission, vessels, run folder, the
# check); ``plan`` fills in the processes, ``stack`` runs them, ``startup_requests`` makes the
# start-up requests and ``final_report`` the report.

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
from pathlib import Path

from seaway.contract.access import AccessError
from seaway.contract.config import ConfigError, repo_root
from seaway.contract.messages import (
    CONTROLLER_NAME_PATTERN,
    CONTROLLER_NAMES,
    MAX_TASK_POWER_W,
    MessageError,
    MissionRequest,
)
from seaway.ros2.rmw import DEFAULT_ROUTER, ROS_DOMAIN_MAX
from seaway.runtime import cpus, host, memory
from seaway.runtime import run as runs
from seaway.runtime.argtypes import positive_float, whole_number
from seaway.runtime.credentials import CredentialsError
from seaway.runtime.private import PRIVATE_UMASK
from seaway.runtime.service import (
    DEFAULT_VESSEL,
    ENV_VESSEL,
    dump_stacks_on_signal,
)
from seaway.simkit.scenario import load_scenario
from seaway.tools.launch import authority, recording_source, run_lock
from seaway.tools.launch.plan import launch_vessels, profile_path, resolve_run, supervised, vessel_dir
from seaway.tools.launch.profile import Profile, instances, load_profile, with_ros2
from seaway.tools.launch.resume import RESUME_WAIT_S
from seaway.tools.launch.stack import _launch
from seaway.tools.launch.startup_requests import _describe_mission
from seaway.tools.launch.supervisor import Supervised


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
    ap.add_argument("--controller", type=_controller_name, default=None,
                    help=f"fly the mission with this controller: {', '.join(CONTROLLER_NAMES)}, or "
                         "one a --controller-module registers (default: the mission's)")
    ap.add_argument("--controller-module", type=_controller_module, action="append", default=[],
                    metavar="FILE|MODULE",
                    help="a controller of one's own, handed to every controller process: a .py "
                         "file or an importable module that registers it (docs/researcher/"
                         "new-controller.md); repeatable")
    ap.add_argument("--predict-disturbance", action=argparse.BooleanOptionalAction, default=None,
                    help="the mission predicts with the estimator's tau_d instead of tau_d = 0 "
                         "(the paper's); default: the mission's")
    ap.add_argument("--task-power-w", type=_task_power, default=None, metavar="W",
                    help=f"the mission's task power T^w [W], in (0, {MAX_TASK_POWER_W:g}] "
                         "(default: the mission's)")
    ap.add_argument("--stay", action="store_true", help="keep running after the mission completes")
    ap.add_argument("--resume-wait", type=positive_float, default=RESUME_WAIT_S, metavar="S",
                    help="real time: how long a mission paused by an interruption of the link (a "
                         "restart of vehicle_io or the sim, a loss of the autopilot) may wait for "
                         "the autopilot (armed) before the run ends it (default "
                         f"{RESUME_WAIT_S:g} s; seaway.tools.launch.resume)")
    ap.add_argument("--max-mission-s", type=positive_float, default=None, metavar="S",
                    help="stop the run, exit 3, when the mission has not ended S s after it was "
                         "sent (simulated time in lockstep, wall clock in real time)")
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
    ap.add_argument("--ros2", action="store_true",
                    help="add the ROS 2 face (seaway-ros2, docs/ros2.md): Seaway's state as ROS 2 "
                         "topics over rmw_zenoh, read only unless --ros2-writes")
    ap.add_argument("--ros2-connect", action="append", default=None, metavar="ENDPOINT",
                    help=f"with --ros2: rmw_zenohd's Zenoh endpoint (default {DEFAULT_ROUTER}; "
                         "repeat for several)")
    ap.add_argument("--ros2-domain", type=whole_number(0, ROS_DOMAIN_MAX), default=None,
                    help="with --ros2: the ROS_DOMAIN_ID (default $ROS_DOMAIN_ID or 0)")
    ap.add_argument("--ros2-writes", action="store_true",
                    help="with --ros2: also take a mission (nav_msgs/Path) and its pause/resume/"
                         "abort (std_msgs/String) from ROS 2, as an operator's requests; the run's "
                         "access rules let the face ask only these (docs/ros2.md)")
    ap.add_argument("--composed", action="store_true",
                    help="a lockstep profile's services as nodes of this one process over the "
                         "in-memory bus (seaway.runtime.host): the same code, the same recording, "
                         "no network; for batch runs and studies (a boat runs processes)")
    ap.add_argument("--check", action="store_true", help="validate the profile and exit")
    return ap


def _cpu_list(text: str) -> frozenset[int]:
    try:
        return cpus.parse_cpus(text)
    except cpus.CpuSetError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _controller_name(text: str) -> str:
    if not re.fullmatch(CONTROLLER_NAME_PATTERN, text):
        raise argparse.ArgumentTypeError(
            f"{text!r}: a controller's name is lower case letters, digits and '-', starting with a "
            f"letter: {', '.join(CONTROLLER_NAMES)}, or one a --controller-module registers")
    return text


def _controller_module(text: str) -> str:
    """A file as an absolute path (the processes run elsewhere), checked to exist; a module name as
    it is (the controller process imports it and says what is wrong)."""
    if text.endswith(".py") or "/" in text or "\\" in text:
        path = Path(text).expanduser().resolve()
        if not path.is_file():
            raise argparse.ArgumentTypeError(f"{text}: no such file (a .py file that registers a "
                                             "controller, or an importable module name)")
        return str(path)
    if not re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*", text):
        raise argparse.ArgumentTypeError(f"{text!r}: neither a .py file nor a module name "
                                         "(e.g. my_package.my_controller)")
    return text


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


MISSION_OVERRIDES = ("controller", "predict_disturbance", "task_power_w")
"""The launch options that replace a mission option of the mission sent (refused when no mission
is sent)."""


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
    return [f"--{o.replace('_', '-')}" for o in MISSION_OVERRIDES if getattr(args, o) is not None]


def hand_time_limit(procs: list[Supervised], max_mission_s: float) -> None:
    """``--max-mission-s`` in lockstep: every sim's clock holds there (``--until-s``), so the run
    stops where the limit says, not wherever the launcher's next look finds it."""
    for p in procs:
        if p.spec.service == "sim":
            p.argv += ["--until-s", repr(max_mission_s)]


def hand_controller_modules(procs: list[Supervised], modules: list[str]) -> bool:
    """``--controller-module``: each module added to the command of every controller process;
    False (nothing changed) when there is none."""
    controllers = [p for p in procs if p.spec.service == "controller"]
    for p in controllers:
        for module in modules:
            p.argv += ["--controller-module", module]
    return bool(controllers)


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
        if args.ros2:
            profile = with_ros2(profile, args.ros2_connect or [DEFAULT_ROUTER], args.ros2_domain,
                                writes=args.ros2_writes)
        elif args.ros2_connect or args.ros2_domain is not None or args.ros2_writes:
            raise ConfigError("--ros2-connect, --ros2-domain and --ros2-writes go with --ros2")
    except ConfigError as err:
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    if args.composed and profile.clock != "lockstep":
        print(f"seaway launch: --composed: profile {profile.name} runs on the wall clock; only a "
              "lockstep profile (sim-batch) composes: a real-time stack talks to an autopilot and "
              "keeps its services apart", file=sys.stderr)
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
    given = _mission_options(args) + (["--max-mission-s"] if args.max_mission_s is not None else [])
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
    if args.controller_module and not hand_controller_modules(procs, args.controller_module):
        print(f"seaway launch: --controller-module: profile {profile.name} runs no controller",
              file=sys.stderr)
        return 2
    if args.max_mission_s is not None and profile.clock == "lockstep":
        hand_time_limit(procs, args.max_mission_s)
    if args.check:
        print(f"profile {profile.name}: {len(procs)} processes"
              + (f" for vessels {', '.join(vessels)}" if len(vessels) > 1 else "") + ", valid"
              + (f"; mission {mission.mission_id} ({_describe_mission(mission)})"
                 if mission is not None else ""))
        return _check_mission(mission, scenario)

    try:  # before anything is written for the run: one launch per run folder (run_lock)
        lock = run_lock.take(run_dir)
    except (run_lock.RunFolderInUseError, OSError) as err:
        print(f"seaway launch: {err}", file=sys.stderr)
        return 2
    try:
        return _locked_launch(args, profile, scenario, mission, run_dir, runs_of, procs, vessels)
    finally:
        lock.release()


def _locked_launch(args: argparse.Namespace, profile: Profile, scenario: str,
                   mission: MissionRequest | None, run_dir: Path, runs_of: dict,
                   procs: list[Supervised], vessels: list[str]) -> int:
    """The launch, once it holds its run folder: its credentials and rendezvous, then ``_launch``."""
    if args.composed:
        # One process, no network: nobody to authenticate, no rendezvous to hold.
        host.activate()
        auth = authority.Authority(credentials=None, rendezvous="", notes=[
            "composed: every service a node of this process, over the in-memory bus"])
        return _launch(args, profile, scenario, mission, run_dir, runs_of, procs, auth)
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
