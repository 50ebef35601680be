"""Seaway recorder, replay and report."""
