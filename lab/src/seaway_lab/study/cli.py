"""``seaway study NAME``: run a study's runs through the real stack in lockstep, tabulate, draw.

    seaway study table1                      # the paper's Table I: 5 conditions x 3 controllers
    seaway study table1 --rows '#1' --json   # one condition, the result as one JSON object
    seaway study table1 --processes          # the same through the services' own processes
    seaway study tw-sweep --workers 1
    seaway study lake --dask tcp://127.0.0.1:8786
    seaway study lake --controller-module my_controller.py --with-controller mine
    seaway study --list

A run is the mission of scenario S flown by controller C (with its T^w and disturbance prediction)
through the real stack in lockstep (sim, estimator, controller, recorder), then the report of its
recording. By default each stack is composed: its launcher and services are nodes of one process
over the in-memory bus (``seaway launch --composed``: the same service code and recording, no
network); ``--processes`` runs them as processes on Zenoh instead, each stack on a rendezvous port
of its own. The two give the same numbers to the last digit.

``--workers N`` runs N stacks at once on this machine, and each stack flies one run after another:
it starts on its first run's scenario with no mission of its own and stays, and each run is a
scenario load (a new lockstep episode from t = 0; not for the first) and the run's mission, sent as
the operator, so that a stack's start-up is paid once, not per run (``shared.SharedStack``).
Composed, each stack is a study worker process of its own (one interpreter each, so stacks fly in
parallel: ``worker``) that starts ``seaway launch sim-batch --composed --no-mission --stay`` as a
node and makes the requests on its hub (``composed.ComposedStack``); through the processes the
study starts ``seaway launch sim-batch --scenario S --no-mission --stay`` and makes them over Zenoh.
``--fresh-stacks`` starts a stack of its own for every run instead (``seaway launch sim-batch
[--composed] --scenario S --controller C [--predict-disturbance] [--task-power-w W] --run-dir
OUT/runs/KEY``); ``--dask ADDRESS`` submits each run to a Dask scheduler (each worker starts the
stack of the run it takes). Local stacks run on CPUs of their own (``seaway launch --cpus``, or a
study worker's whole process: on 2 CPUs, one each) when 2 or more run at once and there are CPUs
enough (``execute.cpu_groups``; ``--no-pin`` leaves them to the kernel); a shared stack still flying
when the other workers have no run left may use every CPU. Writes into ``--out`` (default
``runs/study-NAME-<time>/``): ``results.md``, ``results.csv``, ``results.json``, ``series.json``
(what the figures are drawn from), ``figures/*.png`` and the stacks' folders: ``runs/stack-N/``
(recording with one episode per run, logs, launch.log, worker.log when composed; ``results.json``
says which run is which episode), or ``runs/<key>/`` with ``--fresh-stacks`` and ``--dask``.
``--redraw OUT`` draws the tables and figures of a finished study again without running anything.

Exit code: 0 when every run completed, 1 otherwise, 2 for bad arguments, 130 when interrupted
(Ctrl-C starts no more runs and stops the running ones).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

from seaway.contract.config import repo_root
from seaway.runtime.argtypes import positive_float, positive_int
from seaway.runtime.cpus import format_cpus

from seaway_lab.study import definitions as defs
from seaway_lab.study import results as res
from seaway_lab.study.execute import (
    DEFAULT_TIMEOUT_S,
    RunOutcome,
    cpu_groups,
    run_dask,
    run_local,
    run_shared,
)

DEFAULT_WORKERS = 2


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway study", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("name", nargs="?", help=f"the study: {', '.join(defs.STUDIES)}")
    ap.add_argument("--list", action="store_true", help="list the studies and their runs")
    ap.add_argument("--workers", type=positive_int, default=DEFAULT_WORKERS,
                    help=f"runs at a time on this machine (default {DEFAULT_WORKERS})")
    ap.add_argument("--dask", metavar="ADDRESS", default=None,
                    help="submit the runs to this Dask scheduler (tcp://host:port) instead")
    ap.add_argument("--processes", action="store_true",
                    help="run each stack's services as processes on Zenoh (seaway launch without "
                         "--composed) instead of composed as nodes of one process")
    ap.add_argument("--fresh-stacks", action="store_true",
                    help="start a stack for every run (default: each of the --workers stacks flies "
                         "one run after another)")
    ap.add_argument("--pin", action=argparse.BooleanOptionalAction, default=None,
                    help="give each local stack CPUs of its own (seaway launch --cpus); default: "
                         "when 2 or more stacks, no more than the CPUs, run at once, or one stack "
                         "on 2 CPUs or more (its sim, estimator and controller on one, the rest on "
                         "the others)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default runs/study-NAME-<time>)")
    ap.add_argument("--rows", nargs="+", default=None, help="only these rows (e.g. '#1' '#4')")
    ap.add_argument("--columns", nargs="+", default=None, help="only these columns (e.g. cc-empc nmpc)")
    ap.add_argument("--with-controller", action="append", default=[], metavar="NAME",
                    help="add a column: every row flown by this controller too (one of your own "
                         "needs --controller-module); repeatable")
    ap.add_argument("--controller-module", action="append", default=[], metavar="FILE|MODULE",
                    help="a controller of one's own that every stack loads (seaway launch "
                         "--controller-module; docs/researcher/new-controller.md); repeatable")
    ap.add_argument("--timeout-s", type=positive_float, default=DEFAULT_TIMEOUT_S,
                    help="wall time limit of one run")
    ap.add_argument("--no-figures", action="store_true",
                    help="tables only: do not draw the figures from the recordings (faster)")
    ap.add_argument("--redraw", type=Path, metavar="OUT", default=None,
                    help="draw the tables and figures of the study in OUT again, without running")
    ap.add_argument("--json", action="store_true", help="print the results as one JSON object")
    return ap


def list_studies() -> str:
    out = []
    for s in defs.STUDIES.values():
        out.append(f"{s.name}: {s.title} ({len(s.runs)} runs)")
        out += [f"  {r.row:>6}  {r.column:14s} seaway launch sim-batch {' '.join(r.launch_options())}"
                for r in s.runs]
    return "\n".join(out)


def default_out(name: str) -> Path:
    return (repo_root() or Path.cwd()) / "runs" / f"study-{name}-{time.strftime('%Y%m%d-%H%M%S')}"


def _progress(total: int, quiet: bool) -> Any:
    from tqdm import tqdm

    # On a terminal only: a pipe or a log gets the table at the end, not a bar's every redraw.
    return tqdm(total=total, unit="run", file=sys.stderr, disable=None if not quiet else True,
                dynamic_ncols=True, bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} runs "
                "[{elapsed}<{remaining}]{postfix}")


def run_study(study: defs.Study, out: Path, *, workers: int, dask: str | None, timeout_s: float,
              progress: bool = True, fresh_stacks: bool = False,
              groups: list[frozenset[int]] | None = None, composed: bool = True,
              ) -> tuple[dict[str, RunOutcome], float, dict[str, Any], str]:
    """Run every run of ``study`` into ``out/runs``; (outcomes by key, wall s, executor, start time).
    ``groups``: the local stacks' CPU sets (``stack_cpus``), None to leave them to the kernel.
    ``composed``: each stack's services as nodes of one process, else as processes."""
    jobs = [(spec, out / "runs" / spec.key) for spec in study.runs]
    outcomes: dict[str, RunOutcome] = {}
    counted: set[str] = set()
    bar = _progress(len(jobs), not progress)

    def count(o: RunOutcome, what: str, seconds: float) -> None:
        """The bar moves once per run: when its mission ended (shared stacks) or it is done."""
        if o.spec.key in counted:
            return
        counted.add(o.spec.key)
        bar.set_postfix_str(f"{o.spec.key} {what} {seconds:.0f} s", refresh=False)
        bar.update(1)
        if bar.disable and progress:  # no bar (not a terminal): one line per run on stderr
            print(f"[{len(counted)}/{len(jobs)}] {o.spec.key} {what} {seconds:.1f} s",
                  file=sys.stderr, flush=True)

    def flown(o: RunOutcome) -> None:
        count(o, "flown" if not o.error else "FAILED", o.timing.get("flight_s", 0.0))

    def done(o: RunOutcome) -> None:
        outcomes[o.spec.key] = o
        if not o.ok and bar.disable and progress and o.spec.key in counted:
            print(f"{o.spec.key} FAILED: {o.error.splitlines()[0] if o.error else ''}",
                  file=sys.stderr, flush=True)
        count(o, "ok" if o.ok else "FAILED", o.timing.get("wall_s", 0.0))

    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    t0 = time.monotonic()
    try:
        services = "composed" if composed else "processes"
        if dask:
            executor: dict[str, Any] = {"kind": "dask", "address": dask, "services": services}
            executor.update(run_dask(dask, jobs, done, timeout_s=timeout_s, composed=composed))
        elif fresh_stacks:
            executor = {"kind": "local", "address": None, "stacks": "one per run",
                        "services": services, "cpus": _cpus_text(groups)}
            run_local(jobs, workers, done, timeout_s=timeout_s, cpus=groups, composed=composed)
        else:
            executor = {"kind": "local", "address": None, "stacks": "shared",
                        "services": services, "cpus": _cpus_text(groups)}
            run_shared(study.runs, out / "runs", workers, done, on_flown=flown, timeout_s=timeout_s,
                       cpus=groups, composed=composed)
    finally:
        bar.close()
    return outcomes, time.monotonic() - t0, executor, started


def stack_cpus(workers: int, runs: int, dask: str | None, pin: bool | None
               ) -> list[frozenset[int]] | None:
    """The CPU set of each local stack (``execute.cpu_groups`` for the stacks that run at once),
    None for the kernel to place them or for a Dask cluster; ValueError for a ``--pin`` that cannot
    be done here, saying why."""
    if dask:
        if pin:
            raise ValueError("--pin: a Dask cluster's workers place their own stacks")
        return None
    return cpu_groups(min(workers, runs), pin)


def _cpus_text(groups: list[frozenset[int]] | None) -> list[str] | None:
    """Each local stack's CPUs in the kernel's list format, or None (not pinned)."""
    return None if groups is None else [format_cpus(g) for g in groups]


def workers_of(executor: dict[str, Any], workers: int, runs: int) -> int:
    """Runs at a time: the local pool's size, or the Dask cluster's worker threads (at most ``runs``)."""
    if executor.get("kind") == "dask":
        workers = sum(int(w.get("nthreads") or 1) for w in executor.get("workers", {}).values()) or 1
    return max(1, min(workers, runs))


def write_outputs(study: defs.Study, out: Path, outcomes: dict[str, RunOutcome], wall_s: float,
                  workers: int, executor: dict[str, Any], started: str, host: dict[str, Any],
                  figures: bool = True) -> tuple[dict[str, Any], list[res.Row]]:
    """The tables (Markdown, CSV, JSON), series.json and the figures; returns the JSON document."""
    timings = {k: {**o.timing, **{f"cpu_{n}_s": v for n, v in o.cpu_s.items()}} for k, o in outcomes.items()}
    rows = res.table_rows(study, {k: res.metrics_of(o.report) for k, o in outcomes.items()}, timings,
                          {k: o.error for k, o in outcomes.items() if o.error})
    runs = [outcomes[s.key].to_json() for s in study.runs if s.key in outcomes]
    doc = res.document(study, rows, wall_s=wall_s, workers=workers, executor=executor, started=started,
                       host=host, runs=runs)
    out.mkdir(parents=True, exist_ok=True)
    ok = {r.key for r in rows if r.ok}
    series = {k: o.series for k, o in outcomes.items() if o.series and k in ok}
    if figures:
        t0 = time.monotonic()
        from seaway_lab.study import figures as fig

        written = fig.draw(study, rows, series, out / "figures")
        doc["figures"] = [str(p.relative_to(out)) for p in written]
        doc["timing"]["figures_s"] = time.monotonic() - t0
    (out / "results.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "results.csv").write_text(res.csv_text(rows))
    md = res.markdown(doc, study, rows)
    if doc.get("figures"):
        md += "\n" + "\n".join(f"![{Path(p).stem}]({p})" for p in doc["figures"]) + "\n"
    (out / "results.md").write_text(md)
    if series:
        (out / "series.json").write_text(json.dumps(series) + "\n")
    return doc, rows


def _redraw(args: argparse.Namespace) -> int:
    out: Path = args.redraw
    try:
        doc = json.loads((out / "results.json").read_text())
        series = json.loads((out / "series.json").read_text()) if (out / "series.json").is_file() else {}
        study = defs.get_study(doc["study"])
        runs = doc.get("runs", [])
        added = list(dict.fromkeys(r["column"] for r in runs if r["column"] not in study.columns))
        modules = next((tuple(r.get("controller_modules", ())) for r in runs), ())
        study = defs.with_controllers(study, added, modules) if added else study
        study = defs.only(study, sorted({r["row"] for r in doc.get("runs", [])}, key=study.rows.index),
                          sorted({r["column"] for r in doc.get("runs", [])}, key=study.columns.index))
    except (OSError, KeyError, ValueError) as err:
        print(f"seaway study: cannot redraw {out}: {err}", file=sys.stderr)
        return 2
    outcomes = {}
    for r in doc.get("runs", []):
        spec = next((s for s in study.runs if s.key == r["key"]), None)
        if spec is None:  # a run the study no longer defines
            continue
        outcomes[spec.key] = RunOutcome.from_json({**r, "series": series.get(spec.key)}, spec)
    new, rows = write_outputs(study, out, outcomes, doc["wall_s"], doc["workers"], doc["executor"],
                              doc["started"], doc["machine"], figures=not args.no_figures)
    print(json.dumps(_printed(new)) if args.json else res.text(new, study, rows), end="" if not args.json
          else "\n")
    return 0


def _printed(doc: dict[str, Any]) -> dict[str, Any]:
    """What ``--json`` prints: the document without the per-run details (they are in results.json)."""
    return {k: v for k, v in doc.items() if k != "runs"}


def _interrupt_on_sigterm() -> None:
    """SIGTERM stops a study as Ctrl-C does: no more runs, every stack stopped (a shared stack's
    launcher runs until it is told to stop: ``--stay``)."""
    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, interrupt)


def earlier_runs(out: Path) -> str:
    """'' if ``out`` holds no run of an earlier study, else what it holds (for the refusal).

    A study's stack folders (``out/runs/*``) keep their recordings, and a stack reads every
    recording of its folder: a second study into the same ``--out`` found the first one's
    missions, with the same ids, beside its own (Table I came out scrambled, a run "failed")."""
    runs = out / "runs"
    if not runs.is_dir():
        return ""
    held = sorted(p.name for p in runs.iterdir())
    return "" if not held else f"{runs}: {', '.join(held[:4])}{', ...' if len(held) > 4 else ''}"


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    if args.list:
        print(list_studies())
        return 0
    if args.redraw is not None:
        return _redraw(args)
    if not args.name:
        parser().print_usage(sys.stderr)
        print(f"seaway study: name a study: {', '.join(defs.STUDIES)}", file=sys.stderr)
        return 2
    try:
        modules = tuple(str(Path(m).resolve()) if m.endswith(".py") or "/" in m else m
                        for m in args.controller_module)
        study = defs.with_controllers(defs.get_study(args.name), args.with_controller, modules)
        study = defs.only(study, args.rows, args.columns)
    except KeyError as err:
        print(f"seaway study: {err.args[0]}", file=sys.stderr)
        return 2
    if not study.runs:
        print(f"seaway study: {args.name} has no run in those rows and columns", file=sys.stderr)
        return 2
    try:  # before any folder is made: what cannot be done here is said first
        groups = stack_cpus(args.workers, len(study.runs), args.dask, args.pin)
    except ValueError as err:
        print(f"seaway study: {err}", file=sys.stderr)
        return 2
    out = args.out or default_out(study.name)
    earlier = earlier_runs(out)
    if earlier:
        print(f"seaway study: {out} already holds the runs of an earlier study ({earlier}); a stack "
              "reads every recording in its folder, so that study's missions would be counted as "
              f"this one's. Give another --out, or remove {out / 'runs'} "
              f"(`seaway study --redraw {out}` draws that study's tables again)", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    _interrupt_on_sigterm()
    try:
        outcomes, wall_s, executor, started = run_study(study, out, workers=args.workers, dask=args.dask,
                                                        timeout_s=args.timeout_s,
                                                        fresh_stacks=args.fresh_stacks, groups=groups,
                                                        composed=not args.processes)
    except KeyboardInterrupt:
        print(f"\nseaway study: interrupted; the runs so far are in {out / 'runs'}", file=sys.stderr)
        return 130
    workers = workers_of(executor, args.workers, len(study.runs))
    doc, rows = write_outputs(study, out, outcomes, wall_s, workers, executor, started, res.machine(),
                              figures=not args.no_figures)
    if args.json:
        print(json.dumps(_printed(doc)))
    else:
        print(res.text(doc, study, rows), end="")
        figs = doc.get("figures", [])
        print(f"wrote {out}/results.md, results.csv, results.json"
              + (f", {len(figs)} figures in {out / 'figures'}" if figs else ""))
    return 0 if all(o.ok for o in outcomes.values()) and len(outcomes) == len(study.runs) else 1


if __name__ == "__main__":
    raise SystemExit(main())
