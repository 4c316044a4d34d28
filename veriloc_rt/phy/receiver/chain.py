"""The per-point positioning chain: transmit, channel, receive, locate, authenticate.

:class:`PositioningChain` is configured once (waveform, security, channel and receiver configs,
the UE array, the serving BSs and their keys) and called per trajectory point with that point's
CIRs. It works the same on ray-traced and UMa CIRs (both are :class:`CIR`):

1. the serving BSs' frame (PRS, encryption, tags; cached per frame counter) and the optional
   adversary signal go through their links (:mod:`veriloc_rt.phy.channel`): power control, Doppler,
   thermal noise, in the frequency domain (fast) or the time domain (reference);
2. per BS: cross-spectra with the local replica, Doppler scan, ToA, hearability
   (:mod:`~veriloc_rt.phy.receiver.sync`, :mod:`~veriloc_rt.phy.receiver.toa`); RSTDs against BS 0;
3. the DL fix (:class:`Multilaterator`), the per-BS AoA (:class:`AoAEstimator`, ambiguity
   resolved against the caller's reference azimuths), the tags (:class:`TagVerifier`, on the
   antenna-combined grid) and the UL fix (:class:`UplinkPositioner`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..channel import (Links, add_noise, apply_frequency, apply_time, dbm_to_watt,
                       equal_arrival_powers, occupied_power_factor, re_amplitude,
                       receiver_noise_variance, timing_reference)
from ...config.channel import ChannelConfig, ReceiverConfig
from ...config import ArrayConfig
from ...constants import SPEED_OF_LIGHT
from ...config.nr import NRConfig
from ..transmitter import PRSTransmitter
from ..nr.ofdm import OFDM
from ...propagation.cir import CIR, NO_TX, ula_element_positions
from ...config.security import SecurityConfig
from ..security.keys import BSKeys, make_keys
from .tag_verifier import TagVerifier, estimate_tag_channel
from .aoa import AoAEstimate, AoAEstimator
from .multilateration import MultilaterationResult, Multilaterator
from .sync import frequency_cross_spectra, noise_dof, noise_variance, time_cross_spectra
from .toa import ToAEstimate, ToAEstimator
from .uplink import UplinkPositioner, UplinkResult

log = logging.getLogger(__name__)

__all__ = ["ChainResult", "PositioningChain"]

#: identities given to empty serving slots (top of the u32 range the tags carry)
_DUMMY_ID = 0xFFFF_FF00


#: stages of one chain call, in order: PRS/tag grids and replicas; CIRs applied plus noise;
#: Doppler/timing sync and ToA per BS; multilateration; AoA; tag decoding; the uplink (SRS
#: through its own channel, ToA at the BSs, UL fix)
STAGES = ("waveform", "channel", "toa", "position", "aoa", "tags", "uplink")


class _StageClock:
    """Adds the time since the previous mark to ``totals[stage]`` at each call."""

    def __init__(self, totals: dict):
        self.totals, self.t = totals, time.perf_counter()

    def __call__(self, stage: str) -> None:
        now = time.perf_counter()
        self.totals[stage] += now - self.t
        self.t = now


@dataclass(frozen=True, eq=False)
class ChainResult:
    """Everything the detectors need from one trajectory point.

    detected : [num_bs] bool, BS heard (peak above the hearability threshold)
    toa_s : [num_bs] float64, s, absolute arrival time (the receiver's timing reference t0 plus
        the estimated lag; NaN where not detected); only differences are meaningful
    rstd_s : [num_bs] float64, s, toa_i - toa_0 (NaN where not detected)
    doppler_hz, peak_snr_db : [num_bs] float64, Hz and dB
    position : MultilaterationResult, the DL fix
    aoa : list of AoAEstimate or None (None: not detected)
    azimuth : [num_bs] float64, rad, AoA resolved against the reference (NaN without one)
    tags_valid : [num_bs] bool, every checked tag of the BS verified (False if the scheme is
        'none' or the BS was not detected); tags_checked : bool, the scheme is not 'none'
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


class PositioningChain:
    """Transmitters, channel and receiver of one run, called per trajectory point.

    :param nr: waveform config; security: encryption and tags; channel, receiver: this module's
    :param ue_array: the UE's ULA (number of elements, spacing, axis azimuth)
    :param carrier_frequency_hz: float, Hz
    :param keys: by BS id, for encryption and tags (None if neither is used). The serving BSs of
        a point are the CIR's ``tx_index`` (slot 0: RSTD reference); a transmitter and tag
        verifier are built per serving set and cached. An empty slot (``NO_TX``) transmits under
        a dummy identity through a link without paths, i.e. nothing arrives.
    :param fix_only: compute the DL fix alone: no AoA and no tag check (``aoa`` all None,
        ``tags_checked`` False); the BSs still transmit their tags. For a chain whose
        outcomes alone are used (a run's encrypted-PRS chain)
    """

    #: keep the last serving BSs' signal plus noise and uplink fix for the next call with the
    #: same point and noise generator state (:meth:`_benign`); off where the noise comes from
    #: elsewhere
    keep_benign = True

    def __init__(self, nr: NRConfig, security: SecurityConfig, channel: ChannelConfig,
                 receiver: ReceiverConfig, ue_array: ArrayConfig, carrier_frequency_hz: float,
                 keys: Mapping[int, BSKeys] | None = None, fix_only: bool = False):
        nr.validate()
        security.validate()
        self.nr, self.security, self.channel, self.receiver = nr, security, channel, receiver
        self.keys = dict(keys) if keys is not None else {}
        self.fix_only = bool(fix_only)
        self.ofdm = OFDM(nr)
        self.slots = range(nr.slots_per_frame)
        self._setups: dict[tuple, tuple] = {}
        if any(s >= nr.slots_per_frame for s in receiver.tag_slots):
            raise ValueError(f"receiver.tag_slots {receiver.tag_slots} exceed nr.slots_per_frame "
                             f"{nr.slots_per_frame}")
        wavelength = SPEED_OF_LIGHT / carrier_frequency_hz
        self.element_pos = ula_element_positions(ue_array.num_elements,
                                                 ue_array.spacing_wavelengths * wavelength,
                                                 np.deg2rad(ue_array.axis_azimuth_deg))
        self.aoa = AoAEstimator(receiver.aoa_method, receiver.aoa_num_sources or None,
                                ue_array.spacing_wavelengths, np.deg2rad(ue_array.axis_azimuth_deg))
        self.toa = ToAEstimator(receiver, channel.timing_guard_s)
        self.uplink = UplinkPositioner(nr, channel, receiver) if receiver.uplink else None
        fs = self.ofdm.sample_rate_hz
        self.noise_var = receiver_noise_variance(channel, fs, channel.ue_noise_figure_db)
        self.bs_power_factor = occupied_power_factor(channel.prs_power, nr.num_subcarriers, nr.comb,
                                                     security.tag_scheme != "none")
        self.frame_samples = self.ofdm.num_samples(self.slots)
        self.buffer_samples = self.frame_samples + int(np.ceil(receiver.search_window_s * fs)) + 64
        self.busy_symbols = tuple(int(l) for l in nr.prs_symbols)
        self.decimation = max(1, min(channel.time_decimation, self.ofdm.fft_size // nr.min_fft_size))
        self._frame: tuple | None = None
        #: the last serving BSs' signal plus noise and the last uplink fix (see :meth:`_benign`)
        self._kept_values: dict[str, tuple] = {}
        #: seconds spent per stage over every call (a run reports them; reading is optional)
        self.stage_s = dict.fromkeys(STAGES, 0.0)

    @property
    def num_bs(self) -> int:
        return self.nr.num_bs

    # -- per serving set and per frame caches ----------------------------------------------
    def setup(self, bs_ids: Sequence[int]) -> tuple[PRSTransmitter, TagVerifier | None]:
        """Transmitter and tag verifier of a serving set (cached)."""
        ids = tuple(int(b) for b in bs_ids)
        if ids not in self._setups:
            keys = dict(self.keys)
            ids_tx = tuple(b if b != NO_TX else _DUMMY_ID + j for j, b in enumerate(ids))
            for b in ids_tx:
                if b >= _DUMMY_ID and self.keys:
                    keys[b] = make_keys(b, rng=np.random.default_rng(b))
            tx = PRSTransmitter(self.nr, self.security, ids_tx, keys or None)
            ver = (TagVerifier(self.nr, self.security, ids_tx, keys)
                   if self.security.tag_scheme != "none" else None)
            self._setups[ids] = (tx, ver)
        return self._setups[ids]

    def frame_signals(self, bs_ids: Sequence[int], frame: int, encrypted_replica: bool | None = None) -> dict:
        """Grids, waveforms (time domain) and replicas of one frame (the last one is cached)."""
        key = (tuple(int(b) for b in bs_ids), frame, encrypted_replica)
        if self._frame is None or self._frame[0] != key:
            tx, _ = self.setup(bs_ids)
            grids = tx(frame, self.slots)
            wave = self.ofdm.modulate(grids, self.slots) if self.channel.domain == "time" else None
            reps = [tx.replica(b, frame, self.slots, encrypted_replica) for b in range(self.num_bs)]
            self._frame = (key, {"grids": grids, "waveform": wave, "replicas": reps})
        return self._frame[1]

    # -- stages ----------------------------------------------------------------------------
    def _receive(self, links: Links, amps: np.ndarray, sig: dict, t0: float, adv: Links | None,
                 adv_signal: np.ndarray | None, rng: np.random.Generator, num_slots: int | None = None,
                 key: tuple | None = None):
        """Received (grid [A, S, 14, K], IQ [A, N] or None): the serving BSs' signal plus noise
        (:meth:`_benign`), plus the adversary's signal.

        :param num_slots: frequency domain only: the grid of the first ``num_slots`` slots alone
            (the same values as those slots of the whole grid: the noise is drawn slot-major)
        :param key: identifies the serving BSs' signal and noise (see :meth:`_benign`)
        """
        adv_amp = re_amplitude([dbm_to_watt(self.channel.adversary_power_dbm)], self.ofdm)
        fs = self.ofdm.sample_rate_hz
        m = len(self.slots) if num_slots is None else num_slots
        base = self._benign(links, amps, sig, t0, rng, m, key)
        if self.channel.domain == "frequency":
            if adv is None:
                return base, None
            slots = self.slots[:m]
            if adv_signal.ndim == 3:
                return base + apply_frequency(adv, adv_signal[None, :m], adv_amp, self.ofdm, slots, t0), None
            iq = apply_time(adv, adv_signal[None], adv_amp, fs, t0, self.frame_samples, self.decimation)
            return base + self.ofdm.demodulate(iq, self.slots)[:, :m], None
        iq = base
        if adv is not None:
            wave = self.ofdm.modulate(adv_signal, self.slots) if adv_signal.ndim == 3 else adv_signal
            iq = iq + apply_time(adv, wave[None], adv_amp, fs, t0, self.buffer_samples, self.decimation)
        return self.ofdm.demodulate(iq, self.slots), iq

    def _benign(self, links: Links, amps: np.ndarray, sig: dict, t0: float,
                rng: np.random.Generator, num_slots: int, key: tuple | None) -> np.ndarray:
        """The serving BSs' signal plus noise (read-only): grid [A, num_slots, 14, K] or IQ [A, N].

        The adversary adds to it and does not change it, so a run evaluating several scenarios at
        one point computes it once: the last one is kept under ``key`` (point, frame, replica
        mode, slots, the CIR object and ``rng``'s state on entry; None: not kept), and a call with
        the same key gets it back with ``rng`` moved past the noise draws, as if drawn again.
        """
        def compute():
            if self.channel.domain == "frequency":
                x = apply_frequency(links, sig["grids"][:, :num_slots], amps, self.ofdm,
                                    self.slots[:num_slots], t0)
            else:
                x = apply_time(links, sig["waveform"], amps, self.ofdm.sample_rate_hz, t0,
                               self.buffer_samples, self.decimation)
            x = self._add_noise(x, rng)
            x.flags.writeable = False
            return x

        return self._kept("benign", None if key is None else key + (num_slots,), rng, compute)

    def _uplink(self, bs_ue: CIR, point: int, bs_pos: np.ndarray, ue_h: float,
                rng: np.random.Generator) -> UplinkResult:
        """The uplink fix (the adversary does not touch it: the last one is kept like
        :meth:`_benign`'s grid, under the CIR, the point and ``rng``'s state on entry)."""
        return self._kept("uplink", (bs_ue, point), rng, lambda: self.uplink(
            Links.uplink_from_cir(bs_ue, point, self.element_pos), bs_pos, ue_h, rng))

    def _kept(self, slot: str, key: tuple | None, rng: np.random.Generator, compute):
        """``compute()`` (which draws from ``rng``), or the value kept in ``slot`` by the last
        call with the same key and ``rng`` state, with ``rng`` moved past its draws. ``key[0]``
        is compared by identity (a CIR object), the rest by value; None: not kept."""
        if key is None or not self.keep_benign:
            return compute()
        key = key + (rng.bit_generator.state,)
        c = self._kept_values.get(slot)
        if c is not None and c[0][0] is key[0] and c[0][1:] == key[1:]:
            rng.bit_generator.state = c[2]
            return c[1]
        value = compute()
        self._kept_values[slot] = (key, value, rng.bit_generator.state)
        return value

    def _add_noise(self, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The received signal plus thermal noise: a grid [A, S, 14, K] in the frequency domain,
        IQ [A, N] in the time domain (the one place noise enters the downlink; a benchmark can
        override it to feed two fidelities the same noise realisation). A grid's noise is drawn
        slot by slot, so its first slots get the same noise whatever the number of slots."""
        return add_noise(x, self.noise_var, rng, major_axis=1 if x.ndim == 4 else 0)

    def _tags(self, verifier: TagVerifier, grid: np.ndarray, est: ToAEstimate, bs: int, frame: int,
              replica: np.ndarray | None) -> bool:
        """All checked tags of BS ``bs`` verify, on the grid combined towards its peak (MRC).

        :param replica: [S, 14, K] the BS's own PRS replica (None: the verifier regenerates it)
        """
        w = np.conj(est.peak)
        nrm = np.linalg.norm(w)
        w = w / nrm if nrm > 0 else np.ones_like(w) / np.sqrt(w.size)
        lay = verifier.layout
        for s in self.receiver.tag_slots:
            combined = np.tensordot(w, grid[:, s], axes=(0, 0))
            if replica is None:
                ok = verifier(combined, bs, frame, int(self.slots[s]))
            else:  # same estimate as the verifier's own, from the cached replica
                h_t, nv = estimate_tag_channel(combined, lay, bs, replica[s], verifier.smoothing)
                full = np.zeros_like(combined)
                full[lay.symbols[:, None], lay.tag_subcarriers(bs)] = h_t
                ok = verifier(combined, bs, frame, int(self.slots[s]), channel=full, noise_var=nv)
            if not ok:
                return False
        return True

    def _check_tags(self, verifier: TagVerifier | None, grid: np.ndarray, ests: list, frame: int,
                    sig: dict, encrypted_replica: bool | None) -> np.ndarray:
        """[num_bs] bool: every checked tag of each detected BS verifies (False without tags)."""
        tags = np.zeros(self.num_bs, dtype=bool)
        if verifier is not None:
            for b, e in enumerate(ests):
                rep = sig["replicas"][b] if encrypted_replica is None else None
                tags[b] = e.detected and self._tags(verifier, grid, e, b, frame, rep)
        return tags

    def _zenith(self, bs_pos: np.ndarray, fix: MultilaterationResult) -> np.ndarray:
        """Zenith of arrival from each BS seen from the DL fix (pi/2 without a fix)."""
        if not fix.ok:
            return np.full(len(bs_pos), np.pi / 2)
        d = bs_pos - fix.position[None, :]
        return np.arccos(np.clip(d[:, 2] / np.linalg.norm(d, axis=1), -1.0, 1.0))

    # -- main ------------------------------------------------------------------------------
    def __call__(self, bs_ue: CIR, point: int, rng: np.random.Generator, *, frame: int = 0,
                 adv_ue: CIR | None = None, adversary_signal: np.ndarray | None = None,
                 reference_azimuth=None, zenith=None, encrypted_replica: bool | None = None,
                 estimates: ChainResult | None = None) -> ChainResult:
        """Run the chain on trajectory point ``point``.

        :param bs_ue: CIR [num_points, num_bs] serving BS -> UE (slot 0 = reference)
        :param rng: numpy Generator for the noise (always explicit)
        :param frame: 32-bit frame counter (PRS encryption, tags)
        :param adv_ue: CIR [num_points, 1] adversary -> UE; used with ``adversary_signal``
        :param adversary_signal: what the adversary transmits, in the unit-RE normalisation of the
            BSs' grids: a grid [num_slots, 14, num_subcarriers] aligned with the frame, or IQ
            [num_samples] complex at ``nr.resolved_sample_rate_hz`` starting at t = 0
        :param reference_azimuth: [num_bs] float64, rad, resolves the ULA mirror ambiguity
        :param zenith: [num_bs] float64, rad, known zenith of arrival (None: from the DL fix)
        :param encrypted_replica: None: each BS's own setting; True/False: force the replica
        :param estimates: another chain's result for the same point, serving set, PRS and noise
            stream, differing only in its tags (the HMAC-tagged chain's for a DS-tagged one): its
            timing, fix, AoA and uplink are kept and only this chain's grid and tags are computed
            (the MRC weights of the tag check are its peaks), and in the frequency domain only
            the slots up to the last of ``receiver.tag_slots`` are received. Exact when both
            chains receive the same PRS REs, as they do through the frequency-domain channel
            unless the adversary's signal depends on the tags (a relay's gain control sees them:
            ~1e-3 on its gain)
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
        if bs_ue.num_tx != self.num_bs or bs_ue.num_ant != self.element_pos.shape[0]:
            raise ValueError(f"Argument `bs_ue` must have {self.num_bs} link slots and "
                             f"{self.element_pos.shape[0]} antennas, not {bs_ue.num_tx} and {bs_ue.num_ant}")
        if not 0 <= point < bs_ue.num_points:
            raise ValueError(f"Argument `point` must be in [0, {bs_ue.num_points}), not {point}")
        adv = None
        if adversary_signal is not None:
            if adv_ue is None:
                raise ValueError("Argument `adv_ue` is needed with `adversary_signal`")
            adversary_signal = np.asarray(adversary_signal)
            adv = Links.from_cir(adv_ue, point)
        bs_ids = tuple(int(b) for b in bs_ue.tx_index[point])
        clock = _StageClock(self.stage_s)
        _, verifier = self.setup(bs_ids)
        sig = self.frame_signals(bs_ids, frame, encrypted_replica)
        clock("waveform")
        links = Links.from_cir(bs_ue, point)
        powers = equal_arrival_powers(links.power_gain(), float(dbm_to_watt(self.channel.bs_max_power_dbm)),
                                      self.channel.power_control)
        amps = re_amplitude(powers * self.bs_power_factor, self.ofdm)
        t0 = timing_reference(links, self.channel.timing_guard_s)
        # with another chain's timing only the tags are left to do: the grid of the slots up to
        # the last checked one is enough (frequency domain)
        tag_only = estimates is not None and self.channel.domain == "frequency"
        m = max(self.receiver.tag_slots) + 1 if tag_only else None
        grid, iq = self._receive(links, amps, sig, t0, adv, adversary_signal, rng, m,
                                 (bs_ue, point, frame, encrypted_replica))
        clock("channel")
        if estimates is not None:
            if len(estimates.toa_estimates) != self.num_bs:
                raise ValueError(f"Argument `estimates` has {len(estimates.toa_estimates)} BSs, "
                                 f"the chain {self.num_bs}")
            tags = self._check_tags(verifier, grid, estimates.toa_estimates, frame, sig, encrypted_replica)
            clock("tags")
            return replace(estimates, tags_valid=tags, tags_checked=verifier is not None)
        nv = noise_variance(grid, self.busy_symbols)
        nv = nv if np.isfinite(nv) else self.noise_var
        dof = noise_dof(grid, self.busy_symbols)
        ests = []
        for b in range(self.num_bs):
            if self.channel.per_re_receiver:
                cs = frequency_cross_spectra(grid, sig["replicas"][b], self.ofdm, self.slots)
            else:
                cs = time_cross_spectra(iq, sig["replicas"][b], self.ofdm, self.slots,
                                        self.channel.timing_guard_s, self.receiver.search_window_s)
            ests.append((self.toa(cs, nv, dof), cs))
        det = np.array([e.detected for e, _ in ests])
        toa = np.array([t0 + e.toa_s if e.detected else np.nan for e, _ in ests])
        rstd = toa - toa[0]
        bs_pos = bs_ue.tx_pos[point]
        ue_h = float(bs_ue.rx_pos[point, 2])
        solver = Multilaterator(ue_height_m=ue_h, max_residual_m=self.receiver.max_residual_m)
        clock("toa")
        fix = solver(bs_pos, np.where(det, rstd, np.nan), 0, det)
        clock("position")
        zen = self._zenith(bs_pos, fix) if zenith is None else np.broadcast_to(np.asarray(zenith, float), (self.num_bs,))
        aoas: list[AoAEstimate | None] = []
        az = np.full(self.num_bs, np.nan)
        for b, (e, cs) in enumerate(ests):
            if not e.detected or self.fix_only:
                aoas.append(None)
                continue
            if self.receiver.aoa_snapshots == "peak":
                snaps = e.snapshots
            else:
                rot = np.exp(-2j * np.pi * e.doppler_hz * (cs.block_times - cs.block_times.mean()))
                x = cs.dense * rot[None, :, None]
                snaps = x[:, cs.ref_power > 0]
            est = self.aoa(snaps, float(zen[b]))
            aoas.append(est)
            if reference_azimuth is not None:
                ref = np.broadcast_to(np.asarray(reference_azimuth, dtype=float), (self.num_bs,))[b]
                az[b] = float(est.resolve(ref)[0])
        clock("aoa")
        if self.fix_only:
            verifier = None
        tags = self._check_tags(verifier, grid, [e for e, _ in ests], frame, sig, encrypted_replica)
        clock("tags")
        up = None
        if self.uplink is not None:
            up = self._uplink(bs_ue, point, bs_pos, ue_h, rng)
        clock("uplink")
        log.debug("point %d: detected %s, fix %s", point, det, fix.status)
        return ChainResult(detected=det, toa_s=toa, rstd_s=rstd,
                           doppler_hz=np.array([e.doppler_hz for e, _ in ests]),
                           peak_snr_db=np.array([e.peak_snr_db for e, _ in ests]), position=fix,
                           aoa=aoas, azimuth=az, tags_valid=tags, tags_checked=verifier is not None,
                           uplink=up, tx_power_w=powers, timing_reference_s=t0,
                           toa_estimates=[e for e, _ in ests])
