"""The ``seaway`` console script: the command (``seaway.tools.cli``), and a Ctrl-C that comes before
the command took over its signals ends it quietly.

``seaway.tools.cli`` and a command's module take a few tenths of a second to import (pydantic, Zenoh);
a Ctrl-C then, or in a command that does not handle it, was a KeyboardInterrupt traceback. Nothing
has started by then that needs stopping: the launcher takes SIGINT over before it starts a process.
"""

from __future__ import annotations

import sys

INTERRUPTED = 130
"""The exit code of a command ended by Ctrl-C (128 + SIGINT, as a shell reports it)."""


def main() -> int:
    try:
        from seaway.tools import cli

        return cli.main()
    except KeyboardInterrupt:
        sys.stderr.write("seaway: interrupted\n")
        return INTERRUPTED


if __name__ == "__main__":
    raise SystemExit(main())
