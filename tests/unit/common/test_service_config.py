"""A service's configuration (``seaway.runtime.config``): the model's defaults, then ``--config
FILE``, then the flags made from its fields; every bad value stops the process with one line naming
the flag (or the file and field) and what is allowed, exit status 2."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Literal

import pytest
from pydantic import Field, field_validator, model_validator
from seaway.contract.config import ConfigError, ConfigModel
from seaway.runtime.config import Flag, config_of, flags_of, parse_service_args, service_parser


class DemoConfig(ConfigModel):
    """A service's settings, one of each kind of flag."""

    rate_hz: Annotated[float, Flag()] = Field(default=10.0, gt=0, le=100, description="a rate [Hz]")
    retries: Annotated[int, Flag()] = Field(default=3, ge=0, le=9, description="tries after the first")
    timeout_s: Annotated[float, Flag("--timeout", metavar="S")] = Field(
        default=1.0, gt=0, description="an older, shorter flag name [s]")
    state_file: Annotated[Path | None, Flag()] = Field(default=None, description="a file")
    mode: Annotated[Literal["fast", "slow"], Flag()] = Field(default="fast", description="how")
    verbose: Annotated[bool, Flag()] = Field(default=False, description="say more")
    check: Annotated[bool, Flag()] = Field(default=True, description="check what comes in")
    module: Annotated[list[str], Flag()] = Field(default_factory=list, description="a module")
    gain: float = Field(default=2.0, gt=0, description="set in the file only")

    @field_validator("module")
    @classmethod
    def _named(cls, names: list[str]) -> list[str]:
        if not all(n.strip() for n in names):
            raise ValueError("a module needs a name")
        return names

    @model_validator(mode="after")
    def _timeout_covers_a_period(self) -> DemoConfig:
        if self.timeout_s < 1.0 / self.rate_hz:
            raise ValueError(f"timeout_s ({self.timeout_s}) is shorter than one period")
        return self


def _parse(argv: list[str]) -> tuple[object, DemoConfig]:
    return parse_service_args(service_parser("demo", "a demo service", DemoConfig), argv, DemoConfig)


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        _parse(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("seaway-demo: error: "), err
    return err


def test_flags_are_made_from_the_fields() -> None:
    options = {s.field: s.option for s in flags_of(DemoConfig)}
    assert options == {"rate_hz": "--rate-hz", "retries": "--retries", "timeout_s": "--timeout",
                       "state_file": "--state-file", "mode": "--mode", "verbose": "--verbose",
                       "check": "--no-check", "module": "--module"}  # gain: the file's alone
    help_text = service_parser("demo", "a demo service", DemoConfig).format_help()
    assert "--timeout S" in help_text and "a rate [Hz] (default 10)" in help_text
    assert "--gain" not in help_text and "--config FILE" in help_text


def test_defaults_then_file_then_flags(tmp_path: Path) -> None:
    _args, cfg = _parse([])
    assert cfg == DemoConfig()
    path = tmp_path / "demo.toml"
    path.write_text('rate_hz = 20.0\nretries = 5\ngain = 4.0\nmodule = ["a", "b"]\n')
    _args, cfg = _parse(["--config", str(path)])
    assert (cfg.rate_hz, cfg.retries, cfg.gain, cfg.module) == (20.0, 5, 4.0, ["a", "b"])
    _args, cfg = _parse(["--config", str(path), "--retries", "0", "--module", "c"])
    assert (cfg.rate_hz, cfg.retries, cfg.gain, cfg.module) == (20.0, 0, 4.0, ["c"])  # one field
    assert cfg.model_fields_set == {"rate_hz", "retries", "gain", "module"}
    json_path = tmp_path / "demo.json"
    json_path.write_text(json.dumps({"mode": "slow"}))
    _args, cfg = _parse(["--config", str(json_path), "--rate-hz", "50"])
    assert (cfg.mode, cfg.rate_hz) == ("slow", 50.0)


def test_bool_and_list_flags() -> None:
    _args, cfg = _parse(["--verbose", "--no-check", "--module", "a", "--module", "b",
                         "--state-file", "s.json", "--mode", "slow"])
    assert cfg.verbose is True and cfg.check is False and cfg.module == ["a", "b"]
    assert cfg.state_file == Path("s.json") and cfg.mode == "slow"
    _args, cfg = _parse([])
    assert cfg.verbose is False and cfg.check is True and cfg.module == []
    help_text = service_parser("demo", "a demo service", DemoConfig).format_help()
    assert "turns off (on by default): check what comes in" in " ".join(help_text.split())


def test_an_unknown_field_in_the_file_is_named(tmp_path: Path, capsys) -> None:
    path = tmp_path / "demo.toml"
    path.write_text("rate_hz = 20.0\nretrys = 5\n")
    with pytest.raises(ConfigError, match=r"demo\.toml.*\n  retrys: unknown field"):
        config_of(service_parser("demo", "d", DemoConfig).parse_args(["--config", str(path)]),
                  DemoConfig)
    with pytest.raises(SystemExit) as exit_:
        _parse(["--config", str(path)])
    assert exit_.value.code == 2 and "retrys: unknown field" in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "said"), [
    (["--rate-hz", "0"], "argument --rate-hz: '0' is not a finite number above 0 and at most 100"),
    (["--rate-hz", "nan"], "argument --rate-hz: 'nan' is not a finite number above 0"),
    (["--retries", "10"], "argument --retries: '10' is not a whole number from 0 to 9"),
    (["--timeout", "-1"], "argument --timeout: '-1' is not a finite number above 0"),
    (["--mode", "medium"], "argument --mode: invalid choice: 'medium'"),
    (["--timeout", "0.01"], "timeout_s (0.01) is shorter than one period (with --timeout)"),
    (["--module", "a", "--module", " "], "argument --module: a module needs a name"),
])
def test_a_bad_flag_is_named_with_what_is_allowed(argv, said, capsys) -> None:
    assert said in _refused(argv, capsys)


def test_a_bad_value_in_the_file_names_the_file_and_field(tmp_path: Path, capsys) -> None:
    path = tmp_path / "demo.toml"
    path.write_text("retries = -1\n")
    with pytest.raises(SystemExit) as exit_:
        _parse(["--config", str(path)])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "demo.toml" in err and "retries: Input should be greater" in err
    with pytest.raises(SystemExit):
        _parse(["--config", str(tmp_path / "missing.toml")])
    assert "missing.toml: cannot read" in capsys.readouterr().err


def test_a_flag_cannot_be_made_without_a_description() -> None:
    class Undescribed(ConfigModel):
        x_m: Annotated[float, Flag()] = Field(default=1.0, gt=0)

    with pytest.raises(TypeError, match="--x-m: the field x_m has no description"):
        service_parser("demo", "d", Undescribed)
