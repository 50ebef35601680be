"""Throwaway TLS material for the deployment tests, made with the ``openssl`` command in a tmp folder.

The same commands as docs/deployment.md ("TLS"): a CA, the boat router's certificate (CN and DNS
name ``seaway-boat``, plus ``localhost`` and 127.0.0.1 for tests on one machine) and the shore
router's client certificate (CN ``seaway-shore``, the name the boat router's access control knows).
Nothing here is ever committed: each test run makes its own keys.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


def have_openssl() -> bool:
    return shutil.which("openssl") is not None


def _run(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


def make_ca(folder: Path, name: str = "ca", cn: str = "Seaway test CA") -> Path:
    """``<name>.pem`` and ``<name>-key.pem``: a self-signed CA (EC P-256, 1 day)."""
    folder.mkdir(parents=True, exist_ok=True)
    _run("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
         "-keyout", f"{name}-key.pem", "-out", f"{name}.pem", "-days", "1", "-subj", f"/CN={cn}",
         "-addext", "basicConstraints=critical,CA:TRUE",
         "-addext", "keyUsage=critical,keyCertSign,cRLSign", cwd=folder)
    return folder / f"{name}.pem"


def make_cert(folder: Path, name: str, cn: str, ca: str = "ca",
              dns: tuple[str, ...] = (), ips: tuple[str, ...] = ()) -> tuple[Path, Path]:
    """``<name>.pem`` and ``<name>-key.pem`` signed by ``<ca>.pem``; usable as server and client."""
    _run("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
         "-keyout", f"{name}-key.pem", "-out", f"{name}.csr", "-subj", f"/CN={cn}", cwd=folder)
    san = ",".join([f"DNS:{d}" for d in dns] + [f"IP:{i}" for i in ips]) or f"DNS:{cn}"
    (folder / f"{name}.ext").write_text(
        "basicConstraints=critical,CA:FALSE\n"
        "keyUsage=critical,digitalSignature,keyEncipherment\n"
        "extendedKeyUsage=serverAuth,clientAuth\n"
        f"subjectAltName={san}\n")
    _run("x509", "-req", "-in", f"{name}.csr", "-CA", f"{ca}.pem", "-CAkey", f"{ca}-key.pem",
         "-CAcreateserial", "-out", f"{name}.pem", "-days", "1", "-extfile", f"{name}.ext", cwd=folder)
    return folder / f"{name}.pem", folder / f"{name}-key.pem"


def make_deployment_certs(folder: Path, boat_ips: tuple[str, ...] = ()) -> Path:
    """The files the TLS router configs name (ca.pem, boat.pem, boat-key.pem, shore.pem,
    shore-key.pem), plus ``intruder`` (right CA, unknown CN) and ``rogue`` (CN seaway-shore from
    another CA, ``rogue-ca.pem``) for the negative tests. ``boat_ips``: more addresses the boat's
    certificate names (the shore connects by address). Returns ``folder``."""
    make_ca(folder)
    make_cert(folder, "boat", "seaway-boat", dns=("seaway-boat", "localhost"),
              ips=("127.0.0.1", *boat_ips))
    make_cert(folder, "shore", "seaway-shore")
    make_cert(folder, "intruder", "seaway-intruder")
    make_ca(folder, "rogue-ca", "Not the Seaway CA")
    make_cert(folder, "rogue", "seaway-shore", ca="rogue-ca")
    return folder
