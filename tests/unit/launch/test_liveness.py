"""The launcher's hang detection (``seaway.tools.launch.liveness``): samples and time in, who is
overdue out. No processes, no clock: every time is given."""

from __future__ import annotations

import collections
import random
import re

import pytest
from seaway.contract.config import ConfigError, parse_config
from seaway.tools.launch.liveness import (
    DUTIES,
    LOCKSTEP_WITHIN_S,
    RECENT_PERIODS,
    Duty,
    Watch,
    _Recent,
    duties_for,
)
from seaway.tools.launch.profile import Profile, load_profile

SIM, EST, CTL, REC = "lockstep/sim", "lockstep/estimator", "lockstep/controller", "lockstep/recorder"
W = LOCKSTEP_WITHIN_S


def lockstep_watch() -> Watch:
    w = Watch()
    for process, service in (("sim", "sim"), ("est", "estimator"), ("ctl", "controller"),
                             ("rec", "recorder")):
        w.arm(process, duties_for(service, "lockstep"), 0.0)
    return w


def period(w: Watch, t: float, k: int, *, hold: bool = False, episode: int = 0,
           skip: tuple[str, ...] = ()) -> None:
    """One lockstep period k heard in protocol order at time t (``skip``: who does not answer)."""
    p = (episode, k * 100_000_000)
    for suffix in (SIM, EST, CTL, REC):
        if suffix not in skip:
            w.heard(suffix, t, p, hold=hold and suffix == CTL)


def test_a_stream_counts_from_its_first_sample_and_is_overdue_after_its_time() -> None:
    w = Watch()
    w.arm("ctl", (Duty(key="ctrl/thrust", within_s=5.0),), 0.0)
    assert w.overdue(100.0) == {}  # never published since its start: nothing to miss yet
    w.heard("ctrl/thrust", 10.0)
    assert w.overdue(14.9) == {}
    (why,) = w.overdue(15.1).values()
    assert why.startswith("published no ctrl/thrust for 5.1 s")
    w.heard("ctrl/thrust", 15.2)
    assert w.overdue(16.0) == {}
    w.disarm("ctl")
    assert w.overdue(1000.0) == {}


def test_lockstep_members_answer_each_period_in_chain() -> None:
    w = lockstep_watch()
    for k in range(5):
        period(w, float(k), k)
    assert w.overdue(4.5) == {}
    # The estimator stops answering: it alone is overdue (the others have nothing to answer yet).
    period(w, 10.0, 5, skip=(EST, CTL, REC))
    assert w.overdue(10.0 + W - 0.1) == {}
    late = w.overdue(10.0 + W + 0.1)
    assert set(late) == {"est"} and "no lockstep/estimator for period 0.500 s" in late["est"]


def test_a_hold_stops_time_without_anybody_being_overdue() -> None:
    w = lockstep_watch()
    period(w, 0.0, 0)
    period(w, 1.0, 1, hold=True)  # nothing to fly: the sim does not move on, and need not
    assert w.overdue(1.0 + 10 * W) == {}
    # A mission: the controller answers the held period again (no hold): now the sim must move on.
    w.heard(CTL, 500.0, (0, 100_000_000))
    assert w.overdue(500.0 + W - 0.1) == {}
    assert "sim" in w.overdue(500.0 + W + 0.1)
    w.heard(SIM, 500.0 + W + 0.2, (0, 200_000_000))
    assert w.overdue(500.0 + W + 0.3) == {}


def test_a_stalled_sim_repeating_its_period_is_not_hung() -> None:
    w = lockstep_watch()
    period(w, 0.0, 0)
    period(w, 1.0, 1, skip=(REC,))  # the recorder is not answering: the sim waits, and repeats
    for i in range(1, 40):
        w.heard(SIM, 1.0 + 2.0 * i, (0, 100_000_000))
        w.heard(EST, 1.0 + 2.0 * i, (0, 100_000_000))
        w.heard(CTL, 1.0 + 2.0 * i, (0, 100_000_000))
    assert set(w.overdue(80.0)) == {"rec"}


def test_a_repeat_heard_after_the_answer_it_would_need_is_met() -> None:
    """On a repeat every member repeats its answer, in no particular order across members: the
    controller's may arrive before the estimator's it follows; it still answers that period."""
    w = lockstep_watch()
    period(w, 0.0, 3)
    w.heard(SIM, 1.0, (0, 300_000_000))
    w.heard(CTL, 1.0, (0, 300_000_000), hold=True)
    w.heard(REC, 1.0, (0, 300_000_000))
    w.heard(EST, 1.1, (0, 300_000_000))  # after the controller's repeat
    assert w.overdue(1.0 + 10 * W) == {}


def test_a_member_that_skips_ahead_meets_the_periods_it_skipped() -> None:
    w = lockstep_watch()
    w.heard(SIM, 0.0, (0, 0))
    w.heard(SIM, 0.1, (0, 100_000_000))  # a fast replay: the estimator answers only the latest
    w.heard(EST, 0.2, (0, 100_000_000))
    assert "est" not in w.overdue(1.0 + W)


def test_a_new_episode_moves_the_sim_on() -> None:
    w = lockstep_watch()
    period(w, 0.0, 50)
    w.heard(SIM, 1.0, (1, 0))  # a scenario load: time back to 0 in episode 1
    assert "sim" not in w.overdue(1.0 + 2 * W)


def test_rearming_a_restarted_process_forgets_its_old_duties() -> None:
    w = lockstep_watch()
    period(w, 0.0, 1, skip=(EST, CTL, REC))
    w.disarm("est")
    w.arm("est", duties_for("estimator", "lockstep"), 5.0)
    assert "est" not in w.overdue(5.0 + W + 1)  # the period before its start is not its debt
    w.heard(SIM, 6.0, (0, 100_000_000))  # the repeat its arrival causes
    assert "est" in w.overdue(6.0 + W + 1)


@pytest.mark.parametrize("ahead", [(0, 2**63 - 1), (10**6, 0), (0, 500 * 100_000_000)])
def test_an_answer_for_a_period_the_sim_never_reaches_makes_nobody_overdue(ahead, caplog) -> None:
    """A controller answer for a period far ahead (a stamp near the int64 end, an episode far on)
    obliges nobody: the recorder keeps answering every period the sim reaches and stays healthy;
    the ignored answer is named in a warning."""
    w = lockstep_watch()
    t = 0.0
    for k in range(400):  # 40 s of a healthy chain, 10 periods a wall second
        t = k * 0.1
        period(w, t, k)
        if k == 5:
            w.heard(CTL, t, ahead)
    assert w.overdue(t) == {}
    assert w.unreached[CTL] == 2  # the recorder's duty and the sim's
    assert "ignoring a lockstep/controller answer for period" in caplog.text


def test_an_answer_heard_before_the_sims_answer_for_its_period_still_counts() -> None:
    """Each key is heard on its own: the controller's answer for t_k can be taken before the sim's
    answer that opened t_k; the recorder still owes t_k once the sim's answer is heard."""
    w = lockstep_watch()
    period(w, 0.0, 0)
    w.heard(EST, 0.1, (0, 100_000_000))
    w.heard(CTL, 0.1, (0, 100_000_000))  # the sim's t_1 not heard yet
    w.heard(SIM, 0.2, (0, 100_000_000))
    late = w.overdue(0.2 + W + 0.1)
    assert set(late) == {"rec", "sim"}
    assert "no lockstep/recorder for period 0.100 s (episode 0)" in late["rec"]
    w.heard(REC, 40.0, (0, 100_000_000))
    w.heard(SIM, 40.0, (0, 200_000_000))
    assert w.overdue(40.1) == {}


def test_the_launcher_hears_the_sim_whenever_it_watches_a_lockstep_answer() -> None:
    assert "lockstep/sim" in Watch.keys_of(duties_for("recorder", "lockstep"))
    assert Watch.keys_of(duties_for("estimator", "wall")) == {"nav/state"}


def test_an_answer_outside_the_contract_is_no_answer_to_the_launcher() -> None:
    import json

    from seaway.contract import bundle
    from seaway.tools.launch.liveness import answer_period

    def raw(**fields) -> bytes:
        return bundle.encode(json.dumps({"service": "controller", "seq": 1, "period_ns": 10**8,
                                         **fields}).encode(), [])

    assert answer_period(raw(episode=0, stamp_ns=2**63 - 1)) == ((0, 2**63 - 1), False)
    for bad in ({"episode": 0, "stamp_ns": 2**63}, {"episode": 0, "stamp_ns": 10**400},
                {"episode": 0, "stamp_ns": -1}, {"episode": -1, "stamp_ns": 0}):
        assert answer_period(raw(**bad)) == (None, False), bad


def test_the_recent_answers_match_a_plain_window_across_restarts() -> None:
    """``_Recent`` answers as the last ``RECENT_PERIODS`` periods walked one by one would: periods
    that climb, repeat, and fall back (a restart, a new episode) so that the latest one is evicted."""
    rng = random.Random(58)
    recent, window = _Recent(), collections.deque(maxlen=RECENT_PERIODS)
    episode, k = 0, 0
    for _ in range(5000):
        roll = rng.random()
        if roll < 0.02:  # a restart: time from 0 again, in the same or a new episode
            episode, k = episode + (roll < 0.01), 0
        elif roll < 0.9:
            k += 1
        p = (episode, k * 100_000_000)
        recent.add(p)
        window.append(p)
        for probe in (p, (episode, (k - 1) * 100_000_000), (episode, (k + 1) * 100_000_000),
                      (max(0, episode - 1), k * 100_000_000), window[0]):
            assert recent.has(probe) == (probe in window), probe
            assert recent.has_after(probe) == any(h > probe for h in window), probe


def test_every_listed_service_and_key_is_real_and_the_default_profiles_agree() -> None:
    for clock in DUTIES.values():
        for service, duties in clock.items():
            assert duties and all(isinstance(d, Duty) for d in duties), service
    for name in ("sim", "sim-batch", "boat", "replay"):
        profile = load_profile(name)  # validates that each process produces what it must publish
        for p in profile.processes:
            assert p.duties(profile.clock) == duties_for(p.service, profile.clock)


@pytest.mark.parametrize(("duty", "message"), [
    ({"key": "ctrl/thrus", "within_s": 1}, "'ctrl/thrus' is not a registered topic"),
    ({"key": "ctrl/thrust", "within_s": 1, "after": "nav/state"}, "pairs lockstep answers"),
    ({"key": "lockstep/sim", "within_s": 1, "moves_on": True}, "moves_on needs 'after'"),
    ({"key": "ctrl/thrust", "within_s": 0}, "within_s"),
    ({"key": "nav/state", "within_s": 1}, "must publish 'nav/state' (must_publish), but does not "
                                          "produce it"),
])
def test_a_bad_must_publish_is_refused_naming_it(duty: dict, message: str) -> None:
    doc = {"name": "t", "processes": [{"name": "ctl", "command": ["x"], "service": "controller",
                                       "must_publish": [duty]}]}
    with pytest.raises(ConfigError, match=re.escape(message)):
        parse_config(doc, Profile, "t.toml")


def test_the_launcher_takes_what_it_heard_in_the_order_it_was_published(tmp_path) -> None:
    # The launcher hears the answers through one ring per key (Bus.ring_raw) and takes them a few
    # times a second, key by key: 200 periods at once, more than the watch remembers. Fed in the
    # order taken, the estimator's answers would come before the sim's that asked for them, and
    # every period but the last 64 would stay open for ever (overdue after LOCKSTEP_WITHIN_S).
    import json

    from seaway.contract import keys
    from seaway.runtime.memory_bus import MemoryBus
    from seaway.tools.launch.profile import BackoffPolicy, ProcessSpec
    from seaway.tools.launch.supervisor import Supervised, Supervisor

    procs = [Supervised(ProcessSpec(name=s, command=["true"], service=s), ["true"], "vessel1")
             for s in ("sim", "estimator", "controller", "recorder")]
    sup = Supervisor(procs, tmp_path, {}, BackoffPolicy(), echo=lambda _line: None, clock="lockstep")
    bus = MemoryBus("vessel1")
    sup.watch_on(bus)
    for name in ("sim", "estimator", "controller", "recorder"):
        sup.watches["vessel1"].arm(name, sup.duties[name], 0.0)
    for service in ("recorder", "controller", "estimator", "sim"):  # the worst order there is
        pub = bus.raw_publisher(keys.lockstep_spec(service).key("vessel1"))
        for k in range(200):
            pub.put(json.dumps({"episode": 0, "stamp_ns": k * 100_000_000,
                                "hold": service == "controller" and k == 199}).encode())
    sim = bus.raw_publisher(keys.LOCKSTEP_SIM.key("vessel1"))
    for bad in (b'{"episode": "x"}', b'{"episode": Infinity, "stamp_ns": 1}', b"[1]", b'"x"',
                b"\xff"):  # no answers, and the launcher's loop goes on
        sim.put(bad)
    assert sup.take_heard(1.0) == 800 and sup.take_heard(1.0) == 0
    assert sup.watches["vessel1"].overdue(1.0 + W + 1.0) == {}
    # A member that stops answering is still seen: the sim's next period, and no estimator.
    bus.raw_publisher(keys.LOCKSTEP_SIM.key("vessel1")).put(
        json.dumps({"episode": 0, "stamp_ns": 200 * 100_000_000}).encode())
    sup.take_heard(2.0)
    assert list(sup.watches["vessel1"].overdue(2.0 + W + 1.0)) == ["estimator"]
