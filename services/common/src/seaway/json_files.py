"""JSON files people bring (QGroundControl plans, GeoJSON missions and areas): read bounded, as
UTF-8, strictly.

RFC 8259 JSON in UTF-8 (a leading byte-order mark is skipped; UTF-16 and UTF-32 are refused, not
guessed, so that every reader of one file sees the same text), of at most ``MAX_FILE_BYTES``, with
NaN/Infinity literals refused and a key given twice in one object refused (readers differ on which
one counts, so the mission flown could differ from the one another tool shows). Every refusal is a
``JsonFileError`` naming the file (``what``) and the problem, a syntax error with its position.
``seaway.mission_files`` and ``seaway.area.files`` read their JSON through here.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from seaway.contract.config import unreadable

MAX_FILE_BYTES = 16 << 20
"""Bound on a JSON file's size [bytes]: a plan of 1,000 waypoints as QGroundControl writes it is
about 0.5 MB; parsing a 200 MB file took 15 s and 2 GB before its waypoint count was refused."""


class JsonFileError(ValueError):
    """A JSON file that cannot be taken; the text names the file and what is wrong."""


def shown(value: Any, chars: int = 40) -> str:
    """``value`` as JSON, cut to ``chars`` characters: a refusal quotes the file, not all of it."""
    return json.dumps(value)[:chars]


def read_bytes(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of the file at ``path``, read no further than ``max_bytes`` (a larger file is
    refused after that many, not after reading it all); OSError as opening and reading raise it."""
    with open(path, "rb") as fh:
        data = fh.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise JsonFileError(f"{path}: larger than the {max_bytes} bytes a file may have")
    return data


def load_json(data: bytes | str, what: str, max_bytes: int = MAX_FILE_BYTES) -> Any:
    """Parse JSON text (see the module) of at most ``max_bytes`` [bytes]; ``what`` names it in a
    refusal."""

    def no_constants(name: str) -> float:
        raise JsonFileError(f"{what}: {name} is not a number JSON allows")

    def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise JsonFileError(f"{what}: key {shown(key)} appears more than once in one "
                                    "object; each key may be given once")
            seen.add(key)
        return dict(pairs)

    if len(data) > max_bytes:
        raise JsonFileError(f"{what}: {len(data)} bytes, more than the {max_bytes} allowed")
    encoding = json.detect_encoding(data) if isinstance(data, bytes) else "utf-8"
    if not encoding.startswith("utf-8"):
        raise JsonFileError(f"{what}: {encoding.upper()} text, not UTF-8; save the file as UTF-8")
    try:
        text = data.decode("utf-8-sig") if isinstance(data, bytes) else data
        return json.loads(text, parse_constant=no_constants, object_pairs_hook=unique_keys)
    except JsonFileError:
        raise  # ours, already naming the problem (it is a ValueError too: not "unreadable")
    except UnicodeDecodeError as err:
        raise JsonFileError(f"{what}: not UTF-8 text ({err.reason} at byte {err.start})") from None
    except json.JSONDecodeError as err:
        raise JsonFileError(f"{what}: not JSON: {err.msg} at line {err.lineno} column "
                            f"{err.colno}") from None
    except (ValueError, RecursionError) as err:
        raise JsonFileError(f"{what}: {unreadable(err)}") from None
