"""The stateless detectors on one chain result: HMAC, DigSig, ABSA and the DL-UL handshake.

One function, :func:`point_verdicts`, for every caller: a run (:mod:`veriloc_rt.sim.runner`,
which adds the stateful Kalman tracker) and the benign diagnostics
(:mod:`veriloc_rt.studies.diagnostics`). They differ on purpose only in the ABSA reference
position, a parameter: the run's is the *last validated position* (the tracker's position after
its last accepted fix, before the first one the current DL fix), as the paper's receiver would
have it; the diagnostics' is the true UE position, to measure the AoA against the geometry.
The AoA's mirror ambiguity is resolved against the azimuth from that reference (paper Sec.
"Angular-Based Source Authentication"; :func:`veriloc_rt.phy.receiver.aoa.resolve_ambiguity`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.detectors import DetectorsConfig
from ..phy.chain import ChainResult
from .absa import ABSADetector
from .handshake import HandshakeDetector
from .tags import TagDetector

__all__ = ["PointDetectors", "point_statistics", "point_verdicts"]


@dataclass(frozen=True, eq=False)
class PointDetectors:
    """The four stateless detectors of a run."""

    hmac: TagDetector
    digsig: TagDetector
    absa: ABSADetector
    handshake: HandshakeDetector

    @classmethod
    def from_config(cls, cfg: DetectorsConfig) -> "PointDetectors":
        return cls(TagDetector(cfg.hmac), TagDetector(cfg.digsig), ABSADetector(cfg.absa),
                   HandshakeDetector(cfg.handshake))


def point_verdicts(detectors: PointDetectors, result: ChainResult, bs_pos: np.ndarray,
                   reference_position: np.ndarray | None, ds: ChainResult | None = None) -> dict:
    """``{detector: valid}`` for HMAC, DigSig (with ``ds``), ABSA and Handshake, in that order.

    :param result: the standard chain's result (HMAC tags, AoA, DL and UL fixes)
    :param bs_pos: [num_bs, 3] float64, m, the serving BSs
    :param reference_position: [2 or 3] float64, m, ABSA's reference position (None: none; see
        the module docstring)
    :param ds: the chain result whose tags DigSig checks (None: no DigSig verdict)
    """
    return {d: v for d, (v, _) in
            point_statistics(detectors, result, bs_pos, reference_position, ds).items()}


def point_statistics(detectors: PointDetectors, result: ChainResult, bs_pos: np.ndarray,
                     reference_position: np.ndarray | None,
                     ds: ChainResult | None = None) -> dict:
    """``{detector: (valid, stat)}``: :func:`point_verdicts` with each detector's statistic
    (the verdicts' ``stat``: tag fraction, ABSA deviation in deg, DL-UL distance in m), same
    arguments and order."""
    h = detectors.hmac(result.tags_valid, result.detected)
    v = {"HMAC": (h.valid, h.stat)}
    if ds is not None:
        d = detectors.digsig(ds.tags_valid, ds.detected)
        v["DigSig"] = (d.valid, d.stat)
    ref_az = detectors.absa.reference_azimuth(bs_pos, reference_position)
    # no AoA: NaN; no reference: unresolvable, and ABSA does not check that BS anyway
    az = np.array([float(a.resolve(r)[0]) if (a is not None and np.isfinite(r)) else np.nan
                   for a, r in zip(result.aoa, ref_az)])
    a = detectors.absa(az, bs_pos, reference_position=reference_position)
    v["ABSA"] = (a.valid, a.stat)
    ul = result.uplink.position if result.uplink is not None else None
    hs = detectors.handshake(result.position.position if result.position.ok else None,
                             ul.position if (ul is not None and ul.ok) else None)
    v["Handshake"] = (hs.valid, hs.stat)
    return v
