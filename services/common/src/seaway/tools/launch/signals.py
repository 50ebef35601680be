"""How the launcher signals its processes: each runs in a session of its own, gets SIGTERM when the
launcher dies (``with_parent_death_signal``), and is stopped through its process group
(``signal_group``) with the signal its state calls for (``stop_signal``)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess

from seaway.runtime import host

SETPRIV = shutil.which("setpriv")
"""util-linux's setpriv (every Debian and Ubuntu has it): sets the child's parent-death signal."""


def with_parent_death_signal(argv: list[str]) -> list[str]:
    """``argv`` run so that it gets SIGTERM when the launcher dies (as is, without setpriv)."""
    return [SETPRIV, "--pdeathsig", "TERM", "--", *argv] if SETPRIV else argv


def stop_signal(state: str) -> signal.Signals:
    """The signal that stops a process in ``state``: SIGINT, as a Ctrl-C would; SIGTERM to a service
    still starting. That one may still be importing, before its stop handler is in place
    (``seaway.runtime.service.install_stop_signals``), where Python turns a SIGINT into a
    KeyboardInterrupt traceback in its log and on the terminal; SIGTERM ends it quietly there, and
    once the handler is in place it stops on either the same way."""
    return signal.SIGTERM if state == "starting" else signal.SIGINT


def signal_group(p: subprocess.Popen, sig: int) -> None:
    if isinstance(p, host.NodeThread):  # a node of this process: its own stop, not the group's
        p.send_signal(sig)
        return
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(p.pid, sig)
