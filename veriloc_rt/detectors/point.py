"""The stateless detectors on one chain result: HMAC, DigSig, ABSA and the DL-UL handshake.

The four are the registered built-ins of :mod:`.registry` (a run calls them there, with the
Kalman tracker and any plug-in, :mod:`veriloc_rt.sim.runner`); :func:`point_verdicts` runs them
on one chain result for the benign diagnostics (:mod:`veriloc_rt.studies.diagnostics`). The two
differ on purpose only in the ABSA reference position, a parameter: the run's is the *last
validated position* (the tracker's position after its last accepted fix, before the first one
the current DL fix), as the paper's receiver would have it; the diagnostics' is the true UE
position, to measure the AoA against the geometry.
The AoA's mirror ambiguity is resolved against the azimuth from that reference (paper Sec.
"Angular-Based Source Authentication"; :func:`veriloc_rt.phy.receiver.aoa.resolve_ambiguity`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.detectors import DetectorsConfig
from ..phy.chain import ChainResult
from .registry import ABSA, DigSig, HMAC, Handshake, PointInput

__all__ = ["PointDetectors", "point_statistics", "point_verdicts"]


@dataclass(frozen=True, eq=False)
class PointDetectors:
    """The four stateless built-in detectors of a run (:mod:`.registry`)."""

    hmac: HMAC
    digsig: DigSig
    absa: ABSA
    handshake: Handshake

    @classmethod
    def from_config(cls, cfg: DetectorsConfig) -> "PointDetectors":
        return cls(HMAC(cfg), DigSig(cfg), ABSA(cfg), Handshake(cfg))


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
    x = PointInput(-1, float("nan"), result, ds, bs_pos, reference_position,
                   np.full(2, np.nan), None, None)
    v = {"HMAC": detectors.hmac(x)}
    if ds is not None:
        v["DigSig"] = detectors.digsig(x)
    v["ABSA"] = detectors.absa(x)
    v["Handshake"] = detectors.handshake(x)
    return v
