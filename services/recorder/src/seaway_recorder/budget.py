"""The energy section of a report: what the controller's energy budget (``mission/energy``,
``EnergyBudget``) said along a mission, and how good its prediction of the energy to finish was.

Pure: recorded messages and the report's own metrics in, a JSON-able section out. The energy
actually used is the report's own integral over time (``MissionMetrics.series``: the simulator's
``energy_j`` or the thrust integral, plus T^w t), not the controller's count; the mission's end is
the report's (the last circle of acceptance entered). The comparison itself is
``seaway.vessel.metrics.energy_prediction_check``. Energies [J], times [s] since the report's
mission start (the first state sample at or after the mission became active).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import BatteryState, EnergyBudget
from seaway.contract.units import NS_PER_S
from seaway.vessel.energy_prediction import DERIVED_ON, MEASURED, UNSEEN_ON, known_poor
from seaway.vessel.metrics import MissionMetrics, PredictionCheck, PredictionPoint, energy_prediction_check

NOT_RECORDED = "no energy budget recorded"
"""What the section says for a recording without ``mission/energy`` (made before it existed)."""


@dataclass
class EnergySection:
    """The energy section of one mission; ``to_json`` is what ``metrics.json`` holds, the rest is
    for the plot."""

    summary: dict[str, Any]
    budgets: list[EnergyBudget] = field(default_factory=list)
    check: PredictionCheck | None = None
    check_stamps_ns: list[int] = field(default_factory=list)
    """The stamp of each of ``check.points`` [ns]."""

    def to_json(self) -> dict[str, Any]:
        return self.summary


def mission_budgets(budgets: Sequence[EnergyBudget], mission_id: str, start_ns: int,
                    end_ns: int | None) -> list[EnergyBudget]:
    """The budgets of ``mission_id`` stamped in [start_ns, end_ns] (to the end if None), in stamp
    order."""
    return sorted((b for b in budgets if b.mission_id == mission_id and b.stamp_ns >= start_ns
                   and (end_ns is None or b.stamp_ns <= end_ns)), key=lambda b: b.stamp_ns)


def _t(stamp_ns: int | None, t0_ns: int) -> float | None:
    return None if stamp_ns is None else (stamp_ns - t0_ns) / NS_PER_S


def _pct(frac: float) -> float | None:
    return None if not math.isfinite(frac) else 100.0 * frac


def _point(pt: PredictionPoint | None, stamp_ns: int | None, band: dict[int, EnergyBudget],
           t0_ns: int) -> dict[str, Any] | None:
    if pt is None or stamp_ns is None:
        return None
    b = band[stamp_ns]
    low, high = b.energy_to_go_low_j, b.energy_to_go_high_j
    inside = None if low is None and high is None else (
        (low is None or low <= pt.actual_j) and (high is None or pt.actual_j <= high))
    return {"t_s": _t(stamp_ns, t0_ns), "predicted_j": pt.predicted_j, "actual_j": pt.actual_j,
            "error_pct": _pct(pt.error_frac), "low_j": low, "high_j": high, "in_band": inside}


def _battery_at(reports: Sequence[BatteryState], stamp_ns: int, first_after: bool) -> float | None:
    """The battery's own remaining energy: the newest report at or before ``stamp_ns`` (or, with
    ``first_after`` and none before, the first one after)."""
    have = [r for r in reports if r.remaining_j is not None]
    i = bisect_right([r.stamp_ns for r in have], stamp_ns) - 1
    if i >= 0:
        return have[i].remaining_j
    return have[0].remaining_j if first_after and have else None


def energy_section(budgets: Sequence[EnergyBudget], metrics: MissionMetrics | None, start_ns: int,
                   batteries: Sequence[BatteryState] = (), controller: str | None = None
                   ) -> EnergySection:
    """The section of one mission from its budgets (``mission_budgets``), the report's metrics of
    it (None: its waypoints are unknown, so no energy integral) and the battery's own reports
    (``vehicle/battery``). ``start_ns``: the mission's start when there are no metrics.
    ``controller``: the one that flew it, when known: the band's measured coverage and a warning
    where its prediction is known to be poor (``seaway.vessel.energy_prediction``)."""
    if not budgets:
        return EnergySection({"recorded": False, "note": NOT_RECORDED})
    t0 = metrics.start_ns if metrics is not None else start_ns
    end_ns = metrics.end_ns if metrics is not None else budgets[-1].stamp_ns
    first, last = budgets[0], budgets[-1]
    at_end = [b for b in budgets if b.stamp_ns <= end_ns] or [first]
    end = at_end[-1]
    out: dict[str, Any] = {
        "recorded": True,
        "source": keys.MISSION_ENERGY.suffix,
        "samples": len(budgets),
        "energy_used_j": metrics.energy_j if metrics is not None else None,
        "policy": last.policy,
        "decision": last.decision,
        "decided_ns": last.decided_ns,
        "decided_t_s": _t(last.decided_ns, t0),
        "reason": last.reason,
        "returning": last.returning,
        "energy_to_go_start_j": first.energy_to_go_j,
        "energy_to_home_end_j": end.energy_to_home_j,
        "energy_to_home_end_low_j": end.energy_to_home_low_j,
        "energy_to_home_end_high_j": end.energy_to_home_high_j,
        # The first period that knew the battery: a live mission may start before the autopilot's
        # first report reached the controller (its first budgets have no battery figure).
        "battery_remaining_start_j": next((b.battery_remaining_j for b in budgets
                                           if b.battery_remaining_j is not None), None),
        "battery_remaining_end_j": end.battery_remaining_j,
        "reserve_j": end.reserve_j if end.reserve_j is not None else first.reserve_j,
        "margin_end_j": end.margin_j,
        "no_return_start": (None if first.no_return_along_m is None else
                            {"x_m": first.no_return_x_m, "y_m": first.no_return_y_m,
                             "along_m": first.no_return_along_m}),
        "battery_reported": None,
        "prediction": None,
        "prediction_note": "",
        "band_coverage": _coverage(controller),
        "prediction_warning": known_poor(controller) if controller else None,
    }
    if batteries:
        out["battery_reported"] = {"source": keys.VEHICLE_BATTERY.suffix,
                                   "remaining_start_j": _battery_at(batteries, t0, True),
                                   "remaining_end_j": _battery_at(batteries, end_ns, False)}
    section = EnergySection(out, list(budgets))
    if metrics is None:
        out["prediction_note"] = ("the mission's waypoints are not in the recording: no energy "
                                  "integral to compare the predictions with")
        return section
    if not metrics.completed:
        out["prediction_note"] = ("the mission did not complete: there is no energy to finish "
                                  "to compare the predictions with")
        return section
    preds = [(b.stamp_ns, b.energy_to_go_j) for b in budgets
             if b.energy_to_go_j is not None and t0 <= b.stamp_ns <= end_ns]
    if not preds:
        out["prediction_note"] = "no prediction of the energy to finish during the mission"
        return section
    ser = metrics.series
    used = [(t0 + round(t * NS_PER_S), e) for t, e in zip(ser["t_s"], ser["energy_used_j"],
                                                            strict=True)]
    check = energy_prediction_check(preds, used, end_ns)
    stamps = [s for s, _ in preds]
    by_stamp = {b.stamp_ns: b for b in budgets}
    index = {id(p): i for i, p in enumerate(check.points)}

    def stamp_of(pt: PredictionPoint | None) -> int | None:
        return None if pt is None else stamps[index[id(pt)]]

    section.check, section.check_stamps_ns = check, stamps
    out["prediction"] = {
        "start": _point(check.start, stamp_of(check.start), by_stamp, t0),
        "half": _point(check.half, stamp_of(check.half), by_stamp, t0),
        "last_half_max_abs_error_pct": _pct(check.last_half_max_abs_error_frac),
        "predictions": len(check.points),
    }
    return section


def _coverage(controller: str | None) -> dict[str, Any] | None:
    """The band's measured coverage for ``controller`` (``seaway.vessel.energy_prediction``)."""
    e = MEASURED.get(controller or "")
    if e is None:
        return None
    return {"derived": e.coverage, "derived_on": DERIVED_ON, "unseen": e.coverage_unseen,
            "unseen_on": UNSEEN_ON}


def table_rows(section: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The section as the report's table rows (name, value, unit and note)."""
    if not section.get("recorded"):
        return [("energy budget", "-", section.get("note", NOT_RECORDED))]

    def f(v: Any, fmt: str = "{:.1f}") -> str:
        return "-" if v is None else fmt.format(v)

    s = section
    # The energy used is the report's one figure, above; not repeated here, so that it is one
    # number in one place.
    rows = [("energy budget", "", f"({s['source']}, {s['samples']} periods, policy {s['policy']})")]
    if s.get("prediction_warning"):
        rows.append(("  WARNING", "", s["prediction_warning"]))
    p = s["prediction"]
    if p is not None:
        for name, pt in (("start", p["start"]), ("half way", p["half"])):
            if pt is None:
                rows.append((f"  to finish, predicted at {name}", "-", ""))
                continue
            band = (f", band {f(pt['low_j'])}-{f(pt['high_j'])} J"
                    + ("" if pt.get("in_band") is None else
                       " (actual inside)" if pt["in_band"] else " (actual OUTSIDE)")
                    if pt["low_j"] is not None or pt["high_j"] is not None else "")
            rows.append((f"  to finish, predicted at {name}", f(pt["predicted_j"]),
                         f"J at {pt['t_s']:.1f} s; actual {pt['actual_j']:.1f} J, error "
                         f"{f(pt['error_pct'], '{:+.1f}')} %{band}"))
        rows.append(("  worst |error|, last half", f(p["last_half_max_abs_error_pct"]),
                     "% (until a tenth of the mission is left)"))
        cov = s.get("band_coverage")
        if cov is not None:
            unseen = "-" if cov["unseen"] is None else f"{100 * cov['unseen']:.0f}"
            rows.append(("  band's measured coverage", f"{100 * cov['derived']:.0f} / {unseen}",
                         f"% of predictions held: {cov['derived_on']} (derived there) / "
                         f"{cov['unseen_on']} (unseen)"))
    else:
        rows.append(("  to finish, predicted at start", f(s["energy_to_go_start_j"]),
                     f"J ({s['prediction_note']})"))
    rows.append(("  to home at the end", f(s["energy_to_home_end_j"]), "J"))
    rows.append(("  battery remaining start / end",
                 f"{f(s['battery_remaining_start_j'])} / {f(s['battery_remaining_end_j'])}",
                 f"J (reserve {f(s['reserve_j'])} J)"))
    rep = s["battery_reported"]
    if rep is not None:
        rows.append(("  battery reported start / end",
                     f"{f(rep['remaining_start_j'])} / {f(rep['remaining_end_j'])}",
                     f"J ({rep['source']})"))
    if s["decision"] == "none":
        rows.append(("  decision", "none", "the margin never reached 0"))
    else:
        rows.append(("  decision", s["decision"],
                     f"at {f(s['decided_t_s'], '{:.1f}')} s: {s['reason']}".rstrip(": ")))
    return rows
