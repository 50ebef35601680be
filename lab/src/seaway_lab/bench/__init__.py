"""Every ``seaway bench NAME`` (registered as entry points in ``lab/pyproject.toml``)."""
