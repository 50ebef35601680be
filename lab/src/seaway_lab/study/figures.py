"""A study's figures, drawn from its recordings (the series ``execute.report_json`` reads from each).

* ``trajectories``: one figure per table row with its columns overlaid (paper Fig. 5), the path,
  the waypoints and their circles of acceptance, and all rows side by side in ``trajectories.png``;
* ``thrusts``: CC-EMPC and NMPC of the first row that has both (paper Fig. 4, condition #1);
* ``tw_sweep``: energy, travel time and mean cross-track error against T^w, with the paper's point.

The world is local NED, drawn as a map: east to the right, north up (as ``seaway report`` does).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from seaway_lab.study.definitions import Study
from seaway_lab.study.results import Row

COLORS = {"nmpc": "tab:red", "eo-empc": "tab:orange", "cc-empc": "tab:blue", "cc-empc+pred": "tab:green"}
DPI = 80
"""Small PNGs: the figures are committed under docs/results/."""

Series = Mapping[str, Mapping[str, Any]]


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    _plt().close(fig)
    return path


def _color(column: str, i: int) -> str:
    return COLORS.get(column, f"C{i % 10}")


def _path(ax: Any, s: Mapping[str, Any]) -> None:
    plt = _plt()
    wps, r = s["waypoints_m"], s["coa_radius_m"]
    ax.plot([p[1] for p in wps], [p[0] for p in wps], "k--", lw=0.8)
    for i, (x, y) in enumerate(wps):
        ax.add_patch(plt.Circle((y, x), r, fill=False, color="tab:green", lw=0.8))
        ax.annotate(f"P{i}", (y, x), textcoords="offset points", xytext=(4, 4), fontsize="small")
    ax.set_xlabel("east y [m]")
    ax.set_ylabel("north x [m]")
    ax.set_aspect("equal", adjustable="datalim")


def _trajectory_axes(ax: Any, study: Study, row: str, series: Series) -> bool:
    drawn: list[str] = []
    scenario = ""
    for i, col in enumerate(study.columns):
        spec = study.cell(row, col)
        s = series.get(spec.key) if spec else None
        if spec is None or not s:
            continue
        if not drawn:
            _path(ax, s)
            scenario = spec.scenario
        ax.plot(s["y_m"], s["x_m"], color=_color(col, i), lw=1.2, label=col)
        drawn.append(col)
    if drawn:
        ax.legend(loc="best", fontsize="small")
        label = f" ({study.row_label} {row})" if row != scenario and not row.startswith("#") else ""
        ax.set_title(f"{scenario}{label}: " + ", ".join(drawn), fontsize="medium")
    return bool(drawn)


def trajectories(study: Study, series: Series, out: Path) -> list[Path]:
    """A figure per row (``trajectory-<row>.png``) and all rows together (``trajectories.png``)."""
    plt = _plt()
    written = []
    drawn_rows = []
    for row in study.rows:
        fig, ax = plt.subplots(figsize=(5, 5))
        if _trajectory_axes(ax, study, row, series):
            written.append(_save(fig, out / f"trajectory-{_row_name(study, row)}.png"))
            drawn_rows.append(row)
        else:
            plt.close(fig)
    if len(drawn_rows) > 1:
        n = len(drawn_rows)
        cols = min(n, 3)
        nrows = math.ceil(n / cols)
        fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 4.2 * nrows), squeeze=False)
        for ax, row in zip(axes.flat, drawn_rows, strict=False):
            _trajectory_axes(ax, study, row, series)
        for ax in list(axes.flat)[n:]:
            ax.set_visible(False)
        written.append(_save(fig, out / "trajectories.png"))
    return written


def thrusts(study: Study, series: Series, out: Path, columns: tuple[str, ...] = ("cc-empc", "nmpc")
            ) -> list[Path]:
    """Thrusts of ``columns`` in the first row that has them all (``thrusts-<row>.png``)."""
    plt = _plt()
    for row in study.rows:
        specs = [study.cell(row, c) for c in columns]
        if any(s is None or not series.get(s.key) for s in specs):
            continue
        fig, axes = plt.subplots(len(specs), 1, figsize=(8, 2.6 * len(specs)), squeeze=False)
        for ax, spec in zip(axes[:, 0], specs, strict=True):
            assert spec is not None
            s = series[spec.key]
            ax.step(s["thrust_t_s"], s["thrust_port_n"], where="post", lw=1, label="T1 port")
            ax.step(s["thrust_t_s"], s["thrust_starboard_n"], where="post", lw=1, label="T2 starboard")
            ax.set_ylabel("thrust [N]")
            ax.set_title(f"{spec.scenario}: {spec.controller}", fontsize="medium")
            ax.legend(loc="best", fontsize="small")
        axes[-1, 0].set_xlabel("time [s]")
        return [_save(fig, out / f"thrusts-{_row_name(study, row)}.png")]
    return []


def tw_sweep(study: Study, rows: list[Row], series: Series, out: Path) -> list[Path]:
    """Energy, travel time and mean cross-track error against T^w (log axis), with Table I's point,
    and the trajectories for every T^w (``tw-sweep.png``)."""
    plt = _plt()
    pts = []
    for r in rows:
        spec = study.cell(r.row, r.column)
        if spec is None or spec.task_power_w is None or r.metrics is None:
            continue
        pts.append((spec.task_power_w, r, spec))
    if not pts:
        return []
    pts.sort(key=lambda p: p[0])
    fig, axes = plt.subplots(2, 2, figsize=(9, 7))
    tw = [p[0] for p in pts]
    for ax, (name, label) in zip(axes.flat, (("energy_j", "energy [J]"), ("travel_time_s", "travel time [s]"),
                                             ("avg_cross_track_m", "mean cross-track error [m]")),
                                 strict=False):
        ax.plot(tw, [p[1].value(name) for p in pts], "o-", color="tab:blue", label="cc-empc (this stack)")
        paper = [(p[0], p[1].paper[name]) for p in pts if p[1].paper]
        if paper:
            ax.plot(*zip(*paper, strict=True), "k*", ms=10, label="paper, Table I")
        ax.set_xscale("log")
        ax.set_xticks(tw, [f"{w:g}" for w in tw])
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
        ax.set_xlabel("task power T^w [W]")
        ax.set_ylabel(label)
        ax.grid(True, which="both", lw=0.3)
        ax.legend(loc="best", fontsize="small")
    ax = axes[1, 1]
    first = True
    for i, (w, _r, spec) in enumerate(pts):
        s = series.get(spec.key)
        if not s:
            continue
        if first:
            _path(ax, s)
            first = False
        ax.plot(s["y_m"], s["x_m"], color=plt.cm.viridis(i / max(1, len(pts) - 1)), lw=1, label=f"{w:g} W")
    ax.legend(loc="best", fontsize="x-small", title="T^w")
    scen = pts[0][2].scenario
    fig.suptitle(f"{scen}: {pts[0][2].controller} against the task power T^w")
    return [_save(fig, out / "tw-sweep.png")]


def _row_name(study: Study, row: str) -> str:
    """A file name for a row: its scenario for a paper condition (``paper-c1``), else the row."""
    first = next((r for r in study.runs if r.row == row), None)
    return _safe(first.scenario if first is not None and row.startswith("#") else row)


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "-" for ch in name).strip("-") or "row"


def draw(study: Study, rows: list[Row], series: Series, out: Path) -> list[Path]:
    """Every figure the study asks for, into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    if "trajectories" in study.figures:
        written += trajectories(study, series, out)
    if "thrusts" in study.figures:
        written += thrusts(study, series, out)
    if "tw-sweep" in study.figures:
        written += tw_sweep(study, rows, series, out)
    return written
