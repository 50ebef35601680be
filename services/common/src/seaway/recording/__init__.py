"""Recordings read back: what the recorder wrote, for the report, replay, the ground station's replay
view and the lab. ``reader`` (files and series, messages in log-time order, typed decoding),
``runinfo`` (the run a recording's attachments rebuild: mission, scenario, vessel), ``timebase`` (the
one convention for a message's log time), ``recover`` (a cut or damaged file rebuilt, and the
repaired copies readers use), ``chunks`` (the summary and chunks read at the byte level, each chunk
checked against its CRC), ``layout`` (MCAP's record layouts, shared with the recorder's writer).

Writing stays the recorder's (``seaway_recorder``); this package needs the mcap library
(``seaway[recording]``).
"""
