"""Issue 18, item 5: the command line explains itself. Every ``seaway`` command (built in or a
plugin) and every benchmark has a description and a help text for every option, ``seaway --help``
has a line per command, ``--version`` answers, and files its examples name exist.

The parsers are taken as each command builds them (``ArgumentParser.parse_args`` is intercepted on
``--help``), so a new option without help, or a new command without a summary, fails here."""

from __future__ import annotations

import argparse
import contextlib
import io
import re

import pytest
from seaway.tools import cli

from tests.conftest import REPO

COMMANDS = sorted({*cli.BUILTIN, *cli._plugins("seaway.commands")})
BENCHES = sorted(cli._plugins("seaway.benchmarks"))


def parsers_of(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> tuple[list[argparse.ArgumentParser], str]:
    """The parsers a command builds on its way to reading ``argv`` (and what it printed)."""
    seen: list[argparse.ArgumentParser] = []

    def capture(self: argparse.ArgumentParser, *_a, **_k):
        seen.append(self)
        self.print_help()
        raise SystemExit(0)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", capture)
    out = io.StringIO()
    with (contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()),
          contextlib.suppress(SystemExit)):
        cli.main(argv)
    return seen, out.getvalue()


def undocumented(p: argparse.ArgumentParser) -> list[str]:
    bad = []
    for a in p._actions:
        if isinstance(a, argparse._HelpAction):
            continue
        if not (a.help and a.help.strip() and a.help != argparse.SUPPRESS):
            bad.append("/".join(a.option_strings) or a.dest)
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                bad += [f"{name} {x}" for x in undocumented(sub)]
                if not (sub.description or a._choices_actions):
                    bad.append(f"{name}: no description")
    return bad


@pytest.mark.parametrize("argv", [[c, "--help"] for c in COMMANDS if c != "bench"]
                         + [["bench", b, "--help"] for b in BENCHES])
def test_every_command_has_a_description_and_every_option_a_help(
        argv: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    parsers, printed = parsers_of(argv, monkeypatch)
    assert parsers, f"seaway {' '.join(argv)} built no argument parser (printed {printed[:200]!r})"
    for p in parsers:
        assert p.description and p.description.strip(), f"{p.prog}: no description"
        assert undocumented(p) == [], f"{p.prog}: options without help"
        assert p.prog.startswith("seaway "), f"{p.prog}: calls itself by another name"
    for path in re.findall(r"deploy/[\w/.-]+\.(?:toml|json5|json)\b", printed):
        assert (REPO / path).is_file(), f"seaway {' '.join(argv)}: its example {path} does not exist"


def test_seaway_help_has_a_line_per_command_and_bench_help_a_line_per_benchmark(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for c in COMMANDS:
        line = next((x for x in out.splitlines() if x.split()[:1] == [c]), None)
        assert line is not None and len(line.split()) >= 4, f"{c}: no summary line in {out}"
    assert cli.main(["bench", "--help"]) == 0
    out = capsys.readouterr().out
    for b in BENCHES:
        line = next((x for x in out.splitlines() if x.split()[:1] == [b]), None)
        assert line is not None and len(line.split()) >= 4 and "cannot load" not in line, out


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["--version"]) == 0
    out = capsys.readouterr().out
    assert re.match(r"seaway \d+\.\d+\.\d+ \(Python 3\.\d+", out) and "eclipse-zenoh 1." in out


def test_summary_takes_the_first_sentence_without_the_heading() -> None:
    assert cli.summary("``seaway report FILE``: the metrics of a run. More.") == "the metrics of a run"
    assert cli.summary("Plain text, two lines\n of it.\n\nParagraph two.") == "Plain text, two lines of it"
    assert cli.summary(None) == ""
