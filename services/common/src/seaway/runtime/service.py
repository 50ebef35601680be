"""What every service's thin loop shares: arguments, logging, signals, the bus and the health token.

A service is a pure core (messages and time in, messages out) plus a loop like::

    with run_service("estimator", args) as ctx:      # bus open, signals installed
        ...declare publishers, subscribers, queryables...
        ctx.ready()                                     # health token: "I can serve now"
        while loop.wait():                              # drift-free, ends on SIGINT/SIGTERM
            ...core.step(ctx.clock.now_ns(), inputs)...

The health token ``seaway/<vessel>/health/<service>`` means *ready to serve*: it is declared by
``ctx.ready()`` once every subscriber and queryable exists, because the launcher starts the next
process, or sends the first request, the moment it sees it.

Every service belongs to a run (``seaway.runtime.run``): ``ctx.run`` is its description, from
``--run FILE`` (the launcher's) or the service's own flags. ``ctx.ready()`` first checks it against
the services already running and refuses to start on a difference (``RunMismatchError``).

SIGINT and SIGTERM set ``ctx.stop``; the ``with`` block then closes the session, so the process exits
promptly instead of hanging in Zenoh's threads.
"""

from __future__ import annotations

import argparse
import faulthandler
import io
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from seaway.contract.config import ConfigError
from seaway.runtime import host, memory, refusals
from seaway.runtime import run as runs
from seaway.runtime.bus import Bus, RuntimeEnvError
from seaway.runtime.clock import Clock, WallClock
from seaway.runtime.credentials import NONE, Credentials, CredentialsError

DEFAULT_VESSEL = "vessel1"
ENV_VESSEL = "SEAWAY_VESSEL"
log = logging.getLogger("seaway.runtime.service")


def configure_logging(name: str, level: str = "INFO") -> None:
    """One line per record, prefixed with the service name (the launcher prefixes again per process).
    Also ``dump_stacks_on_signal``. A node of a composed process (``seaway.runtime.host``) leaves
    logging to the host, which names each line's node."""
    if host.active() is not None:
        return
    logging.basicConfig(
        level=getattr(logging, level.upper(), logging.INFO),
        format=f"%(asctime)s {name} %(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
        force=True,
    )
    dump_stacks_on_signal()


STACKS_SIGNAL = signal.SIGUSR2  # SIGUSR1 re-initialises the estimator


def dump_stacks_on_signal() -> None:
    """``kill -USR2 PID`` prints every thread's Python stack to stderr (the process's log under the
    launcher) and the process goes on: where a process that seems hung is waiting."""
    err = sys.__stderr__  # the file descriptor itself (faulthandler writes from the signal)
    if err is None:
        return
    try:
        faulthandler.register(STACKS_SIGNAL, file=err, all_threads=True)
    except (io.UnsupportedOperation, ValueError):  # no descriptor (an embedding host's stderr)
        log.debug("no stack dumps on %s: stderr has no file descriptor", STACKS_SIGNAL.name)


def add_vessel_option(p: argparse.ArgumentParser, wildcard: bool = False) -> None:
    """``--vessel``: the key namespace seaway/<vessel>/... (``wildcard``: ``*`` for every vessel)."""
    p.add_argument("--vessel", default=os.environ.get(ENV_VESSEL, DEFAULT_VESSEL),
                   help=f"vessel name, the key namespace seaway/<vessel>/... "
                        f"{'(* for every vessel) ' if wildcard else ''}(default ${ENV_VESSEL} or "
                        f"{DEFAULT_VESSEL})")


def add_zenoh_config_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--zenoh-config", default=None, metavar="FILE",
                   help="Zenoh config file (default $SEAWAY_ZENOH_CONFIG, else peers on loopback)")


def add_log_level_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--log-level", default=os.environ.get("SEAWAY_LOG_LEVEL", "INFO"),
                   choices=["DEBUG", "INFO", "WARNING", "ERROR"], type=str.upper,
                   help="what the log shows (default $SEAWAY_LOG_LEVEL or INFO)")


def base_parser(name: str, description: str, prog: str | None = None) -> argparse.ArgumentParser:
    """A service's command line: vessel, bus, credentials, log level and the run's description.
    ``prog``: the name it is called by (default ``seaway-<name>``, the service's own script)."""
    p = argparse.ArgumentParser(prog=prog or f"seaway-{name.replace('_', '-')}",
                                description=description)
    add_vessel_option(p)
    add_zenoh_config_option(p)
    p.add_argument("--credentials", default=None, metavar="DIR",
                   help="the stack's credentials folder (default $SEAWAY_CREDENTIALS, else those of "
                        "the stack on the rendezvous port; 'none' runs without authentication)")
    add_log_level_option(p)
    runs.add_run_arguments(p)
    return p


def credentials_arg(value: str | None) -> Credentials | str | None:
    """``--credentials``: a folder, ``none`` (opt out), or None (the default lookup)."""
    if not value:
        return None
    return NONE if value.strip().lower() == NONE else Credentials(Path(value).expanduser())


def resolve_run(args: argparse.Namespace, name: str, load_scenario: object = None) -> runs.RunDescription:
    """The run of this service (``--run`` or its flags); exits with status 2 and the reason if bad."""
    try:
        return runs.resolve(args, name, load_scenario)
    except ConfigError as err:
        print(f"seaway-{name.replace('_', '-')}: {err}", file=sys.stderr)
        raise SystemExit(2) from None


_SIGNAL_ACTS: dict[int, Callable[[int], None]] = {}
"""What each signal routed by ``on_signals`` calls, on the reader thread."""
_SIGNAL_PIPE: tuple[int, int] | None = None
"""(read end, write end) of the wakeup pipe, once the reader thread runs."""


def _noted(_signum: int, _frame: object) -> None:
    """The Python-level handler of a routed signal: nothing (the wakeup pipe carries it)."""


def on_signals(signums: Sequence[int], act: Callable[[int], None]) -> None:
    """Call ``act(signum)`` for each of ``signums`` received, on a reader thread of its own.

    Call from the main thread (Python's rule for signal handlers). CPython's C-level handler writes
    each caught signal's number to the wakeup pipe (``signal.set_wakeup_fd``) on whatever thread the
    kernel delivered it to, and the reader thread acts on it. Neither a Python handler nor the main
    thread takes part, for two reasons:

    * A Python handler runs only on the main thread, between two bytecodes. A process-directed
      signal may be delivered to another thread (Zenoh's, a writer's); then the main thread learns
      of it only when it next runs bytecode, and one blocked on ``ctx.stop.wait()`` never does:
      the process would go on waiting until a second signal.
    * A handler runs possibly inside an ``Event.set()`` of the main thread, whose lock is not
      reentrant: one that set an event itself could wait on that lock for good (e.g. the
      parent-death SIGTERM followed by a second SIGTERM would leave the process waiting on itself).

    The pipe carries every signal with a Python handler (a library's too, e.g. uvicorn's while it
    serves); the reader acts on those routed here alone.
    """
    global _SIGNAL_PIPE
    if host.active() is not None and threading.current_thread() is not threading.main_thread():
        # A node of a composed process: signals are the process's, which its host handles; the
        # node's stop comes from the supervisor (``host.NodeThread.send_signal``).
        log.debug("signals %s not routed: a node of a composed process", list(signums))
        return
    if _SIGNAL_PIPE is None:
        read_fd, write_fd = os.pipe()
        os.set_blocking(write_fd, False)  # set_wakeup_fd's rule: a full pipe never blocks a handler

        def read() -> None:
            while True:
                for signum in os.read(read_fd, 64):
                    routed = _SIGNAL_ACTS.get(signum)
                    if routed is None:
                        continue
                    try:
                        routed(signum)
                    except Exception:  # the next signal must still be heard
                        log.exception("acting on signal %d failed", signum)

        threading.Thread(target=read, name="stop-signals", daemon=True).start()
        _SIGNAL_PIPE = (read_fd, write_fd)
    signal.set_wakeup_fd(_SIGNAL_PIPE[1], warn_on_full_buffer=False)
    for signum in signums:
        _SIGNAL_ACTS[signum] = act
        signal.signal(signum, _noted)


def on_stop_signals(act: Callable[[int], None]) -> None:
    """Call ``act(signum)`` for each SIGINT and SIGTERM, on a thread of its own (``on_signals``)."""
    on_signals((signal.SIGINT, signal.SIGTERM), act)


def install_stop_signals(stop: threading.Event) -> None:
    """SIGINT and SIGTERM set ``stop``; a second SIGINT exits at once (a stuck process)."""

    def act(signum: int) -> None:
        if stop.is_set():
            if signum == signal.SIGINT:
                os._exit(130)
            return
        log.info("received %s, stopping", signal.Signals(signum).name)
        stop.set()

    on_stop_signals(act)


@dataclass
class ServiceContext:
    name: str
    vessel: str
    bus: Bus
    clock: Clock
    stop: threading.Event
    run: runs.RunDescription
    agree: bool = True
    freeze_when_ready: bool = False
    """The process runs for this service (``run_service``): what its start-up made is frozen once
    it is ready (``memory.freeze_start_up``). Not for a context a test makes in its own process."""
    is_ready: bool = False
    _run_answer: object = None

    def ready(self, joining: Callable[[], None] | None = None) -> None:
        """Check the run against the running services, then ``joining`` (a lockstep member's join),
        then declare the health token.

        Call once every subscriber and queryable is in place. A run-wide difference with a service
        already running raises RunMismatchError (``run_service`` turns it into exit status 2), before
        anything is declared. A lockstep member joins before its health token: whoever waits for the
        services to be ready before starting the clock (the launcher, before the sim or a replay)
        then finds each one a member from the first period.
        """
        if not self.is_ready:
            if self.agree:
                self._run_answer = runs.announce(self.bus, self.run, self.name)
            if joining is not None:
                joining()
            self.bus.declare_alive(self.name)
            self.is_ready = True
            if self.freeze_when_ready:
                memory.freeze_start_up()
            log.info("%s ready on vessel %s (run %s)", self.name, self.vessel, self.run.run_id)


@contextmanager
def run_service(name: str, args: argparse.Namespace, clock: Clock | None = None,
                run: runs.RunDescription | None = None, agree: bool = True,
                identity: str | None = None) -> Iterator[ServiceContext]:
    """Open the bus for ``name`` and install the stop signals; close on exit.

    ``run`` is the service's run description (``resolve_run``), resolved here from ``args`` when not
    given; ``agree=False`` keeps a service that only observes (the recorder) out of the run
    agreement. The service declares its health token with ``ctx.ready()`` when it can serve; a run that
    disagrees with the running services ends the process with status 2 and the reason.
    """
    configure_logging(name, args.log_level)
    run = run or resolve_run(args, name)
    node = host.Host.current()
    stop = node.stop if node is not None else threading.Event()
    if node is None:
        install_stop_signals(stop)
    # A service is its own identity (its certificate's name is the service's), whatever
    # $SEAWAY_IDENTITY says; ``identity`` is for test peers that play another part.
    identity = identity or name
    # Before the session opens: it counts from Zenoh's log. In lockstep only the recorder, which
    # hears every publication, names each refusal (the cost: seaway.runtime.refusals).
    if node is None:
        refusals.watch(identity, full=not run.lockstep or name == "recorder")
    # One Zenoh thread (zenoh_bus.LOCKSTEP_RUNTIME), before the session opens.
    if run.lockstep and node is None:
        from seaway.runtime.zenoh_bus import use_lockstep_runtime  # the loop itself needs no Zenoh

        use_lockstep_runtime()
    try:
        bus = Bus.open(args.vessel, args.zenoh_config, identity=identity,
                       credentials=credentials_arg(getattr(args, "credentials", None)))
    except (CredentialsError, RuntimeEnvError) as err:
        log.error("%s", err)
        raise SystemExit(2) from None
    if node is None:  # a composed node has no network to refuse anyone
        refusals.serve(bus, identity)
    ctx = ServiceContext(name, args.vessel, bus, clock or WallClock(), stop, run, agree,
                         freeze_when_ready=True)
    try:
        log.info("%s starting on vessel %s, run %s", name, args.vessel, run.run_id)
        yield ctx
    except runs.RunMismatchError as err:
        log.error("%s", err)
        raise SystemExit(2) from None
    finally:
        stop.set()
        bus.close()
        log.info("%s stopped (published %d, received %d, malformed %d)", name,
                 bus.stats.published, bus.stats.received, bus.stats.malformed)


def parse(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> argparse.Namespace:
    return parser.parse_args(list(argv) if argv is not None else None)
