"""The ground station is configured as every service is: ``GroundStationConfig``'s defaults, then
``--config FILE``, then its flags; ``Settings`` takes its bounds from that model, whoever makes it."""

from __future__ import annotations

from pathlib import Path

import pytest
from seaway.runtime.config import parse_service_args
from seaway_groundstation.config import DEFAULT_RUNS_DIR, GroundStationConfig
from seaway_groundstation.service import parser, resolve_token
from seaway_groundstation.settings import Settings

TOKEN = "t" * 32


def configured(argv: list[str]) -> GroundStationConfig:
    return parse_service_args(parser(), argv, GroundStationConfig)[1]


def test_a_file_sets_what_has_no_flag_and_a_flag_overrides_the_file(tmp_path: Path) -> None:
    f = tmp_path / "gs.toml"
    f.write_text('stream_rate_hz = 5.0\nmax_uploads = 2\nport = 9000\nrate_limit_burst = 3\n')
    config = configured(["--config", str(f), "--port", "9100"])
    assert (config.stream_rate_hz, config.max_uploads, config.rate_limit_burst) == (5.0, 2, 3)
    assert config.port == 9100  # the flag over the file
    settings = Settings.from_config(config, token=TOKEN)
    assert (settings.stream_rate_hz, settings.max_uploads, settings.rate_limit_burst) == (5.0, 2, 3)
    assert settings.max_body_bytes == GroundStationConfig().max_body_bytes  # the model's default


@pytest.mark.parametrize(("text", "named"), [
    ("stream_rate_hz = 0\n", "stream_rate_hz"),
    ("max_stream_clients = 0\n", "max_stream_clients"),
    ("stram_rate_hz = 5\n", "stram_rate_hz"),  # misspelt: an unknown field
])
def test_a_bad_file_is_refused_naming_the_field(tmp_path: Path, capsys, text: str, named: str) -> None:
    f = tmp_path / "gs.toml"
    f.write_text(text)
    with pytest.raises(SystemExit) as err:
        configured(["--config", str(f)])
    assert err.value.code == 2
    assert named in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--port", "70000"], ["--max-body-bytes", "0"],
                                  ["--rate-limit-per-s", "-1"], ["--request-timeout-s", "nan"]])
def test_a_bad_flag_is_refused_naming_it(capsys, argv: list[str]) -> None:
    with pytest.raises(SystemExit) as err:
        configured(argv)
    assert err.value.code == 2
    assert argv[0] in capsys.readouterr().err


def test_the_replay_folder_follows_the_run_folder_unless_given(tmp_path: Path) -> None:
    assert configured([]).runs_folder() == DEFAULT_RUNS_DIR
    assert configured(["--run-dir", str(tmp_path / "runs" / "r1")]).runs_folder() == tmp_path / "runs"
    assert configured(["--run-dir", str(tmp_path / "r1"), "--runs-dir", str(tmp_path / "x")]
                      ).runs_folder() == tmp_path / "x"


def test_settings_made_directly_keep_the_models_bounds() -> None:
    with pytest.raises(ValueError, match="stale_after_s"):
        Settings(token=TOKEN, stale_after_s=0.0)
    with pytest.raises(ValueError, match="max_waypoints"):
        Settings(token=TOKEN, max_waypoints=1)
    assert Settings(token=TOKEN).replay_rate_hz == GroundStationConfig().replay_rate_hz


def test_the_token_file_is_read_or_its_fault_named(tmp_path: Path) -> None:
    f = tmp_path / "token"
    f.write_text(TOKEN + "\n")
    assert resolve_token(configured(["--token-file", str(f)]).token_file) == TOKEN
    with pytest.raises(SystemExit) as err:
        resolve_token(configured(["--token-file", str(tmp_path / "absent")]).token_file)
    assert "token_file" in str(err.value.code) and "absent" in str(err.value.code)
