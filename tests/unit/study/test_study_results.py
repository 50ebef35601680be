"""`seaway study`: percent differences, the table beside the paper's, the relations, the files."""

from __future__ import annotations

import csv
import io
import json

import pytest
from seaway_lab.closed_loop import TABLE_I
from seaway_lab.study import definitions as defs
from seaway_lab.study import results as res


def paper_like(scale: dict[str, float] | None = None) -> dict[str, dict]:
    """Metrics for every table1 run: the paper's own numbers, each scaled by ``scale[key]``."""
    out = {}
    for r in defs.get_study("table1").runs:
        p = r.paper()
        assert p is not None
        f = (scale or {}).get(r.key, 1.0)
        out[r.key] = {"energy_j": p["energy_j"] * f, "avg_cross_track_m": p["avg_cross_track_m"],
                      "travel_time_s": p["travel_time_s"], "completed": True}
    return out


def test_pct() -> None:
    assert res.pct(110.0, 100.0) == pytest.approx(10.0)
    assert res.pct(95.0, 100.0) == pytest.approx(-5.0)
    assert res.pct(None, 1.0) is None
    assert res.pct(1.0, None) is None
    assert res.pct(1.0, 0.0) is None
    assert res.pct(float("nan"), 1.0) is None
    assert res.fmt_pct(1.234) == "+1.2"
    assert res.fmt_pct(-0.04) == "-0.0"
    assert res.fmt_pct(None) == "-"
    assert res.fmt(2328.44, 1) == "2328.4"


def test_rows_carry_the_paper_and_the_difference() -> None:
    study = defs.get_study("table1")
    rows = res.table_rows(study, paper_like({"paper-c2-nmpc": 1.10}), {"paper-c2-nmpc": {"wall_s": 5.0}})
    assert [(r.row, r.column) for r in rows][:4] == [("#1", "nmpc"), ("#1", "eo-empc"), ("#1", "cc-empc"),
                                                    ("#2", "nmpc")]
    r = rows[3]
    assert r.paper == {"energy_j": 2321.0, "avg_cross_track_m": 1.680, "travel_time_s": 36.4}
    assert r.diff_pct["energy_j"] == pytest.approx(10.0)
    assert r.diff_pct["travel_time_s"] == pytest.approx(0.0)
    assert r.timing == {"wall_s": 5.0}
    assert all(x.ok for x in rows)


def test_a_failed_run_shows_no_numbers() -> None:
    study = defs.get_study("table1")
    m = paper_like()
    m["paper-c1-nmpc"]["completed"] = False
    rows = res.table_rows(study, m, errors={"paper-c1-eo-empc": "timed out"})
    by = {r.key: r for r in rows}
    for key in ("paper-c1-nmpc", "paper-c1-eo-empc"):
        assert not by[key].ok
        assert by[key].metrics is None
        assert by[key].diff_pct == {k: None for k in defs.METRICS}
    rel = res.relations(study, rows)["#1"]
    assert rel["holds"] is None and rel["cc_energy_vs_eo_pct"] is None
    doc = res.document(study, rows, wall_s=1.0, workers=2, executor={}, started="now",
                       host={"cores": 2})
    assert doc["failures"] == {"paper-c1-nmpc": "not completed", "paper-c1-eo-empc": "timed out"}
    assert doc["timing"]["failed"] == 2
    assert "FAILED" in res.text(doc, study, rows)


def test_relations_hold_on_the_papers_numbers_and_bite() -> None:
    study = defs.get_study("table1")
    rel = res.relations(study, res.table_rows(study, paper_like()))
    assert set(rel) == {"#1", "#2", "#3", "#4", "#5"}
    assert all(r["holds"] for r in rel.values())
    c1 = TABLE_I[1]
    assert rel["#1"]["cc_energy_vs_eo_pct"] == pytest.approx(100 * (c1["cc-empc"][0] / c1["eo-empc"][0] - 1))
    # CC-EMPC 0.6 % above EO-EMPC in #2: beyond the paper's +0.5 %
    rel = res.relations(study, res.table_rows(study, paper_like({"paper-c2-cc-empc": 1.006 * 328.5 / 328.7})))
    assert rel["#2"]["cc_energy_within_limit"] is False and rel["#2"]["holds"] is False
    assert rel["#1"]["holds"]
    # NMPC cheaper than CC-EMPC in #3
    rel = res.relations(study, res.table_rows(study, paper_like({"paper-c3-nmpc": 0.1})))
    assert rel["#3"]["nmpc_most_expensive"] is False and rel["#3"]["holds"] is False
    assert res.relations(defs.get_study("tw-sweep"), []) == {}


def test_comparisons_are_the_other_column_in_percent_of_the_base() -> None:
    study = defs.get_study("table1")
    cmp = res.comparisons(study, res.table_rows(study, paper_like()))
    assert cmp["#4"]["energy_j"] == pytest.approx(100 * (330.3 / 330.1 - 1))
    assert cmp["#4"]["avg_cross_track_m"] == pytest.approx(100 * (0.477 / 0.507 - 1))


def test_timing_summary() -> None:
    rows = [res.Row("#1", c, c, {"completed": True}, None, timing={"wall_s": w, "startup_s": 2.0})
            for c, w in (("a", 10.0), ("b", 20.0), ("c", 30.0))]
    t = res.timing_summary(rows, wall_s=30.0, workers=2)
    assert t["wall_s_median"] == 20.0 and t["wall_s_max"] == 30.0 and t["wall_s_sum"] == 60.0
    assert t["startup_s_median"] == 2.0
    assert t["parallel_efficiency"] == pytest.approx(1.0)
    assert "mission_s_median" not in t


def test_text_markdown_csv_and_json_say_the_same() -> None:
    study = defs.get_study("table1")
    rows = res.table_rows(study, paper_like({"paper-c1-cc-empc": 1.01}),
                          {r.key: {"wall_s": 4.0} for r in study.runs})
    doc = res.document(study, rows, wall_s=61.5, workers=2, executor={"kind": "local"}, started="t0",
                       host={"cores": 2, "cpu": "test cpu"})
    json.dumps(doc)  # JSON-able
    assert doc["wall_s"] == 61.5
    cell = doc["results"]["#1"]["cc-empc"]
    assert cell["energy_j"] == pytest.approx(332.0 * 1.01)
    assert cell["diff_pct"]["energy_j"] == pytest.approx(1.0)
    assert set(doc["results"]) == {"#1", "#2", "#3", "#4", "#5"}
    assert set(doc["results"]["#3"]) == {"nmpc", "eo-empc", "cc-empc"}
    assert doc["relations"]["#1"]["cc_energy_within_limit"] is False  # +1.0 % over EO-EMPC's +0.03 %

    text = res.text(doc, study, rows)
    line = next(x for x in text.splitlines() if x.startswith("#1") and "cc-empc" in x)
    assert line.split()[2:5] == ["335.3", "332.0", "+1.0"]
    assert "study wall time 61.5 s for 15 runs (0 failed), 2 at a time (local) on 2 cores" in text
    assert "does NOT hold" in text

    md = res.markdown(doc, study, rows)
    assert "| #1 | cc-empc | 335.3 | 332.0 | +1.0 |" in md
    assert md.count("\n| #") == 15 + 5 + 5  # the table, the comparison and the relations

    recs = list(csv.DictReader(io.StringIO(res.csv_text(rows))))
    assert len(recs) == 15
    r = next(x for x in recs if x["key"] == "paper-c1-cc-empc")
    assert float(r["energy_j"]) == pytest.approx(335.32)
    assert float(r["paper_energy_j"]) == 332.0
    assert float(r["diff_pct_energy_j"]) == pytest.approx(1.0)
    assert r["ok"] == "True" and r["wall_s"] == "4.0"


def test_metrics_of_a_report() -> None:
    rep = {"metrics": {"energy_j": 1.0, "avg_cross_track_m": 0.2, "travel_time_s": 3.0, "completed": True,
                       "max_cross_track_m": 9.0}}
    assert res.metrics_of(rep) == {"energy_j": 1.0, "avg_cross_track_m": 0.2, "travel_time_s": 3.0,
                                   "completed": True}
    assert res.metrics_of(None) is None


def test_cpu_seconds_are_summed_by_process() -> None:
    rows = [res.Row("#1", c, c, {"completed": True}, None,
                    timing={"wall_s": 1.0, "cpu_sim_s": s, "cpu_controller_s": 2 * s})
            for c, s in (("a", 1.0), ("b", 3.0))]
    t = res.timing_summary(rows, wall_s=2.0, workers=1)
    assert t["cpu_sim_s_sum"] == 4.0 and t["cpu_controller_s_sum"] == 8.0
    doc = {"timing": t, "executor": {"kind": "local"}, "wall_s": 2.0, "workers": 1, "machine": {"cores": 2}}
    assert "CPU s over all runs, by process: controller 8.0, sim 4.0" in res._timing_lines(doc)
