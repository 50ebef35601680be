"""Which episodes of a recording flew a mission (``report.mission_episodes``): a stack that flew
several runs, each after a scenario load, holds them as episodes of one recording, and
``seaway study`` reports each run from its own (execute.SharedStack)."""

from __future__ import annotations

from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, SimTruth
from seaway.recording.reader import Decoded
from seaway_recorder import report

TRUTH, ACCEPTED = keys.SIM_TRUTH.suffix, keys.MISSION_ACCEPTED.suffix
PERIOD_NS = 100_000_000


def recording(episodes: list[tuple[int, list[str]]]) -> Decoded:
    """Episodes of ``n`` periods each (simulated time from 0, log time going on), with the missions
    accepted in their first period."""
    dec = Decoded(by_suffix={TRUTH: [], ACCEPTED: []}, log_ns={TRUTH: [], ACCEPTED: []})
    log = 0
    for n, accepted in episodes:
        for k in range(n):
            dec.by_suffix[TRUTH].append(SimTruth.model_construct(stamp_ns=k * PERIOD_NS))
            dec.log_ns[TRUTH].append(log)
            if k == 1:
                for mission_id in accepted:
                    dec.by_suffix[ACCEPTED].append(
                        MissionAccepted.model_construct(stamp_ns=k * PERIOD_NS, mission_id=mission_id))
                    dec.log_ns[ACCEPTED].append(log)
            log += PERIOD_NS
    return dec


def test_each_run_is_found_in_its_own_episode() -> None:
    dec = recording([(30, ["paper-c1"]), (20, ["paper-c2-eo-empc"]), (40, ["paper-c1-nmpc"])])
    assert len(report.episodes(dec)) == 3
    assert report.mission_episodes(dec, "paper-c1") == [0]
    assert report.mission_episodes(dec, "paper-c2-eo-empc") == [1]
    assert report.mission_episodes(dec, "paper-c1-nmpc") == [2]
    assert report.mission_episodes(dec, "paper-c3-nmpc") == []


def test_a_mission_accepted_again_names_every_episode_it_flew() -> None:
    # A sim restarted mid-mission: the controller flies the mission again from its first leg in the
    # new episode, and that is the one flown to the end. Accepted twice in one episode (a resumed
    # checkpoint) is one episode.
    dec = recording([(30, ["paper-c1", "paper-c1"]), (50, ["paper-c1"]), (10, ["next"])])
    assert report.mission_episodes(dec, "paper-c1") == [0, 1]
    assert report.mission_episodes(dec, "next") == [2]


def test_one_stamp_far_ahead_of_its_neighbours_starts_no_episode() -> None:
    """A single sim/truth stamped 2^63 - 1 in the middle of a run split it in two, and the report
    scored only the part after it (233 s and 232 J of a 330 J mission). Time going back below
    where it stood before the spike is still a new episode."""
    dec = recording([(30, ["paper-c1"]), (20, ["paper-c2"])])
    dec.by_suffix[TRUTH][10] = SimTruth.model_construct(stamp_ns=2**63 - 1)
    assert len(report.episodes(dec)) == 2
    assert report.mission_episodes(dec, "paper-c1") == [0]
    dec.by_suffix[TRUTH][-1] = SimTruth.model_construct(stamp_ns=2**63 - 1)  # the last one: no next
    assert len(report.episodes(dec)) == 2
