"""Seaway's shared library: messages, keys, bus, vessel model, config, frames and clocks.

Every service imports this package and no service imports another (see design.md).
"""

__version__ = "0.1.0"
