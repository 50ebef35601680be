"""The launcher's side of authority: the run's credentials and its claim on the rendezvous endpoint.

* ``credentials_for``: the stack's credentials: ``$SEAWAY_CREDENTIALS`` if it names a folder (a
  boat's long-lived set; required for a profile that is one side of a deployment; a warning when it
  ends within a week), else a new authority for this run only, with no end of validity
  (``credentials.NO_END``), in a private folder that is removed when the launcher exits; the access
  rules narrow each key to the process the profile runs for it.
* ``claim``: claim the rendezvous endpoint for this stack (``register`` writes its registry entry
  once the launcher's session holds the port), or refuse with the name of the stack already there
  (two stacks on one endpoint would otherwise fight over it: with different credentials neither
  can reach the other, so the second would wait for its own processes forever).
* ``rendezvous_problem``: once the launcher's own session is open, whether the endpoint answers
  with this stack's credentials. A port held before the launch by a process that is not a stack of
  this registry (a Zenoh session without the credentials, a stack registered in another registry
  folder, any other program) would otherwise let every process start and none link: the start
  failed 30 s later with "recorder not ready". Now it fails within ``RENDEZVOUS_PROBE_S``, naming
  the port, the holder's pid and command line where this user may see them, and what to do.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import re
import shutil
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path

from seaway.contract import access
from seaway.mavlink import signing
from seaway.runtime import credentials as creds
from seaway.runtime import stacks
from seaway.runtime.zenoh_bus import ZenohBus, rendezvous_endpoint
from seaway.tools.launch.profile import Profile

RENDEZVOUS_PROBE_S = 5.0
"""How long a launcher whose rendezvous port was already held waits for a session there to accept
its credentials [s]: a link on loopback comes within milliseconds, a few seconds on a loaded
machine."""


class StackInUseError(RuntimeError):
    """Another stack (or another program) holds the rendezvous endpoint."""


@dataclass
class Authority:
    """What a launch runs with; ``release`` undoes ``claim`` and removes per-run credentials."""

    credentials: creds.Credentials | None
    rendezvous: str
    owned_folder: Path | None = None
    mavlink_key: Path | None = None
    registered: bool = False
    port_held: bool = False
    """The rendezvous port was open before this launch (by no stack of this registry)."""
    entry: stacks.StackEntry | None = None
    """This stack's registry entry, made by ``claim``, written by ``register``."""
    notes: list[str] = field(default_factory=list)

    def release(self) -> None:
        if self.registered:
            stacks.unregister(self.rendezvous, os.getpid())
            self.registered = False
        if self.owned_folder is not None:
            shutil.rmtree(self.owned_folder, ignore_errors=True)
            self.owned_folder = None
        if self.mavlink_key is not None:
            self.mavlink_key.unlink(missing_ok=True)
            self.mavlink_key = None


def private_name(run_name: str) -> str:
    """The name of this launch's files in the private stacks folder: the run's name and the
    launcher's pid. Why the pid: two stacks whose run folders share a name (two studies at once,
    ``--run-dir a/run`` and ``--run-dir b/run``) made their credentials in one folder, and the first
    to stop removed it: the other's next restarted process could not open its session."""
    return f"{run_name}.{os.getpid()}"


_PRIVATE = re.compile(r"\.(\d+)\.(credentials|mavlink\.key)$")


def remove_stale() -> list[Path]:
    """Remove what launchers that are gone (killed: no ``release``) left in the stacks folder,
    before this one makes its own: files with this process's pid are then a gone launcher's that
    had the same pid (a container's launcher often has), whose key a new one may not overwrite;
    the paths removed."""
    gone = []
    folder = stacks.stacks_dir()
    for p in folder.iterdir() if folder.is_dir() else ():
        m = _PRIVATE.search(p.name)
        if m and (int(m.group(1)) == os.getpid() or not stacks.alive(int(m.group(1)))):
            if p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
            else:
                p.unlink(missing_ok=True)
            gone.append(p)
    return gone


def mavlink_key_path(run_name: str) -> Path:
    """Where this run's MAVLink signing key is (``{mavlink_key}`` in a profile's commands): a new
    random key per run, in the private stacks folder, removed when the launcher exits."""
    return stacks.stacks_dir() / f"{private_name(run_name)}.mavlink.key"


def credentials_for(profile: Profile, run_name: str) -> Authority:
    """The credentials of this launch (see the module docstring), and its MAVLink signing key."""
    remove_stale()
    stacks.private_folder()  # before the credentials folder made in it would make it 0755
    auth = _zenoh_credentials(profile, run_name)
    key = mavlink_key_path(run_name)
    signing.write_key(key)
    auth.mavlink_key = key
    return auth


def _zenoh_credentials(profile: Profile, run_name: str) -> Authority:
    rendezvous = rendezvous_endpoint()
    given = creds.from_env()
    if given == creds.NONE:
        return Authority(None, rendezvous, notes=[
            f"authentication OFF (${creds.ENV_CREDENTIALS}={creds.NONE}): any local process may "
            "command this stack"])
    if isinstance(given, creds.Credentials):
        given.check("launcher")
        notes = [f"credentials {given.folder}"]
        ends = given.ends("launcher")
        left_s = (ends - dt.datetime.now(dt.UTC)).total_seconds()
        if left_s < creds.EXPIRY_WARNING_S:
            notes.append(f"WARNING: these credentials end on {ends:%Y-%m-%d %H:%M} UTC (in "
                         f"{left_s / 3600:.0f} h): then every link closes, mid-mission too, and no "
                         f"process can join; make new ones before (`seaway credentials create "
                         f"{given.folder}`)")
        if profile.ros2_writes() and not any(p.get("id") == access.ROS2_WRITES_POLICY for p in
                                             given.access_rules().get("policies", [])):
            notes.append("ROS 2 writes: these credentials do not let the ROS 2 face ask anything, "
                         "so its requests will be refused (make them with `seaway credentials "
                         "create --ros2-writes`)")
        return Authority(given, rendezvous, notes=notes)
    if profile.side != "local":
        raise creds.CredentialsError(
            f"profile {profile.name} is the {profile.side} half of a deployment: it needs that side's "
            f"credentials in ${creds.ENV_CREDENTIALS} (one command makes both sides': `seaway "
            f"credentials create DIR --deployment --boat-host <boat address>`, then "
            f"{creds.ENV_CREDENTIALS}=DIR/{profile.side}; docs/deployment.md)")
    folder = stacks.stacks_dir() / f"{private_name(run_name)}.credentials"
    # No end of validity: the launcher's clock may be 1970's on a boat with no real-time clock
    # (``creds.NO_END``).
    made = creds.create(folder, producers=profile.producers(), ros2_writes=profile.ros2_writes(),
                        days=None)
    return Authority(made, rendezvous, owned_folder=folder,
                     notes=[f"credentials: a new authority for this run ({folder})"])


def _port_in_use(endpoint: str) -> bool:
    host, _, port = endpoint.split("/", 1)[-1].rpartition(":")
    with contextlib.suppress(ValueError), socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex((host.strip("[]"), int(port))) == 0
    return False


def claim(auth: Authority, profile: Profile, run_dir: Path, vessel: str) -> None:
    """Claim the rendezvous endpoint for this stack; ``StackInUseError`` if a stack has it.

    For the default peer config only. A port already open without a registered stack is a session
    opened before the launch (noted, not refused: without this stack's credentials it cannot link).
    The entry is written by ``register`` once the launcher's session holds the port.
    """
    other = stacks.lookup(auth.rendezvous)
    if other is not None:
        raise StackInUseError(
            f"another Seaway stack runs on {auth.rendezvous}: {other.describe()}. Stop it "
            f"(kill -INT {other.pid}) or start this one on another port, e.g. "
            f"SEAWAY_ZENOH_RENDEZVOUS=tcp/127.0.0.1:7450")
    if _port_in_use(auth.rendezvous):
        # Not a stack (none is registered): a session opened before the launch (a `seaway echo`
        # waiting, a test) holds the port. It joins only if it has this stack's credentials.
        auth.port_held = True
        auth.notes.append(f"{auth.rendezvous} is already held by a session that is not a stack; "
                          "it takes part only if it has this stack's credentials")
    auth.entry = stacks.StackEntry(
        rendezvous=auth.rendezvous, pid=os.getpid(), profile=profile.name, run_dir=str(run_dir),
        credentials=str(auth.credentials.folder) if auth.credentials else creds.NONE, vessel=vessel)


def register(auth: Authority) -> None:
    """Write the entry ``claim`` made (none: a deployment config, nothing to register).

    Only once the launcher's session is open: whoever finds the stack in the registry (a test, a
    `seaway` command, an operator's session) and opens a session then finds the rendezvous port held
    by the launcher, which counts the links refused there. Registered earlier, such a session took
    the free port itself, and the stack linked through it."""
    if auth.entry is not None and not auth.registered:
        stacks.register(auth.entry)
        auth.registered = True


def _port(endpoint: str) -> int | None:
    with contextlib.suppress(ValueError):
        return int(endpoint.rpartition(":")[2])
    return None


def port_holder(port: int) -> tuple[int, str] | None:
    """(pid, command line) of the process listening on TCP ``port`` of this machine, if this user
    may see it (``/proc``: a listening socket's inode, then the process holding it); else None."""
    inodes = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with contextlib.suppress(OSError):
            for line in Path(table).read_text().splitlines()[1:]:
                f = line.split()
                if len(f) > 9 and f[3] == "0A" and int(f[1].rpartition(":")[2], 16) == port:
                    inodes.add(f"socket:[{f[9]}]")
    for proc in Path("/proc").iterdir() if inodes else ():
        if not proc.name.isdigit() or int(proc.name) == os.getpid():
            continue
        with contextlib.suppress(OSError):
            for fd in (proc / "fd").iterdir():
                with contextlib.suppress(OSError):
                    if os.readlink(fd) in inodes:
                        cmd = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(
                            errors="replace").strip()
                        return int(proc.name), cmd[:200]
    return None


def rendezvous_problem(auth: Authority, bus: object, wait_s: float = RENDEZVOUS_PROBE_S) -> str | None:
    """Why this stack's processes could not meet on the rendezvous endpoint, or None.

    Only when the port was held before the launch (``claim``): the launcher's session, opened with
    the stack's credentials, must then be linked to the holder within ``wait_s``. ``bus``: the
    launcher's (a ``ZenohBus``; any other transport has no rendezvous)."""
    if not auth.port_held or not isinstance(bus, ZenohBus):
        return None
    info = bus.session.info
    deadline = time.monotonic() + wait_s
    while True:
        if list(info.peers_zid()) or list(info.routers_zid()):
            return None
        if time.monotonic() >= deadline:
            break
        time.sleep(0.1)
    port = _port(auth.rendezvous)
    holder = port_holder(port) if port is not None else None
    who = (f"process {holder[0]} ({holder[1]})" if holder is not None
           else "a process this user cannot see")
    return (f"the rendezvous endpoint {auth.rendezvous} is held by {who}, which did not accept this "
            f"stack's credentials within {wait_s:g} s: a Zenoh session without them, or a stack "
            f"registered in another stacks folder (${stacks.ENV_STACKS_DIR} or $XDG_RUNTIME_DIR "
            f"differ; this one is {stacks.stacks_dir()}). No process of this stack could link. Stop "
            f"it, or start this stack on another port, e.g. SEAWAY_ZENOH_RENDEZVOUS=tcp/127.0.0.1:7450")
