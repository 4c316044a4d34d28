"""What one call of the positioning chain computes (:class:`ChainPlan`) and returns
(:class:`ChainResult`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..receiver.multilateration import MultilaterationResult
from ..receiver.uplink import UplinkResult

__all__ = ["ChainPlan", "ChainResult", "FULL", "FIX_ONLY", "REPLICAS"]

#: the local PRS replica a receiver correlates with: each BS's own setting (its encrypted PRS
#: if it encrypts), or the standard / encrypted PRS of every BS
REPLICAS = ("own", "standard", "encrypted")


@dataclass(frozen=True, eq=False)
class ChainResult:
    """Everything the detectors need from one trajectory point.

    detected : [num_bs] bool, BS heard (peak above the hearability threshold)
    toa_s : [num_bs] float64, s, absolute arrival time (the receiver's timing reference t0 plus
        the estimated lag; NaN where not detected); only differences are meaningful
    rstd_s : [num_bs] float64, s, toa_i - toa_0 (NaN where not detected)
    doppler_hz, peak_snr_db : [num_bs] float64, Hz and dB
    position : MultilaterationResult, the DL fix
    aoa : list of AoAEstimate or None (None: not detected, or angles not in the plan)
    azimuth : [num_bs] float64, rad, AoA resolved against the reference (NaN without one)
    tags_valid : [num_bs] bool, every checked tag of the BS verified (False if the scheme is
        'none', the BS was not detected or tags are not in the plan); tags_checked : bool, tags
        were checked (the scheme is not 'none' and the plan has them)
    uplink : UplinkResult or None
    tx_power_w : [num_bs] float64, W, the serving BSs' powers after power control
    timing_reference_s : float, s, t0
    toa_estimates : list of ToAEstimate (per BS, raw)
    """

    detected: np.ndarray
    toa_s: np.ndarray
    rstd_s: np.ndarray
    doppler_hz: np.ndarray
    peak_snr_db: np.ndarray
    position: MultilaterationResult
    aoa: list
    azimuth: np.ndarray
    tags_valid: np.ndarray
    tags_checked: bool
    uplink: UplinkResult | None
    tx_power_w: np.ndarray
    timing_reference_s: float
    toa_estimates: list


@dataclass(frozen=True, eq=False)
class ChainPlan:
    """The receiver stages one chain call runs (the transmitter, channel and timing always run,
    and the DL fix with the timing).

    :param angles: AoA per detected BS (else ``aoa`` all None, ``azimuth`` NaN)
    :param tags: the tag check (else ``tags_valid`` all False, ``tags_checked`` False; the BSs
        still transmit their tags)
    :param uplink: the UL fix (when the chain's receiver config has the uplink)
    :param replica: one of :data:`REPLICAS`
    :param timing_from: another chain's result for the same point, serving set, PRS and noise
        stream, differing only in its tags (the HMAC-tagged chain's for a DS-tagged one): its
        timing, fix, AoA and uplink are kept and only this chain's grid and tags are computed
        (the MRC weights of the tag check are its peaks); in the frequency domain only the slots
        up to the last of ``receiver.tag_slots`` are received. Exact when both chains receive
        the same PRS REs, as they do through the frequency-domain channel unless the
        adversary's signal depends on the tags (a relay's gain control sees them: ~1e-3 on its
        gain). Needs ``angles`` and ``uplink`` False (they come from the given result)
    """

    angles: bool = True
    tags: bool = True
    uplink: bool = True
    replica: str = "own"
    timing_from: ChainResult | None = None

    def __post_init__(self) -> None:
        if self.replica not in REPLICAS:
            raise ValueError(f"Argument `replica` must be one of {REPLICAS}, not {self.replica!r}")
        if self.timing_from is not None:
            if not isinstance(self.timing_from, ChainResult):
                raise TypeError("Argument `timing_from` must be a ChainResult, not "
                                f"{type(self.timing_from).__name__}")
            if self.angles or self.uplink:
                raise ValueError("A plan with `timing_from` keeps that result's angles and "
                                 "uplink: `angles` and `uplink` must be False")

    @property
    def replica_encrypted(self) -> bool | None:
        """The replica as the transmitter takes it: None own, else encrypted or not."""
        return None if self.replica == "own" else self.replica == "encrypted"

    @classmethod
    def tags_on(cls, result: ChainResult, replica: str = "own") -> "ChainPlan":
        """Only this chain's tags, on the timing of ``result`` (see ``timing_from``)."""
        return cls(angles=False, tags=True, uplink=False, replica=replica, timing_from=result)


#: every stage
FULL = ChainPlan()
#: the DL fix alone: no AoA, no tag check, no uplink (a run's encrypted-PRS chain, whose
#: outcomes alone are used)
FIX_ONLY = ChainPlan(angles=False, tags=False, uplink=False)
