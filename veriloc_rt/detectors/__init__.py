"""The five per-point detectors: HMAC and DS tags, ABSA, DL-UL handshake, Kalman tracking.

Each is a small stage configured once by a frozen config and called per trajectory point;
the stateful one (:class:`KalmanTracker`) has ``reset()``. :mod:`.registry` holds the detector
registry (:class:`Detector`, :data:`DETECTOR_REGISTRY`: the five built-ins and any plug-in,
docs/extending.md); :func:`point_verdicts` runs the four stateless ones on a chain result.
"""

from ..config.detectors import ABSAConfig
from .absa import ABSADetector, ABSAVerdict, angle_difference, geometric_azimuth, wrap_angle
from ..config.detectors import HandshakeConfig
from .handshake import HandshakeDetector, HandshakeVerdict
from .point import PointDetectors, point_statistics, point_verdicts
from .registry import DETECTOR_REGISTRY, Detector, PointInput
from .tags import TagDetector, TagVerdict
from ..config.detectors import TagDetectorConfig
from .tracking import KalmanTracker, TrackVerdict, cv_transition, dwna_process_noise, nis_gate
from ..config.detectors import TrackingConfig

__all__ = ["ABSAConfig", "ABSADetector", "ABSAVerdict", "angle_difference", "geometric_azimuth",
           "wrap_angle", "HandshakeConfig", "HandshakeDetector", "HandshakeVerdict", "TagDetector",
           "TagDetectorConfig", "TagVerdict", "PointDetectors", "point_statistics",
           "point_verdicts", "KalmanTracker", "TrackingConfig", "TrackVerdict",
           "cv_transition", "dwna_process_noise", "nis_gate", "DETECTOR_REGISTRY", "Detector",
           "PointInput"]
