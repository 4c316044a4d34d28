"""Example plug-in detector: the spread of the measured ranges (docs/extending.md, "A new
detector").

Its statistic is ``c * (max ToA - min ToA)`` over the TRPs the UE detected, in m: the largest
difference of two measured ranges. A benign point's spread is bounded by the TRPs' geometry;
a spoofer that shifts one TRP's arrival stretches or squeezes it. The point is valid when the
statistic is at most ``MAX_SPREAD_M``; without two detected TRPs the statistic is NaN and the
point valid (nothing to check). Register it by importing this module, then name it in
``detectors.extra``.
"""

from __future__ import annotations

import numpy as np

from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.detectors.registry import DETECTOR_REGISTRY, Detector, PointInput

#: m, the largest accepted spread
MAX_SPREAD_M = 1500.0


@DETECTOR_REGISTRY.register("ToASpread")
class ToASpread(Detector):
    """c (max - min) of the detected TRPs' ToAs, valid iff <= ``MAX_SPREAD_M``."""

    def __call__(self, x: PointInput) -> tuple[bool, float]:
        toa = np.asarray(x.result.toa_s, float)[np.asarray(x.result.detected, bool)]
        if toa.size < 2:
            return True, float("nan")
        spread = float(SPEED_OF_LIGHT * (toa.max() - toa.min()))
        return spread <= MAX_SPREAD_M, spread
