"""What ``seaway report`` shows of an analysed recording (``report.analyse``'s result): the table
printed (``table``) and the plots written (``plots``: trajectory, thrust, cross-track error and the
energy budget's figures along each mission).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from seaway.contract import keys

from seaway_recorder import budget


def _completed_rows(m: dict[str, Any], c: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The 'completed' row, by the track the metrics are taken on; and the controller's verdict
    below it when that differs (``completion``)."""
    if m["completed"]:
        return [("completed", "yes", "")]
    rows = [("completed", "NO", "(metrics up to the last sample)")]
    if c.get("controller"):
        err = c.get("estimate_error_m")
        rows = [("completed", "NO", "on the true track (metrics up to the last sample)"),
                ("  by the controller", "yes", "on its estimate" + (
                    f", {err:.2f} m from the truth at the end" if err is not None else ""))]
    return rows


def _controller_count_rows(used: dict[str, Any] | None) -> list[tuple[str, str, str]]:
    """The controller's count of the energy used at the same end, as a check of the figure above."""
    if used is None or used.get("controller_count_j") is None:
        return []
    status = keys.MISSION_STATUS.suffix
    return [("  controller's count", _f(used["controller_count_j"], "{:.2f}"),
             f"J ({status} at the same end, {_f(used['controller_count_difference_pct'], '{:+.2f}')} %;"
             " the status line's figure)")]


def _f(v: Any, fmt: str = "{:.3f}") -> str:
    return "-" if v is None else fmt.format(v)


def table(res: dict[str, Any]) -> str:
    m, s, live = res["metrics"], res["solve"], res["controller_reported"]
    flown = res["missions"]
    if m is not None:
        rows = [
            *_completed_rows(m, res.get("completion") or {}),
            ("travel time", _f(m["travel_time_s"], "{:.2f}"), "s"),
            ("energy used", _f(m["energy_j"], "{:.2f}"), f"J ({m['energy_source']})"),
            ("  propulsion", _f(m["propulsion_energy_j"], "{:.2f}"), "J"),
            ("  task (T^w * t)", _f(m["task_energy_j"], "{:.2f}"), "J"),
            ("  check", _f(m["energy_check_j"], "{:.2f}"),
             f"J ({m['energy_check_source'] or 'none'})"),
            *_controller_count_rows(res.get("energy_used")),
            ("avg cross-track error", _f(m["avg_cross_track_m"], "{:.4f}"),
             f"m ({m['cross_track_samples']} samples outside the circles)"),
            ("max cross-track error", _f(m["max_cross_track_m"], "{:.4f}"), "m"),
            ("legs completed", str(m["legs_completed"]),
             f"of {len(res['mission']['waypoints_m']) - 1}"),
        ]
    else:  # the mission flown is not described by any document: the controller's own word
        rows = [("state (controller)", str(live.get("state")), ""),
                ("active leg (controller)", str(live.get("active_leg")),
                 f"of {max(int(live.get('waypoint_count') or 0) - 1, 0)}")]
    rows += budget.table_rows(res["energy_budget"])
    rows += [
        ("solves", str(s["count"]), f"{s['failures']} failed" + (
            f", {s['not_ready']} before its solver was ready (a fallback flew)"
            if s.get("not_ready") else "")),
        ("solve time median / p95 / max", f"{_f(s['solve_time_median_ms'], '{:.2f}')} / "
         f"{_f(s['solve_time_p95_ms'], '{:.2f}')} / {_f(s['solve_time_max_ms'], '{:.2f}')}", "ms"),
        ("fallbacks", str(s["fallbacks"]), f"by level {s['fallback_levels'] or '{}'}"),
    ]
    if m is None and live.get("energy_used_j") is not None:  # no integral: the controller's count
        rows.append(("energy used (controller's count)", _f(live["energy_used_j"], "{:.2f}"),
                     f"J ({keys.MISSION_STATUS.suffix})"))
    w = max(len(r[0]) for r in rows)
    v = max(len(r[1]) for r in rows)
    head = f"Run report: {', '.join(res['files'])}\nvessel {res['vessel']}"
    if m is not None:
        head += f", state from {m['state_source']}, mission from {res['mission']['source']}\n"
    else:
        last = flown[-1]
        head += (f"\nmission {last['mission_id']!r}: its waypoints are not in the recording, so the "
                 f"paper's metrics cannot be computed ({last['fit']}); pass --mission FILE with "
                 "the mission sent\n")
    if flown and m is not None:
        head += f"mission {flown[-1]['mission_id']!r}: {flown[-1]['fit']}\n"
    head += "".join(f"NOTE: {line}\n" for line in res["recording"]["repaired"])
    head += "".join(f"NOTE: {line}\n" for line in res["recording"].get("notes", []))
    ep = res["episodes"]
    if ep["time_went_back"]:
        head += (f"simulated time went back {ep['time_went_back']} time(s) (a sim restart or a new "
                 f"scenario): {ep['count']} episodes; these metrics are episode {ep['reported']}'s "
                 "(--episode N for another)\n")
    if len(flown) > 1:
        head += f"{len(flown)} missions flown in this episode; the report is about the last:\n"
        for x in flown:
            mm, rep = x["metrics"], x["controller_reported"]
            figures = (f"completed {'yes' if mm['completed'] else 'NO'}, {_f(mm['energy_j'], '{:.2f}')}"
                       f" J, XTE {_f(mm['avg_cross_track_m'], '{:.4f}')} m, from {x['source']}"
                       if mm is not None else
                       f"{rep['state']} at leg {rep['active_leg']}, {_f(rep['energy_used_j'], '{:.2f}')}"
                       " J (controller's), waypoints not in the recording")
            eb = x["energy_budget"]
            if eb.get("recorded") and eb["decision"] != "none":
                figures += f"; energy budget: {eb['decision']} at {_f(eb['decided_t_s'], '{:.1f}')} s"
            head += f"  {x['mission_id']!r}: {figures}\n"
    return head + "\n".join(f"{a.ljust(w)}  {b.rjust(v)}  {c}".rstrip() for a, b, c in rows)


def plots(res: dict[str, Any], out: Path) -> list[Path]:
    if res["metrics"] is None:
        return []  # no mission document for what was flown: nothing to draw it against
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = res["_"]
    ser = data["series"]
    t0 = data["start_ns"]
    written = []

    # Trajectory: NED, so north up (x) and east right (y).
    fig, ax = plt.subplots(figsize=(6, 6))
    wps = res["mission"]["waypoints_m"]
    r = res["mission"]["coa_radius_m"]
    ax.plot([p[1] for p in wps], [p[0] for p in wps], "k--", lw=1, label="path")
    for i, (x, y) in enumerate(wps):
        ax.add_patch(plt.Circle((y, x), r, fill=False, color="tab:green", lw=1))
        ax.annotate(f"P{i}", (y, x), textcoords="offset points", xytext=(5, 5))
    ax.plot(ser["y_m"], ser["x_m"], color="tab:blue", lw=1.5, label=res["metrics"]["state_source"])
    ax.set_xlabel("east y [m]")
    ax.set_ylabel("north x [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best")
    ax.set_title("trajectory")
    written.append(_save(fig, out / "trajectory.png"))

    fig, ax = plt.subplots(figsize=(8, 4))
    truth, commands = keys.SIM_TRUTH.suffix, keys.THRUST.suffix
    applied = data["thrusts"] if res["metrics"]["state_source"] == truth else []
    for label, seq in ((f"applied ({truth})", applied), (f"commanded ({commands})", data["commands"])):
        seq = [c for c in seq if t0 <= c.stamp_ns <= res["metrics"]["end_ns"]]  # the mission only
        if seq:
            t = [(c.stamp_ns - t0) / 1e9 for c in seq]
            ax.step(t, [c.thrust_port_n for c in seq], where="post", label=f"T1 port, {label}")
            ax.step(t, [c.thrust_starboard_n for c in seq], where="post", label=f"T2 starboard, {label}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("thrust [N]")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("thrusts")
    written.append(_save(fig, out / "thrust.png"))

    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(ser["grid_t_s"], ser["cross_track_m"], lw=1)
    avg = res["metrics"]["avg_cross_track_m"]
    if avg is not None:
        ax.axhline(avg, color="tab:red", ls="--", lw=1, label=f"average {avg:.3f} m")
        ax.legend(loc="best")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("cross-track error [m] (gaps: inside a circle)")
    ax.set_title("cross-track error")
    written.append(_save(fig, out / "cross_track.png"))

    written.append(_save(energy_plot(plt, res), out / "energy.png"))
    return written


def energy_plot(plt: Any, res: dict[str, Any]) -> Any:
    """Energy used (the report's integral) with the controller's energy to the active waypoint
    above; below, the energy to finish as the controller's budget predicted it along the mission
    (its band shaded) against what finishing actually took from each instant."""
    data, ser = res["_"], res["_"]["series"]
    t0, t_end = data["start_ns"], res["metrics"]["end_ns"]
    section: budget.EnergySection = data["energy"]
    with_budget = bool(section.budgets)
    fig, axes = plt.subplots(2 if with_budget else 1, 1, figsize=(8, 7 if with_budget else 4),
                             sharex=True, squeeze=False)
    ax = axes[0][0]
    ax.plot(ser["t_s"], ser["energy_used_j"], label="energy used (incl. T^w)")

    def rel(stamp_ns: int) -> float:
        return (stamp_ns - t0) / 1e9

    # The active leg's figure: SolveRecord.leg_energy_to_go_j (None in recordings made before it
    # was named so), else the status's; the status's energy_to_go_j is the mission's now, and the
    # active leg's only in recordings without a budget.
    def during(seq: list[Any], field: str) -> list[tuple[int, float]]:
        return sorted((s.stamp_ns, getattr(s, field)) for s in seq
                      if getattr(s, field) is not None and t0 <= s.stamp_ns <= t_end)

    leg = during(data["solves"], "leg_energy_to_go_j") or during(data["statuses"], "leg_energy_to_go_j")
    if not leg and not with_budget:
        leg = during(data["statuses"], "energy_to_go_j")
    if leg:
        ax.plot([rel(t) for t, _ in leg], [e for _, e in leg], lw=1,
                label="to the active waypoint (controller)")
    ax.set_ylabel("energy [J]")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("energy")
    if with_budget:
        ax = axes[1][0]
        pts = [b for b in section.budgets if b.energy_to_go_j is not None and t0 <= b.stamp_ns <= t_end]
        t = [rel(b.stamp_ns) for b in pts]
        low = [b.energy_to_go_low_j for b in pts]
        high = [b.energy_to_go_high_j for b in pts]
        if pts and all(v is not None for v in (*low, *high)):
            ax.fill_between(t, low, high, color="tab:orange", alpha=0.25, lw=0,
                            label="predicted band (disturbance +-1 sd and measured error)")
        ax.plot(t, [b.energy_to_go_j for b in pts], color="tab:orange",
                label=f"predicted ({keys.MISSION_ENERGY.suffix})")
        check = section.check
        if check is not None and check.points:
            ax.plot([rel(s) for s in section.check_stamps_ns], [p.actual_j for p in check.points],
                    color="black", lw=1.2, ls="--", label="actual (energy used from then to the end)")
        summary = section.summary
        if summary.get("decided_ns") is not None and summary["decision"] != "none":
            ax.axvline(rel(summary["decided_ns"]), color="tab:red", lw=1,
                       label=f"decision: {summary['decision']}")
        ax.set_ylabel("energy to finish [J]")
        ax.legend(loc="best", fontsize="small")
    axes[-1][0].set_xlabel("time [s]")
    return fig


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
