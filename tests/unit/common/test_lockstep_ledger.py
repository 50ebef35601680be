"""The lockstep bookkeeping (``seaway.runtime.lockstep``): pure logic, no bus."""

from __future__ import annotations

from seaway.contract.messages import PeriodDone
from seaway.runtime.lockstep import Ledger, Period, classify
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryHub

P = 100_000_000


def answer(service: str, k: int, episode: int = 0, seq: int = 1, **kw) -> PeriodDone:
    return PeriodDone(stamp_ns=k * P, service=service, episode=episode, seq=seq, period_ns=P, **kw)


def test_classify_orders_periods_and_sees_restarts() -> None:
    now = Period(0, 5 * P)
    assert classify(None, now) == "first"
    assert classify(now, Period(0, 6 * P)) == "next"
    assert classify(now, Period(0, 5 * P)) == "repeat"
    assert classify(now, Period(0, 0)) == "restart"  # a restarted sim: time went back
    assert classify(now, Period(1, 9 * P)) == "restart"  # a new episode, even if later
    # One stretch of time: the same episode, not later (a restarted sim is episode 0 again).
    assert Period(0, 4 * P).leads_to(now) and now.leads_to(now)
    assert not Period(0, 6 * P).leads_to(now) and not Period(0, 0).leads_to(Period(1, 9 * P))


def test_an_answer_is_complete_once_every_listed_message_on_a_watched_key_was_seen() -> None:
    ledger = Ledger(watched={"sensors/gnss", "ctrl/thrust"})
    tick = answer("sim", 3, published={"sensors/gnss": [3 * P], "sim/truth": [3 * P]},
                  consumed={"ctrl/thrust": [2 * P]})
    assert ledger.on_answer(tick) == "first"
    assert ledger.missing(tick) == [("sensors/gnss", 3 * P), ("ctrl/thrust", 2 * P)]
    ledger.see("sensors/gnss", 3 * P)
    assert not ledger.complete(tick)
    ledger.see("ctrl/thrust", 2 * P)
    assert ledger.complete(tick)  # sim/truth is not watched: never waited for
    # The recorder does not count what the sim consumed (it was answered for when published).
    rec = Ledger(watched=None, consumed=False)
    rec.on_answer(tick)
    rec.see("sensors/gnss", 3 * P)
    assert rec.missing(tick) == [("sim/truth", 3 * P)]


def test_a_restart_keeps_the_new_episodes_first_stamps_and_drops_the_old_ones() -> None:
    ledger = Ledger(watched=None)
    ledger.on_answer(answer("sim", 40))
    ledger.on_answer(answer("estimator", 40))
    ledger.see("nav/state", 40 * P)
    ledger.see("sensors/gnss", 0)  # the new episode's first fix arrived before the sim's answer
    assert ledger.on_answer(answer("sim", 0, episode=1)) == "restart"
    assert ledger.has("sensors/gnss", 0) and not ledger.has("nav/state", 40 * P)
    assert ledger.answer("estimator") is None  # answers of the old episode are forgotten


def test_a_new_episodes_answer_heard_before_the_sims_is_kept_by_the_restart() -> None:
    """Another connection can bring a member's first answer of a new episode before the sim's: the
    restart the sim's brings must not forget it (the controller then waited for an answer already
    given until the sim repeated the period for the stall, and the repeats put the old episode's
    last bundles into the new one's recording)."""
    ledger = Ledger(watched=None)
    ledger.on_answer(answer("sim", 342))
    ledger.on_answer(answer("estimator", 342))
    ledger.on_answer(answer("estimator", 0, episode=1))  # before the sim's t_0 of episode 1
    ledger.on_answer(answer("controller", 342))  # late, of the old episode
    assert ledger.answer("estimator") is None  # not of the current period (yet)
    assert ledger.on_answer(answer("sim", 0, episode=1)) == "restart"
    assert ledger.answer("estimator") == answer("estimator", 0, episode=1)
    assert set(ledger.answers) == {"sim", "estimator"}  # the old episode's controller: forgotten


def test_an_answer_on_another_members_key_is_ignored() -> None:
    hub = MemoryHub()
    member = Member(hub.bus("v1"), "estimator", watched=())
    member.on_answer("seaway/v1/lockstep/controller", answer("sim", 7))  # says "sim", on controller's
    assert member.ledger.period is None
    member.on_answer("seaway/v1/lockstep/sim", answer("sim", 7))
    assert member.ledger.period == Period(0, 7 * P)


def test_a_late_message_of_an_earlier_episode_does_not_count_in_the_next() -> None:
    ledger = Ledger(watched={"nav/state"})
    ledger.on_answer(answer("sim", 0, episode=1))
    ledger.see("nav/state", 3 * P)  # stamped ahead of the episode: the old one's, arriving late
    ledger.on_answer(answer("sim", 1, episode=1))
    assert not ledger.has("nav/state", 3 * P)
    ledger.on_answer(answer("sim", 3, episode=1))
    assert not ledger.complete(answer("estimator", 3, episode=1, published={"nav/state": [3 * P]}))


def test_a_message_wakes_the_loop_only_when_an_answer_of_the_period_may_wait_for_it() -> None:
    hub = MemoryHub()
    member = Member(hub.bus("v1"), "estimator", watched=("sensors/attitude",), hears=("sim",))
    member.on_answer("seaway/v1/lockstep/sim", answer("sim", 1, published={"sensors/attitude": [P]}))
    member.saw("sensors/attitude", P)  # t_1 complete (the loop answers it)
    v = member.version
    member.saw("sensors/attitude", 2 * P)  # t_2's sample, before t_2's answer: nothing to do yet
    assert member.version == v
    member.on_answer("seaway/v1/lockstep/sim",
                     answer("sim", 2, seq=2, published={"sensors/attitude": [2 * P, 2 * P - 5]}))
    v = member.version
    assert not member.ledger.complete(member.ledger.answer("sim"))
    member.saw("sensors/attitude", 2 * P - 5)  # after its answer: the loop must look again
    assert member.version == v + 1 and member.ledger.complete(member.ledger.answer("sim"))


def test_a_member_hears_only_the_answers_it_asked_for() -> None:
    hub = MemoryHub()
    bus = hub.bus("v1")
    member = Member(bus, "estimator", watched=(), hears=("sim",))
    other = Member(hub.bus("v1"), "controller", watched=())
    other.answer(Period(0, P), P)
    assert member.ledger.answers == {}
    Member(hub.bus("v1"), "sim", watched=()).answer(Period(0, P), P)
    assert set(member.ledger.answers) == {"sim"}


def test_a_repeat_of_a_period_not_yet_answered_logs_what_the_member_lacks(caplog) -> None:
    """A stalled run repeats its period every 2 s; each member that has not answered it says, in its
    own log, which answers and which listed messages it is still waiting for."""
    hub = MemoryHub()
    member = Member(hub.bus("v1"), "controller", watched=("nav/state",), hears=("sim", "estimator"))
    tick = answer("sim", 4, members=["estimator", "controller"])
    member.on_answer("seaway/v1/lockstep/sim", tick)
    with caplog.at_level("INFO", logger="seaway.lockstep"):
        member.on_answer("seaway/v1/lockstep/sim", tick.model_copy(update={"seq": 2}))
    assert "controller, lockstep t = 0.400 s (episode 0), repeated: no answer yet from estimator" \
        in caplog.text
    caplog.clear()
    member.on_answer("seaway/v1/lockstep/estimator",
                     answer("estimator", 4, published={"nav/state": [4 * P]}))
    with caplog.at_level("INFO", logger="seaway.lockstep"):
        member.on_answer("seaway/v1/lockstep/sim", tick.model_copy(update={"seq": 3}))
    assert "repeated: estimator's answer lists, not seen: nav/state @ 0.400 s" in caplog.text
    caplog.clear()
    member.saw("nav/state", 4 * P)
    member.answer(Period(0, 4 * P), P)  # answered: a repeat is no news
    with caplog.at_level("INFO", logger="seaway.lockstep"):
        member.on_answer("seaway/v1/lockstep/sim", tick.model_copy(update={"seq": 4}))
    assert "repeated" not in caplog.text


def test_a_recorder_answer_after_the_period_the_sim_published_is_not_recorded() -> None:
    ledger = Ledger(watched=None)
    ledger.on_answer(answer("recorder", 7))
    assert ledger.recorded(Period(0, 6 * P), published=Period(0, 7 * P))
    assert ledger.recorded(Period(0, 7 * P), published=Period(0, 7 * P))
    # Stamped after what the sim has published: for a period nobody has reached, not on disk.
    assert not ledger.recorded(Period(0, 5 * P), published=Period(0, 6 * P))
    ledger.on_answer(PeriodDone(stamp_ns=2**63 - 1, service="recorder", episode=0, seq=2,
                                period_ns=P))
    assert not ledger.recorded(Period(0, 5 * P), published=Period(0, 6 * P))


def test_an_answer_far_ahead_of_the_current_period_is_refused_by_name() -> None:
    ledger = Ledger(watched=None)
    ledger.on_answer(answer("sim", 5))
    assert ledger.refusal(answer("controller", 5)) is None
    assert ledger.refusal(answer("estimator", 7)) is None  # heard before the sim's: within the lead
    assert ledger.refusal(answer("recorder", 8)).startswith("ahead: recorder's answer for t = 0.800 s")
    far = PeriodDone(stamp_ns=2**63 - 1, service="recorder", episode=0, seq=1, period_ns=P)
    assert ledger.refusal(far).startswith("ahead:")
    assert ledger.refusal(answer("recorder", 90, episode=1)) is None  # another stretch of time
    # The sim's own ledger never hears the sim: its last published period is the reference.
    sim_side = Ledger(watched={"ctrl/thrust"})
    assert sim_side.refusal(far, own=answer("sim", 5)).startswith("ahead:")
    assert sim_side.refusal(answer("controller", 5), own=answer("sim", 5)) is None
    assert sim_side.refusal(answer("recorder", 8), own=answer("sim", 5)).startswith("ahead:")


def test_an_answer_listing_a_stamp_after_its_own_period_is_refused_by_name() -> None:
    ledger = Ledger(watched={"ctrl/thrust"})
    ok = answer("sim", 1, consumed={"ctrl/thrust": [0]}, published={"sim/clock": [P]})
    assert ledger.refusal(ok) is None
    late = answer("sim", 1, consumed={"ctrl/thrust": [P + 10**9]})
    assert ledger.refusal(late) == ("listing: sim's answer for t = 0.100 s (episode 0) lists in "
                                    "consumed ctrl/thrust @ t = 1.100 s, more than 2 periods "
                                    "after its own period")
    far = answer("controller", 1, published={"ctrl/thrust": [2**63 - 1]})
    assert ledger.refusal(far).startswith("listing: controller's answer")


def test_a_member_refuses_an_absurd_listing_and_takes_the_next_sane_answer(caplog) -> None:
    """A sim answer listing a command stamped a second after its period: the estimator could never
    see that stamp (``see`` bounds it) and would lack it for ever; it refuses the answer, counts
    and names it, stays responsive, and takes the sim's next sane answer."""
    from seaway.contract import keys

    hub = MemoryHub()
    sim = Member(hub.bus("v1"), "sim", watched=(), subscribe=False)
    est = Member(hub.bus("v1"), "estimator", watched={"ctrl/thrust"}, hears=("sim", "controller"))
    est.deliver = lambda key, msg: est.saw(keys.THRUST.suffix, msg.stamp_ns)
    sim.answer(Period(0, P), P, consumed={keys.THRUST.suffix: [P + 10**9]})
    sim.repeat()
    assert est.ledger.answer("sim") is None and est.refused == {"listing": 2}
    assert "lockstep answer on seaway/v1/lockstep/sim refused (listing: sim's answer" in caplog.text
    sim.answer(Period(0, P), P)
    assert est.ledger.complete(est.ledger.answer("sim"))


def test_a_member_gives_up_on_a_lost_command_whatever_its_stamp() -> None:
    """Giving up marks the stamp seen even where ``see`` would refuse it (beyond the stamp bounds of
    the current period): what is given up on is no longer waited for."""
    ledger = Ledger(watched={"ctrl/thrust"})
    ledger.on_answer(answer("sim", 1))
    assert not ledger.see("ctrl/thrust", 2**62)
    ledger.give_up("ctrl/thrust", 2**62)
    assert ledger.has("ctrl/thrust", 2**62)
