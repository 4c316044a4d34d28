"""The receiver stages of the chain: timing, DL fix, angles, tags, uplink.

Each is configured once and called per point on the previous stages' typed results:

* :class:`TimingStage`: per BS, cross-spectra of the received signal with the BS's replica,
  Doppler scan, ToA and hearability (:mod:`~veriloc_rt.phy.receiver.sync`,
  :mod:`~veriloc_rt.phy.receiver.toa`); RSTDs against BS 0 -> :class:`Timing`;
* :class:`FixStage`: the DL fix from the RSTDs of the detected BSs
  (:class:`~veriloc_rt.phy.receiver.multilateration.Multilaterator`);
* :class:`AngleStage`: the AoA per detected BS (:class:`~veriloc_rt.phy.receiver.aoa.AoAEstimator`),
  the ULA's mirror ambiguity resolved against the caller's reference azimuths -> :class:`Angles`;
* :class:`TagStage`: every checked tag of each detected BS, on the grid combined towards its
  peak (:class:`~veriloc_rt.phy.receiver.tag_verifier.TagVerifier`);
* :class:`UplinkStage`: the UE's SRS at the BSs and the UL fix
  (:class:`~veriloc_rt.phy.receiver.uplink.UplinkPositioner`), kept like the downlink's signal
  (:class:`~veriloc_rt.phy.chain.downlink.KeptDraw`): the adversary does not touch it.
"""

from __future__ import annotations

import json
from importlib import resources
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...config.channel import ChannelConfig, ReceiverConfig
from ...constants import SPEED_OF_LIGHT
from ...propagation.cir import CIR
from ..channel import Links
from ..nr.ofdm import OFDM
from ..receiver.aoa import AoAEstimate, AoAEstimator
from ..receiver.multilateration import MultilaterationResult, Multilaterator
from ..receiver.sync import frequency_cross_spectra_many, noise_estimates, time_cross_spectra
from ..receiver.tag_verifier import TagVerifier, estimate_tag_channel
from ..receiver.toa import CrossSpectra, ToAEstimate, ToAEstimator
from ..receiver.uplink import UplinkPositioner, UplinkResult
from ..shortcuts import reference
from .downlink import KeptDraw, Received

__all__ = ["AngleStage", "Angles", "FixStage", "RangeOverbound", "TagStage", "Timing",
           "TimingStage", "UplinkKey", "UplinkStage", "OVERBOUND_TAIL_MAX", "gaussian_overbound",
           "zenith_from_fix"]


@dataclass(frozen=True, eq=False)
class Timing:
    """Timing of the serving BSs at one point.

    estimates : tuple of ToAEstimate, per BS; spectra : tuple of CrossSpectra, per BS
    detected : [num_bs] bool; toa_s : [num_bs] float64, s, t0 + lag (NaN where not detected)
    rstd_s : [num_bs] float64, s, toa_i - toa_0
    """

    estimates: tuple
    spectra: tuple
    detected: np.ndarray
    toa_s: np.ndarray
    rstd_s: np.ndarray


class TimingStage:
    """ToA of every serving BS from the received signal and the BSs' replicas.

    :param toa: the ToA estimator; ofdm, slots: the waveform's
    :param channel: front end (``per_re_receiver``) and timing guard
    :param search_window_s: s, lags searched by the time-domain correlator
    :param busy_symbols: the PRS symbols of a slot (the others estimate the noise)
    :param noise_var: W, the receiver's nominal noise variance (used where the free symbols give
        no estimate)
    """

    def __init__(self, toa: ToAEstimator, ofdm: OFDM, slots, channel: ChannelConfig,
                 search_window_s: float, busy_symbols: Sequence[int], noise_var: float):
        self.toa, self.ofdm, self.slots, self.channel = toa, ofdm, slots, channel
        self.search_window_s = float(search_window_s)
        self.busy_symbols = tuple(int(s) for s in busy_symbols)
        #: [14, 1] bool, the symbols the noise estimates read
        self.free = np.array([s not in self.busy_symbols for s in range(14)])[:, None]
        self.noise_var = float(noise_var)
        #: the noise estimates by a Hermitian rank-k update (shortcut ``dofherk``)
        self.hermitian = not reference("dofherk")
        #: the last call on a grid without an adversary: (grid, replicas, nv, dof, estimates,
        #: spectra), what a call on that grid plus an adversary confined to some REs reuses
        self._benign: tuple | None = None

    def __call__(self, received: Received, replicas: Sequence[np.ndarray], t0: float,
                 occupied: Sequence[np.ndarray] | None = None) -> Timing:
        """:param replicas: per BS [S, 14, K] complex; t0: s, the timing reference
        :param occupied: per BS [S, 14, K] bool, ``replica != 0`` when known (the frame's
            :attr:`~veriloc_rt.phy.chain.frames.FrameSignals.replica_occupied`), else None

        A BS's estimate depends only on the received grid on its replica's REs and on the
        noise estimates from the free symbols. When ``received`` is the last benign grid plus an
        adversary's signal that reaches neither (``Received.touched``: a false BS spoofing
        other BSs' PRS), that BS's estimate and spectra are the benign call's, reused as they
        are (the same inputs give the same values).
        """
        grid = received.grid
        reuse = self._reusable(received, replicas)
        if reuse is not None:
            nv, dof = reuse[2], reuse[3]
        else:
            nv, dof = noise_estimates(grid, self.busy_symbols, self.hermitian)
            nv = nv if np.isfinite(nv) else self.noise_var
        occ = list(occupied) if occupied is not None else [None] * len(replicas)
        fresh = [j for j, rep in enumerate(replicas)
                 if reuse is None or received.reaches(rep != 0 if occ[j] is None else occ[j])]
        if self.channel.per_re_receiver:   # the TRPs' cross-spectra from one read of the grid
            made = dict(zip(fresh, frequency_cross_spectra_many(
                grid, [replicas[j] for j in fresh], self.ofdm, self.slots, [occ[j] for j in fresh])))
        else:
            made = {j: time_cross_spectra(received.iq, replicas[j], self.ofdm, self.slots,
                                          self.channel.timing_guard_s, self.search_window_s)
                    for j in fresh}
        ests, spectra = [], []
        for j in range(len(replicas)):
            if j not in made:
                ests.append(reuse[4][j])
                spectra.append(reuse[5][j])
                continue
            ests.append(self.toa(made[j], nv, dof))
            spectra.append(made[j])
        if received.plain:
            self._benign = (grid, tuple(replicas), nv, dof, tuple(ests), tuple(spectra))
        det = np.array([e.detected for e in ests])
        toa = np.array([t0 + e.toa_s if e.detected else np.nan for e in ests])
        return Timing(tuple(ests), tuple(spectra), det, toa, toa - toa[0])

    def _reusable(self, received: Received, replicas: Sequence[np.ndarray]) -> tuple | None:
        """The kept benign call when ``received`` is its grid plus an adversary's signal that
        leaves the free symbols alone and the replicas are the same, else None."""
        kept = self._benign
        if (kept is None or not received.adds_to(kept[0]) or len(replicas) != len(kept[1])
                or any(a is not b for a, b in zip(replicas, kept[1]))):
            return None
        return None if received.reaches(self.free) else kept


class FixStage:
    """The DL fix from the RSTDs of the detected BSs (BS 0 the reference).

    :param max_residual_m: m, the solver's residual check
    :param weighted: weighted least squares with each ToA's std from :func:`range_std` and the
        chi-square integrity test (``receiver.fix_weighting``); False: the unweighted fit
    :param bandwidth_hz: Hz, the PRS bandwidth (the CRLB's); floor_m: m, the std floor
    :param false_alarm: the integrity test's size; exclusion: fault exclusion on
    :param overbound: optional :class:`RangeOverbound`: each ToA's std is the larger of
        :func:`range_std`'s and the overbound of its peak-SNR bin
        (``receiver.range_error_model`` 'overbound')
    """

    def __init__(self, max_residual_m: float, weighted: bool = False, bandwidth_hz: float = 0.0,
                 floor_m: float = 0.0, false_alarm: float = 0.01, exclusion: bool = True,
                 overbound: "RangeOverbound | None" = None):
        self.overbound = overbound
        self.max_residual_m = float(max_residual_m)
        self.weighted, self.bandwidth_hz, self.floor_m = bool(weighted), float(bandwidth_hz), float(floor_m)
        self.false_alarm, self.exclusion = float(false_alarm), bool(exclusion)

    def __call__(self, timing: Timing, bs_pos: np.ndarray, ue_height_m: float) -> MultilaterationResult:
        """:param bs_pos: [num_bs, 3] float64, m; ue_height_m: m, the UE's known height"""
        return self.solve(timing.detected, timing.toa_s,
                          [e.peak_snr_db for e in timing.estimates], bs_pos, ue_height_m)

    def solve(self, detected, toa_s, peak_snr_db, bs_pos: np.ndarray,
              ue_height_m: float) -> MultilaterationResult:
        """The fix from the ToAs of the BSs ``detected`` (a subset: the fix from those alone).

        :param detected: [num_bs] bool; toa_s: [num_bs] float64, s; peak_snr_db: [num_bs] dB
        """
        det = np.asarray(detected, dtype=bool)
        toa = np.asarray(toa_s, dtype=float)
        snr = np.asarray(peak_snr_db, dtype=float)
        ref = reference_trp(det, snr)
        rstd = toa - toa[ref]
        if not self.weighted:
            solver = Multilaterator(ue_height_m=ue_height_m, max_residual_m=self.max_residual_m)
            return solver(bs_pos, np.where(det, rstd, np.nan), ref, det)
        # the weighted fit's check is the chi-square test: the rms check is left wide open
        solver = Multilaterator(ue_height_m=ue_height_m, max_residual_m=1e9,
                                false_alarm=self.false_alarm, exclusion=self.exclusion)
        sig = range_std(snr, self.bandwidth_hz, self.floor_m)
        if self.overbound is not None:
            sig = np.maximum(sig, self.overbound.sigma(snr))
        return solver(bs_pos, np.where(det, rstd, np.nan), ref, det, range_std_m=sig)


class RangeOverbound:
    """A zero-mean Gaussian overbound of the ToA range error per peak-SNR bin (the overbounding
    of GNSS integrity, e.g. ARAIM: a Gaussian whose tails are at least as heavy as the measured
    error distribution's), read from a calibration table made by
    ``scripts/calibrate_range_overbound.py`` from benign runs of this simulator.

    The table (JSON): ``snr_edges_db`` [num_bins + 1] ascending, ``sigma_m`` [num_bins], plus
    the description of what it was calibrated on. A peak SNR below the first edge takes the
    first bin's sigma, above the last the last bin's (the table says nothing beyond its data).

    :param edges_db: [num_bins + 1] float64, dB; sigma_m: [num_bins] float64, m
    """

    #: the shipped table, in the package's data folder
    SHIPPED = "range_overbound.json"

    def __init__(self, edges_db, sigma_m):
        self.edges_db = np.asarray(edges_db, dtype=float)
        self.sigma_m = np.asarray(sigma_m, dtype=float)
        if (self.edges_db.ndim != 1 or self.sigma_m.shape != (self.edges_db.size - 1,)
                or self.sigma_m.size < 1 or np.any(np.diff(self.edges_db) <= 0)
                or not np.all(np.isfinite(self.sigma_m) & (self.sigma_m > 0))):
            raise ValueError("Arguments `edges_db` (ascending, num_bins + 1) and `sigma_m` "
                             "(num_bins, finite, > 0) do not make a table")

    @classmethod
    def from_json(cls, text: str) -> "RangeOverbound":
        d = json.loads(text)
        return cls(d["snr_edges_db"], d["sigma_m"])

    @classmethod
    def shipped(cls) -> "RangeOverbound":
        """The table shipped with the package (``veriloc_rt/data/range_overbound.json``)."""
        return cls.from_json(resources.files("veriloc_rt").joinpath(
            "data", cls.SHIPPED).read_text())

    def sigma(self, peak_snr_db) -> np.ndarray:
        """[num_bs] float64, m: the overbound sigma of each ToA's peak-SNR bin (non-finite SNR:
        the first bin)."""
        snr = np.asarray(peak_snr_db, dtype=float)
        snr = np.where(np.isfinite(snr), snr, -np.inf)
        b = np.clip(np.searchsorted(self.edges_db, snr, side="right") - 1, 0,
                    self.sigma_m.size - 1)
        return self.sigma_m[b]


#: the overbound checks the tails only: empirical tail probabilities up to this (near the
#: median z(1 - q) -> 0 and the ratio y / z is the sampling noise of the median over ~0)
OVERBOUND_TAIL_MAX = 0.1


def gaussian_overbound(y, p_min: float, q_max: float = OVERBOUND_TAIL_MAX) -> float:
    """Smallest sigma of a zero-mean Gaussian with at least the empirical tail probability of
    the sample ``y`` in both tails: for each y_k > 0 with empirical P(Y >= y_k) = q in
    [p_min, q_max], sigma >= y_k / z(1 - q) (z the standard normal quantile), and the same for
    -y (the left tail). 0 for a sample with no such point. y : [n] float64."""
    from scipy.stats import norm

    y = np.asarray(y, dtype=float)
    out = 0.0
    for side in (np.sort(y)[::-1], np.sort(-y)[::-1]):     # right tail, then the left one
        q = np.arange(1, y.size + 1) / y.size              # P(Y >= y_k), k-th largest
        keep = (side > 0) & (q >= p_min) & (q <= q_max)
        if keep.any():
            out = max(out, float(np.max(side[keep] / norm.isf(q[keep]))))
    return out


def range_std(peak_snr_db: np.ndarray, bandwidth_hz: float, floor_m: float) -> np.ndarray:
    """Range std of each ToA, m: the CRLB of a delay estimate, var(tau) >= 1 / (8 pi^2 beta^2
    SNR) with beta the rms bandwidth (Kay, Fundamentals of Statistical Signal Processing:
    Estimation Theory, 1993, ch. 3's range estimation; Gezici et al., IEEE Signal Processing
    Magazine 22(4), 2005: references as recalled, their equation numbers not checked here;
    tests/unit/phy/test_reference_trp.py checks the formula as written), for a PRS spectrum
    flat over B (beta^2 = B^2 / 12), so
    sigma_r^2 = 3 c^2 / (2 pi^2 B^2 SNR), plus ``floor_m`` in quadrature. SNR is the
    post-integration SNR, taken from the correlation peak over its noise floor as
    10^(peak_snr_db / 10) - 1 (the peak metric holds the noise's mean once); at least 1e-3.

    :param peak_snr_db: [num_bs] float64, dB (non-finite counts as SNR 1e-3: such a BS is not
        detected and the fix does not use it)
    :returns: [num_bs] float64, m
    """
    snr = np.maximum(10.0 ** (np.asarray(peak_snr_db, dtype=float) / 10.0) - 1.0, 1e-3)
    snr = np.where(np.isfinite(snr), snr, 1e-3)
    crlb = 3.0 * SPEED_OF_LIGHT**2 / (2.0 * np.pi**2 * bandwidth_hz**2 * snr)
    return np.sqrt(crlb + floor_m**2)


def reference_trp(detected, peak_snr_db) -> int:
    """The RSTD reference: slot 0 (the strongest TRP by the serving order) when it is heard,
    else the heard TRP with the highest correlation-peak SNR (0 when none is heard). With three
    TRPs a lost slot 0 leaves two, too few for a fix whichever is the reference.

    :param detected: [num_bs] bool; peak_snr_db: [num_bs] float64, dB
    """
    det = np.asarray(detected, bool)
    if det[0] or not det.any():
        return 0
    return int(np.argmax(np.where(det, np.asarray(peak_snr_db, dtype=float), -np.inf)))


def zenith_from_fix(bs_pos: np.ndarray, fix: MultilaterationResult) -> np.ndarray:
    """[num_bs] float64, rad, zenith of arrival from each BS seen from the DL fix (pi/2 without a
    fix): arccos(dz / |d|), d = BS - fix."""
    if not fix.ok:
        return np.full(len(bs_pos), np.pi / 2)
    d = bs_pos - fix.position[None, :]
    return np.arccos(np.clip(d[:, 2] / np.linalg.norm(d, axis=1), -1.0, 1.0))


@dataclass(frozen=True, eq=False)
class Angles:
    """aoa : list of AoAEstimate or None (None: BS not detected); azimuth : [num_bs] float64,
    rad, resolved against the reference (NaN without one)."""

    aoa: list
    azimuth: np.ndarray


class AngleStage:
    """AoA per detected BS.

    :param aoa: the AoA estimator
    :param snapshots: 'peak' (the per-block correlations at the ToA) or every occupied bin of
        the Doppler-derotated cross-spectra (``receiver.aoa_snapshots``)
    """

    def __init__(self, aoa: AoAEstimator, snapshots: str):
        self.aoa, self.snapshots = aoa, snapshots

    def __call__(self, timing: Timing, zenith: np.ndarray, reference_azimuth=None) -> Angles:
        """:param zenith: [num_bs] float64, rad; reference_azimuth: [num_bs] float64, rad, or None"""
        n = len(timing.estimates)
        aoas: list[AoAEstimate | None] = []
        az = np.full(n, np.nan)
        for b, (e, cs) in enumerate(zip(timing.estimates, timing.spectra)):
            if not e.detected:
                aoas.append(None)
                continue
            est = self.aoa(self._snapshots(e, cs), float(zenith[b]))
            aoas.append(est)
            if reference_azimuth is not None:
                ref = np.broadcast_to(np.asarray(reference_azimuth, dtype=float), (n,))[b]
                az[b] = float(est.resolve(ref)[0])
        return Angles(aoas, az)

    def _snapshots(self, e: ToAEstimate, cs: CrossSpectra) -> np.ndarray:
        if self.snapshots == "peak":
            return e.snapshots
        rot = np.exp(-2j * np.pi * e.doppler_hz * (cs.block_times - cs.block_times.mean()))
        x = cs.dense * rot[None, :, None]
        return x[:, cs.ref_power > 0]


class TagStage:
    """The tag check of every detected BS.

    :param tag_slots: which of each BS's PRS slots have their tags checked (indices in the
        frame with one slot group; else counted from the BS's group's first slot)
    :param slots: the frame's slot numbers
    """

    def __init__(self, tag_slots: Sequence[int], slots):
        self.tag_slots, self.slots = tuple(int(s) for s in tag_slots), slots
        #: the last call on a grid without an adversary: (grid, verifier, frame, estimates,
        #: tags), what a call on that grid plus an adversary confined to some REs reuses
        self._benign: tuple | None = None

    def __call__(self, verifier: TagVerifier, grid: np.ndarray, estimates: Sequence[ToAEstimate],
                 frame: int, replicas: Sequence[np.ndarray] | None,
                 received: Received | None = None) -> np.ndarray:
        """[num_bs] bool: every checked tag of each detected BS verifies.

        A BS's check reads the grid only on its PRS and tag REs of the checked slots, with its
        ToA estimate. When ``received`` is the last benign grid plus an adversary's signal
        (``Received.benign``, ``Received.touched``) that leaves those REs alone, and the estimate
        is the benign call's own (:class:`TimingStage` reused it), the benign verdict is reused.

        :param grid: [A, S, 14, K] complex, the received grid (its first slots suffice)
        :param replicas: per BS [S, 14, K], the BSs' own PRS replicas (None: the verifier
            regenerates them)
        :param received: what ``grid`` came from (None: nothing is kept or reused)
        """
        kept = self._benign
        reuse = (kept is not None and received is not None and received.adds_to(kept[0])
                 and kept[1] is verifier and kept[2] == frame)
        lay = verifier.layout
        tags = np.zeros(len(estimates), dtype=bool)
        for b, e in enumerate(estimates):
            if (reuse and b < len(kept[3]) and e is kept[3][b]
                    and not received.reaches(lay.prs_mask(b) | lay.tag_mask(b),
                                             self.slots_of(lay, b))):
                tags[b] = kept[4][b]
                continue
            rep = replicas[b] if replicas is not None else None
            tags[b] = e.detected and self.one(verifier, grid, e, b, frame, rep)
        if received is not None and received.plain:
            self._benign = (grid, verifier, frame, tuple(estimates), tags.copy())
        return tags

    def slots_of(self, layout, bs: int) -> list[int]:
        """Indices of the frame's slots whose tags of BS ``bs`` are checked: its own
        ``tag_slots``-th PRS slots (:meth:`~veriloc_rt.phy.nr.grid.ReLayout.own_slot`)."""
        return [layout.own_slot(bs, t) for t in self.tag_slots]

    def one(self, verifier: TagVerifier, grid: np.ndarray, est: ToAEstimate, bs: int, frame: int,
            replica: np.ndarray | None) -> bool:
        """All checked tags of BS ``bs`` verify, on the grid combined towards its peak (MRC).

        :param replica: [S, 14, K] the BS's own PRS replica (None: the verifier regenerates it)
        """
        w = np.conj(est.peak)
        nrm = np.linalg.norm(w)
        w = w / nrm if nrm > 0 else np.ones_like(w) / np.sqrt(w.size)
        lay = verifier.layout
        for s in self.slots_of(lay, bs):
            combined = np.tensordot(w, grid[:, s], axes=(0, 0))
            if replica is None:
                ok = verifier(combined, bs, frame, int(self.slots[s]))
            else:  # same estimate as the verifier's own, from the cached replica
                h_t, nv = estimate_tag_channel(combined, lay, bs, replica[s], verifier.smoothing)
                ok = verifier(combined, bs, frame, int(self.slots[s]), noise_var=nv, tag_channel=h_t)
            if not ok:
                return False
        return True


@dataclass(frozen=True)
class UplinkKey:
    """What an uplink fix depends on besides the generator: the CIR (the same object) and the point."""

    cir: CIR
    point: int


class UplinkStage:
    """The UL fix of a point, the last one kept under its :class:`UplinkKey` and the generator's
    state (the adversary does not touch the uplink).

    :param positioner: the uplink receiver
    :param element_pos: [num_ant, 3] float64, m, the UE's array (the SRS leaves its centre)
    :param fix: the solver of the UL fix: the DL's :class:`FixStage` (the same fit, weighting,
        integrity test and exclusion on the BSs' TDOAs; with three TRPs and the unweighted fit
        the same call as the positioner's own), None: the positioner's own
    """

    def __init__(self, positioner: UplinkPositioner, element_pos: np.ndarray,
                 fix: FixStage | None = None):
        self.positioner, self.element_pos, self.fix = positioner, element_pos, fix
        self._kept = KeptDraw()

    def __call__(self, bs_ue: CIR, point: int, bs_pos: np.ndarray, ue_height_m: float,
                 rng: np.random.Generator) -> UplinkResult:
        def compute():
            return self.positioner(Links.uplink_from_cir(bs_ue, point, self.element_pos), bs_pos,
                                   ue_height_m, rng,
                                   solve=None if self.fix is None else self.fix.solve)

        if not self.positioner.noise.follows_call_rng:
            return compute()
        return self._kept(UplinkKey(bs_ue, point), rng, compute)
