"""The run's report after a launch stops: ``seaway report`` on each vessel's recording, run in a
session of its own and given at most ``REPORT_TIMEOUT_S`` seconds, or the command to make it later.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rich.console import Console

from seaway.tools.launch.supervisor import Supervisor

REPORT_TIMEOUT_S = 120.0  # the final report is skipped (with the command to make it) past this


def _final_report(run_dir: Path, scenario: str, mission_file: Path | None = None,
                  sup: Supervisor | None = None, make: bool = True,
                  idle_vessel: str | None = None) -> None:
    """The run's metrics (from its recording, by ``seaway report``) and where the recording is;
    with ``make`` False (``--no-report``) only where the recording is, and how to make the report.

    The report takes the mission from ``mission_file`` (what the launcher sent, options applied)
    when there is one, else from what the recording holds. An ``idle_vessel`` (one the launcher
    sent no mission and whose controller accepted none either: a fleet's vessel the operator left
    idle) gets no report, and that is said. The report runs in a session of its own, so that a Ctrl-C
    reaches only the launcher, which then stops it and says how to make it later."""
    recordings = sorted(run_dir.glob("*.mcap"))
    if not recordings:
        return
    print(f"recording: {', '.join(str(r) for r in recordings)}", flush=True)
    if idle_vessel is not None and mission_file is None:
        # The report would judge the scenario's path, which the vessel was never sent (a fleet's
        # missions come from the operator).
        print(f"(no report: vessel {idle_vessel} flew no mission in this run)", flush=True)
        return
    seaway = shutil.which("seaway", path=str(Path(sys.executable).parent)) or "seaway"
    cmd = [seaway, "report", str(run_dir), "--out", str(run_dir / "report")]
    if scenario:
        cmd += ["--scenario", scenario]
    if mission_file is not None:
        cmd += ["--mission", str(mission_file)]
    if not make:
        print(f"(report skipped: --no-report; make it with: {' '.join(cmd)})", flush=True)
        return
    hurried = sup.hurried if sup is not None else 0
    console = Console(file=sys.stdout)  # the real stdout: fd 1 is the refusal counter's pipe
    # (seaway.runtime.refusals). The report's output is kept until it is done, then shown whole, so
    # that the progress line and the report's table do not tear each other.
    with tempfile.TemporaryFile("w+") as out:
        try:
            sys.stdout.flush()
            proc = subprocess.Popen(cmd, start_new_session=True, stdout=out, stderr=subprocess.STDOUT)
        except OSError as err:
            print(f"(no report: {err})")
            return
        t0 = time.monotonic()
        if not console.is_terminal:
            print("making the report (metrics, plots) ...", flush=True)
        with console.status("making the report (metrics, plots) ...") as shown:
            while proc.poll() is None:
                skipped = sup is not None and sup.hurried > hurried
                if skipped or time.monotonic() - t0 > REPORT_TIMEOUT_S:
                    proc.kill()
                    proc.wait()
                    shown.stop()
                    why = "Ctrl-C" if skipped else f"it took over {REPORT_TIMEOUT_S:g} s"
                    print(f"(report skipped: {why}; make it with: {' '.join(cmd)})", flush=True)
                    return
                shown.update(f"making the report (metrics, plots): {time.monotonic() - t0:4.0f} s")
                time.sleep(0.05)
        out.seek(0)
        sys.stdout.write(out.read())
        sys.stdout.flush()
