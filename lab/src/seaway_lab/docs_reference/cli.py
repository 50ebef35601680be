"""``seaway docs reference``: write the documentation site's generated reference pages.

    seaway docs reference            # write docs/reference/*.md
    seaway docs reference --check    # say which pages differ from a fresh generation (exit 1)

The pages (``docs/reference/``): every command's ``--help``, every key with its message type,
producer and who may use it, every message's fields and JSON Schema, every file's fields with their
bounds, every status value and reason. They are committed; a contract test regenerates them and
fails when the committed ones are out of date.
"""

from __future__ import annotations

import argparse
import difflib
import sys
from collections.abc import Callable
from pathlib import Path

from seaway.contract.config import repo_root

REGENERATE = "seaway docs reference"
"""The command that regenerates the pages (``.venv/bin/seaway docs reference``)."""


def _index() -> str:
    from seaway_lab.docs_reference.markdown import GENERATED_NOTE

    return (GENERATED_NOTE + "# Reference\n\n"
            "Generated from the code by `seaway docs reference`, so it cannot go stale: a test "
            "fails when a page differs from what the code gives.\n\n"
            "- [Commands](commands.md): every `seaway` command's and subcommand's `--help`, and "
            "each service's.\n"
            "- [Keys](keys.md): every key on the bus, its message type, its producer and who may "
            "use it.\n"
            "- [Messages](messages.md): every message's fields and JSON Schema.\n"
            "- [Files](files.md): the fields of vessel, scenario, mission, area, profile and "
            "service config files, with their bounds.\n"
            "- [Status values](status-values.md): every status value and reason a message "
            "carries.\n")


def builders() -> dict[str, Callable[[], str]]:
    """Each page's file name and the function that writes it."""
    from seaway_lab.docs_reference import commands, files_page, keys_page, schemas_page, status_page

    return {"index.md": _index, "commands.md": commands.page, "keys.md": keys_page.page,
            "messages.md": schemas_page.page, "files.md": files_page.page,
            "status-values.md": status_page.page}


def generate() -> dict[str, str]:
    """Every page's text, by file name."""
    return {name: build() for name, build in builders().items()}


def default_dir() -> Path | None:
    """``docs/reference`` of the checkout Seaway runs from; None when installed from a wheel."""
    root = repo_root()
    return None if root is None else root / "docs" / "reference"


def stale(out: Path, pages: dict[str, str]) -> list[str]:
    """The pages in ``out`` that differ from ``pages`` (or are missing), and files there that no
    page writes, each with a short diff."""
    problems = []
    for name, text in sorted(pages.items()):
        path = out / name
        old = path.read_text(encoding="utf-8") if path.is_file() else None
        if old is None:
            problems.append(f"{path}: missing")
        elif old != text:
            diff = list(difflib.unified_diff(old.splitlines(), text.splitlines(), f"{path} (committed)",
                                             f"{path} (from the code)", n=1, lineterm=""))
            shown = "\n".join(diff[:40]) + ("\n..." if len(diff) > 40 else "")
            problems.append(f"{path}: out of date\n{shown}")
    if out.is_dir():
        problems += [f"{p}: no page writes it (remove it)" for p in sorted(out.glob("*.md"))
                     if p.name not in pages]
    return problems


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="seaway docs", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="action", required=True, metavar="ACTION",
                            help="reference: the generated reference pages")
    ref = sub.add_parser("reference", help="write (or --check) the generated reference pages",
                         description="write the reference pages generated from the code")
    ref.add_argument("--out", type=Path, default=None,
                     help="folder to write the pages into (default: docs/reference of this checkout)")
    ref.add_argument("--check", action="store_true",
                     help="write nothing; list the pages that differ from the code, exit 1 if any")
    args = ap.parse_args(list(sys.argv[1:] if argv is None else argv))
    out = args.out or default_dir()
    if out is None:
        print("seaway docs reference: not run from a checkout; say where with --out DIR", file=sys.stderr)
        return 2
    pages = generate()
    if args.check:
        problems = stale(out, pages)
        for p in problems:
            print(p, file=sys.stderr)
        if problems:
            print(f"seaway docs reference --check: {len(problems)} page(s) out of date; regenerate "
                  f"with `.venv/bin/{REGENERATE}` and commit docs/reference/", file=sys.stderr)
            return 1
        print(f"{len(pages)} reference pages up to date in {out}")
        return 0
    out.mkdir(parents=True, exist_ok=True)
    for name, text in pages.items():
        (out / name).write_text(text, encoding="utf-8")
    for p in out.glob("*.md"):
        if p.name not in pages:
            p.unlink()
    print(f"wrote {len(pages)} reference pages to {out}")
    return 0
