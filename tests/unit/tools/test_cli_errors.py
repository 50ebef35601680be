"""Errors of a person's making end a command with exit 2 and one line naming what is wrong, not a
traceback: a file that is not UTF-8 (read_document, behind every mission, scenario, vessel and
config file), a vessel name that cannot form a key (``--vessel ../x``)."""

from __future__ import annotations

import pytest
from seaway.contract import keys
from seaway.contract.config import ConfigError, read_document
from seaway.tools import cli


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_file_that_is_not_utf8_is_a_config_error_naming_the_byte(tmp_path, suffix) -> None:
    path = tmp_path / f"latin{suffix}"
    path.write_bytes(b'name = "caf\xe9"\n')
    with pytest.raises(ConfigError, match=rf"{path.name}: not UTF-8 text \(byte 11 is 0xe9\); TOML "
                                          r"and JSON files must be UTF-8"):
        read_document(path)


BIG_NUMBER = "1" + "0" * 5000  # past Python's 4300-digit limit on converting a str to an int
DEEP = 3000  # nesting past the interpreter's recursion limit
TOO_LONG = r"a number too long to read \(Exceeds the limit \(4300 digits\)"


@pytest.mark.parametrize(("name", "text", "named"), [
    ("bigint.toml", f"x = {BIG_NUMBER}\n", TOO_LONG),
    ("bigint.json", f'{{"x": {BIG_NUMBER}}}', TOO_LONG),
    ("deep.toml", "x = " + "[" * DEEP + "]" * DEEP + "\n", "nested too deeply"),
    ("deep.json", '{"x": ' + "[" * DEEP + "]" * DEEP + "}", "nested too deeply"),
])
def test_a_file_the_parser_chokes_on_is_a_config_error_naming_it(tmp_path, name, text, named) -> None:
    """A 5000-digit number (ValueError) or arrays nested 3000 deep (RecursionError) escaped
    read_document as a traceback."""
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"{name}: not a usable document: {named}") as err:
        read_document(path)
    assert "set_int_max_str_digits" not in str(err.value)  # no advice to raise the limit


def test_a_vessel_name_that_cannot_be_a_key_exits_2_with_one_line(monkeypatch, capsys) -> None:
    def command(argv: list[str]) -> int:
        keys.check_vessel(argv[0])  # as every command's bus does with --vessel
        return 0

    monkeypatch.setitem(cli.BUILTIN, "mission", command)
    assert cli.main(["mission", "../x"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("seaway mission: ") and "'../x'" in err and err.count("\n") == 1, err
