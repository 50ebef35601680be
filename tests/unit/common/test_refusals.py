"""Refusal counting from Zenoh's own log (``seaway.runtime.refusals``), on lines Zenoh 1.10 wrote.

The lines below were captured from real sessions of one stack (``RUST_LOG`` at trace on the
interceptor): a cached verdict (a publisher on a declared key), an uncached one (a wildcard
subscriber, which Zenoh never caches), a cache fill (verdicts with no drop after them), a refused
query, and a TLS link refused before any identity. The live path (Zenoh writing them, the service
counting and answering) is tested in tests/system/launch/test_authority.py.
"""

from __future__ import annotations

import pytest
from seaway.contract import keys
from seaway.contract import messages as m
from seaway.runtime.refusals import _ANSI, LOG_INTERVAL_S, UNAUTHENTICATED, UNKNOWN, RefusalCounter

from tests.conftest import wait_for

EST = "c8716696cd321eb2dfcf5f7c8e0e624a"
SUBJECT = f"{EST} on Interface(lo)+CertCommonName(estimator)+Transport(Tls)+{EST}"
ACL = "\x1b[2mzenoh::net::routing::interceptor::access_control\x1b[0m\x1b[2m:\x1b[0m"
DROP = "\x1b[2mzenoh::net::routing::interceptor\x1b[0m\x1b[2m:\x1b[0m Msg intercepted!"


def line(thread: int, text: str) -> str:
    return f"2026-11-23T06:15:15.372429Z \x1b[35mTRACE\x1b[0m  rx-0 ThreadId({thread}) {text}"


FILL = [line(1, f"{ACL} ACL (ingress): caching permissions for `seaway/v1/ctrl/thrust` ..."),
        line(1, f"{ACL} {SUBJECT} is unauthorized to Query (ingress) on seaway/v1/ctrl/thrust"),
        line(1, f"{ACL} {SUBJECT} is unauthorized to Put (ingress) on seaway/v1/ctrl/thrust")]
CACHED_PUT = [line(14, f"{ACL} Using cached result: {EST} is unauthorized to Put (ingress) on "
                       "seaway/v1/ctrl/thrust"), line(14, DROP)]
UNCACHED_PUT = [line(13, f"{ACL} {SUBJECT} is unauthorized to Put (ingress) on seaway/v1/mission/status"),
                line(13, DROP)]
QUERY = [line(15, f"{ACL} Using cached result: {EST} is unauthorized to Query (ingress) on "
                  "seaway/v1/vehicle/arm"), line(15, DROP)]
ALLOWED = line(14, f"{ACL} Using cached result: {EST} is authorized to Put (ingress) on seaway/v1/nav/state")
TLS = ("2026-11-23T06:16:26.167618Z \x1b[33m WARN\x1b[0m acc-0 ThreadId(05) \x1b[2mzenoh_link_tls::unicast"
       "\x1b[0m\x1b[2m:\x1b[0m received corrupt message of type InvalidContentType.")


def feed(c: RefusalCounter, lines: list[str], t_s: float = 0.0) -> list[str]:
    out = []
    for text in lines:
        out += c.feed(_ANSI.sub("", text), t_s, int(t_s * 1e9))  # as the reader strips them
    return out


def test_a_cache_fill_alone_counts_nothing_and_names_the_session():
    c = RefusalCounter("vehicle_io")
    assert feed(c, [*FILL, ALLOWED]) == []
    assert c.total == 0 and c.names == {EST: "estimator"}


def test_each_drop_is_counted_with_the_verdict_before_it_on_its_thread():
    c = RefusalCounter("vehicle_io")
    feed(c, FILL)
    feed(c, CACHED_PUT * 3 + UNCACHED_PUT + QUERY)
    assert c.total == 5
    report = c.report(stamp_ns=7)
    got = {(r.identity, r.action, r.key): r.count for r in report.counts}
    assert got == {("estimator", "put", "seaway/v1/ctrl/thrust"): 3,
                   ("estimator", "put", "seaway/v1/mission/status"): 1,
                   ("estimator", "query", "seaway/v1/vehicle/arm"): 1}
    # The report is a valid bus message and survives the wire.
    assert m.Refusals.decode(report.encode()) == report


def test_interleaved_threads_keep_their_own_verdicts():
    c = RefusalCounter("vehicle_io")
    feed(c, FILL)
    feed(c, [CACHED_PUT[0], QUERY[0], CACHED_PUT[1], QUERY[1]])
    got = {(r.action, r.key): r.count for r in c.report(0).counts}
    assert got == {("put", "seaway/v1/ctrl/thrust"): 1, ("query", "seaway/v1/vehicle/arm"): 1}


def test_a_session_never_named_is_reported_by_its_id():
    c = RefusalCounter("vehicle_io")
    feed(c, CACHED_PUT)
    assert [r.identity for r in c.report(0).counts] == [f"session {EST}"]


def test_a_drop_without_a_verdict_and_a_refused_link_are_counted_too():
    c = RefusalCounter("sim")
    feed(c, [line(3, DROP), TLS, TLS])
    got = {(r.identity, r.action): r.count for r in c.report(0).counts}
    assert got == {(UNKNOWN, "refused"): 1, (UNAUTHENTICATED, "connect"): 2}


def test_each_source_is_logged_once_then_at_most_once_a_minute_with_what_it_did():
    c = RefusalCounter("vehicle_io")
    feed(c, FILL)
    first = feed(c, CACHED_PUT, t_s=0.0)
    assert len(first) == 1 and "estimator" in first[0] and "seaway/v1/ctrl/thrust" in first[0]
    assert feed(c, CACHED_PUT * 50, t_s=1.0) == []
    assert feed(c, [TLS], t_s=2.0) != []  # another source is logged on its own
    later = feed(c, CACHED_PUT, t_s=LOG_INTERVAL_S + 0.5)
    assert len(later) == 1 and "51 more times" in later[0]
    assert c.total == 53


def test_distinct_kinds_are_bounded_and_the_rest_is_summed():
    c = RefusalCounter("recorder")
    feed(c, FILL)
    for i in range(m.MAX_REFUSAL_ENTRIES + 10):
        feed(c, [line(14, f"{ACL} Using cached result: {EST} is unauthorized to Put (ingress) on "
                          f"seaway/v1/junk/{i}"), line(14, DROP)])
    report = c.report(0)
    assert len(report.counts) == m.MAX_REFUSAL_ENTRIES and report.overflow == 10
    assert report.total == m.MAX_REFUSAL_ENTRIES + 10


@pytest.mark.parametrize(("key", "identity"), [
    ("seaway/v1/refusals/vehicle_io", "vehicle_io"),
    ("seaway/v1/refusals/", None), ("seaway/v1/refusals/a/b", None), ("seaway/v1/run/sim", None),
    ("other/v1/refusals/sim", None)])
def test_a_refusal_report_key_names_its_reporter(key, identity):
    assert keys.refusals_identity(key) == identity


def test_the_recorder_records_reports_with_their_schema():
    from seaway_recorder.schemas import channel_for_key

    ch = channel_for_key(keys.refusals_key("v1", "sim"), "application/json")
    assert ch.message_type is m.Refusals and ch.schema_name == m.Refusals.SCHEMA
    assert ch.metadata["producer"] == "sim" and ch.metadata["registered"] == "true"


def test_the_reader_counts_from_the_pipe_and_forwards_only_other_lines_when_asked():
    """The reader thread on a real pipe: refusals counted; with $RUST_LOG set by the user, Zenoh's
    other lines reach stdout and the interceptor's own lines do not."""
    import os
    import threading

    from seaway.runtime.refusals import _Watch

    log_r, log_w = os.pipe()
    out_r, out_w = os.pipe()
    counter = RefusalCounter("vehicle_io")
    _Watch(counter, log_r, out_w, forward=True)
    other = "2026-11-23T06:16:26Z  WARN zenoh_transport::unicast::manager: something else"
    os.write(log_w, ("\n".join([*FILL, *CACHED_PUT, other, *QUERY]) + "\n").encode())
    os.close(log_w)
    done = threading.Event()
    got = bytearray()

    def drain() -> None:
        while b"something else" not in got:
            chunk = os.read(out_r, 1 << 16)
            if not chunk:
                break
            got.extend(chunk)
        done.set()

    threading.Thread(target=drain, daemon=True).start()
    assert done.wait(30)
    wait_for(lambda: counter.total == 2, 30, what="both refusals counted")
    assert got.decode().strip() == other
    os.close(out_w)
    os.close(out_r)
