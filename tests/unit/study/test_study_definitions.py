"""`seaway study`: the studies as data, and their runs' launcher options against the real parser."""

from __future__ import annotations

import pytest
from seaway.contract.messages import CONTROLLER_NAMES
from seaway.simkit.scenario import load_scenario
from seaway.tools.launch.main import parser as launch_parser
from seaway_lab.closed_loop import TABLE_I
from seaway_lab.study import definitions as defs


def test_table1_is_the_papers_table() -> None:
    s = defs.get_study("table1")
    assert len(s.runs) == 15
    assert s.rows == ("#1", "#2", "#3", "#4", "#5")
    assert s.columns == defs.PAPER_ORDER == ("nmpc", "eo-empc", "cc-empc")
    assert set(defs.PAPER_ORDER) == set(CONTROLLER_NAMES)
    for r in s.runs:
        cond = int(r.row[1:])
        assert r.scenario == f"paper-c{cond}"
        e, x, t = TABLE_I[cond][r.controller]
        assert r.paper() == {"energy_j": e, "avg_cross_track_m": x, "travel_time_s": t}


def test_every_study_names_scenarios_that_load_and_unique_keys() -> None:
    for s in defs.STUDIES.values():
        assert s.runs, s.name
        assert len({r.key for r in s.runs}) == len(s.runs)
        for r in s.runs:
            assert load_scenario(r.scenario).mission is not None
            assert r.controller in CONTROLLER_NAMES


def test_the_other_studies() -> None:
    d = defs.get_study("disturbance")
    assert d.rows == ("#1", "#2", "#3", "#4", "#5", "steady-current")
    assert d.columns == ("cc-empc", "cc-empc+pred")
    assert all(r.controller == "cc-empc" and r.predict_disturbance == (r.column == "cc-empc+pred")
               for r in d.runs)
    # the paper's numbers apply without the prediction only, and to paper scenarios only
    assert [r.paper() is not None for r in d.runs] == [True, False] * 5 + [False, False]
    lake = defs.get_study("lake")
    assert [r.controller for r in lake.runs] == list(defs.PAPER_ORDER)
    assert all(r.paper() is None for r in lake.runs)
    tw = defs.get_study("tw-sweep")
    assert [r.task_power_w for r in tw.runs] == list(defs.TW_SWEEP_W)
    assert [r.paper() is not None for r in tw.runs] == [w == 0.49 for w in defs.TW_SWEEP_W]
    assert "tw-sweep" in tw.figures


def test_keys_and_launch_options() -> None:
    r = defs.RunSpec("paper-c3", "eo-empc", "#3", "eo-empc")
    assert r.key == "paper-c3-eo-empc"
    assert r.launch_options() == ["--scenario", "paper-c3", "--controller", "eo-empc"]
    p = defs.RunSpec("paper-c1", "cc-empc", "#1", "x", predict_disturbance=True, task_power_w=0.25)
    assert p.key == "paper-c1-cc-empc-pred-tw0p25"
    assert p.launch_options()[4:] == ["--predict-disturbance", "--task-power-w", "0.25"]


@pytest.mark.parametrize("name", list(defs.STUDIES))
def test_every_runs_options_mean_the_run_to_the_launcher(name: str) -> None:
    for r in defs.get_study(name).runs:
        args = launch_parser().parse_args(["sim-batch", *r.launch_options(), "--run-dir", "/tmp/x"])
        assert args.scenario == r.scenario
        assert args.controller == r.controller
        assert bool(args.predict_disturbance) == r.predict_disturbance
        assert args.task_power_w == r.task_power_w


def test_paper_condition() -> None:
    assert defs.paper_condition("paper-c4") == 4
    assert defs.paper_condition("paper-c4-perturbed") is None
    assert defs.paper_condition("paper-c9") is None
    assert defs.paper_condition("lake") is None


def test_a_study_refuses_two_runs_in_one_cell() -> None:
    a = defs.RunSpec("paper-c1", "nmpc", "#1", "c")
    b = defs.RunSpec("paper-c1", "eo-empc", "#1", "c")
    with pytest.raises(ValueError, match="table cell"):
        defs.Study("x", "x", "row", (a, b))
    with pytest.raises(ValueError, match="share a key"):
        defs.Study("x", "x", "row", (a, defs.RunSpec("paper-c1", "nmpc", "#2", "c")))
    with pytest.raises(ValueError, match="compare"):
        defs.Study("x", "x", "row", (a,), compare=("c", "d"))


def test_only_restricts_rows_and_columns() -> None:
    s = defs.only(defs.get_study("table1"), ["#1", "#4"], ["cc-empc", "eo-empc"])
    assert [r.key for r in s.runs] == ["paper-c1-eo-empc", "paper-c1-cc-empc", "paper-c4-eo-empc",
                                       "paper-c4-cc-empc"]
    assert s.compare == ("eo-empc", "cc-empc")
    assert defs.only(defs.get_study("table1"), None, ["nmpc"]).compare is None
    with pytest.raises(KeyError, match="no row #7"):
        defs.only(defs.get_study("table1"), ["#7"])
    with pytest.raises(KeyError, match="no study"):
        defs.get_study("table2")


def test_with_controllers_adds_a_column_of_ones_own_loaded_by_every_stack() -> None:
    """``seaway study lake --controller-module FILE --with-controller mine``: a column more, every
    row's first run flown by it, every run's stack loading the module; compared with CC-EMPC."""
    lake = defs.get_study("lake")
    s = defs.with_controllers(lake, ["mine"], ("/x/mine.py",))
    assert s.columns == (*lake.columns, "mine") and s.rows == lake.rows
    mine = s.cell("lake", "mine")
    assert mine is not None and (mine.scenario, mine.controller) == ("lake", "mine")
    assert s.compare == ("cc-empc", "mine")
    assert all(r.controller_modules == ("/x/mine.py",) for r in s.runs)
    opts = mine.launch_options()
    assert opts[-2:] == ["--controller-module", "/x/mine.py"]
    args = launch_parser().parse_args(["sim-batch", *opts[:-2]])  # the launcher takes them all
    assert args.controller == "mine"
    assert defs.only(s, None, ["cc-empc", "mine"]).columns == ("cc-empc", "mine")
    with pytest.raises(KeyError, match="has a column nmpc already"):
        defs.with_controllers(lake, ["nmpc"])
