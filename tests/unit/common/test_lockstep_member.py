"""A lockstep member's sources (``seaway.runtime.lockstep_member.Member``): active ones move it on as their
bundles arrive, passive ones are taken with them (nothing runs for those on arrival), and a service
that answers on the bus's thread (``on_ready``) is not woken for what it has already done. On the
in-memory bus: pure logic, no network."""

from __future__ import annotations

import threading
from pathlib import Path

from seaway.contract import bundle, keys
from seaway.contract.messages import PeriodDone, ThrustCommand
from seaway.runtime import timeline
from seaway.runtime.lockstep import KEPT_PERIODS, Period
from seaway.runtime.lockstep_member import KEPT_BUNDLES, Member
from seaway.runtime.memory_bus import MemoryHub

P = 100_000_000
V = "vessel1"


def cmd(stamp_ns: int) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=stamp_ns, thrust_port_n=1.0, thrust_starboard_n=1.0, seq=1)


def test_a_passive_bundle_waits_for_the_next_active_one_and_is_taken_first() -> None:
    """The estimator: the controller's bundle (the command the sim will apply) is only taken when
    the sim's next bundle comes, and before it, so the sim's tick finds the command it lists."""
    hub = MemoryHub()
    taken: list[tuple[str, int]] = []
    est = Member(hub.bus(V), "estimator", watched={"ctrl/thrust"}, hears=("sim", "controller"),
                 passive=("controller",))
    est.deliver = lambda key, msg: (taken.append((key.rsplit("/", 2)[-2], msg.stamp_ns)),
                                    est.saw(keys.THRUST.suffix, msg.stamp_ns))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P)
    ctl.answer(Period(0, 0), P, [(keys.THRUST, cmd(0))])
    assert taken == [] and "controller" not in est.ledger.answers  # held by the transport
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [0]})
    assert taken == [("ctrl", 0)]
    tick = est.ledger.answer("sim")
    assert tick is not None and tick.stamp_ns == P and est.ledger.complete(tick)
    assert not est.expecting()


def test_a_member_knows_when_a_passive_bundle_is_due_and_its_loop_finds_it() -> None:
    """The controller: the estimator's answer for t_1 came before the sim's bundle for t_1 (another
    connection): the loop looks again soon, and ``wait`` takes the sim's bundle when it is there."""
    hub = MemoryHub()
    ctl = Member(hub.bus(V), "controller", watched=(), hears=("sim", "estimator"), passive=("sim",))
    sim_bus = hub.bus(V)
    sim = Member(sim_bus, "sim", watched=(), subscribe=False)
    est = Member(hub.bus(V), "estimator", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P)
    est.answer(Period(0, 0), P)
    assert ctl.ledger.period == Period(0, 0) and not ctl.expecting()
    # The estimator's t_1 before the sim's (held back here by sending it after).
    est.answer(Period(0, P), P)
    with ctl.changed:
        assert ctl.ledger.answer("estimator") is None and ctl.expecting()
    sim.answer(Period(0, P), P)  # now in the transport's ring: nothing ran for it
    assert ctl.ledger.period == Period(0, 0)
    ctl.wait(ctl.version, 5.0)  # returns at once: the ring had it
    assert ctl.ledger.period == Period(0, P) and ctl.ledger.answer("estimator") is not None
    with ctl.changed:
        assert not ctl.expecting()


def test_an_inline_service_answers_on_the_bus_thread_and_its_loop_is_not_woken() -> None:
    hub = MemoryHub()
    est = Member(hub.bus(V), "estimator", watched=(), hears=("sim", "controller"),
                 passive=("controller",))
    ready_on: list[str] = []
    est.on_ready = lambda: ready_on.append(threading.current_thread().name)
    woken = threading.Event()

    def loop() -> None:
        with est.changed:
            if est.changed.wait(0.5):
                woken.set()

    waiter = threading.Thread(target=loop, name="loop")
    waiter.start()
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P)
    waiter.join()
    assert ready_on == ["MainThread"]  # the publishing thread: the in-memory bus's "bus thread"
    assert not woken.is_set()
    assert est.ledger.period == Period(0, 0)


def test_a_repeat_sends_the_previous_bundle_again_for_a_recorder_and_only_a_recorder_takes_it() -> None:
    """The recorder may trail by a period (``RECORDER_LAG``): a member repeating its last bundle
    first sends its previous one again, marked ``resent``. A restarted recorder gets both periods it
    can have missed; the other members, and a subscriber of the keys, pass it over."""
    hub = MemoryHub()
    raw: list[tuple[str, bytes]] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_CONTROLLER.key(V), lambda s: raw.append((s.key, s.payload)))
    commands = hub.bus(V).subscribe(keys.THRUST, mode="fifo")
    sim = Member(hub.bus(V), "sim", watched={"ctrl/thrust"})
    got: list[int] = []
    sim.deliver = lambda _key, msg: got.append(msg.stamp_ns)
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    for k in (0, 1):
        ctl.answer(Period(0, k * P), P, [(keys.THRUST, cmd(k * P))])
    assert got == [0, P] and [c.stamp_ns for c in commands.drain()] == [0, P]
    raw.clear()
    ctl.repeat()
    answers = [PeriodDone.decode(p) for _, p in raw]
    assert [(a.stamp_ns, a.resent) for a in answers] == [(0, True), (P, False)]
    assert bundle.unpack(raw[0][0], raw[0][1])[0][1] == cmd(0).encode()  # with its messages
    assert got == [0, P, P]  # the sim took the repeat, not the copy
    assert [c.stamp_ns for c in commands.drain()] == [P]
    assert sim.ledger.answers["controller"].stamp_ns == P


def test_a_restarted_member_takes_what_it_lacks_from_a_copy_for_the_recorder() -> None:
    """The estimator was killed in the middle of its put for t_1: the controller had its answer and
    answered t_1, the sim had not. The sim repeats t_1, whose ``consumed`` names the command of
    t_0; the controller repeats its t_1 and sends its t_0 again only as a copy for a recorder. The
    restarted estimator takes that command from the copy (it lacks it), and nothing else."""
    hub = MemoryHub()
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    for k in (0, 1):
        ctl.answer(Period(0, k * P), P, [(keys.THRUST, cmd(k * P))])
    taken: list[int] = []
    est = Member(hub.bus(V), "estimator", watched={"ctrl/thrust"}, hears=("sim", "controller"),
                 passive=("controller",))  # the restarted one: it heard none of that
    est.deliver = lambda key, msg: (taken.append(msg.stamp_ns),
                                    est.saw(keys.THRUST.suffix, msg.stamp_ns))
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [0]})
    tick = est.ledger.answer("sim")
    assert tick is not None and not est.ledger.complete(tick)
    ctl.repeat()
    est.drain()
    assert taken == [0, P]  # t_0's command from the copy, then the repeat's own, as always
    assert est.ledger.complete(tick)
    assert est.ledger.answers["controller"].stamp_ns == P and not est.ledger.answers["controller"].resent


def test_a_command_whose_sender_died_putting_it_is_taken_as_lost_after_a_while(caplog) -> None:
    """The controller was killed in the middle of its put for t_0: the sim had its command and
    applied it, the estimator never heard it, and no living member holds it. The estimator waits
    (the sim repeats t_1) for ``GIVE_UP_LACKING_S``, then takes that command as lost, says so, and
    can answer; before, it waited for ever and the run hung (the restarted controller waiting for
    it in turn)."""
    from seaway.runtime.lockstep_member import GIVE_UP_LACKING_S

    now = [0]
    hub = MemoryHub()
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    est = Member(hub.bus(V), "estimator", watched={"ctrl/thrust"}, hears=("sim", "controller"),
                 passive=("controller",), clock=lambda: now[0])
    est.deliver = lambda key, msg: est.saw(keys.THRUST.suffix, msg.stamp_ns)
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [0]})
    for t_s in (2.0, 4.0, GIVE_UP_LACKING_S):  # the sim repeats its stalled period
        now[0] = round(t_s * 1e9)
        sim.repeat()
        assert not est.ledger.complete(est.ledger.answer("sim")) and est.given_up == []
    now[0] = round((GIVE_UP_LACKING_S + 2.0) * 1e9)
    sim.repeat()
    assert est.given_up == [(keys.THRUST.suffix, 0)]
    assert est.ledger.complete(est.ledger.answer("sim"))
    assert any("taken as lost" in r.getMessage() for r in caplog.records if r.levelname == "WARNING")


def test_a_command_that_comes_late_is_not_given_up_on() -> None:
    """A command that arrives while the sim repeats is taken as always, and nothing is lost."""
    now = [0]
    hub = MemoryHub()
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    est = Member(hub.bus(V), "estimator", watched={"ctrl/thrust"}, hears=("sim", "controller"),
                 passive=("controller",), clock=lambda: now[0])
    est.deliver = lambda key, msg: est.saw(keys.THRUST.suffix, msg.stamp_ns)
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [0]})
    now[0] = 2 * 10**9
    sim.repeat()
    ctl.answer(Period(0, 0), P, [(keys.THRUST, cmd(0))])
    now[0] = 30 * 10**9
    sim.repeat()
    assert est.given_up == [] and est.ledger.complete(est.ledger.answer("sim"))


def test_a_repeat_sends_every_bundle_a_recorder_can_lack_once_more() -> None:
    """A held period is answered again for a mission taken there: a recorder killed after covering
    the first answer lacked the mission's acceptance, and the sim went on two periods without it
    (it may trail by ``RECORDER_LAG``). A repeat sends every bundle of the last ``KEPT_PERIODS``
    periods again, in the order sent, marked ``resent``, then the last one; older ones are gone."""
    hub = MemoryHub()
    raw: list[bytes] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_CONTROLLER.key(V), lambda s: raw.append(s.payload))
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    ctl.answer(Period(0, 0), P, [(keys.THRUST, cmd(0))])
    ctl.answer(Period(0, P), P, hold=True)  # nothing to fly
    news = ThrustCommand.make(stamp_ns=P, thrust_port_n=0.0, thrust_starboard_n=0.0, seq=2)
    ctl.answer(Period(0, P), P, [(keys.THRUST, news)], hold=True)  # again: a mission taken there
    for k in (1, 2, 3):
        ctl.answer(Period(0, k * P), P, [(keys.THRUST, cmd(k * P))])
    assert KEPT_PERIODS == 3
    raw.clear()
    ctl.repeat()
    sent = [(PeriodDone.decode(a), lines) for a, lines in map(bundle.split, raw)]
    assert [(a.stamp_ns // P, a.hold, a.resent) for a, _ in sent] == [
        (1, True, True), (1, True, True), (1, False, True), (2, False, True), (3, False, False)]
    assert [lines for _, lines in sent[:3]] == [[], [("ctrl/thrust", news.encode())],
                                                [("ctrl/thrust", cmd(P).encode())]]
    assert ctl.last_answer is not None and not ctl.last_answer.resent
    # The repeat stands for the last one: the next repeat sends the same five, no copy of a copy.
    raw.clear()
    ctl.repeat()
    assert len(raw) == 5


def test_a_member_keeps_no_more_than_kept_bundles(caplog) -> None:
    hub = MemoryHub()
    raw: list[bytes] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_CONTROLLER.key(V), lambda s: raw.append(s.payload))
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    for seq in range(KEPT_BUNDLES + 5):  # a held period answered again and again
        ctl.answer(Period(0, P), P, [(keys.THRUST, ThrustCommand.make(
            stamp_ns=P, thrust_port_n=0.0, thrust_starboard_n=0.0, seq=seq + 1))], hold=True)
    raw.clear()
    ctl.repeat()
    # The newest ones, the oldest dropped: a repeat fits a link's queue (zenoh_bus.LOCKSTEP_TX_QUEUE).
    seqs = [ThrustCommand.decode(bundle.split(p)[1][0][1]).seq for p in raw]
    assert seqs == list(range(6, KEPT_BUNDLES + 6))
    assert "controller sent more than 7 bundles in 3 periods" in caplog.text  # messages lost


def test_answers_alone_dropped_from_the_kept_ones_are_no_warning(caplog) -> None:
    """The recorder answers its first period again as each member joins (a test of a normal run
    found its warning): its bundles are answers alone, and a restarted recorder misses nothing."""
    hub = MemoryHub()
    rec = Member(hub.bus(V), "recorder", watched=(), subscribe=False)
    for _ in range(KEPT_BUNDLES + 3):
        rec.answer(Period(0, 0), P)
    assert len(rec._kept) == KEPT_BUNDLES
    assert "more than" not in caplog.text


def test_after_a_sim_restart_nothing_of_the_dead_sims_time_is_sent_again() -> None:
    """The sim died at t_1 and started again at t_0 of the same episode number: the member's t_0
    of the dead run is stamped as the new t_0 (``leads_to`` cannot tell them apart), so a restart
    forgets every bundle kept; a repeat then sends the new answer alone."""
    hub = MemoryHub()
    raw: list[bytes] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_CONTROLLER.key(V), lambda s: raw.append(s.payload))
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    for k in (0, 1):
        ctl.answer(Period(0, k * P), P, [(keys.THRUST, cmd(k * P))])
    fresh = ThrustCommand.make(stamp_ns=0, thrust_port_n=2.0, thrust_starboard_n=2.0, seq=9)
    ctl.answer(Period(0, 0), P, [(keys.THRUST, fresh)])  # the restarted sim's t_0
    raw.clear()
    ctl.repeat()
    assert [bundle.split(p)[1] for p in raw] == [[("ctrl/thrust", fresh.encode())]]


def test_the_estimators_first_answer_of_an_episode_before_the_sims_moves_the_controller_on() -> None:
    """The CI failure of test_lockstep_restarts' back-to-back missions: after a scenario restart
    the estimator's t_0 reached the controller before the sim's (its passive source). The sim's,
    taken next, restarted the ledger and forgot the estimator's answer: no answer for 2 s, until
    the sim repeated t_0 for the stall."""
    hub = MemoryHub()
    ctl = Member(hub.bus(V), "controller", watched=(), hears=("sim", "estimator"), passive=("sim",))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    est = Member(hub.bus(V), "estimator", watched=(), subscribe=False)
    sim.answer(Period(0, 342 * P), P)
    est.answer(Period(0, 342 * P), P)
    assert ctl.ledger.answer("estimator") is not None
    est.answer(Period(1, 0), P)  # the new episode's, on its way before the sim's
    sim.answer(Period(1, 0), P)  # in the ring
    ctl.wait(ctl.version, 5.0)
    assert ctl.ledger.period == Period(1, 0)
    assert ctl.ledger.answer("estimator") is not None and ctl.restarts == [(Period(0, 342 * P),
                                                                            Period(1, 0))]


def test_a_member_does_not_repeat_an_answer_of_an_earlier_episode() -> None:
    """The sim repeats the new episode's t_0 (a newcomer, a stall) before a member has answered
    it: that member's last answer is of the old episode, of no use to anyone now, and a recorder
    took its messages as the new episode's. It repeats nothing; in its own episode it does."""
    hub = MemoryHub()
    raw: list[PeriodDone] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_CONTROLLER.key(V),
                             lambda s: raw.append(PeriodDone.decode(bundle.split(s.payload)[0])))
    ctl = Member(hub.bus(V), "controller", watched=(), hears=("sim",))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    for k in (341, 342):
        sim.answer(Period(0, k * P), P)
        ctl.answer(Period(0, k * P), P, [(keys.THRUST, cmd(k * P))])
    sim.answer(Period(0, 342 * P), P)  # a repeat in the episode: the last two again
    assert [(a.stamp_ns, a.resent) for a in raw[2:]] == [(341 * P, True), (342 * P, False)]
    del raw[:]
    for episode, k in ((1, 0), (1, 0), (0, 0), (0, 0)):  # a scenario restart; a restarted sim
        sim.answer(Period(episode, k), P)
    assert raw == [] and ctl.repeats == 1
    # Once it has answered the restarted sim's t_0, a repeat of it sends that answer alone, not the
    # dead sim's last one (episode 0 too) as a ``resent`` copy: a recorder would write it again,
    # in the new episode's time.
    ctl.answer(Period(0, 0), P, [(keys.THRUST, cmd(0))])
    sim.answer(Period(0, 0), P)
    assert [(a.episode, a.stamp_ns, a.resent) for a in raw[1:]] == [(0, 0, False)]


def test_a_bundle_that_does_not_read_is_counted_and_the_next_one_is_taken() -> None:
    hub = MemoryHub()
    est = Member(hub.bus(V), "estimator", watched={"sensors/attitude"}, hears=("sim",))
    raw = hub.bus(V).raw_publisher(keys.LOCKSTEP_SIM.key(V), bundle.ENCODING)
    raw.put(b'{"stamp_ns": 0}\n["sensors/attitude",{"stamp_ns": 0}')  # framing: no closing bracket
    raw.put(b'{"stamp_ns": "soon"}')  # an answer that does not validate
    assert est.bus.stats.malformed == 2 and est.ledger.period is None
    Member(hub.bus(V), "sim", watched=(), subscribe=False).answer(Period(0, 0), P)
    assert est.ledger.period == Period(0, 0)


def test_an_active_bundle_marks_its_arrival_before_its_intake_a_passive_one_only_its_intake(
        tmp_path: Path) -> None:
    """The bench's split of a hand-over (``seaway bench lockstep``): ``arrived`` when Zenoh hands an
    active source's bundle over, ``heard`` once it is taken; a passive source's bundle sat in a ring,
    so only its ``heard`` is noted (an arrival there would time the ring, not the transport)."""
    hub = MemoryHub()
    est = Member(hub.bus(V), "estimator", watched={"ctrl/thrust"}, hears=("sim", "controller"),
                 passive=("controller",))
    est.timeline = timeline.Timeline("estimator", tmp_path)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    ctl.answer(Period(0, 0), P, [(keys.THRUST, cmd(0))])
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [0]})
    got = [(what, of, stamp) for _, what, of, stamp in est.timeline.marks or []]
    assert got == [("heard", "controller", 0), ("arrived", "sim", P), ("heard", "sim", P)]
    t = {(what, of): t_ns for t_ns, what, of, _ in est.timeline.marks or []}
    assert t[("arrived", "sim")] <= t[("heard", "controller")] <= t[("heard", "sim")]


def test_in_one_process_the_chain_answers_within_the_sims_put_and_wakes_no_loop() -> None:
    """Composed (every member on one hub, answering on arrival): the sim's put runs the estimator
    and then the controller on the sim's own thread, the controller finding the sim's bundle in its
    (passive) ring before the estimator's answer comes, so no member's loop needs to look."""
    from seaway.runtime.node import Answer, MemberDriver, MemberSpec, Node

    class Echo(Node):
        def __init__(self, spec: MemberSpec) -> None:
            self.name, self.member = spec.service, spec

        def answer(self, at):  # type: ignore[no-untyped-def]
            return Answer([(keys.THRUST, cmd(at.period.stamp_ns))] if self.name == "controller"
                          else [])

    hub = MemoryHub()
    est = MemberDriver(hub.bus(V), Echo(MemberSpec("estimator", needs=("sim",),
                                                   inputs=frozenset(), hears=("sim",))))
    ctl = MemberDriver(hub.bus(V), Echo(MemberSpec("controller", needs=("sim", "estimator"),
                                                   inputs=frozenset(), hears=("sim", "estimator"),
                                                   passive=("sim",))))
    # The estimator subscribed first: it is handed the sim's bundle before the controller's ring.
    est.answer_on_arrival()
    ctl.answer_on_arrival()
    sim = Member(hub.bus(V), "sim", watched={keys.THRUST.suffix}, passive=("estimator",))
    commands: list[int] = []
    sim.deliver = lambda _key, msg: commands.append(msg.stamp_ns)
    for k in range(3):
        sim.answer(Period(0, k * P), P, members=["controller", "estimator"])
        assert commands == [i * P for i in range(k + 1)]  # before the put returned
        with ctl.member.changed:
            assert not ctl.member.expecting()  # nothing for its loop to look for


def test_an_active_answer_that_lists_what_a_passive_source_sends_makes_the_loop_look() -> None:
    """The estimator: the sim's answer (its active source) names the command it applied, which
    comes in the controller's bundle (a passive source) not yet there: its loop must look for
    it (else it waits for the next wake-up, a tenth of a second, every period)."""
    hub = MemoryHub()
    est = Member(hub.bus(V), "estimator", watched={keys.THRUST.suffix}, hears=("sim", "controller"),
                 passive=("controller",))
    est.deliver = lambda _key, msg: est.saw(keys.THRUST.suffix, msg.stamp_ns)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    ctl = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P)
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [0]})
    with est.changed:
        assert est.expecting()
    ctl.answer(Period(0, 0), P, [(keys.THRUST, cmd(0))])
    est.drain()
    with est.changed:
        assert not est.expecting()
