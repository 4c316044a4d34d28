"""The detector registry: each per-point detector as a :class:`Detector` registered by name.

A run evaluates the five built-in detectors (:data:`~veriloc_rt.detectors.outcomes.DETECTORS`,
the results CSV's columns in the paper's order) and then the plug-in detectors named in
``detectors.extra`` (docs/extending.md, "A new detector"), each on the :class:`PointInput` of
every point, in that order. The built-ins register here the way a plug-in does:

* ``HMAC``, ``DigSig``: the tag verdicts (:class:`~veriloc_rt.detectors.tags.TagDetector`) on
  the standard chain's and the DS-tagged chain's tag checks;
* ``ABSA``: the AoA per BS, resolved against and compared with the azimuth from the reference
  position (:class:`~veriloc_rt.detectors.absa.ABSADetector`);
* ``Handshake``: DL fix against UL fix (:class:`~veriloc_rt.detectors.handshake.HandshakeDetector`);
* ``Tracking``: the Kalman tracker on the DL fix (:class:`~veriloc_rt.detectors.tracking.KalmanTracker`),
  the one with state; its last accepted position is the next points' ABSA reference.

Each returns ``(valid, stat)``: its verdict (True: no anomaly) and its decision statistic.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..config.detectors import DetectorsConfig
from ..registry import Registry
from .absa import ABSADetector
from .handshake import HandshakeDetector
from .outcomes import DETECTORS, PointRow
from .tags import TagDetector
from .tracking import KalmanTracker

__all__ = ["DETECTOR_REGISTRY", "Detector", "PointInput", "ABSA", "DigSig", "HMAC",
           "Handshake", "Tracking"]


@dataclass(frozen=True, eq=False)
class PointInput:
    """What a detector sees at one point of one scenario.

    index : int, trajectory point; time_s : float, s
    result : ChainResult of the standard-PRS chain (tags, ToAs, AoAs, DL and UL fixes)
    ds : ChainResult whose tags DigSig checks (the DS-tagged chain's; None: no DigSig verdict)
    bs_pos : [num_trps, 3] float64, m, the serving TRPs of the point
    reference_position : [2 or 3] float64, m, the last validated position (the tracker's after
        its last accepted fix; before the first one the current DL fix), None: none
    est_xy : [2] float64, m, the DL fix (NaN without one); covariance : [2, 2] float64, m^2, its
        covariance (None without a fix)
    dt_s : float, s, since the previous evaluated point (None: first point)
    """

    index: int
    time_s: float
    result: Any
    ds: Any
    bs_pos: np.ndarray
    reference_position: np.ndarray | None
    est_xy: np.ndarray
    covariance: np.ndarray | None
    dt_s: float | None


class Detector(ABC):
    """One per-point detector: configured once per run, called per point.

    :meth:`from_config` makes it from the run's :class:`~veriloc_rt.config.Config` (default:
    ``cls(cfg)``). A detector with state clears it in :meth:`reset` (a new scenario) and
    rebuilds it from the saved rows in :meth:`replay` (a resumed run).
    """

    #: set by the registry
    name: str = ""

    def __init__(self, cfg: Any = None):
        self.cfg = cfg

    @classmethod
    def from_config(cls, cfg) -> "Detector":
        return cls(cfg)

    @abstractmethod
    def __call__(self, x: PointInput) -> tuple[bool, float]:
        """``(valid, stat)`` at one point."""

    def reset(self) -> None:
        """Forget the state of the previous scenario (stateless detectors: nothing)."""

    def replay(self, row: PointRow, dt_s: float | None) -> None:
        """Feed one saved row back (resume); stateless detectors: nothing."""


#: detectors by name (the built-ins, then ``detectors.extra``)
DETECTOR_REGISTRY: Registry[type[Detector]] = Registry("detector", "detectors.extra")


@DETECTOR_REGISTRY.register("HMAC")
class HMAC(Detector):
    """The HMAC tags' verdict: :class:`TagDetector` on the standard chain's tag checks."""

    def __init__(self, cfg: DetectorsConfig):
        super().__init__(cfg)
        self.tags = TagDetector(cfg.hmac)

    @classmethod
    def from_config(cls, cfg) -> "HMAC":
        return cls(cfg.detectors)

    def __call__(self, x: PointInput) -> tuple[bool, float]:
        v = self.tags(x.result.tags_valid, x.result.detected)
        return v.valid, v.stat


@DETECTOR_REGISTRY.register("DigSig")
class DigSig(HMAC):
    """The digital-signature tags' verdict: the same rule on the DS-tagged chain's checks."""

    def __init__(self, cfg: DetectorsConfig):
        Detector.__init__(self, cfg)
        self.tags = TagDetector(cfg.digsig)

    def __call__(self, x: PointInput) -> tuple[bool, float]:
        v = self.tags(x.ds.tags_valid, x.ds.detected)
        return v.valid, v.stat


@DETECTOR_REGISTRY.register("ABSA")
class ABSA(Detector):
    """Each BS's AoA, its mirror ambiguity resolved against the azimuth from the reference
    position, compared with that azimuth (no AoA: NaN; no reference: unresolvable, and ABSA
    does not check that BS)."""

    def __init__(self, cfg: DetectorsConfig):
        super().__init__(cfg)
        self.absa = ABSADetector(cfg.absa)

    @classmethod
    def from_config(cls, cfg) -> "ABSA":
        return cls(cfg.detectors)

    def __call__(self, x: PointInput) -> tuple[bool, float]:
        ref_az = self.absa.reference_azimuth(x.bs_pos, x.reference_position)
        az = np.array([float(a.resolve(r)[0]) if (a is not None and np.isfinite(r)) else np.nan
                       for a, r in zip(x.result.aoa, ref_az)])
        v = self.absa(az, x.bs_pos, reference_position=x.reference_position)
        return v.valid, v.stat


@DETECTOR_REGISTRY.register("Handshake")
class Handshake(Detector):
    """The DL fix against the UL fix."""

    def __init__(self, cfg: DetectorsConfig):
        super().__init__(cfg)
        self.handshake = HandshakeDetector(cfg.handshake)

    @classmethod
    def from_config(cls, cfg) -> "Handshake":
        return cls(cfg.detectors)

    def __call__(self, x: PointInput) -> tuple[bool, float]:
        r = x.result
        ul = r.uplink.position if r.uplink is not None else None
        v = self.handshake(r.position.position if r.position.ok else None,
                           ul.position if (ul is not None and ul.ok) else None)
        return v.valid, v.stat


@DETECTOR_REGISTRY.register("Tracking")
class Tracking(Detector):
    """The Kalman tracker on the DL fix (with ``detectors.tracking.measurement_noise``
    'fix_covariance', the fix's covariance as the measurement's). :attr:`last_valid`: its
    position after its last accepted fix (None before the first)."""

    def __init__(self, cfg: DetectorsConfig):
        super().__init__(cfg)
        self.tracker = KalmanTracker(cfg.tracking)
        self.last_valid: np.ndarray | None = None

    @classmethod
    def from_config(cls, cfg) -> "Tracking":
        """The tracker of a run's config, ``measurement_noise`` 'auto' resolved
        (:attr:`Config.tracking_measurement_noise`; built from a ``DetectorsConfig`` alone,
        'auto' is 'fixed')."""
        d = cfg.detectors
        return cls(replace(d, tracking=replace(d.tracking,
                                               measurement_noise=cfg.tracking_measurement_noise)))

    def reset(self) -> None:
        self.tracker.reset()
        self.last_valid = None

    def update(self, est_xy: np.ndarray, dt_s: float | None,
               cov: np.ndarray | None = None) -> tuple[bool, float]:
        """(valid, stat) of the tracker on the DL fix ``est_xy``."""
        z = est_xy if np.all(np.isfinite(est_xy)) else None
        if self.cfg.tracking.measurement_noise == "fix_covariance" and cov is not None:
            v = self.tracker(z, dt_s, cov)
        else:
            v = self.tracker(z, dt_s)
        if v.accepted:
            self.last_valid = v.position.copy()
        return v.valid, v.stat

    def __call__(self, x: PointInput) -> tuple[bool, float]:
        return self.update(x.est_xy, x.dt_s, x.covariance)

    def replay(self, row: PointRow, dt_s: float | None) -> None:
        self.update(row.est_xy, dt_s, row.fix_cov)


if DETECTOR_REGISTRY.names() != DETECTORS:   # the built-ins are the CSV's columns, in its order
    raise RuntimeError(f"built-in detectors {DETECTOR_REGISTRY.names()} are not {DETECTORS}")
