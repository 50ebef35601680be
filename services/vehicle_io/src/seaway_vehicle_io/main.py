"""``seaway-vehicle-io``: vehicle I/O's configuration, and its node run (``seaway.runtime.node``).

The node (``seaway_vehicle_io.node``) says what vehicle_io hears, answers and publishes; this reads
the configuration (``seaway_vehicle_io.config``, made by ``seaway.runtime.config``: its defaults,
``--config FILE``, then its flags; and the run's vessel) and hands the node to the runtime, on
the wall clock.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

from seaway.contract.config import ConfigError
from seaway.mavlink.signing import KeyFileError
from seaway.runtime.config import config_of, parse_service_args, service_parser
from seaway.runtime.run import RunDescription
from seaway.runtime.runner import run_node
from seaway.runtime.service import resolve_run, run_service
from seaway.simkit.scenario import load_scenario
from seaway.vessel.battery import BatteryParams
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_vehicle_io.config import CONFIG_DIR, VehicleIoConfig
from seaway_vehicle_io.link import check_url
from seaway_vehicle_io.node import MAX_SLEEP_S, VehicleIoNode
from seaway_vehicle_io.signing import SigningSetup
from seaway_vehicle_io.thrust import ThrusterLimits

log = logging.getLogger("seaway.vehicle_io")


def build_parser() -> argparse.ArgumentParser:
    return service_parser("vehicle_io", "The only MAVLink speaker: autopilot telemetry to the bus, "
                                        "thrust commands to the autopilot, with a watchdog.",
                          VehicleIoConfig, shipped=CONFIG_DIR)


def load(args: argparse.Namespace, run: RunDescription) -> tuple[VehicleIoConfig, ThrusterLimits]:
    """The configuration (``seaway.runtime.config``: defaults, ``--config``, flags) and ``checked``.
    ConfigError."""
    return checked(config_of(args, VehicleIoConfig), run)


def checked(cfg: VehicleIoConfig, run: RunDescription) -> tuple[VehicleIoConfig, ThrusterLimits]:
    """The config with its URL checked, and the run's vessel's thruster limits. ConfigError."""
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
    args, cfg = parse_service_args(build_parser(), argv, VehicleIoConfig)
    run = resolve_run(args, "vehicle_io", load_scenario)
    try:
        cfg, limits = checked(cfg, run)
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
