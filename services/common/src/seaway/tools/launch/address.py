"""The ground station's address file in a run folder: ``<run_dir>/groundstation/address.json``.

A ground station started with ``--run-dir`` (the ``sim``, ``fleet`` and ``shore`` profiles) writes
it once it serves, before it declares itself ready; the launcher reads it then and prints the page's
address (``seaway launch``: ``ground station: <page>``). It holds the operator token, so it is
readable by its owner only (mode 0600), and the token is written nowhere else in the run folder::

    {"url": "http://127.0.0.1:8321/", "token": "...", "page": "http://127.0.0.1:8321/#token=...",
     "pid": 1234}

``page`` is ``url`` with the token in the fragment (which a browser never sends to the server): the
page takes it from there and removes it from the address bar. ``pid`` is the ground station's
process, so a reader can tell the file of the running one from a leftover in a reused run folder.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError

ENV_TILES = "SEAWAY_GROUNDSTATION_TILES"
"""The ground station's map tiles when its command line gives none (``--tiles``): the launcher
sets it from ``seaway launch --tiles`` or the profile's ``tiles``."""
FOLDER = "groundstation"
"""The ground station's folder in a run folder (its address file, its requests journal)."""
FILE = "address.json"


class AddressError(ValueError):
    """An address file that is missing, unreadable or not an address."""


class GroundStationAddress(BaseModel):
    """Where a ground station serves its page, and its operator token."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    url: str = Field(min_length=1, description="the page's address, e.g. http://127.0.0.1:8321/")
    token: str = Field(min_length=1, description="the operator token (Authorization: Bearer ...)")
    page: str = Field(min_length=1, description="url with #token=<token>: opens the page logged in")
    pid: int = Field(ge=1, description="the ground station's process id")


def address_path(run_dir: Path) -> Path:
    return Path(run_dir) / FOLDER / FILE


def write(run_dir: Path, url: str, token: str, pid: int) -> Path:
    """Write the address file (mode 0600, also over an older file with other bits); its path."""
    doc = GroundStationAddress(url=url, token=token, page=f"{url}#token={token}", pid=pid)
    path = address_path(run_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        os.fchmod(fh.fileno(), 0o600)
        json.dump(doc.model_dump(), fh, indent=2)
        fh.write("\n")
    return path


def read(run_dir: Path) -> GroundStationAddress:
    """The address file of ``run_dir``; ``AddressError`` saying what is wrong with it."""
    path = address_path(run_dir)
    try:
        return GroundStationAddress.model_validate_json(path.read_bytes())
    except OSError as err:
        raise AddressError(f"cannot read {path}: {err.strerror or err}") from None
    except ValidationError as err:
        raise AddressError(f"{path} is not a ground station address: "
                           f"{err.errors()[0]['msg']}") from None
