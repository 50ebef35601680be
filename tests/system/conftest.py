"""Fixtures the system tests of several services share."""

from tests.system.small_disk import small_disk  # noqa: F401 - a fixture, registered by its import
