"""The command reference: every ``seaway`` command's and subcommand's ``--help``, and each service's.

The ``seaway`` dispatcher (``seaway.tools.cli``) is walked in process: each command is called with
``--help`` while ``argparse.ArgumentParser.print_help`` is replaced by a catch of the parser that
was about to print, so nothing runs past parsing and the parser's subcommands (``add_subparsers``)
can be walked in turn. A command that prints its help itself (``seaway``, ``seaway bench``) is read
from its output. Help is formatted for a fixed terminal width (``HELP_COLUMNS``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
from collections.abc import Callable, Iterator
from importlib.metadata import entry_points

from seaway_lab.docs_reference.markdown import GENERATED_NOTE

HELP_COLUMNS = 100
"""The terminal width argparse formats the help for (``COLUMNS``): the page does not depend on the
terminal it was made in."""

HAND_DISPATCHED: dict[str, tuple[str, ...]] = {
    "mission": ("check", "home"),
    "record": ("run", "recover"),
}
"""Subcommands a command picks by its first word before its parser runs (so no ``add_subparsers``
shows them): each has a parser and a ``--help`` of its own."""

SERVICE_PREFIX = "seaway-"
"""Each service's own command (a console script): ``seaway-sim``, ``seaway-controller``, ..."""


class _Printed(Exception):  # noqa: N818 -- a catch, not an error
    def __init__(self, parser: argparse.ArgumentParser) -> None:
        super().__init__(parser.prog)
        self.parser = parser


@contextlib.contextmanager
def _fixed_terminal(prog: str) -> Iterator[None]:
    """``COLUMNS`` and ``sys.argv[0]`` as a reader's terminal would not have them: fixed."""
    saved_env = {k: os.environ.get(k) for k in ("COLUMNS", "LINES")}
    saved_argv = sys.argv
    os.environ["COLUMNS"], os.environ["LINES"] = str(HELP_COLUMNS), "50"
    sys.argv = [prog]
    try:
        yield
    finally:
        sys.argv = saved_argv
        for k, v in saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def capture_help(prog: str, call: Callable[[], object]) -> tuple[str, argparse.ArgumentParser | None]:
    """The help ``call`` prints (it was given ``--help``), and the parser that printed it, if any."""
    out, err = io.StringIO(), io.StringIO()
    original = argparse.ArgumentParser.print_help

    def print_help(self: argparse.ArgumentParser, file: object = None) -> None:
        raise _Printed(self)

    argparse.ArgumentParser.print_help = print_help  # type: ignore[method-assign]
    try:
        with _fixed_terminal(prog), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                call()
            except _Printed as printed:
                return printed.parser.format_help(), printed.parser
            except SystemExit:
                pass
    finally:
        argparse.ArgumentParser.print_help = original  # type: ignore[method-assign]
    text = out.getvalue() or err.getvalue()
    if not text.strip():
        raise RuntimeError(f"{prog} --help printed nothing")
    return text, None


def subcommands(parser: argparse.ArgumentParser | None) -> list[str]:
    """The subcommands a parser declares (``add_subparsers``), in their order, without aliases."""
    if parser is None:
        return []
    names: list[str] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            names += [a.dest for a in action._choices_actions]
    return names


def _seaway(argv: list[str]) -> Callable[[], object]:
    from seaway.tools import cli

    return lambda: cli.main([*argv, "--help"])


def seaway_helps() -> list[tuple[list[str], str]]:
    """``(words, help)`` of ``seaway`` and of every command and subcommand under it, in order."""
    from seaway.tools import cli

    commands = sorted({*cli.BUILTIN, *(ep.name for ep in entry_points(group="seaway.commands"))})
    benches = sorted(ep.name for ep in entry_points(group="seaway.benchmarks"))
    out = [([], capture_help("seaway", lambda: cli.main(["--help"]))[0])]

    def walk(words: list[str]) -> None:
        text, parser = capture_help(" ".join(["seaway", *words]), _seaway(words))
        out.append((words, text))
        subs = subcommands(parser) or list(HAND_DISPATCHED.get(" ".join(words), ()))
        if words == ["bench"]:
            subs = benches
        for sub in subs:
            walk([*words, sub])

    for name in commands:
        walk([name])
    return out


def service_helps() -> list[tuple[str, str]]:
    """``(command, help)`` of each service's own command, sorted by name."""
    out = []
    eps = {ep.name: ep for ep in entry_points(group="console_scripts") if ep.name.startswith(SERVICE_PREFIX)}
    for name in sorted(eps):
        main = eps[name].load()
        out.append((name, capture_help(name, lambda main=main, name=name: _call_service(main, name))[0]))
    return out


def _call_service(main: Callable[..., object], name: str) -> object:
    sys.argv = [name, "--help"]
    return main()


def _fence(text: str) -> str:
    return "```text\n" + text.rstrip() + "\n```\n\n"


def page() -> str:
    """``docs/reference/commands.md``."""
    parts = [GENERATED_NOTE, "# Commands\n\n",
             "Every `seaway` command and subcommand, and each service's own command, as its "
             "`--help` prints it. The `seaway` command is in `.venv/bin/` after `./test` or `./run` "
             "(or on the PATH of an installed boat).\n\n"]
    for words, text in seaway_helps():
        level = "#" * min(2 + max(len(words) - 1, 0), 4)
        parts.append(f"{level} `{' '.join(['seaway', *words])}`\n\n" + _fence(text))
    parts.append("## Service commands\n\n"
                 "The launcher starts each service with its command; by hand, each takes the same "
                 "run flags (`--run`, or `--scenario`, `--vessel-file`, ...).\n\n")
    for name, text in service_helps():
        parts.append(f"### `{name}`\n\n" + _fence(text))
    return "".join(parts)
