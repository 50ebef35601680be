"""Two Linux network namespaces joined by a veth pair: a boat computer and a shore computer.

Each namespace has only loopback and its end of the veth, addressed in a private /30 of
10.231.0.0/16 chosen at random per run; the link can be cut (``ip link set ... down`` on the boat's
end) and restored. Names carry a per-run id, so parallel runs never meet, and ``close()`` kills
every process started in the namespaces, then deletes both (which destroys the veth pair), even
after a failure. Needs root; ``NetnsPair.unavailable()`` says why it cannot run here, or None.
"""

from __future__ import annotations

import contextlib
import os
import random
import shutil
import signal
import subprocess
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20, check=check)


class NetnsPair:
    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.id = f"{os.getpid() % 10000:04d}{random.randrange(1000):03d}"
        self.boat_ns, self.shore_ns = f"swb-{self.id}", f"sws-{self.id}"
        self.boat_if, self.shore_if = f"swb{self.id}", f"sws{self.id}"  # <= 15 characters
        net = random.randrange(256)
        base = random.randrange(0, 256, 4)
        self.boat_ip, self.shore_ip = f"10.231.{net}.{base + 1}", f"10.231.{net}.{base + 2}"
        self.procs: list[subprocess.Popen] = []
        self.created: list[str] = []

    @staticmethod
    def unavailable() -> str | None:
        if os.geteuid() != 0:
            return "needs root to create network namespaces (ip netns)"
        if shutil.which("ip") is None:
            return "the ip command (iproute2) is not installed"
        return None

    def open(self) -> None:
        """Create both namespaces and the link. Raises RuntimeError saying what the system refused."""
        for ns in (self.boat_ns, self.shore_ns):
            r = _ip("netns", "add", ns, check=False)
            if r.returncode != 0:
                raise RuntimeError(f"ip netns add {ns}: {r.stderr.strip()}")
            self.created.append(ns)
        steps = [
            ("link", "add", self.boat_if, "type", "veth", "peer", "name", self.shore_if),
            ("link", "set", self.boat_if, "netns", self.boat_ns),
            ("link", "set", self.shore_if, "netns", self.shore_ns),
            ("-n", self.boat_ns, "addr", "add", f"{self.boat_ip}/30", "dev", self.boat_if),
            ("-n", self.shore_ns, "addr", "add", f"{self.shore_ip}/30", "dev", self.shore_if),
            ("-n", self.boat_ns, "link", "set", "lo", "up"),
            ("-n", self.shore_ns, "link", "set", "lo", "up"),
            ("-n", self.boat_ns, "link", "set", self.boat_if, "up"),
            ("-n", self.shore_ns, "link", "set", self.shore_if, "up"),
        ]
        for step in steps:
            r = _ip(*step, check=False)
            if r.returncode != 0:
                raise RuntimeError(f"ip {' '.join(step)}: {r.stderr.strip()}")
        ping = subprocess.run(["ip", "netns", "exec", self.shore_ns, "ping", "-c", "1", "-W", "2",
                               self.boat_ip], capture_output=True, text=True, timeout=10)
        if ping.returncode != 0 and shutil.which("ping"):
            raise RuntimeError(f"the veth link does not carry traffic: {ping.stdout}{ping.stderr}")

    def start(self, ns: str, args: list[str], name: str, env: dict[str, str] | None = None,
              ) -> subprocess.Popen:
        """Run ``args`` inside ``ns``; stdout to ``<name>.out``, stderr to ``<name>.err``."""
        # Nothing of the caller's own stack leaks in: each side says what it runs with in ``env``.
        inherited = {k: v for k, v in os.environ.items()
                     if not k.startswith(("SEAWAY_ZENOH_", "SEAWAY_ROUTER_", "SEAWAY_CREDENTIALS",
                                          "SEAWAY_IDENTITY", "SEAWAY_STACKS_DIR"))}
        full_env = {**inherited, "PYTHONUNBUFFERED": "1", **(env or {})}
        out = open(self.tmp / f"{name}.out", "wb")  # noqa: SIM115 - closed with the process
        err = open(self.tmp / f"{name}.err", "wb")  # noqa: SIM115
        p = subprocess.Popen(["ip", "netns", "exec", ns, *args], stdout=out, stderr=err, env=full_env,
                             cwd=REPO, start_new_session=True)
        p.name = name  # type: ignore[attr-defined]
        self.procs.append(p)
        return p

    def out(self, name: str) -> str:
        return (self.tmp / f"{name}.out").read_text(errors="replace")

    def err(self, name: str) -> str:
        return (self.tmp / f"{name}.err").read_text(errors="replace")

    def cut(self) -> float:
        """Take the boat's end of the link down; returns time.monotonic() just after."""
        _ip("-n", self.boat_ns, "link", "set", self.boat_if, "down")
        return time.monotonic()

    def restore(self) -> float:
        _ip("-n", self.boat_ns, "link", "set", self.boat_if, "up")
        return time.monotonic()

    @staticmethod
    def stop(p: subprocess.Popen, sig: int = signal.SIGINT, timeout_s: float = 10.0) -> int:
        if p.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, sig)
            try:
                p.wait(timeout_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):  # Python's faulthandler, if registered
                    os.killpg(p.pid, signal.SIGUSR1)
                time.sleep(0.5)
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)
        return p.returncode

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    p.wait(5)
        for ns in self.created:
            # every process in the namespace, even one a test lost track of
            r = _ip("netns", "pids", ns, check=False)
            for pid in r.stdout.split():
                with contextlib.suppress(ProcessLookupError, ValueError):
                    os.kill(int(pid), signal.SIGKILL)
            _ip("netns", "del", ns, check=False)
        # the veth pair dies with its namespace; if it never got there, remove it here
        _ip("link", "del", self.boat_if, check=False)
