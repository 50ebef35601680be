"""Configuration types and loading. Config types reject unknown fields, so a typo fails loudly.

Files are TOML (``.toml``) or JSON (``.json``). Every error names the file and the field.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from seaway.contract.units import in_range


class ConfigError(ValueError):
    """A configuration, vessel, scenario or mission document is invalid; the text says where."""


class ConfigModel(BaseModel):
    """Base of every configuration type: unknown fields are errors, values finite, immutable."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


MIN_ALT_M = -1000.0
"""The lowest origin altitude [m]: below the Dead Sea's shore (-430 m) and the geoid's deepest
dip under the ellipsoid (-106 m) together."""
MAX_ALT_M = 9000.0
"""The highest origin altitude [m]: above any water a vessel floats on (the highest lakes lie near
6,400 m), and well inside MAVLink's int32 millimetres, which the simulator's GNSS messages carry."""


class Origin(ConfigModel):
    """A geodetic origin in WGS84 degrees: the local NED frame's x = y = 0 (scenarios, runs, configs)."""

    lat_deg: Annotated[float, in_range(-90, 90, "deg")] = Field(default=47.0, ge=-90, le=90)
    lon_deg: Annotated[float, in_range(-180, 180, "deg")] = Field(default=8.0, ge=-180, le=180)
    alt_m: Annotated[float, in_range(MIN_ALT_M, MAX_ALT_M, "m")] = Field(
        default=0.0, ge=MIN_ALT_M, le=MAX_ALT_M,
        description="altitude of the origin, the water surface [m]")


C = TypeVar("C", bound=ConfigModel)


def describe_validation_error(err: ValidationError, where: str) -> str:
    lines = [f"{where}: {len(err.errors())} problem(s)"]
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(document)"
        msg = "unknown field (check the spelling)" if e["type"] == "extra_forbidden" else e["msg"]
        lines.append(f"  {loc}: {msg}")
    return "\n".join(lines)


def unreadable(err: ValueError | RecursionError) -> str:
    """Why a JSON or TOML text its parser raised on past its syntax checks cannot be read: an
    integer past Python's 4300-digit conversion limit (ValueError) or arrays or tables nested
    about a thousand deep (RecursionError). Every file reader says it this way."""
    if isinstance(err, RecursionError):
        return "not a usable document: nested too deeply (no file here nests more than a few levels)"
    what = str(err).split(";")[0]  # not its advice to raise the limit: that is no fix for a file
    return f"not a usable document: a number too long to read ({what})"


def read_document(path: str | Path) -> dict[str, Any]:
    """Read a TOML or JSON file into a dict; errors name the file and the parse position."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"{p}: cannot read: {err.strerror or err}") from None
    except UnicodeDecodeError as err:
        raise ConfigError(f"{p}: not UTF-8 text (byte {err.start} is 0x{err.object[err.start]:02x}); "
                          f"TOML and JSON files must be UTF-8") from None
    try:
        if p.suffix == ".toml":
            return tomllib.loads(text)
        if p.suffix == ".json":
            doc = json.loads(text)
            if not isinstance(doc, dict):
                raise ConfigError(f"{p}: the top level must be an object")
            return doc
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as err:
        raise ConfigError(f"{p}: not valid {p.suffix[1:].upper()}: {err}") from None
    except ConfigError:
        raise
    except (ValueError, RecursionError) as err:
        raise ConfigError(f"{p}: {unreadable(err)}") from None
    raise ConfigError(f"{p}: unknown file type {p.suffix!r}; use .toml or .json")


def parse_config(doc: dict[str, Any], model: type[C], where: str = "config") -> C:
    """Validate a document against a config type."""
    try:
        return model.model_validate(doc)
    except ValidationError as err:
        raise ConfigError(describe_validation_error(err, where)) from None


def load_config(path: str | Path, model: type[C]) -> C:
    """Read and validate a config file."""
    return parse_config(read_document(path), model, str(path))


def repo_root() -> Path | None:
    """The checkout this package runs from (for default deploy/ files), or None if installed."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "deploy").is_dir() and (parent / "services").is_dir():
            return parent
    return None


def deploy_path(*parts: str) -> Path:
    """A file under the checkout's ``deploy/`` folder; raises ConfigError if there is none."""
    root = repo_root()
    if root is None:
        raise ConfigError("cannot find the deploy/ folder: pass the file's path explicitly")
    return root.joinpath("deploy", *parts)


def named_file(folder: Path, name_or_path: str | Path, what: str, shown: str) -> Path:
    """``name_or_path`` if it is a file's path (it ends in .toml or .json), else
    ``<folder>/<name>.toml``; a name with no such file raises ConfigError listing the names there
    are (``what``: "scenario", "vessel file", ... and ``shown``: the folder, for the message)."""
    p = Path(name_or_path)
    if p.suffix in (".toml", ".json"):
        return p
    if p.suffix and p.is_file():  # a file, of a kind this does not read (a .plan, a .geojson)
        raise ConfigError(f"{p}: a {what} is a .toml or .json file, not {p.suffix}")
    p = folder / f"{name_or_path}.toml"
    if not p.is_file():
        names = sorted(q.stem for q in folder.glob("*.toml"))
        raise ConfigError(f"no {what} {str(name_or_path)!r} ({shown}); there are: "
                          + (", ".join(names) or "none") + "; or give a file's path")
    return p


def deploy_named(folder: str, name_or_path: str | Path, what: str) -> Path:
    """``named_file`` in ``deploy/<folder>/``."""
    p = Path(name_or_path)
    if p.suffix in (".toml", ".json"):
        return p
    return named_file(deploy_path(folder), name_or_path, what, f"deploy/{folder}/")
