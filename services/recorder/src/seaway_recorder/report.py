"""``seaway report FILE``: the paper's metrics of a recorded run, solve statistics, a table and plots.

Each mission flown (the controller's ``mission/status``) is measured against the mission the
controller recorded accepting (``mission/accepted``: what was actually flown, however it was sent);
a mission without one (a recording made before the controller published it) against a document that
fits it: ``--mission``, ``--scenario``, else the recording's ``mission/*`` or ``scenario/*``
attachment (``missions.py``). The vessel's alpha comes from ``--vessel-file``, else the
``vessel/*`` attachment, else the vessel the scenario names. Positions and energy come from
``sim/truth`` when it was recorded, else ``nav/state`` with the ``ctrl/thrust`` commands. The
energy section (``budget.py``) is the controller's energy budget (``mission/energy``) along each
mission: its prediction of the energy to finish against the energy the report integrates, the
energy to home, the battery and the decision; a recording without it says so.

Writes ``metrics.json`` and, unless ``--no-plots``, ``trajectory.png``, ``thrust.png``,
``cross_track.png`` and ``energy.png`` into ``--out`` (default: ``report/`` beside the recording).
"""

from __future__ import annotations

import argparse
import bisect
import json
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.contract.config import ConfigError, load_config, read_document
from seaway.contract.messages import (
    BatteryState,
    EnergyBudget,
    MissionAccepted,
    MissionStatus,
    NavOrigin,
    SimTruth,
    SolveRecord,
    StateEstimate,
    ThrustCommand,
)
from seaway.recording import reader, runinfo
from seaway.runtime.argtypes import positive_float
from seaway.runtime.run import CONTROL_PERIOD_S
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.metrics import mission_metrics
from seaway.vessel.model import VesselParams

from seaway_recorder import budget, clock_bridge, missions
from seaway_recorder import metrics as mx
from seaway_recorder.report_render import plots, table

TRUTH, STATE, ORIGIN = keys.SIM_TRUTH.suffix, keys.NAV_STATE.suffix, keys.NAV_ORIGIN.suffix
COMMANDS, SOLVES, STATUS = keys.THRUST.suffix, keys.SOLVE.suffix, keys.MISSION_STATUS.suffix
ACCEPTED, ENERGY = keys.MISSION_ACCEPTED.suffix, keys.MISSION_ENERGY.suffix
BATTERY = keys.VEHICLE_BATTERY.suffix
REPORT_TOPICS = (TRUTH, STATE, ORIGIN, COMMANDS, SOLVES, STATUS, ACCEPTED, ENERGY, BATTERY)
"""The keys a report reads (suffixes, ``sim/truth``)."""


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="seaway report", description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="+", help="recording file(s) or folder(s)")
    p.add_argument("--scenario", default=None,
                   help=f"take a mission the recording has no {ACCEPTED} for from this scenario "
                        "(name or file)")
    p.add_argument("--mission", default=None,
                   help=f"take a mission the recording has no {ACCEPTED} for from this file")
    p.add_argument("--vessel-file", default=None, help="vessel file for alpha")
    p.add_argument("--vessel", default=None, help="which vessel, if the recording has several")
    p.add_argument("--out", type=Path, default=None, help="folder for metrics.json and plots")
    p.add_argument("--state", choices=["auto", TRUTH, STATE], default="auto",
                   help=f"position source (default: {TRUTH} when recorded, else {STATE})")
    p.add_argument("--sample-period", type=positive_float, default=None,
                   help="cross-track sample period [s] (default: the recorded run's control period)")
    p.add_argument("--episode", type=int, default=None,
                   help="which episode (simulated time went back between two: a sim restart or a "
                        "scenario load); 0 is the first, -1 the last (the default)")
    p.add_argument("--no-plots", action="store_true", help="metrics only: draw no plots (faster)")
    p.add_argument("--json", action="store_true", help="print the metrics JSON instead of the table")
    return p


def _origin(dec: reader.Decoded, scenario_origin: GeoOrigin | None) -> GeoOrigin | None:
    origins = dec.get(ORIGIN)
    if origins:
        o = origins[-1]
        assert isinstance(o, NavOrigin)
        return GeoOrigin(o.lat_rad, o.lon_rad, o.alt_m)
    return scenario_origin


Read = tuple[reader.RecordingInfo, reader.Decoded]
"""A recording as a report reads it: its info (attachments, metadata) and the report's keys decoded."""


def read_for_report(files: list[Path], vessel: str | None = None) -> Read:
    """What ``analyse`` reads of ``files``: one decode, for as many episodes as are reported."""
    info = reader.read_info(files)
    dec = reader.decode_vessel(files, vessel, REPORT_TOPICS, info.summaries)
    steps, bad = clock_bridge.steps_in(files, info.topics)
    if bad:  # said with the other undecodable messages: left out of every figure
        dec.undecodable += bad
        dec.undecodable_by_topic[clock_bridge.CLOCK_STEP_TOPIC] = bad
    bridged = clock_bridge.bridge(dec, steps)
    dec.clock_steps = [(s.stamp_ns, s.step_ns, s in bridged) for s in steps]
    return info, dec


def mission_episodes(dec: reader.Decoded, mission_id: str) -> list[int]:
    """The indexes of the episodes in which the controller accepted ``mission_id`` (its
    ``mission/accepted``), in order: which episode flew a mission, where one stack flew several,
    each after a scenario load. More than one: the sim restarted while it flew, and the controller
    flew it again from its first leg in the new episode (the last one is the one flown to its end)."""
    accepted = dec.get(ACCEPTED)
    logs = dec.log_ns.get(ACCEPTED, [])
    mine = [t for t, m in zip(logs, accepted, strict=True)
            if isinstance(m, MissionAccepted) and m.mission_id == mission_id]
    return [i for i, (start, end) in enumerate(episodes(dec))
            if any(start <= t and (end is None or t < end) for t in mine)]


def episodes(dec: reader.Decoded) -> list[tuple[int, int | None]]:
    """The recording's episodes as [start, end) log-time spans: a new one wherever simulated time
    went back (``sim/truth``): the sim restarted, or loaded a scenario (a lockstep episode)."""
    truth, logs = dec.get(TRUTH), dec.log_ns.get(TRUTH, [])
    stamps = [t.stamp_ns for t in truth]
    starts = [0]
    last = stamps[0] if stamps else 0  # the latest stamp time went on from
    for i in range(1, len(stamps)):
        if stamps[i] < last:
            starts.append(logs[i])
        elif 0 < i + 1 < len(stamps) and last <= stamps[i + 1] < stamps[i]:
            # One stamp ahead of both neighbours, time going on after it from where it was
            # before (a corrupted stamp): no restart follows it, and it is not where time stood.
            continue
        last = stamps[i]
    return [(a, b) for a, b in zip(starts, [*starts[1:], None], strict=True)]


def analyse(files: list[Path], *, scenario: str | None = None, mission_file: str | None = None,
            vessel_file: str | None = None, vessel: str | None = None, state: str = "auto",
            sample_period_s: float | None = None, episode: int | None = None,
            read: Read | None = None) -> dict[str, Any]:
    """Everything the report prints, as one JSON-able dict (plus the series for plots under '_').

    The metrics are those of one episode (default the last): where simulated time went back, the
    episodes before are reported as such, not mixed in. ``read``: ``files`` as ``read_for_report``
    gave them, to report several episodes of one recording from one decode."""
    info, dec = read if read is not None else read_for_report(files, vessel)
    bounds = episodes(dec)
    if episode is None:
        episode = len(bounds) - 1
    if not -len(bounds) <= episode < len(bounds):
        raise ValueError(f"--episode {episode}: the recording has {len(bounds)} episode(s), "
                         f"0..{len(bounds) - 1}")
    episode %= len(bounds)
    start, end = bounds[episode]
    dec = dec.between(start, end)
    scen = load_scenario(runinfo.scenario_path(scenario)) if scenario else \
        runinfo.scenario_from_attachments(info.attachments)
    scen_origin = runinfo.scenario_origin(scen) if scen is not None else None
    origin = _origin(dec, scen_origin)

    candidates = _candidates(scenario, scen, mission_file, info.attachments, origin)
    vp: VesselParams | None
    if vessel_file:
        vp = load_config(runinfo.vessel_path(vessel_file), VesselParams)
    else:
        vp = runinfo.vessel_from_attachments(info.attachments) or runinfo.load_vessel_for(scen)
    alpha = vp.alpha_w_per_n2 if vp is not None else None

    truth = sorted(dec.get(TRUTH), key=lambda m: m.stamp_ns)
    statuses = sorted((m for m in dec.get(STATUS) if isinstance(m, MissionStatus)),
                      key=lambda m: m.stamp_ns)
    nav = sorted((m for m in dec.get(STATE) if isinstance(m, StateEstimate)), key=lambda m: m.stamp_ns)
    if state == TRUTH and not truth:
        bad = sum(n for t, n in dec.undecodable_by_topic.items() if t.endswith(f"/{TRUTH}"))
        raise ValueError(f"no {TRUTH} in the recording" + (
            f" that decodes ({bad:,} messages do not)" if bad else ""))
    notes = undecodable_notes(info, dec, bool(truth)) + clock_step_notes(dec)
    if truth and state != STATE:
        states: Sequence[Any] = truth
        thrusts: Sequence[Any] = truth
        energy: list[float] | None = [t.energy_j for t in truth if isinstance(t, SimTruth)]
        state_source, thrust_source = TRUTH, TRUTH
    else:
        states = nav
        thrusts = sorted(dec.get(COMMANDS), key=lambda m: m.stamp_ns)
        energy = None
        state_source, thrust_source = STATE, COMMANDS
    # Cross-track samples are taken once per control period: the recording's run says which.
    run = runinfo.run_from_attachments(info.attachments)
    if sample_period_s is None:
        sample_period_s = run.control_period_s if run is not None else CONTROL_PERIOD_S

    def metrics_of(mission: runinfo.Mission, start_ns: int | None, end_ns: int | None):
        """The paper's metrics of ``mission`` over the states from start_ns to end_ns (the next
        mission's first status, computed from the state that may complete this one: included)."""
        keep = [i for i, x in enumerate(states) if end_ns is None or x.stamp_ns <= end_ns]
        return mission_metrics([states[i] for i in keep], mission.waypoints, mission.coa_radius_m,
                               mission.task_power_w, alpha_w_per_n2=alpha, thrusts=thrusts,
                               energy_j=None if energy is None else [energy[i] for i in keep],
                               mission_start_ns=start_ns, sample_period_s=sample_period_s,
                               state_source=state_source, thrust_source=thrust_source)

    # The missions flown (the controller's statuses), each with what the controller recorded
    # accepting, else the document that fits it.
    accepted = missions.acceptances([m for m in dec.get(ACCEPTED) if isinstance(m, MissionAccepted)])
    budgets = sorted((m for m in dec.get(ENERGY) if isinstance(m, EnergyBudget)),
                     key=lambda m: m.stamp_ns)
    batteries = sorted((m for m in dec.get(BATTERY) if isinstance(m, BatteryState)),
                       key=lambda m: m.stamp_ns)
    flown = []
    sections = []
    for r in missions.mission_runs(statuses):
        chosen = missions.choose(r, accepted, candidates, nav)
        doc = chosen.mission
        met = metrics_of(doc, chosen.start_ns, r.end_ns) if doc is not None else None
        sections.append(budget.energy_section(
            budget.mission_budgets(budgets, r.mission_id, chosen.start_ns, r.end_ns), met,
            chosen.start_ns, batteries, doc.controller if doc is not None else None))
        flown.append({"mission_id": r.mission_id, "start_ns": r.start_ns, "end_ns": r.end_ns,
                      "source": doc.source if doc is not None else None, "fit": chosen.how,
                      "mission": _mission_json(doc), "metrics": met,
                      "controller_reported": r.controller_reported(),
                      "energy_budget": sections[-1].to_json()})
    if flown:
        primary = flown[-1]
        mission_doc, met = primary["mission"], primary["metrics"]
        live = primary["controller_reported"]
        energy = sections[-1]
    else:  # no status recorded: the last mission accepted, else the document given or attached
        if accepted:
            only = runinfo.mission_from_accepted(accepted[-1], f"recorded {ACCEPTED}")
        elif candidates:
            only = candidates[0].mission
        else:
            raise ConfigError("the recording has no mission or scenario attachment: pass "
                              "--scenario or --mission")
        mission_doc = _mission_json(only)
        met = metrics_of(only, None, None)
        live = {}
        # No status says which mission flew: the budgets of the last one that published any.
        mine = [b for b in budgets if b.mission_id == budgets[-1].mission_id]
        energy = budget.energy_section(mine, met, met.start_ns, batteries, only.controller)
    solves = [m for m in dec.get(SOLVES) if isinstance(m, SolveRecord)]
    commands = sorted((m for m in dec.get(COMMANDS) if isinstance(m, ThrustCommand)),
                      key=lambda m: m.stamp_ns)
    out: dict[str, Any] = {
        "files": [str(f) for f in files],
        "vessel": sorted(dec.vessels)[0] if vessel is None and dec.vessels else vessel,
        "mission": mission_doc,
        "missions": [{k: (v.to_json() if k == "metrics" and v is not None else v)
                      for k, v in m.items()} for m in flown],
        "alpha_w_per_n2": alpha,
        "run": run.model_dump(mode="json") if run is not None else None,
        "control_period_s": sample_period_s,
        "episodes": {"count": len(bounds), "reported": episode,
                     "time_went_back": len(bounds) - 1},
        "metrics": met.to_json() if met is not None else None,
        "energy_used": energy_used(met, statuses, flown[-1]["mission_id"] if flown else None),
        "completion": completion(met, live, truth if state_source == TRUTH else [], nav),
        "energy_budget": energy.to_json(),
        "solve": mx.solve_stats(solves).to_json(),
        "controller_reported": live,
        "recording": {"messages": info.message_count, "topics": info.topics,
                      "duration_s": (info.end_ns - info.start_ns) / 1e9,
                      "undecodable": dec.undecodable,
                      "undecodable_by_topic": dict(dec.undecodable_by_topic),
                      "duplicates": dec.duplicates, "notes": notes,
                      "clock_steps": [{"seen_ns": at, "step_s": step / 1e9, "bridged": done}
                                      for at, step, done in dec.clock_steps],
                      "recorder_summary": info.metadata.get("seaway.recorder.summary", {}),
                      "recovered": info.metadata.get("seaway.recover", {}),
                      "repaired": reader.repaired(info)},
        "_": {"series": met.series if met is not None else None, "commands": commands,
              "thrusts": thrusts, "states": states, "solves": solves, "statuses": statuses,
              "start_ns": met.start_ns if met is not None else None, "energy": energy},
    }
    return out


def undecodable_notes(info: reader.RecordingInfo, dec: reader.Decoded, truth_decoded: bool
                      ) -> list[str]:
    """A line per topic with messages that do not decode as its key's type (they are left out of
    every figure), and, where the truth was recorded and none of it decodes, that the states come
    from the estimate instead."""
    notes = [f"{topic}: {n:,} of {info.topics.get(topic, n):,} messages do not decode as its "
             "type and are left out" for topic, n in sorted(dec.undecodable_by_topic.items())]
    recorded = sum(n for topic, n in info.topics.items()
                   if (spec := keys.spec_for_key(topic)) is not None and spec.suffix == TRUTH
                   and topic in dec.undecodable_by_topic)
    if recorded and not truth_decoded:
        notes.append(f"{TRUTH} was recorded ({recorded:,} messages) but none decodes: positions and "
                     f"energy come from {STATE} and {COMMANDS}")
    return notes


def clock_step_notes(dec: reader.Decoded) -> list[str]:
    """A line per step of the wall clock the recorder said: bridged (forward) or not (back)."""
    return [f"the wall clock stepped {step / 1e9:+.3f} s during the recording: "
            + ("every time before it is moved on by the step" if done else
               "not bridged (the times before and after a step back overlap)")
            for _at, step, done in dec.clock_steps]


ENERGY_USED_DEFINITION = ("alpha (T1^2 + T2^2) + T^w integrated from the mission's start to its "
                          "completion (the paper's energy)")
"""What "energy used" means in the report, and in the status line and the ground station, which show
the controller's live count of the same integral (``MissionStatus.energy_used_j``)."""


def energy_used(met: Any, statuses: Sequence[MissionStatus], mission_id: str | None
                ) -> dict[str, Any] | None:
    """The mission's one energy used [J]: the report's integral (``met.energy_j``), and beside it the
    controller's count of the same integral at the same end (its last status of the mission at or
    before ``met.end_ns``), as a check: the status line showed that count. None without metrics."""
    if met is None:
        return None
    mine = [s for s in statuses if s.energy_used_j is not None and s.stamp_ns <= met.end_ns
            and (mission_id is None or s.mission_id == mission_id)]
    count = mine[-1].energy_used_j if mine else None
    diff = (100.0 * (count - met.energy_j) / met.energy_j
            if count is not None and met.energy_j else None)
    return {"j": met.energy_j, "source": met.energy_source, "definition": ENERGY_USED_DEFINITION,
            "controller_count_j": count, "controller_count_difference_pct": diff}


def completion(met: Any, live: dict[str, Any], truth: Sequence[Any],
               nav: Sequence[StateEstimate]) -> dict[str, Any]:
    """Who says the mission was completed: the track the metrics are taken on (``track``: the
    simulator's truth when recorded), and the controller, which judges by its estimate
    (``controller``: its last status said so; None without statuses). ``estimate_error_m``: how
    far the last state estimate was from the truth at its stamp (nearest truth sample) [m]: where
    the two verdicts differ, this is why (the controller ends the mission on a circle of
    acceptance its estimate reached, and the true boat may still be outside it)."""
    state = live.get("state")
    err = None
    if truth and nav:
        last = nav[-1]
        stamps = [t.stamp_ns for t in truth]
        i = bisect.bisect_left(stamps, last.stamp_ns)
        near = min((j for j in (i - 1, i) if 0 <= j < len(truth)),
                   key=lambda j: abs(stamps[j] - last.stamp_ns))
        err = math.hypot(last.x_m - truth[near].x_m, last.y_m - truth[near].y_m)
    return {"track": None if met is None else bool(met.completed),
            "controller": None if state is None else state == "complete",
            "estimate_error_m": err}


def _mission_json(m: runinfo.Mission | None) -> dict[str, Any] | None:
    if m is None:
        return None
    out = {"waypoints_m": [list(w) for w in m.waypoints], "coa_radius_m": m.coa_radius_m,
           "task_power_w": m.task_power_w, "source": m.source}
    if m.controller is not None:  # known when the controller recorded it
        out |= {"controller": m.controller, "predict_disturbance": m.predict_disturbance}
    return out


def _candidates(scenario: str | None, scen: Any, mission_file: str | None,
                atts: Mapping[str, bytes], origin: GeoOrigin | None) -> list[missions.Candidate]:
    """The mission documents a report may use, in order of preference: ``--mission``, the
    ``--scenario``'s ``[mission]``, then the recording's attachments."""
    out = []
    if mission_file:
        doc = read_document(mission_file)
        out.append(missions.Candidate(runinfo.mission_from_document(doc, origin, mission_file),
                                      runinfo.mission_id_of(doc)))
    if scenario:
        if scen is None or scen.mission is None:
            raise ConfigError(f"scenario {scenario} has no [mission]")
        m = scen.mission
        out.append(missions.Candidate(
            runinfo.Mission(tuple(m.waypoints_m), m.coa_radius_m, m.task_power_w,
                            f"scenario {scenario}"), m.mission_id or scen.name))
    out += [missions.Candidate(m, mid) for m, mid in runinfo.missions_from_attachments(atts, origin)]
    return out


def _clean(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_clean(x) for x in v]
    return v


def default_out(given: Sequence[str | Path]) -> Path:
    """``report/`` beside the first recording named (in the folder named): where the user put it,
    never where a repaired copy of it is read from (``reader.readable``)."""
    first = Path(given[0])
    return (first if first.is_dir() else first.parent) / "report"


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        files = reader.open_paths(args.files)
        res = analyse(files, scenario=args.scenario, mission_file=args.mission,
                      vessel_file=args.vessel_file, vessel=args.vessel, state=args.state,
                      sample_period_s=args.sample_period, episode=args.episode)
    except (ConfigError, ValueError, FileNotFoundError) as err:
        print(f"seaway report: {err}", file=sys.stderr)
        return 2
    out = args.out or default_out(args.files)
    out.mkdir(parents=True, exist_ok=True)
    doc = _clean({k: v for k, v in res.items() if k != "_"})
    (out / "metrics.json").write_text(json.dumps(doc, indent=2) + "\n")
    written = [] if args.no_plots else plots(res, out)
    if args.json:
        for note in res["recording"]["notes"]:  # the table carries them otherwise
            print(f"seaway report: NOTE: {note}", file=sys.stderr)
        print(json.dumps(doc))
    else:
        print(table(res))
        print(f"\nwrote {out / 'metrics.json'}" + "".join(f", {p.name}" for p in written))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
