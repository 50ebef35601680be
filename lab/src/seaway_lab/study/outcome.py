"""What a run gave (``RunOutcome``), its verdict (``_concluded``), and the report of its recording:
``seaway_recorder.report.analyse`` called in-process, the same JSON as ``seaway report DIR --mission
DIR/mission.json --json --no-plots`` and from the same decode the series the figures need
(``report_json``)."""

from __future__ import annotations

import socket
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from seaway.contract import keys

from seaway_lab.study.definitions import RunSpec


@dataclass
class RunOutcome:
    """What one run gave: the report's JSON, the series for the figures, and where the time went."""

    spec: RunSpec
    run_dir: str
    episode: int | None = None
    """Which lockstep episode of the run folder's recording is this run's (``seaway report
    --episode``), where one stack flew several runs (``run_shared``); None: its only one."""
    ok: bool = False
    error: str = ""
    host: str = field(default_factory=socket.gethostname)
    port: int | None = None
    command: list[str] = field(default_factory=list)
    returncode: int | None = None
    report: dict[str, Any] | None = None
    """The JSON ``seaway report DIR --json --no-plots`` prints."""
    series: dict[str, Any] | None = None
    """The mission's trajectory and thrusts: t_s, x_m, y_m; thrust_t_s, thrust_port_n, thrust_starboard_n."""
    cpu_s: dict[str, float] = field(default_factory=dict)
    """CPU seconds by process: ``launch``, ``recorder``, ``sim``, ``estimator``, ``controller``,
    ``report`` (the launcher's own)."""
    timing: dict[str, float] = field(default_factory=dict)
    """Wall seconds: ``wall_s`` (all), ``startup_s`` (spawn to every service ready), ``ready_reported_s``
    (the launcher's own figure), ``mission_s`` (ready to complete), ``stop_s``, ``launcher_report_s``
    (the launcher's final report and exit), ``report_s`` (this report), ``sim_per_wall`` (simulated s
    per wall s over the mission phase)."""

    def metric(self, name: str) -> float | None:
        if self.report is None:
            return None
        v = self.report.get("metrics", {}).get(name)
        return None if v is None else float(v)

    def to_json(self, with_series: bool = False) -> dict[str, Any]:
        d: dict[str, Any] = {**self.spec.to_json(), "run_dir": self.run_dir,
                             "episode": self.episode, "ok": self.ok,
                             "error": self.error, "host": self.host, "port": self.port,
                             "command": self.command, "returncode": self.returncode,
                             "timing": self.timing, "cpu_s": self.cpu_s, "report": self.report}
        if with_series:
            d["series"] = self.series
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any], spec: RunSpec | None = None) -> RunOutcome:
        """The outcome ``to_json`` gave (``spec``: the run, else read from ``d``)."""
        return cls(spec or RunSpec.from_json(d), d["run_dir"], episode=d.get("episode"), ok=d["ok"],
                   error=d["error"], host=d["host"], port=d["port"], command=d["command"],
                   returncode=d["returncode"], report=d["report"], series=d.get("series"),
                   timing=d["timing"], cpu_s=d.get("cpu_s", {}))


def _concluded(out: RunOutcome) -> RunOutcome:
    """``out`` with its simulated seconds per wall second and its verdict: ok only when nothing
    failed and the recording shows the mission completed."""
    travel = out.metric("travel_time_s")
    if travel and out.timing.get("mission_s"):
        out.timing["sim_per_wall"] = travel / out.timing["mission_s"]
    completed = bool(out.report and out.report.get("metrics", {}).get("completed"))
    if not out.error and not completed:
        out.error = not_completed_text(out.report or {})
    out.ok = not out.error
    return out


def not_completed_text(report: dict[str, Any]) -> str:
    """Why a run whose launcher saw the mission complete counts as not completed: the recording's
    true track did not complete it, while the controller did on its estimate (``completion``)."""
    met, c = report.get("metrics") or {}, report.get("completion") or {}
    text = "the recording shows the mission not completed"
    legs = (report.get("mission") or {}).get("waypoints_m")
    if met.get("legs_completed") is not None and legs:
        text += f" on the true track ({met['legs_completed']} of {len(legs) - 1} legs)"
    if c.get("controller"):
        err = c.get("estimate_error_m")
        text += ("; the controller completed it on its estimate"
                 + (f", {err:.2f} m from the truth" if err is not None else ""))
    return text


MISSION_FILE = "mission.json"
"""The mission the launcher sent, in the run folder: the launcher's own report takes it from there."""


def report_args(run_dir: str | Path) -> list[str]:
    """The ``seaway report`` arguments of a run folder: the mission sent, when the launcher wrote it.

    Without it the report takes the mission from the recording's scenario attachment, whose T^w is
    the scenario's, not the ``--task-power-w`` the run flew.
    """
    mission = Path(run_dir) / MISSION_FILE
    return [str(run_dir), *(["--mission", str(mission)] if mission.is_file() else [])]


def report_json(run_dir: str | Path, *, episode: int | None = None, read: Any = None,
                scenario: str | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """(what ``seaway report <report_args> --json --no-plots`` prints, the series for the figures).

    ``episode``, ``read`` (``report.read_for_report`` of the folder) and ``scenario``: one of the
    runs a shared stack flew (``run_shared``), from one decode of its recording; its mission is the
    one the controller recorded accepting (the launcher sent none: no ``mission.json``)."""
    from seaway.recording import reader as recording
    from seaway_recorder import report as rep

    mission = Path(run_dir) / MISSION_FILE
    files = recording.open_paths([run_dir]) if read is None else read[0].files
    res = rep.analyse(files, scenario=scenario, episode=episode, read=read,
                      mission_file=str(mission) if mission.is_file() else None)
    doc = rep._clean({k: v for k, v in res.items() if k != "_"})  # exactly what --json prints
    data = res["_"]
    ser = data["series"]
    start, end = data["start_ns"], res["metrics"]["end_ns"]
    thrusts = [c for c in data["thrusts"] if start <= c.stamp_ns <= end]
    series = {"t_s": ser["t_s"], "x_m": ser["x_m"], "y_m": ser["y_m"],
              "thrust_source": keys.SIM_TRUTH.suffix if res["metrics"]["state_source"] ==
              keys.SIM_TRUTH.suffix else keys.THRUST.suffix,
              "thrust_t_s": [(c.stamp_ns - start) / 1e9 for c in thrusts],
              "thrust_port_n": [c.thrust_port_n for c in thrusts],
              "thrust_starboard_n": [c.thrust_starboard_n for c in thrusts],
              "waypoints_m": res["mission"]["waypoints_m"], "coa_radius_m": res["mission"]["coa_radius_m"]}
    return doc, rep._clean(series)
