"""``seaway-vehicle-io``: vehicle I/O's configuration, and its node run (``seaway.runtime.node``).

The node (``seaway_vehicle_io.node``) says what vehicle_io hears, answers and publishes; this reads
the configuration (a TOML or JSON file, ``seaway_vehicle_io.config``, command-line overrides and the
run's vessel) and hands the node to the runtime, on the wall clock.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

from seaway.contract.config import ConfigError, load_config, parse_config
from seaway.mavlink.signing import KeyFileError
from seaway.runtime.argtypes import positive_float
from seaway.runtime.node import run_node
from seaway.runtime.run import RunDescription
from seaway.runtime.service import base_parser, parse, resolve_run, run_service
from seaway.simkit.scenario import load_scenario
from seaway.vessel.battery import BatteryParams
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_vehicle_io.config import AUTOPILOT_CHOICES, VehicleIoConfig, config_path
from seaway_vehicle_io.link import check_url
from seaway_vehicle_io.node import MAX_SLEEP_S, VehicleIoNode
from seaway_vehicle_io.signing import SigningSetup
from seaway_vehicle_io.thrust import ThrusterLimits

log = logging.getLogger("seaway.vehicle_io")


def build_parser() -> argparse.ArgumentParser:
    p = base_parser("vehicle_io", "The only MAVLink speaker: autopilot telemetry to the bus, "
                                  "thrust commands to the autopilot, with a watchdog.")
    p.add_argument("--config", default=None, help="vehicle_io config file (.toml or .json), or the "
                   "name of one in services/vehicle_io/config (e.g. ardupilot-sitl)")
    p.add_argument("--mavlink", default=None,
                   help="MAVLink URL (overrides the config): udpin:HOST:PORT, udpout:HOST:PORT, "
                        "tcp:HOST:PORT or /dev/ttyX")
    p.add_argument("--autopilot", choices=AUTOPILOT_CHOICES, default=None,
                   help="expected autopilot (overrides the config; default auto)")
    p.add_argument("--thrust-timeout", type=positive_float, default=None, metavar="S",
                   help="watchdog timeout [s] (overrides the config; default 0.3)")
    p.add_argument("--signing-key-file", default=None, metavar="PATH",
                   help="MAVLink 2 signing key file, 64 hex characters (overrides the config's "
                        "signing_key_file): sign everything sent, refuse unsigned or wrongly signed "
                        "messages. Create one with: seaway signing new PATH")
    return p


def load(args: argparse.Namespace, run: RunDescription) -> tuple[VehicleIoConfig, ThrusterLimits]:
    """Config file + command-line overrides, validated together; the run's vessel's thruster limits."""
    cfg = load_config(config_path(args.config), VehicleIoConfig) if args.config else VehicleIoConfig()
    overrides = {k: v for k, v in {
        "mavlink": args.mavlink, "autopilot": args.autopilot,
        "thrust_timeout_s": args.thrust_timeout, "signing_key_file": args.signing_key_file,
    }.items() if v is not None}
    if overrides:
        cfg = parse_config({**cfg.model_dump(), **overrides}, VehicleIoConfig, "command line")
    try:
        check_url(cfg.mavlink)
    except ValueError as err:
        raise ConfigError(str(err)) from None
    vessel = load_vessel(run.model_vessel_file)
    try:
        limits = ThrusterLimits.from_vessel(vessel)
    except ValueError as err:
        raise ConfigError(f"vessel {vessel.name}: {err}") from None
    return cfg, limits


def battery_of(run: RunDescription) -> BatteryParams | None:
    """The propulsion battery of the run's vessel file (its ``[battery]``; None: it names none), which
    completes what the autopilot measures (``conversions.battery_state``). ConfigError."""
    return load_vessel(run.model_vessel_file).battery


def signing_setup(cfg: VehicleIoConfig) -> SigningSetup | None:
    """The MAVLink signing the config asks for (None: no signing). ConfigError."""
    try:
        return cfg.signing_setup()
    except KeyFileError as err:  # changed since the config was validated
        raise ConfigError(f"signing_key_file: {err}") from None


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(build_parser(), argv)
    run = resolve_run(args, "vehicle_io", load_scenario)
    try:
        cfg, limits = load(args, run)
        signing = signing_setup(cfg)
        battery = battery_of(run)
    except ConfigError as err:
        print(f"seaway-vehicle-io: {err}", file=sys.stderr)
        return 2
    with run_service("vehicle_io", args, run=run) as ctx:
        log.info("config: mavlink %s, autopilot %s, thrust timeout %.0f ms, MANUAL_CONTROL %.0f Hz; "
                 "vessel limits +%.1f/-%.1f N, dead zone %.1f N; battery %s; MAVLink signing %s",
                 cfg.mavlink, cfg.autopilot, cfg.thrust_timeout_s * 1e3,
                 cfg.manual_control_rate_hz, limits.thrust_max_n, limits.reverse_max_n,
                 limits.dead_zone_n, "none in the vessel file (measured figures only)"
                 if battery is None else f"{battery.energy_j / 1e3:.1f} kJ usable, reserve "
                 f"{battery.reserve_energy_j / 1e3:.1f} kJ, nominal {battery.nominal_voltage_v:g} V",
                 f"on (key file {cfg.signing_key_file})" if signing is not None else "off")
        o = run.origin
        node = VehicleIoNode(cfg, limits, signing=signing, battery=battery, origin=None if o is None
                             else GeoOrigin.from_degrees(o.lat_deg, o.lon_deg, o.alt_m))
        run_node(ctx, node, MAX_SLEEP_S)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
