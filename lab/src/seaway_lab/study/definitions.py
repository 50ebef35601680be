"""The studies, as data: every run's scenario, controller and options, and its place in the table.

A run is one ``seaway launch sim-batch`` with the run's launcher options (``RunSpec.launch_options``)
and its own run folder; a study is a list of such runs, independent of one another, laid out as a
table of rows (the condition, scenario or T^w) by columns (the controller and variant).

The paper's numbers come from ``seaway_lab.closed_loop.TABLE_I``; a run is compared with them only
when it flies what the paper flew: a ``paper-cN`` scenario, the paper's task power (the scenario's
own), and no disturbance prediction (the paper's controllers predict with tau_d = 0).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field, replace
from typing import Any

from seaway.contract.messages import ControllerName
from seaway.simkit.scenario import load_mission

from seaway_lab.closed_loop import TABLE_I

PAPER_ORDER: tuple[ControllerName, ...] = ("nmpc", "eo-empc", "cc-empc")
"""The three controllers in the order of the paper's Table I (``CONTROLLER_NAMES`` as a set)."""
PAPER_SCENARIOS: tuple[str, ...] = tuple(f"paper-c{n}" for n in sorted(TABLE_I))
"""One scenario per condition of Table I (deploy/scenarios/paper-cN.toml)."""
STEADY_CURRENT = "steady-current"
"""A uniform water current (deploy/scenarios/steady-current.toml): a disturbance the paper's
conditions do not have, which carries the vessel instead of pushing it."""
TW_SWEEP_W: tuple[float, ...] = (0.25, 0.49, 1.0, 2.0, 4.0, 8.0)
"""Task powers T^w of the sweep [W]; 0.49 W is the paper's (shared/reproduction.md)."""
METRICS: tuple[str, ...] = ("energy_j", "avg_cross_track_m", "travel_time_s")
"""The paper's three metrics, in Table I's order (energy, average cross-track error, travel time),
named as in the report's JSON (``metrics.energy_j``, ...)."""

_PAPER_SCENARIO = re.compile(r"^paper-c(\d+)$")


def paper_condition(scenario: str) -> int | None:
    """Table I's condition number of a ``paper-cN`` scenario, else None (``paper-c4-perturbed``)."""
    m = _PAPER_SCENARIO.match(scenario)
    if m is None or int(m.group(1)) not in TABLE_I:
        return None
    return int(m.group(1))


@functools.cache
def scenario_task_power_w(scenario: str) -> float:
    """The task power T^w of a scenario's own mission [W]."""
    return load_mission(scenario).task_power_w


@dataclass(frozen=True)
class RunSpec:
    """One run: what to launch, and where its numbers go in the study's table."""

    scenario: str
    controller: ControllerName
    row: str
    """The table's row: the condition (``#1``), the scenario, or the swept value."""
    column: str
    """The table's column: the controller, with the variant when a study has several."""
    predict_disturbance: bool = False
    task_power_w: float | None = None
    """T^w [W] for this run; None: the scenario's own."""
    controller_modules: tuple[str, ...] = ()
    """Files or modules of controllers of one's own the stack loads (``seaway launch
    --controller-module``), for a run of one of them (``with_controllers``)."""

    @property
    def key(self) -> str:
        """A name unique within a study, safe for a folder and a run id."""
        k = f"{self.scenario}-{self.controller}"
        if self.predict_disturbance:
            k += "-pred"
        if self.task_power_w is not None:
            k += "-tw" + f"{self.task_power_w:g}".replace(".", "p")
        return k

    def launch_options(self) -> list[str]:
        """The ``seaway launch sim-batch`` options of this run (the run folder aside)."""
        opts = ["--scenario", self.scenario, "--controller", self.controller]
        if self.predict_disturbance:
            opts.append("--predict-disturbance")
        if self.task_power_w is not None:
            opts += ["--task-power-w", f"{self.task_power_w:g}"]
        return opts + self.module_options()

    def module_options(self) -> list[str]:
        """``--controller-module M`` for each of ``controller_modules`` (a stack's start needs them)."""
        return [o for m in self.controller_modules for o in ("--controller-module", m)]

    def paper(self) -> dict[str, float] | None:
        """Table I's energy, cross-track error and time for what this run flies, if the paper flew it."""
        cond = paper_condition(self.scenario)
        if cond is None or self.predict_disturbance or self.controller not in TABLE_I[cond]:
            return None
        if self.task_power_w is not None and not math.isclose(self.task_power_w,
                                                              scenario_task_power_w(self.scenario)):
            return None
        energy, xte, time_s = TABLE_I[cond][self.controller]
        return {"energy_j": energy, "travel_time_s": time_s, "avg_cross_track_m": xte}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RunSpec:
        """The run ``to_json`` gave (its ``key`` follows from the rest)."""
        return cls(d["scenario"], d["controller"], d["row"], d["column"],
                   predict_disturbance=bool(d.get("predict_disturbance")),
                   task_power_w=d.get("task_power_w"),
                   controller_modules=tuple(d.get("controller_modules") or ()))

    def to_json(self) -> dict[str, object]:
        return {"key": self.key, "scenario": self.scenario, "controller": self.controller,
                "predict_disturbance": self.predict_disturbance, "task_power_w": self.task_power_w,
                "row": self.row, "column": self.column,
                "controller_modules": list(self.controller_modules)}


@dataclass(frozen=True)
class Study:
    name: str
    title: str
    row_label: str
    """What the rows are (``condition``, ``scenario``, ``T^w [W]``)."""
    runs: tuple[RunSpec, ...]
    compare: tuple[str, str] | None = None
    """(base, other) columns: each row also shows the other's metrics in percent of the base's."""
    relations: bool = False
    """Check the paper's relations between the three controllers in each row."""
    figures: tuple[str, ...] = ("trajectories",)
    """``trajectories`` (a figure per row, the columns overlaid: paper Fig. 5), ``thrusts`` (CC-EMPC
    and NMPC of the first row: Fig. 4), ``tw-sweep`` (the metrics against T^w)."""
    notes: str = ""
    columns: tuple[str, ...] = field(init=False)
    rows: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        keys = [r.key for r in self.runs]
        if len(set(keys)) != len(keys):
            raise ValueError(f"study {self.name}: two runs share a key")
        cells = [(r.row, r.column) for r in self.runs]
        if len(set(cells)) != len(cells):
            raise ValueError(f"study {self.name}: two runs share a table cell")
        object.__setattr__(self, "rows", tuple(dict.fromkeys(r.row for r in self.runs)))
        object.__setattr__(self, "columns", tuple(dict.fromkeys(r.column for r in self.runs)))
        if self.compare is not None and not set(self.compare) <= set(self.columns):
            raise ValueError(f"study {self.name}: compare names a column it does not have")

    def cell(self, row: str, column: str) -> RunSpec | None:
        return next((r for r in self.runs if r.row == row and r.column == column), None)


def _row(scenario: str) -> str:
    cond = paper_condition(scenario)
    return f"#{cond}" if cond is not None else scenario


def _table1() -> Study:
    return Study(
        name="table1", title="Table I: the paper's five conditions, three controllers",
        row_label="condition",
        runs=tuple(RunSpec(s, c, _row(s), c) for s in PAPER_SCENARIOS for c in PAPER_ORDER),
        compare=("eo-empc", "cc-empc"), relations=True, figures=("trajectories", "thrusts"),
        notes="CC-EMPC vs EO-EMPC is the paper's claim: at most a few tenths of a percent more "
              "energy for a lower cross-track error in every condition.")


def _disturbance() -> Study:
    runs = []
    for s in (*PAPER_SCENARIOS, STEADY_CURRENT):
        runs.append(RunSpec(s, "cc-empc", _row(s), "cc-empc"))
        runs.append(RunSpec(s, "cc-empc", _row(s), "cc-empc+pred", predict_disturbance=True))
    return Study(
        name="disturbance", title="CC-EMPC predicting with tau_d = 0 (the paper's) vs with the "
        "estimated disturbance", row_label="condition", runs=tuple(runs),
        compare=("cc-empc", "cc-empc+pred"), figures=("trajectories",),
        notes="cc-empc+pred: the controller predicts with the estimator's disturbance "
              "(--predict-disturbance); the paper's numbers apply to the cc-empc column only.")


def _lake() -> Study:
    return Study(
        name="lake", title="The lake (field-trial conditions): three controllers", row_label="scenario",
        runs=tuple(RunSpec("lake", c, "lake", c) for c in PAPER_ORDER), compare=("eo-empc", "cc-empc"),
        relations=True, figures=("trajectories", "thrusts"),
        notes="No Table I numbers: the paper reports 0.22 m average cross-track error on the real "
              "lake (section V-B), a different mission.")


def _tw_sweep() -> Study:
    return Study(
        name="tw-sweep", title="CC-EMPC on condition #1 for a range of task powers T^w",
        row_label="T^w [W]",
        runs=tuple(RunSpec("paper-c1", "cc-empc", f"{w:g}", "cc-empc", task_power_w=w) for w in TW_SWEEP_W),
        figures=("tw-sweep", "trajectories"),
        notes="T^w sets the economic cruise speed u* = sqrt(2 T^w / alpha) / Xu; the paper's "
              "T^w = 0.49 W row is compared with Table I.")


STUDIES: dict[str, Study] = {s.name: s for s in (_table1(), _disturbance(), _lake(), _tw_sweep())}
"""Every study ``seaway study NAME`` knows, by name."""


def get_study(name: str) -> Study:
    try:
        return STUDIES[name]
    except KeyError:
        raise KeyError(f"no study {name!r}; studies: {', '.join(STUDIES)}") from None


def with_controllers(study: Study, names: list[str], modules: tuple[str, ...] = ()) -> Study:
    """The study with a column more for each controller in ``names`` (``seaway study
    --with-controller``): in every row, the row's first run flown by that controller. Every run's
    stack loads ``modules`` (``--controller-module``), so that any stack can fly any run; a
    comparison with CC-EMPC is shown when there is one column more and a cc-empc column."""
    runs = list(study.runs)
    for name in names:
        if name in study.columns:
            raise KeyError(f"study {study.name} has a column {name} already")
        for row in study.rows:
            first = next(r for r in study.runs if r.row == row)
            runs.append(replace(first, controller=name, column=name))
    runs = [replace(r, controller_modules=tuple(modules)) for r in runs]
    compare = (("cc-empc", names[0]) if len(names) == 1 and "cc-empc" in study.columns
               else study.compare)
    return Study(study.name, study.title, study.row_label, tuple(runs), compare, study.relations,
                 study.figures, study.notes)


def only(study: Study, rows: list[str] | None = None, columns: list[str] | None = None) -> Study:
    """The study restricted to some rows and columns (``--rows``, ``--columns``); KeyError if unknown."""
    for what, asked, have in (("row", rows, study.rows), ("column", columns, study.columns)):
        bad = [a for a in asked or [] if a not in have]
        if bad:
            raise KeyError(f"study {study.name} has no {what} {', '.join(bad)}; {what}s: {', '.join(have)}")
    runs = tuple(r for r in study.runs
                 if (not rows or r.row in rows) and (not columns or r.column in columns))
    compare = study.compare if study.compare and set(study.compare) <= {r.column for r in runs} else None
    return Study(study.name, study.title, study.row_label, runs, compare, study.relations, study.figures,
                 study.notes)
