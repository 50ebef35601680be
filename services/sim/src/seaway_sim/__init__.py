"""Seaway simulator service (see services/sim/README.md)."""

__version__ = "0.1.0"
