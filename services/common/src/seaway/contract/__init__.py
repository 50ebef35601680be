"""The wire contract: every message type, every key, and the documents users write (config, missions).

What two Seaway processes must agree on to talk, and nothing else: no maths, no I/O beyond reading
documents. Every other section builds on this one.
"""
