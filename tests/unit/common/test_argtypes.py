"""Command-line numbers (``seaway.runtime.argtypes``): every bench's and the study's refuse a bad value
at parse time, naming the option and what is allowed, before any work starts."""

from __future__ import annotations

import argparse
import math
from importlib.metadata import entry_points

import pytest
from seaway.runtime.argtypes import positive_float, positive_int, whole_number


def test_whole_numbers_and_positive_floats() -> None:
    assert positive_int("3") == 3 and whole_number(0)("0") == 0
    assert positive_float("0.25") == 0.25 and positive_float("1e3") == 1000.0
    for bad in ("0", "-2", "2.5", "abc", ""):
        with pytest.raises(argparse.ArgumentTypeError, match="not a whole number of at least 1"):
            positive_int(bad)
    with pytest.raises(argparse.ArgumentTypeError, match="'-1' is not a whole number of at least 0"):
        whole_number(0)("-1")
    for bad in ("0", "-0.5", "nan", "inf", "-inf", "abc"):
        with pytest.raises(argparse.ArgumentTypeError, match="not a finite number above 0"):
            positive_float(bad)


class _ParsedError(Exception):
    """Raised instead of parsing, carrying the parser a command built."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self.parser = parser


BARE_ALLOWED = {("report", "--episode")}
"""Options whose numbers are meant to run both ways: an episode counts from the end when negative."""


def _commands() -> list[tuple[str, object]]:
    """Every command line of the project: each bench, each plugin command (``seaway study``, ``seaway
    report``, ...), each ``seaway`` built-in but ``bench``, and each service's executable."""
    from seaway.tools import cli

    benches = [(f"bench {ep.name}", ep.load()) for ep in entry_points(group="seaway.benchmarks")]
    plugins = [(ep.name, ep.load()) for ep in entry_points(group="seaway.commands")]
    services = [(ep.name, ep.load()) for ep in entry_points(group="console_scripts")
                if ep.value.startswith("seaway_")]
    builtins = [(name, fn) for name, fn in cli.BUILTIN.items() if name != "bench"]
    assert len(benches) >= 11 and len(plugins) >= 7 and len(services) >= 6  # the registries were found
    return [*benches, *plugins, *services, *builtins]


def _parser_of(command, monkeypatch: pytest.MonkeyPatch) -> argparse.ArgumentParser:
    def capture(self, args=None, namespace=None):
        raise _ParsedError(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", capture)
    with pytest.raises(_ParsedError) as got:
        command([])
    monkeypatch.undo()
    return got.value.parser


def _options(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    """(subcommand words, action) of every option, into subcommands."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for word, sub in action.choices.items():
                yield from _options(sub, (*prefix, word))
        elif action.option_strings:
            yield prefix, action


@pytest.mark.parametrize(("name", "command"), _commands(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_numeric_option_refuses_a_bad_value_by_name(name, command, monkeypatch, capsys) -> None:
    """No option of any command line takes a bare ``int`` or ``float`` (they let 0, nan and inf
    through: a study's ``--timeout-s nan`` waited for ever, ``seaway report --sample-period -1``
    never ended, ``seaway bench sim --periods 0`` divided by zero); each numeric one refuses 0 (or
    -1 where 0 is allowed), nan and a word, exit 2, naming itself and what it allows."""
    parser = _parser_of(command, monkeypatch)
    options = list(_options(parser))
    bare = [a.option_strings[-1] for _, a in options if a.type in (int, float)
            and (name, a.option_strings[-1]) not in BARE_ALLOWED]
    assert not bare, (name, bare)
    ours = [(words, a) for words, a in options
            if getattr(a.type, "__module__", "") == "seaway.runtime.argtypes"]
    for words, action in ours:
        option = action.option_strings[-1]
        zero_allowed = _accepts(action.type, "0")
        for bad in ("-1" if zero_allowed else "0", "nan", "many"):
            with pytest.raises(SystemExit) as exit_:
                command([*words, option, bad])
            err = capsys.readouterr().err
            assert exit_.value.code == 2, (name, option, bad)
            assert f"argument {option}" in err and repr(bad) in err and (
                "whole number" in err or "finite number" in err), err


def test_the_commands_take_their_numbers_through_argtypes(monkeypatch) -> None:
    """The sweep above reaches the options that matter (so it cannot pass by finding none)."""
    found = {(name, a.option_strings[-1]) for name, command in _commands()
             for _, a in _options(_parser_of(command, monkeypatch))
             if getattr(a.type, "__module__", "") == "seaway.runtime.argtypes"}
    assert {("study", "--timeout-s"), ("report", "--sample-period"), ("bench lockstep", "--repeat"),
            ("seaway-sim", "--sysid"), ("seaway-recorder", "--flush-interval"), ("credentials", "--days"),
            ("seaway-groundstation", "--port"), ("identify", "--arm-m")} <= found, found


def _accepts(parse, text: str) -> bool:
    try:
        value = parse(text)
    except argparse.ArgumentTypeError:
        return False
    return not (isinstance(value, float) and math.isnan(value))


@pytest.mark.parametrize("argv", [
    ["run", "--level-n", "0"], ["fly", "--level-n", "nan"], ["fly", "--wait", "-3"],
    ["fit", "x.mcap", "--arm-m", "inf"], ["fit", "x.mcap", "--dead-zone-n", "-1"],
    ["fit", "x.mcap", "--dead-zone-n", "nan"]])
def test_identify_refuses_a_bad_number_by_name(argv, capsys) -> None:
    from seaway_lab.identify import cli as identify

    with pytest.raises(SystemExit) as exit_:
        identify.main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and f"argument {argv[-2]}: {argv[-1]!r} is not a finite number" in err, err
