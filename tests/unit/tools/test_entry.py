"""The ``seaway`` console script: a Ctrl-C before a command took over its signals (while its modules
import) ends it with 130 and one line, not a KeyboardInterrupt traceback."""

from __future__ import annotations

import sys
import types

from seaway.tools import entry


def test_a_ctrl_c_while_the_command_imports_exits_130_with_one_line(monkeypatch, capsys) -> None:
    def interrupted() -> int:
        raise KeyboardInterrupt

    monkeypatch.setitem(sys.modules, "seaway.tools.cli", types.SimpleNamespace(main=interrupted))
    monkeypatch.delattr("seaway.tools.cli", raising=False)
    assert entry.main() == entry.INTERRUPTED == 130
    assert capsys.readouterr().err == "seaway: interrupted\n"


def test_the_command_s_own_exit_code_passes_through(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "seaway.tools.cli", types.SimpleNamespace(main=lambda: 3))
    monkeypatch.delattr("seaway.tools.cli", raising=False)
    assert entry.main() == 3
