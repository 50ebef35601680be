"""Copying a recording with its messages changed on the way: the tests' way to a damaged, stepped
or otherwise altered recording from a real one (the mcap library writes the copy)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.writer import Writer

Each = Callable[[Any, Any], tuple[int, bytes, int]]
"""(channel, message) -> (log time, bytes, publish time) to write for it."""


def rewritten(src: Path, out: Path, each: Each, extra: Callable[[Writer], None] | None = None
              ) -> Any:
    """Copy ``src`` to ``out``: its schemas, channels and attachments as they are, each message as
    ``each`` makes it (file order), then what ``extra`` writes; ``src``'s summary."""
    with open(src, "rb") as fh, open(out, "wb") as dst:
        r = make_reader(fh)
        summary = r.get_summary()
        w = Writer(dst)
        w.start()
        sids = {k: w.register_schema(s.name, s.encoding, s.data) for k, s in summary.schemas.items()}
        cids = {k: w.register_channel(c.topic, c.message_encoding, sids.get(c.schema_id, 0),
                                      dict(c.metadata)) for k, c in summary.channels.items()}
        for a in r.iter_attachments():
            w.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        for _, c, m in r.iter_messages(log_time_order=False):
            log_ns, data, pub_ns = each(c, m)
            w.add_message(cids[c.id], log_ns, data, pub_ns, m.sequence)
        if extra is not None:
            extra(w)
        w.finish()
    return summary
