"""``seaway-sim``: the simulator (plant, disturbances, sensors, a PX4-like MAVLink endpoint).

Real time (default): wall clock, driven over MAVLink on ``--mavlink`` (``udpin:127.0.0.1:14580``).
Lockstep (``--lockstep``): sim time, driven by ThrustCommand on the bus (``seaway_sim.lockstep``).
Both publish sim/truth, sim/disturbance and sim/clock and serve sim/scenario.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Sequence

from seaway.contract.config import ConfigError
from seaway.runtime.service import base_parser, parse, run_service

from seaway_sim.app import SimApp, load_world
from seaway_sim.core import SimCore
from seaway_sim.lockstep import Lockstep
from seaway_sim.mavlink_link import DEFAULT_ENDPOINT, MavlinkLink
from seaway_sim.px4_autopilot import COMPID, Px4Autopilot, Px4Config
from seaway_sim.realtime import Realtime

log = logging.getLogger("seaway_sim")

DEFAULT_PERIOD_S = 0.1  # the paper's control period dt
DEFAULT_LOCKSTEP_TIMEOUT_S = 5.0
DEFAULT_STEP_S = 0.01  # real-time tick: the plant's internal RK4 step, 100 Hz


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0 or value != value or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    p = base_parser("sim", "The Seaway simulator: vessel plant, disturbances, sensor noise and a "
                           "PX4-like MAVLink endpoint (real time), or lockstep on the bus.")
    p.add_argument("--scenario", default="lake",
                   help="scenario name in deploy/scenarios, or a .toml/.json path (default lake)")
    p.add_argument("--lockstep", action="store_true",
                   help="own the time: advance one period per ThrustCommand (no MAVLink)")
    p.add_argument("--period", type=_positive, default=DEFAULT_PERIOD_S,
                   help="control period [s]: lockstep step; truth publishing period in real time")
    p.add_argument("--lockstep-timeout", type=_positive, default=DEFAULT_LOCKSTEP_TIMEOUT_S,
                   help="wall seconds to wait for a command before logging and republishing "
                        "the tick")
    p.add_argument("--mavlink", default=DEFAULT_ENDPOINT,
                   help=f"real time: where the simulated autopilot listens "
                        f"(default {DEFAULT_ENDPOINT})")
    p.add_argument("--step", type=_positive, default=DEFAULT_STEP_S,
                   help="real time: plant and MAVLink tick [s] (default 0.01)")
    p.add_argument("--sysid", type=int, default=1, help="real time: MAVLink system id (default 1)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="real time: set a simulated PX4 parameter at boot (repeatable), e.g. NAV_RCL_ACT=1")
    return p


def parse_params(items: Sequence[str]) -> tuple[tuple[str, float], ...]:
    """``NAME=VALUE`` items -> overrides; the autopilot's ParamStore checks names, types, ranges."""
    out = []
    for item in items:
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out.append((name.strip(), float(value)))
        except ValueError:
            raise ConfigError(f"--param wants NAME=VALUE with a number, got {item!r}") from None
    return tuple(out)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(build_parser(), argv)
    try:
        scenario, vessel = load_world(args.scenario)
    except ConfigError as err:
        print(f"seaway-sim: {err}", file=sys.stderr)
        return 2
    try:
        params = parse_params(args.param)
        Px4Autopilot(Px4Config(thrust_max_n=1.0, param_overrides=params))  # validates them now
    except (ConfigError, ValueError) as err:
        print(f"seaway-sim: {err}", file=sys.stderr)
        return 2
    if not 1 <= args.sysid <= 255:
        print(f"seaway-sim: --sysid must be 1..255, got {args.sysid}", file=sys.stderr)
        return 2
    link = None
    if not args.lockstep:
        try:
            link = MavlinkLink(args.mavlink, args.sysid, COMPID)
        except (ValueError, OSError) as err:
            print(f"seaway-sim: --mavlink {args.mavlink}: {err}", file=sys.stderr)
            return 2
    with run_service("sim", args) as ctx:
        boot_ns = time.monotonic_ns()
        core = SimCore(scenario, vessel, epoch_ns=0 if args.lockstep else time.time_ns())
        app = SimApp(ctx.bus, core, lockstep=args.lockstep)
        log.info("scenario %s (seed %d), vessel %s, %s", scenario.name, scenario.seed, vessel.name,
                 "lockstep" if args.lockstep else "real time")
        if link is None:
            lockstep = Lockstep(app, args.period, args.lockstep_timeout, ctx.stop)
            ctx.ready()
            lockstep.run()
        else:
            autopilot = Px4Autopilot(Px4Config(thrust_max_n=vessel.thrust_max_n, sysid=args.sysid,
                                               param_overrides=params))
            try:
                realtime = Realtime(app, autopilot, link, args.step, args.period, ctx.stop, boot_ns)
                ctx.ready()
                realtime.run()
            finally:
                link.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
