"""Composition: a stack's services as nodes of ONE process, over the in-memory bus.

``seaway launch sim-batch --composed`` runs the same service code as the processes do (each
service's ``main``, its loop, its lockstep member) but as threads of the launcher's process, on
one ``MemoryHub`` instead of Zenoh sessions. Nothing in a service knows: the seams are

* ``Bus.open`` gives a bus on the host's hub (``active``), not a Zenoh session;
* ``run_service`` takes the node's own stop event instead of installing signal handlers (one
  process has one set, the launcher's), and leaves logging to the host;
* the supervisor starts a ``NodeThread`` where it would start a process: the same
  ``poll``/``wait``/``send_signal``/``stdout`` it uses on a ``subprocess.Popen``, so starting,
  readiness, liveness, restarts, the stop in order and the logs per service are its own code.

What a process gives and a thread cannot: isolation (a service that corrupts memory or hangs the
GIL takes the others with it; a SIGKILL of one is a stop request, and one that ignores it is left
behind as a daemon thread). So composition is for batch runs and studies, where speed matters and
the processes' fault tests have already held; a boat runs processes.

Output: a node's ``print`` and log lines, and those of threads it starts, go to its own pipe (the
supervisor writes it to ``logs/<node>.log``, as a process's stdout); everything else goes where it
went before the host was made.
"""

from __future__ import annotations

import io
import logging
import os
import signal
import subprocess
import sys
import threading
import traceback
from collections.abc import Callable, Sequence
from importlib import metadata
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from seaway.runtime.memory_bus import MemoryBus

log = logging.getLogger("seaway.runtime.host")

Entry = Callable[[Sequence[str]], int | None]
"""A service's ``main(argv)``: its exit status (None: 0), or it raises ``SystemExit``."""

KILLED = -signal.SIGKILL
"""A node's exit status after a SIGKILL it outlived (a thread cannot be killed: it is abandoned)."""

_NODE_ATTR = "_seaway_node"
"""The attribute a thread carries naming the node it works for (``current``)."""


class HostError(FileNotFoundError):
    """A node that cannot be started in this process (no such command): the supervisor says so as
    of a process whose command is not found."""


def entry_point(command: str) -> Entry:
    """The function behind a console script (``seaway-sim`` -> ``seaway_sim.main:main``)."""
    found = metadata.entry_points(group="console_scripts", name=command)
    if not found:
        raise HostError(f"command {command!r} is not a console script of an installed package: "
                        "it cannot run as a node of this process")
    return next(iter(found)).load()


class NodeThread:
    """One service running as a thread of this process, with the face of a ``subprocess.Popen``."""

    def __init__(self, host: Host, name: str, entry: Entry, argv: Sequence[str]) -> None:
        self.host, self.name, self.argv = host, name, list(argv)
        self.stop = threading.Event()
        """Set by SIGINT, SIGTERM or SIGKILL: the service's ``ctx.stop``."""
        self.pid = os.getpid()
        self.returncode: int | None = None
        self._killed = False
        read_fd, write_fd = os.pipe()
        self.stdout = os.fdopen(read_fd, "rb")
        self.out: TextIO = os.fdopen(write_fd, "w", buffering=1, encoding="utf-8", errors="replace")
        self._thread = threading.Thread(target=self._run, args=(entry,), name=f"node-{name}",
                                        daemon=True)
        setattr(self._thread, _NODE_ATTR, self)

    def start(self) -> NodeThread:
        self._thread.start()
        return self

    def _run(self, entry: Entry) -> None:
        code: int = 1
        try:
            result = entry(self.argv)
            code = 0 if result is None else int(result)
        except SystemExit as ex:
            if isinstance(ex.code, str):
                self.out.write(ex.code + "\n")
                code = 1
            else:
                code = 0 if ex.code is None else int(ex.code)
        except BaseException:  # a bug ends the node, as a traceback ends a process
            self.out.write(traceback.format_exc())
            code = 1
        finally:
            self.returncode = code
            self.out.close()  # the supervisor's reader sees the end of the output

    # -- what the supervisor uses of a Popen -----------------------------------------------------

    def poll(self) -> int | None:
        if self._killed:
            return KILLED if self._thread.is_alive() else self.returncode
        return None if self._thread.is_alive() else self.returncode

    def wait(self, timeout: float | None = None) -> int:
        self._thread.join(timeout)
        if self._thread.is_alive():
            if self._killed:
                return KILLED
            raise subprocess.TimeoutExpired(self.argv, timeout or 0.0)
        return self.returncode if self.returncode is not None else 1

    def send_signal(self, sig: int) -> None:
        """SIGINT and SIGTERM stop the node as they stop a service; SIGKILL too, and a node that
        does not end is then left running on its own (``poll`` says it was killed)."""
        if sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            self.stop.set()
        if sig == signal.SIGKILL and self._thread.is_alive():
            self._killed = True
            log.warning("node %s did not stop; left behind (a thread cannot be killed)", self.name)


class _Routed(io.TextIOBase):
    """``sys.stdout``/``sys.stderr`` while a host is active: each node's output to its own pipe."""

    def __init__(self, host: Host, fallback: TextIO) -> None:
        self.host, self.fallback = host, fallback

    def _target(self) -> TextIO:
        node = self.host.current()
        return node.out if node is not None and not node.out.closed else self.fallback

    def write(self, s: str) -> int:
        try:
            return self._target().write(s)
        except ValueError:  # the node's pipe closed between the look and the write
            return self.fallback.write(s)

    def flush(self) -> None:
        target = self._target()
        if not target.closed:
            target.flush()

    def isatty(self) -> bool:
        return False

    def writable(self) -> bool:
        return True


class _NodeName(logging.Filter):
    def __init__(self, host: Host) -> None:
        super().__init__()
        self.host = host

    def filter(self, record: logging.LogRecord) -> bool:
        node = self.host.current()
        record.node = node.name if node is not None else "launcher"
        return True


class Host:
    """The hub every node's bus is on, and the nodes started on it."""

    def __init__(self) -> None:
        from seaway.runtime.memory_bus import MemoryHub  # it needs the service module, which needs this

        self.hub = MemoryHub()
        self.nodes: list[NodeThread] = []

    def bus(self, vessel: str) -> MemoryBus:
        return self.hub.bus(vessel)

    def start(self, name: str, argv: Sequence[str], entry: Entry | None = None) -> NodeThread:
        """Start the service ``argv[0]`` (a console script, unless ``entry`` is its function) with
        ``argv[1:]`` as node ``name``."""
        node = NodeThread(self, name, entry or entry_point(argv[0]), argv[1:]).start()
        self.nodes.append(node)
        return node

    @staticmethod
    def current() -> NodeThread | None:
        """The node the calling thread works for (its own thread, or one it started), else None."""
        return getattr(threading.current_thread(), _NODE_ATTR, None)


def adopt(thread: threading.Thread, node: NodeThread | None) -> None:
    """Make ``thread`` work for ``node`` (a thread started on its behalf by another's)."""
    if node is not None:
        setattr(thread, _NODE_ATTR, node)


_HOST: Host | None = None
_thread_init = threading.Thread.__init__


def _init_naming_node(self: threading.Thread, *args: object, **kwargs: object) -> None:
    """``Thread.__init__`` while a host is active: a thread started by a node works for it."""
    _thread_init(self, *args, **kwargs)  # type: ignore[arg-type]
    node = Host.current()
    if node is not None:
        setattr(self, _NODE_ATTR, node)


def active() -> Host | None:
    """The host of this process, if it composes its services."""
    return _HOST


def activate(level: int = logging.INFO) -> Host:
    """Make this process a host (once; from the main thread, before any node starts): buses from
    ``Bus.open`` are on its hub, output and log lines are routed per node."""
    global _HOST
    if _HOST is not None:
        return _HOST
    host = Host()
    sys.stdout = _Routed(host, sys.stdout)  # type: ignore[assignment]
    sys.stderr = _Routed(host, sys.stderr)  # type: ignore[assignment]
    threading.Thread.__init__ = _init_naming_node  # type: ignore[method-assign]
    handler = logging.StreamHandler(sys.stderr)
    handler.addFilter(_NodeName(host))
    handler.setFormatter(logging.Formatter("%(asctime)s %(node)s %(levelname)s %(name)s: %(message)s"))
    logging.basicConfig(level=level, handlers=[handler], force=True)
    _HOST = host
    return host
