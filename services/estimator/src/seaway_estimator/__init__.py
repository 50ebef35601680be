"""Seaway's estimator: an extended Kalman filter on the shared vessel model, with the disturbance.

``EstimatorCore`` is the pure core (messages and time in, ``StateEstimate`` out); ``service`` is the
thin loop on the bus; ``bench`` is ``seaway bench estimator``.
"""

from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore, EstimatorError

__all__ = ["EstimatorConfig", "EstimatorCore", "EstimatorError"]
