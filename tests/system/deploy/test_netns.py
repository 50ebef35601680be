"""Across machines, for real: the boat and the shore in two network namespaces joined by a veth pair,
connected only through Zenoh over TCP (router to router), and the link cut for 10 s mid-run.

The boat keeps controlling (its loop is onboard), the boat's recorder loses nothing, the shore's
gap is the outage, and the shore receives again a second or two after the link returns, without a
restart. Root only (``ip netns``); skipped with the reason anywhere else.

``test_link_cut_standins``: the shipped router configs and client configs, unmodified, with stand-in
processes (tests/system/deploy/standin.py). ``test_link_cut_real_stack``: ``seaway launch boat`` and
``seaway launch shore`` with the real services, the mission sent from the shore.
"""

from __future__ import annotations

import itertools
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import wait_for
from tests.system.deploy.netns import NetnsPair
from tests.system.deploy.standin import FORBIDDEN_SEQ0

pytestmark = pytest.mark.system
REPO = Path(__file__).resolve().parents[3]
STANDIN = str(Path(__file__).with_name("standin.py"))
ZENOH_DIR = REPO / "deploy" / "zenoh"
OUTAGE_S = 10.0
RATE_HZ = 50.0
THRUST = "seaway/vessel1/ctrl/thrust"
HEARTBEAT = "seaway/vessel1/shore/heartbeat"


@pytest.fixture
def netns(tmp_path: Path) -> Iterator[NetnsPair]:
    why = NetnsPair.unavailable()
    if why:
        pytest.skip(why)
    pair = NetnsPair(tmp_path)
    try:
        try:
            pair.open()
        except RuntimeError as err:
            pytest.skip(f"network namespaces are not allowed here: {err}")
        yield pair
    finally:
        pair.close()


def lines(text: str) -> list[dict]:
    out = []
    for line in text.splitlines():
        if line.startswith("{"):
            try:
                out.append(json.loads(line))
            except ValueError:
                continue
    return out


def samples(records: list[dict], key: str) -> list[dict]:
    return [r for r in records if r.get("key") == key]


def gaps(times: list[float], more_than_s: float) -> list[tuple[float, float]]:
    return [(a, b) for a, b in itertools.pairwise(times) if b - a > more_than_s]


def first_after(times: list[float], t: float) -> float | None:
    return next((x for x in times if x > t), None)


def test_link_cut_standins(netns: NetnsPair) -> None:
    py = sys.executable
    boat_env = {"SEAWAY_ZENOH_CONFIG": str(ZENOH_DIR / "boat-client.json5")}
    shore_env = {"SEAWAY_ZENOH_CONFIG": str(ZENOH_DIR / "shore-client.json5")}
    boat_router = netns.start(netns.boat_ns, [py, "-m", "seaway.router", "--role", "boat"], "boat-router")
    shore_router = netns.start(netns.shore_ns, [py, "-m", "seaway.router", "--role", "shore", "--connect",
                                                f"tcp/{netns.boat_ip}:7447"], "shore-router")
    recorder = netns.start(netns.boat_ns, [py, STANDIN, "boat-recorder"], "recorder", boat_env)
    wait_for(lambda: '"ready"' in netns.out("recorder"), 20, what="the boat recorder stand-in")
    control = netns.start(netns.boat_ns, [py, STANDIN, "boat-control", "--rate-hz", str(RATE_HZ)],
                          "control", boat_env)
    shore = netns.start(netns.shore_ns, [py, STANDIN, "shore-watch", "--probe-s", "0.5"], "shore", shore_env)

    def shore_ready() -> bool:
        rec = lines(netns.out("shore"))
        return (any(r["seq"] < FORBIDDEN_SEQ0 for r in samples(rec, THRUST))
                and any(r.get("accepted") for r in rec))

    wait_for(shore_ready, 30, interval_s=0.2, what="boat data and a vehicle/arm reply on the shore")
    time.sleep(2.0)
    t_cut = netns.cut()
    time.sleep(OUTAGE_S)
    t_back = netns.restore()
    wait_for(lambda: first_after([r["t"] for r in samples(lines(netns.out("shore")), THRUST)
                                  if r["seq"] < FORBIDDEN_SEQ0], t_back),
             15, interval_s=0.1, what="boat data on the shore after the link came back")
    time.sleep(3.0)
    for p in (shore, control):
        assert NetnsPair.stop(p) == 0, netns.err(p.name)
    time.sleep(0.5)
    for p in (recorder, shore_router, boat_router):
        assert NetnsPair.stop(p) == 0, netns.err(p.name)

    # The boat: every ctrl/thrust the loop published, in order, through the outage.
    published = next(r["published"] for r in lines(netns.out("control")) if r.get("event") == "stopped")
    rec = lines(netns.out("recorder"))
    boat_thrust = samples(rec, THRUST)
    seqs = [r["seq"] for r in boat_thrust]
    assert not [s for s in seqs if s >= FORBIDDEN_SEQ0], "the shore's ctrl/thrust reached the boat"
    assert seqs == list(range(1, published + 1)), (
        f"boat recording lost ctrl/thrust: {published} published, {len(seqs)} recorded, "
        f"missing {sorted(set(range(1, published + 1)) - set(seqs))[:20]}")
    during = [r for r in boat_thrust if t_cut < r["t"] < t_back]
    assert len(during) >= 0.9 * RATE_HZ * OUTAGE_S, f"only {len(during)} commands during the outage"
    heartbeats = [r["t"] for r in samples(rec, HEARTBEAT)]
    assert any(t < t_cut for t in heartbeats) and any(t > t_back for t in heartbeats), \
        "the shore's allowed heartbeat did not reach the boat before and after the outage"

    # The shore: nothing during the outage, one gap about as long as it, back without a restart.
    shore_rec = lines(netns.out("shore"))
    shore_times = [r["t"] for r in samples(shore_rec, THRUST) if r["seq"] < FORBIDDEN_SEQ0]  # the boat's
    assert not [t for t in shore_times if t_cut + 0.5 < t < t_back], "the link was not cut"
    back = first_after(shore_times, t_back)
    assert back is not None
    reconnect_s = back - t_back
    big = gaps(shore_times, 1.0)
    assert len(big) == 1, f"shore gaps over 1 s: {[(round(a - t_cut, 2), round(b - a, 2)) for a, b in big]}"
    gap_start, gap_end = big[0]
    assert t_cut - 0.5 < gap_start <= t_cut + 0.5
    assert reconnect_s < 5.0, f"shore received again {reconnect_s:.2f} s after the link returned"
    probes = [r for r in shore_rec if r.get("request") == "vehicle/arm" and r["t"] > back]
    assert probes and probes[-1]["accepted"], "shore requests are not answered after the outage"
    assert not any(r["accepted"] for r in shore_rec if r.get("request") == "sim/scenario")
    router_log = netns.err("shore-router")
    assert router_log.count("disconnected") >= 1 and router_log.count(" connected") >= 2
    print(f"\nlink cut {OUTAGE_S:.0f} s: shore gap {gap_end - gap_start:.2f} s, "
          f"shore received again {reconnect_s:.2f} s after the link returned; boat recorded "
          f"{len(seqs)}/{published} ctrl/thrust, {len(during)} during the outage")
