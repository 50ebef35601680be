"""A launch's run, from start to stop: the environment its processes get, the run folder's files,
the bus, the start-up requests and the mission, the watch loop with its status line, the stop in
order on Ctrl-C or SIGTERM, and the report per vessel (``seaway.tools.launch.main`` decides what
to run; this runs it). Times are seconds of monotonic time; mission points local NED, m.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from pathlib import Path

from seaway.contract import keys
from seaway.contract.config import deploy_path
from seaway.contract.messages import MissionRequest
from seaway.runtime import cpus, host, refusals
from seaway.runtime import run as runs
from seaway.runtime.bus import Bus, RuntimeEnvError
from seaway.runtime.credentials import ENV_CREDENTIALS, NONE
from seaway.runtime.lockstep import CHAIN
from seaway.runtime.service import ENV_VESSEL, on_stop_signals
from seaway.runtime.zenoh_bus import ENV_CONFIG, use_lockstep_runtime
from seaway.simkit.scenario import load_scenario
from seaway.tools.launch import address, authority, recording_source
from seaway.tools.launch.final_report import _final_report
from seaway.tools.launch.mission_end import MissionEnd, MissionsTaken
from seaway.tools.launch.plan import tiles_for, vessel_dir
from seaway.tools.launch.profile import Profile
from seaway.tools.launch.resume import LinkTender
from seaway.tools.launch.startup_requests import _operator_requests, mission_reply_lines
from seaway.tools.launch.status_line import StatusLine
from seaway.tools.launch.supervisor import Supervised, Supervisor, default_echo

EXIT_MISSION_TIME = 3
"""The launcher's exit code when ``--max-mission-s`` ran out before the mission ended (the run is
stopped in order and its report made, as after any stop)."""
EXIT_WENT_WITHOUT = 4
"""The launcher's exit code after an otherwise clean stop of a run that went on without a process
the profile does not require, which failed for good (``Supervisor.failed_optional``): in real time
the recorder is one, so the recording ends early."""


def _required_failure(sup: Supervisor) -> str | None:
    """Notice exits now; the failure of a required process, with its log's tail, else None."""
    sup.poll()
    failed = sup.failed_required()
    if not failed:
        return None
    return (f"required process(es) failed: {', '.join(failed)}\n"
            + "\n".join(sup.log_tail(name) for name in failed))


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


def _rally_points(scenario: str) -> tuple[tuple[float, float], ...]:
    """The rally points of ``scenario``'s operating area (local NED, m); none without one."""
    if not scenario:
        return ()
    area = load_scenario(scenario).operating_area()
    return () if area is None else tuple(r.position_m for r in area.rally_points)


def _launch(args: argparse.Namespace, profile: Profile, scenario: str, mission: MissionRequest | None,
            run_dir: Path, runs_of: dict[str, runs.RunDescription], procs: list[Supervised],
            auth: authority.Authority) -> int:
    """Start the stack, make the profile's requests, watch it until done; stop it."""
    vessels = list(runs_of)
    run = runs_of[vessels[0]]  # the run-wide facts, the same for every vessel of the launch
    if run.lockstep:
        use_lockstep_runtime()  # the launcher's own Zenoh, and so its processes' (zenoh_bus says why)
    composed = host.active() is not None  # services as nodes of this process (runtime.host)
    placement, split = None, None
    # A composed stack is one process: its chain has no process of its own to place.
    if (run.lockstep and args.cpus is not None and not composed
            and (split := cpus.split_chain(args.cpus))):
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
                     placement, finishes=frozenset([profile.stop_after] if profile.stop_after else []))
    stop = _stop_event(sup)
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
    # Composed, there is no network to refuse anyone, and the watch would take this process's
    # stdout from the host, which routes each node's output to its own log.
    if not composed:
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
    if not composed:
        refusals.serve(bus, "launcher")
    code = 0
    t0 = time.monotonic()
    taken = MissionsTaken(vessels)
    try:
        # The launcher's own token on each vessel (``seaway health`` lists it); not one of the
        # processes it supervises, so the supervisor does not hear it. A shore launcher's would be
        # the boat's to refuse: it declares none. On a shore, only the shore's own tokens stand
        # for its processes (keys.own_service), never the boat's of the same service.
        def on_token(v: str, token: str, alive: bool) -> None:
            service = keys.own_service(token, profile.side)
            if service is not None and service != "launcher":
                sup.on_health(v, service, alive)

        bus.watch_fleet_health(on_token)
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
            status.without = sup.failed_optional_by_vessel()
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
            stops_when_over = profile.stop_when_complete and not args.stay
            timed = args.max_mission_s is not None
            over = (stops_when_over or timed) and ending.over(time.time_ns())
            if stops_when_over and over:
                status.show(time.monotonic() - t_run, final=True)
                print("mission complete", flush=True)
                break
            spent = ending.timed_out(args.max_mission_s) if timed else None
            if spent is not None:
                status.show(time.monotonic() - t_run, final=True)
                print(f"\nseaway launch: the mission did not end within --max-mission-s "
                      f"{args.max_mission_s:g} s ({spent:.1f} s of "
                      f"{'simulated' if run.lockstep else 'wall-clock'} time since it was sent); "
                      "stopping the run", file=sys.stderr, flush=True)
                code = EXIT_MISSION_TIME
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
        without = sup.failed_optional()
        if without:
            print(f"seaway launch: the run went on without {', '.join(without)}, which failed for "
                  "good (its log and the status table above say why)", file=sys.stderr, flush=True)
            if code == 0:
                code = EXIT_WENT_WITHOUT
    return code


def _stop_event(sup: Supervisor) -> threading.Event:
    """What stops the run: the node's own stop when the launcher runs as a node of a composed
    process (``seaway.runtime.host``: signals are that process's, and whoever composes it stops
    the launcher as the launcher stops its services, ``NodeThread.send_signal``), else SIGINT or
    SIGTERM (``_install_stop_signals``)."""
    node = host.Host.current()
    if node is not None:
        return node.stop
    stop = threading.Event()
    _install_stop_signals(stop, sup)
    return stop


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
