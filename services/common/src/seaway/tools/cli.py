"""The ``seaway`` command: one entry point for the tools.

Built in: ``launch`` (start a profile), ``bench`` (benchmarks registered by any installed Seaway
package), ``echo`` (print a key's messages), ``health`` (which services are alive), ``schemas``
(write every message's JSON Schema), ``mission`` and ``vehicle`` (the operator's requests to a
running vessel), ``credentials``, ``router``.
Packages add subcommands (launch, record, replay, report, mission, ...) through the entry-point
group ``seaway.commands``: a function ``main(argv: list[str]) -> int``.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from importlib.metadata import entry_points
from pathlib import Path

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import ALL_MESSAGES
from seaway.runtime.argtypes import non_negative_float, whole_number


def _plugins(group: str) -> dict[str, object]:
    return {ep.name: ep for ep in entry_points(group=group)}


def summary(doc: str | None) -> str:
    """A docstring's first sentence without its ````seaway NAME ...``:`` heading: one help line."""
    text = " ".join((doc or "").strip().split("\n\n")[0].split())
    if text.startswith("``") and "``:" in text:
        text = text.split("``:", 1)[1].strip()
    end = text.find(". ")
    return (text[:end] if end >= 0 else text).rstrip(".").replace("``", "")


def _plugin_summary(ep: object) -> str:
    """The one-line summary of a plugin command or benchmark: its module's docstring."""
    import importlib

    try:
        return summary(importlib.import_module(ep.module).__doc__)  # type: ignore[attr-defined]
    except Exception as err:  # a broken plugin must not break the help of the others
        return f"(cannot load: {err})"


def _listing(items: dict[str, str]) -> str:
    width = max(map(len, items), default=0) + 2
    return "\n".join(f"  {name.ljust(width)}{text}" for name, text in sorted(items.items()))


def cmd_bench(argv: list[str]) -> int:
    benches = _plugins("seaway.benchmarks")
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: seaway bench NAME [--json] [options]\n\n"
              "Run one benchmark: a table of its figures, with its targets; --json prints the same "
              "figures as one JSON object. `seaway bench NAME --help` gives its options.\n\n"
              + ("benchmarks:\n" + _listing({n: _plugin_summary(ep) for n, ep in benches.items()})
                 if benches else "benchmarks installed: none (they come with the seaway-lab package)"))
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in benches:
        print(f"seaway bench: no benchmark {name!r}; installed: {', '.join(sorted(benches))}",
              file=sys.stderr)
        return 2
    as_json = "--json" in rest
    rest = [a for a in rest if a != "--json"]
    try:
        result = benches[name].load()(rest)  # type: ignore[attr-defined]
    except ConfigError as err:  # a bad vessel, scenario or config file: say which, no traceback
        print(f"seaway bench {name}: {err}", file=sys.stderr)
        return 2
    print(result.dumps() if as_json else result.table())
    return 0


def _spec_by_key(key: str) -> tuple[keys.KeySpec, str | None]:
    """The registered topic a key names, by suffix (``nav/state``) or in full
    (``seaway/vessel1/nav/state``, ``seaway/*/nav/state``), and the vessel a full key names."""
    vessel = None
    if key.startswith(f"{keys.ROOT}/"):
        parts = key.split("/", 2)
        if len(parts) < 3:
            raise SystemExit(f"seaway echo: {key!r} names no key; e.g. "
                             f"{keys.NAV_STATE.key('vessel1')}")
        vessel, key = parts[1], parts[2]
    spec = keys.spec_for_suffix(key)
    if spec is not None and spec.kind == "topic":
        return spec, vessel
    known = ", ".join(s.suffix for s in keys.REGISTRY if s.kind == "topic")
    raise SystemExit(f"seaway echo: {key!r} is not a registered topic; topics: {known} (a suffix, or "
                     f"in full: {keys.NAV_STATE.key('vessel1')})")


ECHO_LOOK_S = 3.0
"""How long ``seaway echo`` waits for a first message before saying which vessels are on the bus."""


ECHO_POLL_S = 0.05
"""How often ``seaway echo`` looks for new messages when none is waiting [s]."""


def echo_line(key: str, msg: object, every: bool) -> str:
    """One output line of ``seaway echo``: the message as JSON; with ``--vessel '*'`` wrapped as
    ``{"vessel": ..., "message": ...}``, the vessel taken from the key it came on."""
    text = msg.model_dump_json()  # type: ignore[attr-defined]
    if not every:
        return text
    vessel = key.split("/")[1] if key.startswith(f"{keys.ROOT}/") else key
    return f'{{"vessel": {json.dumps(vessel)}, "message": {text}}}'


def cmd_echo(argv: list[str]) -> int:
    from seaway.runtime.bus import Bus
    from seaway.runtime.service import DEFAULT_VESSEL, add_zenoh_config_option, install_stop_signals
    from seaway.tools import vessel_choice

    ap = argparse.ArgumentParser(
        prog="seaway echo", description="print the messages of one key as JSON lines, until Ctrl-C "
                                        "or --count; says which vessels are on the bus if none "
                                        "publishes it")
    ap.add_argument("key", help=f"a registered topic: its suffix ({keys.NAV_STATE.suffix}) or the "
                                f"full key ({keys.NAV_STATE.key('vessel1')})")
    vessel_choice.add_option(ap, wildcard=True)
    ap.add_argument("--count", type=whole_number(0), default=0, help="stop after N messages (0: never)")
    add_zenoh_config_option(ap)
    args = ap.parse_args(argv)
    spec, named = _spec_by_key(args.key)
    named = named or args.vessel
    stop = threading.Event()
    install_stop_signals(stop)
    n = 0
    with Bus.open(named if named and named != "*" else DEFAULT_VESSEL, args.zenoh_config) as bus:
        vessel = vessel_choice.resolve(bus, named, "seaway echo")
        if vessel is None:
            return 2
        every = vessel == "*"  # each line then says whose message it is
        seen: set[str] = set()
        watch = bus.watch_fleet_health(lambda v, _service, alive: seen.add(v) if alive else None)
        sub = bus.subscribe(spec, mode="fifo", vessel=vessel)
        look_until = time.monotonic() + ECHO_LOOK_S
        while not stop.is_set():
            got = sub.drain_with_keys()
            if not got:
                if look_until and time.monotonic() >= look_until:
                    look_until = 0.0
                    if not every and vessel not in seen:
                        print(f"seaway echo: no service of vessel {vessel!r} on the bus; vessels "
                              f"seen: {', '.join(sorted(seen)) or 'none'} (still listening; "
                              "Ctrl-C stops)", file=sys.stderr, flush=True)
                stop.wait(ECHO_POLL_S)
                continue
            for key, msg in got:
                print(echo_line(key, msg, every), flush=True)
                n += 1
                if args.count and n >= args.count:
                    break
            if args.count and n >= args.count:
                break
        watch.undeclare()
    return 0


def cmd_health(argv: list[str]) -> int:
    from seaway.contract.messages import Refusals, VehicleStatus
    from seaway.runtime.bus import Bus
    from seaway.runtime.service import DEFAULT_VESSEL, add_zenoh_config_option
    from seaway.tools import vessel_choice

    ap = argparse.ArgumentParser(
        prog="seaway health",
        description="list the services alive and what each one refused: access control (per "
                    "identity, action and key) and vehicle_io's MAVLink link (per reason)")
    vessel_choice.add_option(ap)
    ap.add_argument("--wait", type=non_negative_float, default=1.0,
                    help="seconds to wait for peers first")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of the table")
    add_zenoh_config_option(ap)
    args = ap.parse_args(argv)
    with Bus.open(args.vessel or DEFAULT_VESSEL, args.zenoh_config) as bus:
        vessel = vessel_choice.resolve(bus, args.vessel, "seaway health")
        if vessel is None:
            return 2
        status = bus.subscribe(keys.VEHICLE_STATUS, vessel=vessel)
        time.sleep(args.wait)
        alive = sorted(bus.alive_services(vessel))
        reports: list[Refusals] = []
        for reply in bus.query_raw(keys.refusals_wildcard(vessel), timeout_s=2.0, every=True):
            if reply.error is not None:
                print(f"seaway health: a refusal report failed: {reply.error}", file=sys.stderr)
                continue
            try:
                reports.append(Refusals.decode(reply.payload))
            except ValueError as err:
                print(f"seaway health: {reply.key} answered a malformed report: {err}", file=sys.stderr)
        latest: VehicleStatus | None = status.latest()
    mavlink = dict(latest.refused_messages) if latest is not None else {}
    reports.sort(key=lambda r: r.identity)
    if args.json:
        print(json.dumps({"vessel": vessel, "alive": alive,
                          "refusals": [r.model_dump(mode="json") for r in reports],
                          "mavlink_refused": mavlink}))
        return 0
    print(f"vessel {vessel}:")
    for s in keys.SERVICES:
        print(f"{s:15s} {'alive' if s in alive else '-'}")
    print("\nrefused by access control (since each process started):")
    if not reports:
        print("  no process answered (none running, or started without authentication)")
    for r in reports:
        print(f"  {r.identity:13s} {r.total:8d}" + ("" if r.total else "  none"))
        for c in sorted(r.counts, key=lambda c: -c.count)[:10]:
            print(f"  {'':13s} {c.count:8d}  {c.identity} {c.action} {c.key}".rstrip())
        if len(r.counts) > 10 or r.overflow:
            print(f"  {'':13s} ... {len(r.counts) - 10 if len(r.counts) > 10 else 0} more kinds, "
                  f"{r.overflow} refusals beyond those listed")
    if latest is not None:
        what = ", ".join(f"{k} {v}" for k, v in sorted(mavlink.items())) or "none"
        print(f"\nMAVLink messages refused by vehicle_io: {what}")
    return 0


def cmd_schemas(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="seaway schemas", description="write every JSON Schema")
    ap.add_argument("out", type=Path, help="folder to write <schema name>.json into")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for m in ALL_MESSAGES:
        (args.out / f"{m.SCHEMA}.json").write_text(json.dumps(m.json_schema(), indent=2) + "\n")
    print(f"wrote {len(ALL_MESSAGES)} schemas to {args.out}")
    return 0


def cmd_launch(argv: list[str]) -> int:
    from seaway.tools.launch.main import main as launch_main

    return launch_main(argv)


def cmd_mission(argv: list[str]) -> int:
    from seaway.tools.mission_cli import main as mission_main

    return mission_main(argv)


def cmd_vehicle(argv: list[str]) -> int:
    from seaway.tools.vehicle_cli import main as vehicle_main

    return vehicle_main(argv)


def cmd_credentials(argv: list[str]) -> int:
    from seaway.tools.credentials_cli import main as credentials_main

    return credentials_main(argv)


def cmd_router(argv: list[str]) -> int:
    from seaway.tools.router import main as router_main

    return router_main(argv)


def _subcommand(prog: str, choices: dict[str, str], argv: list[str]) -> tuple[str, list[str]]:
    """The subcommand of ``seaway PROG`` and the arguments it takes (argparse says what is wrong)."""
    ap = argparse.ArgumentParser(prog=f"seaway {prog}", description="; ".join(
        f"{k}: {v}" for k, v in choices.items()), add_help=not argv or argv[0] in ("-h", "--help"))
    ap.add_argument("what", choices=sorted(choices), help="subcommand (`seaway PROG WHAT --help`)")
    args, rest = ap.parse_known_args(argv[:1])
    return args.what, [*rest, *argv[1:]]


def cmd_ros2(argv: list[str]) -> int:
    what, rest = _subcommand("ros2", {"bridge": "Seaway's state as ROS 2 topics over rmw_zenoh "
                                                "(docs/ros2.md)"}, argv)
    from seaway.ros2.bridge import main as bridge_main

    assert what == "bridge"
    return bridge_main(rest)


def cmd_export(argv: list[str]) -> int:
    what, rest = _subcommand("export", {"ros2": "RECORDING OUT: an MCAP that rosbag2 plays "
                                                "(docs/ros2.md)"}, argv)
    from seaway.ros2.export import main as export_main

    assert what == "ros2"
    return export_main(rest)


BUILTIN = {"bench": cmd_bench, "echo": cmd_echo, "health": cmd_health, "schemas": cmd_schemas,
           "launch": cmd_launch, "router": cmd_router, "credentials": cmd_credentials,
           "mission": cmd_mission, "vehicle": cmd_vehicle, "ros2": cmd_ros2, "export": cmd_export}
SUMMARIES = {
    "bench": "run a benchmark (seaway bench --help lists them)",
    "echo": "print the messages of one key as they come",
    "health": "which services are alive, and what access control and vehicle_io refused",
    "schemas": "write every message's JSON Schema to a folder",
    "launch": "start a profile (sim, sim-batch, fleet, boat, shore, ...): every process, in order",
    "router": "the Zenoh router of a boat or shore deployment, with the side's credentials",
    "credentials": "make and show the credentials of a stack or a boat/shore deployment",
    "mission": "send a mission (or start, pause, resume, abort) to a running vessel",
    "vehicle": "arm, disarm, set the mode of, or read the status of a running vessel",
    "ros2": "the ROS 2 face: Seaway's state as ROS 2 topics over rmw_zenoh (seaway ros2 bridge)",
    "export": "write a recording for another tool: seaway export ros2 RECORDING OUT (rosbag2)",
}
"""One line per built-in command for ``seaway --help``; plugins' come from their module docstring."""


def version_text() -> str:
    from importlib.metadata import PackageNotFoundError, version

    def v(dist: str) -> str:
        try:
            return version(dist)
        except PackageNotFoundError:
            return "not installed"

    return (f"seaway {v('seaway')} (Python {sys.version.split()[0]}, eclipse-zenoh {v('eclipse-zenoh')}, "
            f"casadi {v('casadi')})")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    plugins = _plugins("seaway.commands")
    commands = sorted({*BUILTIN, *plugins})
    if argv and argv[0] == "--version":
        print(version_text())
        return 0
    if not argv or argv[0] in ("-h", "--help"):
        lines = {n: SUMMARIES.get(n) or _plugin_summary(plugins[n]) for n in commands}
        print("usage: seaway COMMAND [args]   (seaway COMMAND --help for its options)\n\n"
              "Seaway: economic MPC for twin-thruster surface vessels, as processes on Zenoh.\n\n"
              "commands:\n" + _listing(lines) + "\n\n  --version   the versions of Seaway and "
              "its core packages")
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    from seaway.runtime.credentials import CredentialsError

    try:
        if name in BUILTIN:
            return BUILTIN[name](rest)
        if name in plugins:
            return int(plugins[name].load()(rest) or 0)  # type: ignore[attr-defined]
    except CredentialsError as err:  # any command that opens the bus: say how to get credentials
        print(f"seaway {name}: {err}", file=sys.stderr)
        return 2
    except keys.KeyNameError as err:  # --vessel ../x: the name is wrong, not the program
        print(f"seaway {name}: {err}", file=sys.stderr)
        return 2
    print(f"seaway: unknown command {name!r}; commands: {', '.join(commands)}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
