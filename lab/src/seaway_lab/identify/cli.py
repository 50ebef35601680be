"""``seaway identify``: fly the identification manoeuvre, and fit a vessel model to a recording.

    seaway identify run --sim --vessel paper-sim --out runs/identify/paper-sim.mcap
    seaway launch identify-ardupilot     # flies it on ArduPilot SITL through vehicle_io (identify fly)
    seaway identify fit runs/identify/paper-sim.mcap --base paper-sim --compare paper-sim
    seaway identify fit runs/<run>/recording.mcap --base paper-boat --arm-m 0.1025 --name my-boat

``run --sim`` flies the manoeuvre (surge steps, turns both ways, spins, weaving, coasting:
``seaway_lab.identify.manoeuvre``) on the simulator's core in process, with realistic sensor noise
by default, and records it (MCAP: ctrl/thrust, sensors/gnss, sensors/attitude, sim/truth).

``fly`` flies it on a running vessel through vehicle_io, in the controller's place (a launcher
profile runs it as the controller, e.g. ``identify-ardupilot``; on a real boat, a copy of the
``boat`` profile with the controller's command replaced): it waits until the vessel is armed in a
manual mode, publishes the manoeuvre on ctrl/thrust in real time and ends when it is flown; the
run's recording is what ``fit`` reads (``seaway_lab.identify.live_run``).

``fit`` reads the commands and the raw sensors of a recording (not the estimator's state: it
predicts with the model being replaced), fits m11, m22, m33, Xu, Yv, Nr and the dead zone with the
thruster arm fixed (``--arm-m``, else the base vessel file's), and writes a vessel file loadable by
``load_vessel`` with the fit's standard errors and residuals in comments, and a plot of measured
against predicted motion on the held-out tail of the run. What the data can and cannot determine,
and how the fit works: docs/identify.md.

Exit code: 0 done, 1 the recording cannot support a fit (the message says what is missing), 2 a bad
command line or file.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from seaway.contract.config import ConfigError
from seaway.runtime import service
from seaway.runtime.argtypes import non_negative_float, positive_float, whole_number
from seaway.simkit.scenario import SensorNoise, load_scenario
from seaway.vessel.model import VesselParams, load_vessel

from seaway_lab.identify import fit as fitmod
from seaway_lab.identify import live_run, output, parameters, sim_run
from seaway_lab.identify import trace as tracemod
from seaway_lab.identify.manoeuvre import Manoeuvre
from seaway_lab.identify.trace import IdentifyError

NOISE = ("realistic", "scenario", "none")


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway identify", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="action", required=True, metavar="ACTION",
                            help="run (fly the manoeuvre and record it) or fit (a model from a recording)")
    run = sub.add_parser("run", prog="seaway identify run", help="fly the manoeuvre and record it",
                         description="Fly the identification manoeuvre and record it (MCAP).")
    run.add_argument("--sim", action="store_true",
                     help="on the simulator's core in process (on a running vessel: seaway identify fly)")
    run.add_argument("--vessel", default="paper-sim",
                     help="the vessel file the simulator integrates (name in deploy/vessels or path; "
                          "default paper-sim)")
    run.add_argument("--scenario", default=None,
                     help="take the water (disturbances), sensors, dead-zone and lag flags from this "
                          "scenario (default: calm water)")
    run.add_argument("--noise", choices=NOISE, default="realistic",
                     help="sensors: realistic (GNSS 0.3 m and 0.05 m/s at 5 Hz, heading 1 deg and "
                          "yaw rate 0.005 rad/s at 20 Hz; the default), the scenario's, or none")
    run.add_argument("--dead-zone", action="store_true",
                     help="apply the vessel file's thrust dead zone in the simulated plant")
    run.add_argument("--level-n", type=positive_float, default=None,
                     help="the manoeuvre's full thrust level per thruster [N] (default: the vessel's "
                          "thrust_max_n)")
    run.add_argument("--seed", type=whole_number(0), default=1,
                     help="the sensors' noise seed (calm water only)")
    run.add_argument("--out", type=Path, default=Path("runs/identify/identify.mcap"),
                     help="the recording to write (default runs/identify/identify.mcap; a file "
                          "there already is kept and the next free name used)")
    fly = service.base_parser("controller", "Fly the identification manoeuvre on a running "
                              "vessel through vehicle_io, in the controller's place.",
                              prog="seaway identify fly")
    live_run.add_arguments(fly)
    sub.add_parser("fly", parents=[fly], add_help=False, help="fly the manoeuvre on a running vessel "
                   "through vehicle_io (as the run's controller)", description=fly.description)
    fit = sub.add_parser("fit", prog="seaway identify fit", help="fit a vessel model to a recording",
                         description="Fit the paper's vessel model to a recording of the manoeuvre "
                                     "and write it as a vessel file, with a held-out plot.")
    fit.add_argument("recording", type=Path, help="the recording (an MCAP file or a run folder)")
    fit.add_argument("--vessel", default=None,
                     help="which vessel of the recording (its key name), if it holds several")
    fit.add_argument("--base", default="paper-sim",
                     help="vessel file giving what the motion cannot: thrust bounds, power alpha and, "
                          "unless --arm-m, the thruster arm (default paper-sim)")
    fit.add_argument("--arm-m", type=positive_float, default=None,
                     help="the thruster arm l: distance from the centre line to each thruster, from the "
                          "drawing [m] (default: the base vessel file's)")
    fit.add_argument("--dead-zone-n", type=non_negative_float, default=None,
                     help="take this dead zone [N] instead of fitting it")
    fit.add_argument("--friction", action="store_true",
                     help="also fit surge friction (sliding and near rest: friction_n, "
                          "static_friction_n), for a plant that has it (a wheeled test rover); give "
                          "--dead-zone-n too (both explain a vessel that does not move)")
    fit.add_argument("--friction-speed-mps", type=positive_float, default=parameters.FRICTION_SPEED_MPS,
                     help=f"the least speed over which the friction builds up [m/s] (default "
                          f"{parameters.FRICTION_SPEED_MPS}; raised to what the control period integrates)")
    fit.add_argument("--fit-lag", action="store_true",
                     help="also fit a thruster time constant (it trades against m11: only when the "
                          "thrusters are known to lag)")
    fit.add_argument("--holdout", type=non_negative_float, default=fitmod.HOLDOUT_FRACTION,
                     help=f"fraction of the run held out of the fit and only predicted (default "
                          f"{fitmod.HOLDOUT_FRACTION})")
    fit.add_argument("--name", default=None, help="the new vessel's name (default: <recording>-identified)")
    fit.add_argument("--out", type=Path, default=None,
                     help="the vessel file to write (default <recording>.vessel.toml)")
    fit.add_argument("--plot", type=Path, default=None,
                     help="the held-out plot to write (default <recording>.identify.png)")
    fit.add_argument("--compare", default=None,
                     help="a vessel file to compare the fit with (e.g. the simulator's own): prints "
                          "each parameter's error in percent")
    fit.add_argument("--json", action="store_true", help="print the result as one JSON object")
    return ap


def _run(args: argparse.Namespace) -> int:
    if not args.sim:
        print("seaway identify run: only --sim (the manoeuvre on the simulator in process); on a "
              "vessel use 'seaway identify fly' in the controller's place (seaway launch "
              "identify-ardupilot does that on ArduPilot SITL)", file=sys.stderr)
        return 2
    plant = load_vessel(args.vessel)
    level = args.level_n if args.level_n is not None else plant.thrust_max_n
    if not 0 < level <= plant.thrust_max_n:
        print(f"seaway identify run: --level-n must be in (0, {plant.thrust_max_n:g}] N (the vessel's "
              f"thrust_max_n), got {level:g}", file=sys.stderr)
        return 2
    if args.scenario:
        sc = load_scenario(args.scenario).model_copy(update={"vessel": str(args.vessel)})
        if args.noise == "realistic":
            sc = sc.model_copy(update={"sensors": _realistic()})
        elif args.noise == "none":
            sc = sc.model_copy(update={"sensors": SensorNoise()})
        if args.dead_zone:
            sc = sc.model_copy(update={"dead_zone": True})
    else:
        noise = _realistic() if args.noise == "realistic" else SensorNoise()
        sc = sim_run.calm_scenario(str(args.vessel), noise, seed=args.seed, dead_zone=args.dead_zone)
    man = Manoeuvre(level_n=level, reverse_level_n=min(level, plant.reverse_max_n))
    res = sim_run.fly_in_sim(sc, plant, man, args.out)
    print(f"flew the manoeuvre ({res.duration_s:.0f} s, level {level:g} N) on {plant.name} in "
          f"{sc.name}: {res.messages:,} messages in {res.path}")
    return 0


def _realistic() -> SensorNoise:
    from seaway_lab.closed_loop import REALISTIC_NOISE

    return REALISTIC_NOISE


def _fit(args: argparse.Namespace) -> int:
    base = load_vessel(args.base)
    compare = load_vessel(args.compare) if args.compare else None
    arm = args.arm_m if args.arm_m is not None else base.arm_m
    rec = args.recording
    if not rec.exists():
        print(f"seaway identify fit: {rec}: no such file or folder", file=sys.stderr)
        return 2
    stem = rec / "identify" if rec.is_dir() else rec.with_suffix("")
    name = args.name or f"{(rec.name if rec.is_dir() else rec.stem)}-identified"
    out = args.out or stem.with_name(stem.name + ".vessel.toml")
    png = args.plot or stem.with_name(stem.name + ".identify.png")
    trace = tracemod.from_recording(rec, args.vessel)
    tracemod.check(trace)
    result = fitmod.fit(trace, arm, fit_dead_zone=args.dead_zone_n is None,
                        dead_zone_n=args.dead_zone_n or 0.0, fit_lag=args.fit_lag,
                        lag_s=base.thruster_time_constant_s, holdout_fraction=args.holdout,
                        start_theta=np.array([getattr(base, p) for p in fitmod.PARAMS]),
                        fit_friction=args.friction, friction_least_mps=args.friction_speed_mps)
    text = output.vessel_toml(result, base, name, str(rec))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    fitted = load_vessel(out)  # what we wrote must load as any vessel file does
    output.plot(result, png, title=f"{name}: identified from {rec.name}")
    errors = _errors(fitted, compare) if compare else None
    if args.json:
        print(json.dumps({"vessel_file": str(out), "plot": str(png), "arm_m": arm,
                          "params": {p: {"value": e.value, "std": e.std}
                                     for p, e in result.params.items()},
                          "friction": {p: {"value": e.value, "std": e.std}
                                       for p, e in result.friction.items()},
                          "friction_speed_mps": result.friction_speed_mps,
                          "dead_zone_n": result.dead_zone_n, "lag_s": result.lag_s,
                          "current_ne_mps": result.current_ne_mps, "rms_fit": result.rms_fit,
                          "rms_holdout": result.rms_holdout, "errors_pct": errors,
                          "notes": result.notes}, indent=2))
        return 0
    print(f"fitted {trace.duration_s:.0f} s of {rec} (arm l = {arm:g} m fixed; held out after "
          f"{result.split_s:.0f} s)")
    for p, e in (*result.params.items(), *result.friction.items()):
        err = f"   {errors[p]:+6.2f} % vs {compare.name}" if errors and compare and p in errors else ""
        print(f"  {p:<10} {e.value:10.4g}  +- {e.std:.3g} ({100 * e.rel_std:.2f} %){err}")
    if result.friction:
        print(f"  friction build-up speed {result.friction_speed_mps:.3g} m/s (not fitted)")
    dz_err = (f"   ({compare.dead_zone_n:g} N in {compare.name})" if compare else "")
    print(f"  dead zone  {result.dead_zone_n:10.4g} N{dz_err}")
    print(f"  residual RMS fitted: {output._rms(result.rms_fit)}")
    print(f"  residual RMS held out: {output._rms(result.rms_holdout)}")
    for n in result.notes:
        print(f"  note: {n}")
    print(f"vessel file: {out}\nplot: {png}")
    return 0


def _errors(fitted: VesselParams, truth: VesselParams) -> dict[str, float]:
    return {p: 100.0 * (getattr(fitted, p) / getattr(truth, p) - 1.0) for p in fitmod.PARAMS}


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        if args.action == "fly":
            return live_run.fly(args)
        return _run(args) if args.action == "run" else _fit(args)
    except IdentifyError as err:
        print(f"seaway identify {args.action}: {err}", file=sys.stderr)
        return 1
    except (ConfigError, FileNotFoundError, ValueError) as err:
        print(f"seaway identify {args.action}: {err}", file=sys.stderr)
        return 2
