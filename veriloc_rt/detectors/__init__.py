"""The five per-point detectors: HMAC and DS tags, ABSA, DL-UL handshake, Kalman tracking.

Each is a small stage configured once by a frozen config and called per trajectory point;
the stateful one (:class:`KalmanTracker`) has ``reset()``.
"""

from .absa import ABSAConfig, ABSADetector, ABSAVerdict, angle_difference, geometric_azimuth, wrap_angle
from .handshake import HandshakeConfig, HandshakeDetector, HandshakeVerdict
from .tags import TagDetector, TagDetectorConfig, TagVerdict
from .tracking import (KalmanTracker, TrackingConfig, TrackVerdict, cv_transition,
                       dwna_process_noise, nis_gate)

__all__ = ["ABSAConfig", "ABSADetector", "ABSAVerdict", "angle_difference", "geometric_azimuth",
           "wrap_angle", "HandshakeConfig", "HandshakeDetector", "HandshakeVerdict", "TagDetector",
           "TagDetectorConfig", "TagVerdict", "KalmanTracker", "TrackingConfig", "TrackVerdict",
           "cv_transition", "dwna_process_noise", "nis_gate"]
