"""Seaway's controller: mission management and the paper's CC-EMPC with EO-EMPC and NMPC baselines.

Pure core (``core.ControllerCore``) plus a thin service loop (``service``). See README.md.
"""

__version__ = "0.1.0"
