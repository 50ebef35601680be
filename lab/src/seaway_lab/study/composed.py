"""A shared stack composed in this process: ``ComposedStack``, the launcher and its services as
nodes of this process's host (``seaway.runtime.host``), the study's requests on the host's hub.

A composed launcher has no network, so the study's requests (a scenario load, a mission per run)
come from inside the composing process: this one, a study worker of its own per stack (``worker``),
since a host is one process with one GIL and stacks that fly side by side need a process each.
"""

from __future__ import annotations

import io
import os
import signal
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from seaway_lab.study.definitions import RunSpec
from seaway_lab.study.launcher import PROFILE, seaway_command
from seaway_lab.study.monitor import ProcessCpu
from seaway_lab.study.shared import SHARED_FLAGS, SharedStack, _RunFailedError

COMPOSED_FLAG = "--composed"
"""The launcher's option that makes its services nodes of its process (``seaway launch``)."""
LAUNCHER_NODE = "launcher"
"""The node the launcher runs as."""
STOP_GRACE_S = 30.0
"""How long the launcher node may take to stop its services (the recorder finishing its file)
before it is left behind; the process ends with it then."""


def vessel() -> str:
    """The vessel a launch runs when none is named (``$SEAWAY_VESSEL``, else the default)."""
    from seaway.runtime.service import DEFAULT_VESSEL, ENV_VESSEL

    return os.environ.get(ENV_VESSEL) or DEFAULT_VESSEL


def launcher_argv(spec: RunSpec, folder: Path) -> list[str]:
    """``seaway`` arguments of a composed shared stack's launcher in ``folder``, on ``spec``'s
    scenario: no mission of its own, no stop at a mission's end, no report of its own (the study
    reads the recording), the vessel the study's requests go to."""
    return ["launch", PROFILE, COMPOSED_FLAG, "--scenario", spec.scenario, *SHARED_FLAGS,
            *spec.module_options(), "--no-report", "--vessel", vessel(), "--run-dir", str(folder)]


class ComposedStack(SharedStack):
    """``seaway launch sim-batch --composed --no-mission --stay`` as a node of this process, which
    must be a host (``host.activate()``): the same runs as ``SharedStack`` (a scenario load and a
    mission each, one episode of the folder's recording per run, reported together), its requests
    made on the host's hub (``Bus.open`` gives a bus there) as the operator's would be. The
    launcher stops when its node's stop is set; this process's CPU is counted as a whole
    (``ProcessCpu``). ``cpus`` is not used: the process running it is placed as a whole."""

    def _launch(self, spec: RunSpec) -> Iterable[str]:
        from seaway.runtime import host
        from seaway.tools import cli

        composing = host.active()
        if composing is None:
            raise _RunFailedError("a composed stack runs in a process that composes "
                                  "(seaway.runtime.host.activate())")
        argv = launcher_argv(spec, self.folder)
        self.command = [*seaway_command(), *argv]
        node = host.NodeThread(composing, LAUNCHER_NODE, cli.main, argv)
        composing.nodes.append(node)
        self.proc = node.start()
        self.cpu = ProcessCpu().__enter__()
        return io.TextIOWrapper(node.stdout, encoding="utf-8", errors="replace")

    def _open_bus(self) -> Any:
        from seaway.runtime.bus import Bus

        return Bus.open(vessel(), identity="operator")

    def _end_launcher(self) -> None:
        """SIGINT's stop, the node's (``NodeThread.send_signal``): the launcher stops its services
        in order, the recorder last; one that outlives ``STOP_GRACE_S`` is left behind."""
        assert self.proc is not None
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(STOP_GRACE_S)
        except Exception:  # subprocess.TimeoutExpired: the node is abandoned with its process
            self.proc.send_signal(signal.SIGKILL)

    def widen(self, cpus: frozenset[int]) -> None:
        """Nothing: the study places the worker process as a whole (``worker.WorkerStack``)."""
