"""``seaway credentials``: make a stack's credentials (``seaway.runtime.credentials``).

    seaway credentials create /etc/seaway/credentials --profile boat --days 365
    export SEAWAY_CREDENTIALS=/etc/seaway/credentials      # every process of the stack, and `seaway`

``seaway launch`` makes a new set for each run by itself; a folder made here is for a stack whose
credentials must outlive a run (a boat, processes started by hand). Creating again in the same
folder replaces the authority: every earlier certificate stops working (rotation).
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path

from cryptography import x509

from seaway.contract import access
from seaway.contract.config import ConfigError
from seaway.runtime import credentials


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="seaway credentials", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="action", required=True)
    c = sub.add_parser("create", help="a new authority and a certificate per identity")
    c.add_argument("folder", type=Path)
    c.add_argument("--profile", default=None,
                   help="narrow each key to the process this launcher profile runs for it")
    c.add_argument("--days", type=int, default=credentials.DEFAULT_DAYS,
                   help=f"validity of the certificates [days] (default {credentials.DEFAULT_DAYS})")
    c.add_argument("--harness", action="store_true",
                   help="also the test harness identity, which may do everything (tests only)")
    s = sub.add_parser("show", help="the identities in a folder and when they expire")
    s.add_argument("folder", type=Path)
    args = ap.parse_args(argv)
    if args.action == "create":
        producers = None
        if args.profile:
            from seaway.tools.launch.profile import load_profile

            try:
                producers = load_profile(args.profile).producers()
            except ConfigError as err:
                print(f"seaway credentials: {err}", file=sys.stderr)
                return 2
        if args.days < 1:
            print("seaway credentials: --days must be at least 1", file=sys.stderr)
            return 2
        made = credentials.create(args.folder, producers=producers, harness=args.harness, days=args.days)
        print(f"created {made.folder}: authority and {len(access.IDENTITIES) + args.harness} identities, "
              f"valid {args.days} days; use it with {credentials.ENV_CREDENTIALS}={made.folder}")
        return 0
    folder = args.folder
    for pem in sorted(folder.glob("*.pem")):
        if pem.name.endswith("-key.pem"):
            continue
        cert = x509.load_pem_x509_certificate(pem.read_bytes())
        left = cert.not_valid_after_utc - dt.datetime.now(dt.UTC)
        print(f"{pem.stem:14s} expires {cert.not_valid_after_utc:%Y-%m-%d} ({left.days} days)")
    try:
        credentials.Credentials(folder).check("operator")
    except credentials.CredentialsError as err:
        print(f"NOT USABLE: {err}")
        return 1
    return 0
