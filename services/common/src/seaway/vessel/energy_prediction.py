"""How far the controller's energy-to-finish prediction is known to be off, by controller.

The energy budget (``seaway_controller.energy``) predicts the energy to finish the mission from the
controller's own model and cost. Its band was the prediction under the disturbance one standard
deviation away: only the disturbance's share of the error. On the lake it was +-0.3 % wide while the
prediction was 2.2 % low, and over the paper's conditions and the lake it held 87 % (CC-EMPC), 82 %
(EO-EMPC) and 1.5 % (NMPC) of the predictions, 21 % of the lake's.

The band is now that spread widened by the prediction's own error as measured: low = (lowest of the
spread) x ``ratio_low``, high = (highest) x ``ratio_high``, the smallest and largest actual /
predicted over every pricing of the paper's five conditions and the lake (``DERIVED_ON``), from the
mission's start until a tenth of its time was left (``python -m seaway_lab.energy_band`` measures
them and the coverage, in the in-process closed loop). So it held every one of those predictions
(``coverage``). Out of sample (``coverage_unseen``, ``UNSEEN_ON``: a current the estimator sees) it
held 77 % (CC-EMPC) and 81 % (EO-EMPC), worst error 11 %; on a plant 20 % off the model
(paper-c4-perturbed) none, the prediction being 25-33 % high: the band is the model's error, not a
wrong model's. The NMPC's unseen coverage is not measured: with battery reports its budget priced
the way home at an infinite energy there and turned back.

A controller whose prediction was measured off by more than ``POOR_ERROR_FRAC`` is flagged
(``known_poor``): the launcher and the report say so beside its figures. The NMPC is: its budget
prices the mission at its present speed (``seaway_controller.energy``), near zero at the start.

BY VEHICLE

The prediction is the model's: on the vehicle a vessel file was identified from, it is as good as
the model. Where the prediction was measured on that vehicle and found off beyond what the
model's own closed loop shows, ``VEHICLES_MEASURED`` holds the measured ratio of the energy used to
the energy predicted at the mission's start, and the budget scales its prediction by it
(``forecast_ratio``). It describes that vehicle, not the file: a simulation flying the file's own
model as its plant is not that vehicle (the file under another name is not corrected).
"""

from __future__ import annotations

from dataclasses import dataclass

DERIVED_ON = "paper-c1..c5, lake"
"""The scenarios the band was derived from (every controller; ``seaway_lab.energy_band``)."""
UNSEEN_ON = "steady-current"
"""The scenario its coverage was measured on out of sample."""
POOR_ERROR_FRAC = 0.10
"""A prediction measured more than this far off (|predicted / actual - 1|) is called poor."""


@dataclass(frozen=True)
class PredictionError:
    """One controller's measured energy-to-finish prediction error (``seaway_lab.energy_band``)."""

    ratio_low: float
    """The smallest actual / predicted measured: the band's low end is the prediction times this."""
    ratio_high: float
    """The largest actual / predicted measured: the band's high end is the prediction times this."""
    samples: int
    """Predictions measured."""
    coverage: float
    """Fraction of the measured predictions whose band held the energy actually used (1 by
    construction)."""
    coverage_unseen: float | None
    """The same on ``UNSEEN_ON``, not used to derive the band (None: not measured)."""

    @property
    def worst_error_frac(self) -> float:
        """The largest |predicted / actual - 1| measured."""
        return max(abs(1.0 / self.ratio_low - 1.0), abs(1.0 / self.ratio_high - 1.0))


MEASURED: dict[str, PredictionError] = {
    "cc-empc": PredictionError(
        ratio_low=0.9641, ratio_high=1.0288, samples=1561, coverage=1.0, coverage_unseen=0.772
    ),
    "eo-empc": PredictionError(
        ratio_low=0.9621, ratio_high=1.0310, samples=1591, coverage=1.0, coverage_unseen=0.812
    ),
    "nmpc": PredictionError(
        ratio_low=0.1523, ratio_high=4.0560, samples=201, coverage=1.0, coverage_unseen=None
    ),
}
"""By controller (``ControllerName``); measured on paper-c1..c5 and the lake (module docstring)."""


def band_factors(controller: str) -> tuple[float, float]:
    """(low, high) factors of the band's ends; (1, 1) for a controller never measured."""
    e = MEASURED.get(controller)
    return (1.0, 1.0) if e is None else (e.ratio_low, e.ratio_high)


def band_coverage(controller: str) -> float | None:
    """The measured fraction of predictions the band held, or None if never measured."""
    e = MEASURED.get(controller)
    return None if e is None else e.coverage


def known_poor(controller: str) -> str | None:
    """Why ``controller``'s energy prediction is known to be poor (for people), or None."""
    e = MEASURED.get(controller)
    if e is None or e.worst_error_frac <= POOR_ERROR_FRAC:
        return None
    return (
        f"{controller}'s energy prediction is known to be poor: measured "
        f"{100 * (1.0 / e.ratio_high - 1.0):+.0f} % to {100 * (1.0 / e.ratio_low - 1.0):+.0f} % "
        "off the energy actually used; read 'to finish' and 'to home' as rough"
    )


@dataclass(frozen=True)
class VehicleError:
    """The energy-to-finish prediction as measured on the vehicle a vessel file was identified
    from, with the model's own prediction (``seaway_controller.energy``)."""

    ratio: float
    """Energy used / energy predicted at the mission's start, as measured: the budget's prediction
    is scaled by it."""
    runs: tuple[float, ...]
    """The ratio of each run it was measured on (``ratio`` is their mean)."""
    measured_on: str
    """The vehicle, mission and controller."""


VEHICLES_MEASURED: dict[str, VehicleError] = {
    # The model's turns and straights both price high there: ArduPilot's boat has quadratic drag
    # (a forward 'disturbance' of ~0.45 N underway at 2.3 m/s on the identified linear drag) and
    # turns in ~5 s for ~1.2-1.4 kJ where the model's turn at its cruise takes ~2.6 kJ.
    "ardupilot-sitl-motorboat": VehicleError(
        ratio=0.818, runs=(0.814, 0.821),
        measured_on="ArduPilot Rover SITL (motorboat-skid), the lake mission, CC-EMPC"),
}
"""By vessel file name (``VesselParams.name``)."""


def forecast_ratio(vessel_name: str) -> float:
    """The factor the budget's prediction is scaled by for the vessel file ``vessel_name``: the
    measured ratio on its vehicle, 1 for a file never measured on one."""
    e = VEHICLES_MEASURED.get(vessel_name)
    return 1.0 if e is None else e.ratio
