"""``seaway credentials``: make a stack's credentials (``seaway.runtime.credentials``).

    seaway credentials create /etc/seaway/credentials --days 365
    export SEAWAY_CREDENTIALS=/etc/seaway/credentials      # every process of the stack, and `seaway`
    seaway credentials create ~/seaway-credentials --deployment --boat-host 192.168.8.2
        # ~/seaway-credentials/boat -> the boat's /etc/seaway/credentials, .../shore -> the laptop's

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
from seaway.runtime.argtypes import positive_int


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="seaway credentials", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="action", required=True, metavar="ACTION",
                            help="create: new credentials; show: what a folder holds")
    c = sub.add_parser("create", help="a new authority and a certificate per identity")
    c.add_argument("folder", type=Path, help="folder to create (it must not hold credentials yet)")
    c.add_argument("--profile", default=None,
                   help="narrow each key to the process this launcher profile runs for it")
    c.add_argument("--days", type=positive_int, default=credentials.DEFAULT_DAYS,
                   help=f"validity of the certificates [days] (default {credentials.DEFAULT_DAYS})")
    c.add_argument("--deployment", action="store_true",
                   help="a boat and its shore: FOLDER/boat and FOLDER/shore from one authority, each "
                        "with its side's identities and rules (docs/deployment.md)")
    c.add_argument("--boat-host", action="append", default=None, metavar="NAME_OR_ADDRESS",
                   help="with --deployment: a name or address the shore dials the boat router by "
                        f"(repeatable; default {', '.join(credentials.DEFAULT_BOAT_HOSTS)}; "
                        "localhost and 127.0.0.1 always)")
    c.add_argument("--harness", action="store_true",
                   help="also the test harness identity, which may do everything (tests only)")
    c.add_argument("--ros2-writes", action="store_true",
                   help="let the ROS 2 face (seaway-ros2 --ros2-writes) ask a mission and its "
                        "pause/resume/abort, as an operator does (docs/ros2.md)")
    s = sub.add_parser("show", help="the identities in a folder and when they expire")
    s.add_argument("folder", type=Path, help="a credentials folder")
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
        if args.boat_host and not args.deployment:
            print("seaway credentials: --boat-host goes with --deployment", file=sys.stderr)
            return 2
        if args.deployment:
            sides = credentials.create_deployment(
                args.folder, boat_hosts=args.boat_host or credentials.DEFAULT_BOAT_HOSTS,
                producers=producers, harness=args.harness, days=args.days,
                ros2_writes=args.ros2_writes)
            print(f"created {args.folder}: one authority (its key ca-key.pem stays here), valid "
                  f"{args.days} days")
            for side, made in sides.items():
                print(f"  {side:5s} {made.folder}: {', '.join(_identities(made.folder))}; on the {side} "
                      f"computer: {credentials.ENV_CREDENTIALS}={made.folder} (or where you copy it)")
            return 0
        made = credentials.create(args.folder, producers=producers, harness=args.harness,
                                  days=args.days, ros2_writes=args.ros2_writes)
        print(f"created {made.folder}: authority and {len(access.IDENTITIES) + args.harness} identities, "
              f"valid {args.days} days; use it with {credentials.ENV_CREDENTIALS}={made.folder}")
        return 0
    sides = [args.folder / side for side in credentials.DEPLOYMENT_SIDES]
    if all(side.is_dir() for side in sides):
        return max(_show(side) for side in sides)
    return _show(args.folder)


def _identities(folder: Path) -> list[str]:
    return sorted(p.stem for p in folder.glob("*.pem") if not p.name.endswith("-key.pem")
                  and p.name not in ("ca.pem",))


def _show(folder: Path) -> int:
    print(f"{folder}:")
    for pem in sorted(folder.glob("*.pem")):
        if pem.name.endswith("-key.pem"):
            continue
        cert = x509.load_pem_x509_certificate(pem.read_bytes())
        left_s = (cert.not_valid_after_utc - dt.datetime.now(dt.UTC)).total_seconds()
        left = f"{left_s // 86_400:.0f} days" if left_s >= 0 else "EXPIRED"
        print(f"  {pem.stem:14s} expires {cert.not_valid_after_utc:%Y-%m-%d} ({left})")
    try:
        credentials.Credentials(folder).check("operator")
    except credentials.CredentialsError as err:
        print(f"  NOT USABLE: {err}")
        return 1
    return 0
