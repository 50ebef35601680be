"""A stack's credentials: its own certificate authority and one certificate per identity.

Each process proves who it is with Zenoh's mutual TLS: its certificate's common name is its
identity (``seaway.contract.access``), signed by the stack's authority; every process trusts only
that authority. Zenoh's access control then matches each remote process by that name, in both
directions of every link (user/password authentication identifies only the side that connects, so
it cannot protect a peer-to-peer mesh where either side may connect first).

A credentials folder (mode 0700, keys 0600; refused otherwise)::

    ca.pem ca-key.pem            the authority (its key issues certificates; not in a deployment's
                                 boat/ and shore/ folders, which ``create_deployment`` makes)
    <identity>.pem               a certificate per identity (common name = identity)
    <identity>-key.pem
    access.json                  the stack's access rules (contract.access.acl), the same for everyone

The launcher creates one per run (``create`` with no end of validity: ``NO_END``) unless
``$SEAWAY_CREDENTIALS`` names one (a boat's long-lived set, ``seaway credentials create``).
``$SEAWAY_CREDENTIALS=none`` runs without authentication (benchmarks' baseline): every process on
the machine may then do anything. ``Credentials.check`` refuses certificates the clock finds
outside their validity.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import json
import os
import stat
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from seaway.contract import access

ENV_CREDENTIALS = "SEAWAY_CREDENTIALS"
ENV_IDENTITY = "SEAWAY_IDENTITY"
NONE = "none"
"""``$SEAWAY_CREDENTIALS=none``: no authentication, no access control (explicit opt-out)."""
ACCESS_FILE = "access.json"
CA_NAME = "seaway-stack-ca"
DEFAULT_DAYS = 30
VALID_FROM = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
"""Every certificate's start of validity: the Unix epoch, not the moment it is made. A boat's
computer often has no real-time clock: it boots at the time it last saved (or 1970) and may run for
days behind, with no network to set it, until GPS time does. Certificates valid only from the
moment they were made on the shore would be "not yet valid" there, and the stack could not start.
The start of validity protects nothing for an authority whose key never leaves the machine that
made it; the end of validity (``days``) stays."""
NO_END = dt.datetime(9999, 12, 31, 23, 59, 59, tzinfo=dt.UTC)
"""The end of validity of a run's own authority (``create`` with ``days`` None): RFC 5280's
"no well-defined expiration date" (section 4.1.2.5). A launcher's clock is not to be trusted on a
boat: one that boots at 1970 makes its run's credentials then, and certificates valid for 30 days
from that moment were expired once GPS time came; each process restarted after that could not
join the stack. A run's authority is trusted by that run's processes only, and its folder goes
with the run: an end of validity protects nothing there."""
EXPIRY_WARNING_S = 7 * 86_400
"""Credentials that end within this [s] get a warning at launch: every link of a session closes
as its certificate ends (``close_link_on_expiration``), mid-mission too."""


class CredentialsError(ValueError):
    """Credentials that are missing, unsafe or unusable, with what to do in words."""


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def _write_private(path: Path, data: bytes) -> None:
    # Created 0600 from the start: never a moment where another user could read the key.
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def _name(cn: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])


def _san(hosts: Iterable[str]) -> x509.SubjectAlternativeName:
    names: list[x509.GeneralName] = []
    for h in dict.fromkeys(["localhost", "127.0.0.1", *hosts]):
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(h)))
        except ValueError:
            names.append(x509.DNSName(h))
    return x509.SubjectAlternativeName(names)


def _not_after(days: int | None) -> dt.datetime:
    """The end of validity of certificates made now for ``days`` (None: ``NO_END``)."""
    return NO_END if days is None else dt.datetime.now(dt.UTC) + dt.timedelta(days=days)


def _issue(identity: str, ca_key: ec.EllipticCurvePrivateKey, ca_cert: x509.Certificate,
           days: int | None, hosts: Iterable[str] = ()) -> tuple[bytes, bytes]:
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (x509.CertificateBuilder().subject_name(_name(identity)).issuer_name(ca_cert.subject)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(VALID_FROM).not_valid_after(_not_after(days))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            # Every process both listens and connects on loopback: it is a TLS server and client.
            # A boat router is also reached over the link by the names in ``hosts``.
            .add_extension(_san(hosts), critical=False)
            .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                  ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False)
            .sign(ca_key, hashes.SHA256()))
    return cert.public_bytes(serialization.Encoding.PEM), _key_pem(key)


def _private_folder(folder: Path) -> Path:
    folder = Path(folder)
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    return folder


def _authority(days: int | None) -> tuple[ec.EllipticCurvePrivateKey, x509.Certificate]:
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_cert = (x509.CertificateBuilder().subject_name(_name(CA_NAME)).issuer_name(_name(CA_NAME))
               .public_key(ca_key.public_key()).serial_number(x509.random_serial_number())
               .not_valid_before(VALID_FROM).not_valid_after(_not_after(days))
               .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
               .add_extension(x509.KeyUsage(digital_signature=False, content_commitment=False,
                                            key_encipherment=False, data_encipherment=False,
                                            key_agreement=False, key_cert_sign=True, crl_sign=True,
                                            encipher_only=False, decipher_only=False), critical=True)
               .sign(ca_key, hashes.SHA256()))
    return ca_key, ca_cert


def _write_authority(folder: Path, ca_key: ec.EllipticCurvePrivateKey, ca_cert: x509.Certificate,
                     with_key: bool) -> None:
    if with_key:
        _write_private(folder / "ca-key.pem", _key_pem(ca_key))
    (folder / "ca.pem").write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))


def _populate(folder: Path, ca_key: ec.EllipticCurvePrivateKey, ca_cert: x509.Certificate,
              names: Iterable[str], rules: dict[str, Any], days: int | None,
              router_hosts: Iterable[str] = ()) -> None:
    for ident in names:
        hosts = router_hosts if ident == access.RELAY else ()
        cert, key = _issue(ident, ca_key, ca_cert, days, hosts)
        (folder / f"{ident}.pem").write_bytes(cert)
        _write_private(folder / f"{ident}-key.pem", key)
    (folder / ACCESS_FILE).write_text(json.dumps(rules, indent=1))


def create(folder: Path, identities: Iterable[str] | None = None, *,
           producers: Mapping[str, str] | None = None, harness: bool = False,
           days: int | None = DEFAULT_DAYS, ros2_writes: bool = False) -> Credentials:
    """A new authority and a certificate for each identity in ``folder`` (created 0700), valid for
    ``days`` from now (None: to ``NO_END``, for a run's own authority).

    ``producers``: the profile's producer of each key it narrows (``access.producers``);
    ``harness``: also the test harness identity, with every right; ``ros2_writes``: the ROS 2 face
    may ask the mission's requests (``access.ROS2_REQUESTS``). An existing authority in ``folder``
    is replaced: certificates of the old one stop working.
    """
    folder = _private_folder(folder)
    ca_key, ca_cert = _authority(days)
    _write_authority(folder, ca_key, ca_cert, with_key=True)
    base = access.IDENTITIES if identities is None else identities
    names = list(dict.fromkeys([*base, *([access.HARNESS] if harness else [])]))
    _populate(folder, ca_key, ca_cert, names,
              access.acl(producers, harness=harness, ros2_writes=ros2_writes), days)
    return Credentials(folder)


DEPLOYMENT_SIDES = ("boat", "shore")
DEFAULT_BOAT_HOSTS = ("seaway-boat",)
"""The names the shore reaches the boat router by, in its certificate (docs/deployment.md)."""


def create_deployment(folder: Path, *, boat_hosts: Iterable[str] = DEFAULT_BOAT_HOSTS,
                      producers: Mapping[str, str] | None = None, harness: bool = False,
                      days: int = DEFAULT_DAYS, ros2_writes: bool = False) -> dict[str, Credentials]:
    """One authority for a boat and its shore: ``folder/boat`` and ``folder/shore``, each a
    credentials folder with that side's identities and rules (``access.acl(side=...)``).

    The authority's key stays in ``folder`` (``ca-key.pem``), on neither machine's folder: copy
    ``boat/`` to the boat and ``shore/`` to the shore. The routers' certificates carry
    ``boat_hosts`` (names or addresses the shore dials) besides localhost and 127.0.0.1.
    ``producers`` narrows the boat's keys as its profile runs them; ``ros2_writes`` lets the boat's
    ROS 2 face ask the mission's requests (``access.ROS2_REQUESTS``). Creating again replaces the
    authority (rotation): every earlier certificate stops working.
    """
    root = _private_folder(folder)
    ca_key, ca_cert = _authority(days)
    _write_authority(root, ca_key, ca_cert, with_key=True)
    made = {}
    for side in DEPLOYMENT_SIDES:
        sub = _private_folder(root / side)
        for old in sub.glob("*.pem"):
            old.unlink()
        _write_authority(sub, ca_key, ca_cert, with_key=False)
        names = [*access.side_identities(side), *([access.HARNESS] if harness else [])]
        rules = access.acl(producers if side == "boat" else None, harness=harness, side=side,
                           ros2_writes=ros2_writes and side == "boat")
        _populate(sub, ca_key, ca_cert, names, rules, days, router_hosts=boat_hosts)
        made[side] = Credentials(sub)
    return made


@dataclass(frozen=True)
class Credentials:
    """A credentials folder, checked before use."""

    folder: Path

    def check(self, identity: str) -> None:
        """Raise ``CredentialsError`` unless ``identity`` can use this folder safely."""
        f = self.folder
        if not f.is_dir():
            raise CredentialsError(f"credentials folder {f} does not exist (create one with "
                                   f"`seaway credentials create {f}`, or start the stack with "
                                   "`seaway launch`, which creates its own)")
        mode = stat.S_IMODE(f.stat().st_mode)
        if mode & 0o077:
            raise CredentialsError(f"credentials folder {f} is open to other users (mode "
                                   f"{mode:04o}); allowed: owner only, `chmod 700 {f}`")
        for need in ("ca.pem", f"{identity}.pem", f"{identity}-key.pem", ACCESS_FILE):
            if not (f / need).is_file():
                have = sorted(p.name[:-4] for p in f.glob("*.pem")
                              if not p.name.endswith("-key.pem") and p.name != "ca.pem")
                raise CredentialsError(f"credentials folder {f} has no {need} for identity "
                                       f"{identity!r}; identities there: {', '.join(have) or 'none'}")
        kmode = stat.S_IMODE((f / f"{identity}-key.pem").stat().st_mode)
        if kmode & 0o077:
            raise CredentialsError(f"{f / (identity + '-key.pem')} is readable by other users "
                                   f"(mode {kmode:04o}); allowed: 0600")
        now = dt.datetime.now(dt.UTC)
        for name in ("ca.pem", f"{identity}.pem"):
            start, end = self.validity(name)
            if not start <= now <= end:
                # Else TLS refuses every link, and the process waits for a stack it never joins,
                # with nothing in its own log to say why.
                raise CredentialsError(
                    f"{f / name} is valid from {start:%Y-%m-%d %H:%M} to {end:%Y-%m-%d %H:%M} UTC, "
                    f"and this machine's clock says {now:%Y-%m-%d %H:%M} UTC: no link would be "
                    f"accepted. Make new credentials (`seaway credentials create {f}`), or set "
                    "the clock if it is wrong")

    def validity(self, name: str) -> tuple[dt.datetime, dt.datetime]:
        """(start, end) of validity of the certificate ``name`` in this folder (UTC)."""
        try:
            cert = x509.load_pem_x509_certificate((self.folder / name).read_bytes())
        except (OSError, ValueError) as err:
            raise CredentialsError(f"{self.folder / name} is not a readable certificate: {err}") \
                from None
        return cert.not_valid_before_utc, cert.not_valid_after_utc

    def ends(self, identity: str) -> dt.datetime:
        """When the first of ``identity``'s certificate and the authority's ends (UTC)."""
        return min(self.validity(name)[1] for name in ("ca.pem", f"{identity}.pem"))

    def access_rules(self) -> dict[str, Any]:
        try:
            return json.loads((self.folder / ACCESS_FILE).read_text())
        except (OSError, ValueError) as err:
            raise CredentialsError(f"{self.folder / ACCESS_FILE} is unreadable: {err}") from None

    @property
    def side(self) -> str:
        """``local``, ``boat`` or ``shore``: whose rules these are (``access.side_of``)."""
        return access.side_of(self.access_rules())

    def zenoh_settings(self, identity: str) -> dict[str, Any]:
        """The Zenoh settings (key -> value) that make a session ``identity`` of this stack."""
        self.check(identity)
        f = self.folder
        cert, key = str(f / f"{identity}.pem"), str(f / f"{identity}-key.pem")
        return {
            "transport/link/tls": {
                "root_ca_certificate": str(f / "ca.pem"),
                "listen_certificate": cert, "listen_private_key": key,
                "connect_certificate": cert, "connect_private_key": key,
                "enable_mtls": True,
                "close_link_on_expiration": True,
            },
            "access_control": self.access_rules(),
        }


def from_env(environ: Mapping[str, str] | None = None) -> Credentials | str | None:
    """``$SEAWAY_CREDENTIALS``: a ``Credentials``, ``None`` if unset, ``NONE`` if opted out."""
    value = (os.environ if environ is None else environ).get(ENV_CREDENTIALS, "").strip()
    if not value:
        return None
    if value.lower() == NONE:
        return NONE
    return Credentials(Path(value).expanduser())
