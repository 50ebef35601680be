"""The operator's tools: the ``seaway`` command, the launcher, mission requests and the Zenoh router."""
