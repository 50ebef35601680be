"""A study's results: the table beside the paper's numbers, the comparisons, and the output files.

Everything here is pure: it takes the study and, per run key, the report's metrics (``energy_j``,
``avg_cross_track_m``, ``travel_time_s``, ``completed``) and timings, and returns rows, text,
Markdown, CSV or JSON. Differences are in percent of the reference: ``100 (ours - ref) / ref``.
"""

from __future__ import annotations

import csv
import io
import math
import os
import platform
import statistics
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from seaway_lab.study.definitions import METRICS, Study

SHORT = {"energy_j": "energy J", "avg_cross_track_m": "xte m", "travel_time_s": "time s"}
DIGITS = {"energy_j": 1, "avg_cross_track_m": 3, "travel_time_s": 1}
"""Decimals as Table I prints them."""
TIMINGS = ("wall_s", "startup_s", "switch_s", "mission_s", "stop_s", "launcher_report_s", "report_s")
"""A run's wall time [s] and its phases: its stack's start-up (a shared stack's first run), the
scenario load before it (a shared stack's next runs), its mission, its stack's stop (the last run
of a stack), the launcher's own report, and the report of its recording."""
CC_EO_ENERGY_MAX_PCT = 0.5
"""The paper's claim, as the system test checks it: CC-EMPC at most +0.5 % of EO-EMPC's energy."""


def pct(ours: float | None, ref: float | None) -> float | None:
    """``100 (ours - ref) / ref``; None when either is missing or the reference is 0."""
    if ours is None or ref is None or ref == 0 or not (math.isfinite(ours) and math.isfinite(ref)):
        return None
    return 100.0 * (ours - ref) / ref


def fmt(v: float | None, digits: int) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def fmt_pct(v: float | None) -> str:
    return "-" if v is None else f"{v:+.1f}"


def metrics_of(report: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The paper's metrics and ``completed`` from a report's JSON (``seaway report --json``)."""
    if report is None:
        return None
    m = report.get("metrics", {})
    return {k: m.get(k) for k in (*METRICS, "completed")}


@dataclass
class Row:
    """One cell of the study's table (one run) with its paper reference and differences."""

    row: str
    column: str
    key: str
    metrics: dict[str, Any] | None
    paper: dict[str, float] | None
    diff_pct: dict[str, float | None] = field(default_factory=dict)
    timing: dict[str, float] = field(default_factory=dict)
    ok: bool = True
    error: str = ""

    def value(self, name: str) -> float | None:
        v = None if self.metrics is None else self.metrics.get(name)
        return None if v is None else float(v)


def table_rows(study: Study, metrics: Mapping[str, dict[str, Any] | None],
               timings: Mapping[str, dict[str, float]] | None = None,
               errors: Mapping[str, str] | None = None) -> list[Row]:
    """The study's cells in table order (row by row, columns in order), with the paper's numbers."""
    out = []
    for r in study.rows:
        for c in study.columns:
            spec = study.cell(r, c)
            if spec is None:
                continue
            m = metrics.get(spec.key)
            paper = spec.paper()
            row = Row(r, c, spec.key, m, paper, timing=dict((timings or {}).get(spec.key, {})),
                      error=(errors or {}).get(spec.key, ""))
            row.ok = m is not None and bool(m.get("completed")) and not row.error
            if not row.ok:  # a run cut short has no travel time, and its energy is not the mission's
                row.metrics = None
            row.diff_pct = {k: pct(row.value(k), paper[k]) if paper else None for k in METRICS}
            out.append(row)
    return out


def comparisons(study: Study, rows: list[Row]) -> dict[str, dict[str, float | None]]:
    """Per table row: the ``compare`` pair's other column in percent of its base, per metric."""
    if study.compare is None:
        return {}
    base, other = study.compare
    cells = {(r.row, r.column): r for r in rows}
    out = {}
    for r in study.rows:
        a, b = cells.get((r, base)), cells.get((r, other))
        if a is not None and b is not None:
            out[r] = {k: pct(b.value(k), a.value(k)) for k in METRICS}
    return out


def relations(study: Study, rows: list[Row]) -> dict[str, dict[str, Any]]:
    """Per table row with all three controllers: the paper's relations between them.

    ``cc_energy_vs_eo_pct`` (CC-EMPC's energy in percent of EO-EMPC's, the paper's <= +0.5 %),
    ``cc_xte_lower`` (CC-EMPC's mean cross-track error below EO-EMPC's), ``nmpc_fastest`` and
    ``nmpc_most_expensive``; ``holds`` when all four do. None where a metric is missing.
    """
    if not study.relations:
        return {}
    by = {(r.row, r.column): r for r in rows}
    out: dict[str, dict[str, Any]] = {}
    for r in study.rows:
        cc, eo, nm = (by.get((r, c)) for c in ("cc-empc", "eo-empc", "nmpc"))
        if cc is None or eo is None or nm is None:
            continue
        e = {k: x.value("energy_j") for k, x in (("cc", cc), ("eo", eo), ("nm", nm))}
        t = {k: x.value("travel_time_s") for k, x in (("cc", cc), ("eo", eo), ("nm", nm))}
        x_cc, x_eo = cc.value("avg_cross_track_m"), eo.value("avg_cross_track_m")
        ratio = pct(e["cc"], e["eo"])
        rel: dict[str, Any] = {
            "cc_energy_vs_eo_pct": ratio,
            "cc_energy_within_limit": None if ratio is None else ratio <= CC_EO_ENERGY_MAX_PCT,
            "cc_xte_lower": None if x_cc is None or x_eo is None else x_cc < x_eo,
            "nmpc_fastest": None if None in t.values() else t["nm"] < min(t["cc"], t["eo"]),  # type: ignore[type-var]
            "nmpc_most_expensive": None if None in e.values() else e["nm"] > max(e["cc"], e["eo"]),  # type: ignore[type-var]
        }
        checks = [rel["cc_energy_within_limit"], rel["cc_xte_lower"], rel["nmpc_fastest"],
                  rel["nmpc_most_expensive"]]
        rel["holds"] = None if None in checks else all(checks)
        out[r] = rel
    return out


def timing_summary(rows: list[Row], wall_s: float, workers: int) -> dict[str, Any]:
    """Study wall time and, over the runs, the median and maximum of each phase [s]."""
    out: dict[str, Any] = {"study_wall_s": wall_s, "runs": len(rows),
                           "failed": sum(1 for r in rows if not r.ok), "workers": workers}
    cpu = sorted({k for r in rows for k in r.timing if k.startswith("cpu_")})
    for k in (*TIMINGS, *cpu):
        vals = [r.timing[k] for r in rows if k in r.timing]
        if vals:
            out[f"{k}_median"] = statistics.median(vals)
            out[f"{k}_max"] = max(vals)
            out[f"{k}_sum"] = sum(vals)
    if "wall_s_sum" in out and wall_s > 0 and workers > 0:
        out["parallel_efficiency"] = out["wall_s_sum"] / (wall_s * workers)
    return out


def machine() -> dict[str, Any]:
    """The machine a study ran on: cores, CPU model, Python."""
    model = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count() or 0
    return {"cores": usable, "cpu": model or platform.processor(), "python": platform.python_version(),
            "system": f"{platform.system()} {platform.release()}"}


# -- the document -----------------------------------------------------------------------------------


def document(study: Study, rows: list[Row], *, wall_s: float, workers: int,
             executor: Mapping[str, Any], started: str, host: Mapping[str, Any],
             runs: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    """The study's results as one JSON object (``--json``, ``results.json``)."""
    results: dict[str, dict[str, Any]] = {}
    for r in rows:
        results.setdefault(r.row, {})[r.column] = {
            **{k: r.value(k) for k in METRICS},
            "completed": None if r.metrics is None else r.metrics.get("completed"),
            "paper": r.paper, "diff_pct": r.diff_pct, "ok": r.ok, "wall_s": r.timing.get("wall_s"),
            "key": r.key}
    doc: dict[str, Any] = {
        "study": study.name, "title": study.title, "row_label": study.row_label, "started": started,
        "wall_s": wall_s, "workers": workers, "executor": dict(executor), "machine": dict(host),
        "results": results,
        "comparison": ({"base": study.compare[0], "other": study.compare[1],
                        "pct": comparisons(study, rows)} if study.compare else None),
        "relations": relations(study, rows) or None,
        "timing": timing_summary(rows, wall_s, workers),
        "failures": {r.key: r.error or "not completed" for r in rows if not r.ok},
    }
    if runs is not None:
        doc["runs"] = runs
    return doc


def _cells(r: Row) -> list[str]:
    cells = [r.row, r.column]
    for k in METRICS:
        cells += [fmt(r.value(k), DIGITS[k]), fmt(r.paper[k] if r.paper else None, DIGITS[k]),
                  fmt_pct(r.diff_pct.get(k))]
    cells.append(fmt(r.timing.get("wall_s"), 1))
    if not r.ok:
        cells[-1] += " FAILED"
    return cells


def _header(study: Study) -> list[str]:
    head = [study.row_label, "controller"]
    for k in METRICS:
        head += [SHORT[k], "paper", "diff %"]
    return [*head, "wall s"]


def text(doc: Mapping[str, Any], study: Study, rows: list[Row]) -> str:
    """The table for a terminal, with the comparisons, relations and timing under it."""
    head = _header(study)
    body = [_cells(r) for r in rows]
    widths = [max(len(x[i]) for x in [head, *body]) for i in range(len(head))]

    def line(cells: list[str]) -> str:
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w)
                         for i, (c, w) in enumerate(zip(cells, widths, strict=True))).rstrip()

    out = [f"seaway study {study.name}: {study.title}", "", line(head), line(["-" * w for w in widths])]
    prev = None
    for r, cells in zip(rows, body, strict=True):
        if prev is not None and r.row != prev:
            out.append("")
        prev = r.row
        out.append(line(cells))
    out += ["", *_comparison_lines(doc), *_relation_lines(doc), *_timing_lines(doc)]
    for key, err in doc["failures"].items():
        out.append(f"FAILED {key}: {err.splitlines()[0] if err else ''}")
    return "\n".join(out).rstrip() + "\n"


def _comparison_lines(doc: Mapping[str, Any]) -> list[str]:
    c = doc.get("comparison")
    if not c or not c["pct"]:
        return []
    out = [f"{c['other']} in percent of {c['base']}: " + ", ".join(SHORT[k] for k in METRICS)]
    for row, d in c["pct"].items():
        out.append(f"  {row}: " + "  ".join(f"{SHORT[k].split()[0]} {fmt_pct(d[k])} %" for k in METRICS))
    return [*out, ""]


def _relation_lines(doc: Mapping[str, Any]) -> list[str]:
    rel = doc.get("relations")
    if not rel:
        return []
    out = [f"the paper's relations (CC-EMPC energy <= +{CC_EO_ENERGY_MAX_PCT:g} % of EO-EMPC's and lower "
           "cross-track error; NMPC fastest and most expensive):"]

    def yn(v: Any) -> str:
        return "-" if v is None else ("yes" if v else "NO")

    for row, d in rel.items():
        out.append(f"  {row}: CC/EO energy {fmt_pct(d['cc_energy_vs_eo_pct'])} % "
                   f"({yn(d['cc_energy_within_limit'])}), CC xte lower {yn(d['cc_xte_lower'])}, "
                   f"NMPC fastest {yn(d['nmpc_fastest'])}, most expensive {yn(d['nmpc_most_expensive'])}"
                   f" -> {'holds' if d['holds'] else 'does NOT hold' if d['holds'] is False else '-'}")
    return [*out, ""]


def _timing_lines(doc: Mapping[str, Any]) -> list[str]:
    t = doc["timing"]
    ex = doc["executor"]
    where = ex.get("kind", "local") + (f" {ex['address']}" if ex.get("address") else "")
    out = [f"study wall time {doc['wall_s']:.1f} s for {t['runs']} runs ({t['failed']} failed), "
           f"{doc['workers']} at a time ({where}) on {doc['machine'].get('cores')} cores"]
    parts = []
    for k in TIMINGS:
        if f"{k}_median" in t:
            parts.append(f"{k[:-2].replace('_', ' ')} {t[f'{k}_median']:.1f}/{t[f'{k}_max']:.1f}")
    if parts:
        out.append("per run, median/max s: " + ", ".join(parts))
    cpu = sorted((k for k in t if k.startswith("cpu_") and k.endswith("_s_sum") and t[k] >= 0.05),
                 key=lambda k: -t[k])
    if cpu:
        out.append("CPU s over all runs, by process: " + ", ".join(
            f"{k[4:-6]} {t[k]:.1f}" for k in cpu))
    if "parallel_efficiency" in t:
        out.append(f"sum of run wall times {t['wall_s_sum']:.1f} s; parallel efficiency "
                   f"{100 * t['parallel_efficiency']:.0f} %")
    if "figures_s" in t:
        out.append(f"figures drawn in {t['figures_s']:.1f} s after the runs")
    return out


def markdown(doc: Mapping[str, Any], study: Study, rows: list[Row]) -> str:
    """The same as ``text`` as Markdown tables."""
    head = _header(study)
    out = [f"## `seaway study {study.name}`: {study.title}", "",
           f"Started {doc['started']}; {doc['wall_s']:.1f} s of wall time for {len(rows)} runs, "
           f"{doc['workers']} at a time, on {doc['machine'].get('cores')} cores "
           f"({doc['machine'].get('cpu')}).", ""]
    if study.notes:
        out += [study.notes, ""]
    out += ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * 2 + ["---:"] * (len(head) - 2)) + "|"]
    out += ["| " + " | ".join(_cells(r)) + " |" for r in rows]
    out.append("")
    c = doc.get("comparison")
    if c and c["pct"]:
        out += [f"{c['other']} in percent of {c['base']}:", "",
                f"| {study.row_label} | " + " | ".join(f"{SHORT[k]} diff %" for k in METRICS) + " |",
                "|---|" + "---:|" * len(METRICS)]
        out += [f"| {row} | " + " | ".join(fmt_pct(d[k]) for k in METRICS) + " |"
                for row, d in c["pct"].items()]
        out.append("")
    rel = doc.get("relations")
    if rel:
        out += ["The paper's relations:", "",
                f"| {study.row_label} | CC/EO energy % | CC xte lower | NMPC fastest | NMPC most expensive "
                "| holds |", "|---|---:|---|---|---|---|"]
        for row, d in rel.items():
            out.append(f"| {row} | {fmt_pct(d['cc_energy_vs_eo_pct'])} | {d['cc_xte_lower']} | "
                       f"{d['nmpc_fastest']} | {d['nmpc_most_expensive']} | {d['holds']} |")
        out.append("")
    out += [f"- {line}" for line in _timing_lines(doc)]
    failures = doc.get("failures") or {}
    out += [f"- FAILED {key}: {err.splitlines()[0] if err else ''}" for key, err in failures.items()]
    return "\n".join(out).rstrip() + "\n"


CSV_FIELDS = ("row", "column", "key", *METRICS, "completed", *(f"paper_{k}" for k in METRICS),
              *(f"diff_pct_{k}" for k in METRICS), *TIMINGS, "ok")


def csv_text(rows: list[Row]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_FIELDS, lineterminator="\n")
    w.writeheader()
    for r in rows:
        rec: dict[str, Any] = {"row": r.row, "column": r.column, "key": r.key, "ok": r.ok,
                               "completed": None if r.metrics is None else r.metrics.get("completed")}
        for k in METRICS:
            rec[k] = r.value(k)
            rec[f"paper_{k}"] = r.paper[k] if r.paper else None
            rec[f"diff_pct_{k}"] = r.diff_pct.get(k)
        for k in TIMINGS:
            rec[k] = r.timing.get(k)
        w.writerow(rec)
    return buf.getvalue()
