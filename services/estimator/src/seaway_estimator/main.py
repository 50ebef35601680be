"""``seaway-estimator``: the estimator's configuration, and its node run (``seaway.runtime.node``).

The node (``seaway_estimator.node``) says what the estimator hears and publishes; this reads the
configuration (``seaway_estimator.config``, made by ``seaway.runtime.config``: its defaults,
``--config FILE``, its flags; and the run's facts), serves
re-initialisation (``nav/reset``, SIGUSR1) and hands the node to the runtime.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
from collections.abc import Sequence

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.runtime.config import parse_service_args, service_parser
from seaway.runtime.run import RunDescription
from seaway.runtime.runner import run_node
from seaway.runtime.service import on_signals, resolve_run, run_service
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin

from seaway_estimator import origin_file
from seaway_estimator.config import CONFIG_DIR, EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_estimator.node import EstimatorNode, stats_line
from seaway_estimator.replay import TraceWriter

log = logging.getLogger("seaway.estimator")

RUN_WIDE_CONFIG = ("vessel", "apply_dead_zone", "origin")  # what the run says, not the config file


def with_run(cfg: EstimatorConfig, run: RunDescription) -> EstimatorConfig:
    """The config with the run's model vessel, dead zone and NED origin.

    Those are run-wide facts (the controller and simulator must agree on them): a config file that
    sets them is refused, naming the fields, rather than silently overridden.
    """
    clash = sorted(set(RUN_WIDE_CONFIG) & cfg.model_fields_set)
    if clash:
        raise ConfigError(f"estimator config sets {', '.join(clash)}: these come from the run "
                          "(--run, or --vessel-file/--origin/--dead-zone/--scenario)")
    return cfg.model_copy(update={"vessel": run.model_vessel_file, "apply_dead_zone": run.dead_zone,
                                  "origin": run.origin})


def build_parser() -> argparse.ArgumentParser:
    return service_parser("estimator", f"EKF state and disturbance estimator: {keys.GNSS.suffix}, "
                                       f"{keys.ATTITUDE.suffix} -> {keys.NAV_STATE.suffix}",
                          EstimatorConfig, shipped=CONFIG_DIR)


def main(argv: Sequence[str] | None = None) -> int:
    args, cfg = parse_service_args(build_parser(), argv, EstimatorConfig)
    run = resolve_run(args, "estimator", load_scenario)
    try:
        cfg = with_run(cfg, run)
    except ConfigError as err:
        print(f"seaway-estimator: {err}", file=sys.stderr)
        return 2
    recorder = TraceWriter(cfg.record_inputs) if cfg.record_inputs else None
    core = EstimatorCore(cfg)
    keep = None
    if cfg.state_file is not None and core.origin is None:  # a boat's: taken from its first fix
        state_file = cfg.state_file
        core.origin = origin_file.load(state_file, args.run)
        if core.origin is not None:
            log.warning("NED origin kept from %s (before this restart): lat %.7f deg, lon %.7f "
                        "deg", state_file, math.degrees(core.origin.lat_rad),
                        math.degrees(core.origin.lon_rad))

        def keep(origin: GeoOrigin) -> None:
            try:
                origin_file.save(state_file, origin)
            except OSError as err:  # the estimate goes on; a restart would take a new origin
                log.error("cannot keep the NED origin in %s: %s", state_file, err)

    node = EstimatorNode(core, recorder, keep)
    with run_service("estimator", args, run=run) as ctx:
        on_signals((signal.SIGUSR1,), lambda _signum: node.reset_requested.set())
        log.info("estimator %s, vessel file %s", "lockstep" if run.lockstep
                 else f"realtime, publishing at {cfg.publish_rate_hz:g} Hz", cfg.vessel)
        try:
            run_node(ctx, node, 1.0 / cfg.publish_rate_hz, stamps=node.stamps)
        finally:
            if recorder is not None:
                recorder.close()
            log.info("estimator final: %s", stats_line(node.core, node))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
