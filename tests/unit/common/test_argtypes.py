"""Command-line numbers (``seaway.tools.argtypes``): every bench's and the study's refuse a bad value
at parse time, naming the option and what is allowed, before any work starts."""

from __future__ import annotations

import argparse
import math
from importlib.metadata import entry_points

import pytest
from seaway.tools.argtypes import positive_float, positive_int, whole_number


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


def _commands() -> list[tuple[str, object]]:
    from seaway_lab.study import cli as study

    benches = [(f"bench {ep.name}", ep.load()) for ep in entry_points(group="seaway.benchmarks")]
    assert len(benches) >= 11  # the registry was found
    return [*benches, ("study", lambda argv: study.main(["table1", *argv]))]


def _parser_of(command, monkeypatch: pytest.MonkeyPatch) -> argparse.ArgumentParser:
    def capture(self, args=None, namespace=None):
        raise _ParsedError(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    with pytest.raises(_ParsedError) as got:
        command([])
    monkeypatch.undo()
    return got.value.parser


@pytest.mark.parametrize(("name", "command"), _commands(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_numeric_option_refuses_a_bad_value_by_name(name, command, monkeypatch, capsys) -> None:
    """No bench or study option takes a bare ``int`` or ``float`` (they let 0, nan and inf through:
    a study's ``--timeout-s nan`` waited for ever, ``seaway bench sim --periods 0`` divided by
    zero); each numeric one refuses 0 (or -1 where 0 is allowed), nan and a word, exit 2, naming
    itself and what it allows."""
    parser = _parser_of(command, monkeypatch)
    numeric = [a for a in parser._actions if a.option_strings and a.type is not None
               and a.type not in (str,) and not isinstance(a.type, argparse.FileType)
               and getattr(a.type, "__module__", "") != "pathlib"]
    assert not [a.option_strings for a in numeric if a.type in (int, float)], name
    ours = [a for a in numeric if getattr(a.type, "__module__", "") == "seaway.tools.argtypes"]
    assert ours or name == "bench energy", name  # energy has no number to give
    for action in ours:
        option = action.option_strings[-1]
        zero_allowed = action.type("0") == 0 if _accepts(action.type, "0") else False
        for bad in ("-1" if zero_allowed else "0", "nan", "many"):
            with pytest.raises(SystemExit) as exit_:
                command([option, bad])
            err = capsys.readouterr().err
            assert exit_.value.code == 2, (name, option, bad)
            assert f"argument {option}" in err and repr(bad) in err and (
                "whole number of at least" in err or "finite number above 0" in err), err


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
