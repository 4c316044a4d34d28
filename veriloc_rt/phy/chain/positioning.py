"""The per-point positioning chain: the stage blocks composed.

:class:`PositioningChain` is configured once (waveform, security, channel and receiver configs,
the UE array, the keys, the noise sources) and called per trajectory point with that point's
CIRs and a :class:`~veriloc_rt.phy.chain.plan.ChainPlan`. It works the same on ray-traced and
UMa CIRs (both are :class:`CIR`):

1. :class:`~.frames.FrameSource`: the serving BSs' frame (PRS, encryption, tags) and replicas;
2. :class:`~.downlink.DownlinkChannel`: links, power control, timing reference; the frame
   through the links plus noise (:mod:`veriloc_rt.phy.noise`) plus the adversary's signal;
3. :class:`~.receiver.TimingStage`, :class:`~.receiver.FixStage`, :class:`~.receiver.AngleStage`,
   :class:`~.receiver.TagStage`, :class:`~.receiver.UplinkStage`: ToA and RSTDs, the DL fix,
   the AoA per BS, the tags, the UL fix, as far as the plan asks.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from ...config import ArrayConfig, Config
from ...config.channel import ChannelConfig, ReceiverConfig, resolved_range_error_model
from ...config.nr import NRConfig
from ...config.security import SecurityConfig
from ...constants import SPEED_OF_LIGHT
from ...propagation.cir import CIR, ula_element_positions
from ..channel import occupied_power_factor, receiver_noise_variance
from ..noise import NoiseSource, WhiteNoise
from ..nr.grid import ReLayout
from ..receiver.aoa import AoAEstimator
from ..receiver.toa import ToAEstimator
from ..receiver.uplink import UplinkPositioner
from ..security.keys import BSKeys
from .downlink import Adversary, DownlinkChannel, SignalKey
from .frames import FrameSignals, FrameSource, ServingSetup
from .plan import FULL, ChainPlan, ChainResult
from .receiver import (AngleStage, FixStage, RangeOverbound, TagStage, TimingStage, UplinkStage,
                       zenith_from_fix)

log = logging.getLogger(__name__)

__all__ = ["PositioningChain", "STAGES"]

#: stages of one chain call, in order: PRS/tag grids and replicas; CIRs applied plus noise;
#: Doppler/timing sync and ToA per BS; multilateration; AoA; tag decoding; the uplink (SRS
#: through its own channel, ToA at the BSs, UL fix)
STAGES = ("waveform", "channel", "toa", "position", "aoa", "tags", "uplink")


class _StageClock:
    """Adds the calling thread's CPU time since the previous mark to ``totals[stage]`` at each
    call (CPU, not wall: a stage's figure does not grow when other processes share the cores)."""

    def __init__(self, totals: dict):
        self.totals, self.t = totals, time.thread_time()

    def __call__(self, stage: str) -> None:
        now = time.thread_time()
        self.totals[stage] += now - self.t
        self.t = now


class PositioningChain:
    """Transmitters, channel and receiver of one run, called per trajectory point.

    :param nr: waveform config; security: encryption and tags; channel, receiver: their configs
    :param ue_array: the UE's ULA (number of elements, spacing, axis azimuth)
    :param carrier_frequency_hz: float, Hz
    :param keys: by BS id, for encryption and tags (None if neither is used). The serving BSs of
        a point are the CIR's ``tx_index`` (slot 0: RSTD reference). An empty slot (``NO_TX``)
        transmits under a dummy identity through a link without paths, i.e. nothing arrives.
    :param noise: the UE's noise source (default :class:`~veriloc_rt.phy.noise.WhiteNoise`)
    :param uplink_noise: the BSs' noise source for the uplink (default ``WhiteNoise``)
    """

    @classmethod
    def from_config(cls, cfg: Config, keys: Mapping[int, BSKeys] | None = None, *,
                    max_doppler_hz: float, security: SecurityConfig | None = None,
                    receiver: ReceiverConfig | None = None, noise: NoiseSource | None = None,
                    uplink_noise: NoiseSource | None = None) -> "PositioningChain":
        """The chain of a run's config: its ``nr``, ``channel``, UE array and carrier, and its
        ``security`` and ``receiver`` unless given (a run's DS-tagged or encrypted chain), the
        receiver's Doppler scan fitted to ``max_doppler_hz`` (``ReceiverConfig.scanned_for``:
        the largest |Doppler| the UE receives). The one place a chain is built from a config
        (:class:`~veriloc_rt.sim.runner.ScenarioRunner`,
        :func:`~veriloc_rt.studies.diagnostics.benign_chain`).
        """
        sec = cfg.security if security is None else security
        rx = (cfg.receiver if receiver is None else receiver).scanned_for(max_doppler_hz)
        rx = replace(rx, range_error_model=resolved_range_error_model(
            rx, cfg.propagation.model, cfg.propagation.uma_mode))
        return cls(cfg.nr, sec, cfg.channel, rx, cfg.propagation.ue_array,
                   cfg.propagation.carrier_frequency_hz, keys, noise=noise,
                   uplink_noise=uplink_noise)

    def __init__(self, nr: NRConfig, security: SecurityConfig, channel: ChannelConfig,
                 receiver: ReceiverConfig, ue_array: ArrayConfig, carrier_frequency_hz: float,
                 keys: Mapping[int, BSKeys] | None = None, *, noise: NoiseSource | None = None,
                 uplink_noise: NoiseSource | None = None):
        nr.validate()
        security.validate()
        if any(s >= nr.slots_per_frame for s in receiver.tag_slots):
            raise ValueError(f"receiver.tag_slots {receiver.tag_slots} exceed nr.slots_per_frame "
                             f"{nr.slots_per_frame}")
        self.nr, self.security, self.channel, self.receiver = nr, security, channel, receiver
        time_domain = channel.domain == "time"
        # the frame's slots whose tags are checked: each TRP's own receiver.tag_slots-th PRS
        # slots (the same slots for all with one slot group; ReLayout.own_slot)
        lay = ReLayout.from_config(nr, security.tag_scheme != "none")
        #: indices of the frame's slots any TRP's tags are checked in
        self.checked_slots = tuple(sorted({lay.own_slot(b, t) for b in range(nr.num_bs)
                                           for t in receiver.tag_slots}))
        self.frames = FrameSource(nr, security, keys if keys is not None else {}, time_domain,
                                  None if time_domain else self.checked_slots)
        self.ofdm, self.slots = self.frames.ofdm, self.frames.slots
        wavelength = SPEED_OF_LIGHT / carrier_frequency_hz
        axis = np.deg2rad(ue_array.axis_azimuth_deg)
        self.element_pos = ula_element_positions(ue_array.num_elements,
                                                 ue_array.spacing_wavelengths * wavelength, axis)
        fs = self.ofdm.sample_rate_hz
        self.noise_var = receiver_noise_variance(channel, fs, channel.ue_noise_figure_db)
        self.bs_power_factor = occupied_power_factor(channel.prs_power, nr.num_subcarriers, nr.comb,
                                                     security.tag_scheme != "none")
        self.frame_samples = self.ofdm.num_samples(self.slots)
        buffer_samples = self.frame_samples + int(np.ceil(receiver.search_window_s * fs)) + 64
        decimation = max(1, min(channel.time_decimation, self.ofdm.fft_size // nr.min_fft_size))
        self.downlink = DownlinkChannel(channel, self.ofdm, self.slots, self.bs_power_factor,
                                        buffer_samples, decimation,
                                        noise if noise is not None else WhiteNoise(), self.noise_var,
                                        read_symbols=[s for s in range(14) if s not in nr.prs_symbols],
                                        read_slots=self.checked_slots)
        self.timing = TimingStage(ToAEstimator(receiver, channel.timing_guard_s), self.ofdm, self.slots,
                                  channel, receiver.search_window_s, nr.prs_symbols, self.noise_var)
        weighted = (receiver.fix_weighting == "snr"
                    or (receiver.fix_weighting == "auto" and nr.num_bs > 3))
        self.fix = FixStage(receiver.max_residual_m, weighted,
                            nr.num_subcarriers * nr.subcarrier_spacing_hz,
                            receiver.range_std_floor_m, receiver.integrity_false_alarm,
                            receiver.fault_exclusion,
                            overbound=(RangeOverbound.shipped()
                                       if receiver.range_error_model == "overbound" else None))
        # 'auto' is resolved by from_config (it knows the channel); a chain built directly
        # from a ReceiverConfig left at 'auto' uses the CRLB alone
        self.angles = AngleStage(AoAEstimator(receiver.aoa_method, receiver.aoa_num_sources or None,
                                              ue_array.spacing_wavelengths, axis),
                                 receiver.aoa_snapshots)
        self.tags = TagStage(receiver.tag_slots, self.slots)
        self.uplink = (UplinkStage(UplinkPositioner(nr, channel, receiver, uplink_noise), self.element_pos,
                                   self.fix)
                       if receiver.uplink else None)
        #: seconds spent per stage over every call (a run reports them; reading is optional)
        self.stage_s = dict.fromkeys(STAGES, 0.0)

    @property
    def num_bs(self) -> int:
        return self.nr.num_bs

    def setup(self, bs_ids: Sequence[int]) -> ServingSetup:
        """Transmitter and tag verifier of a serving set (cached)."""
        return self.frames.setup(bs_ids)

    def frame_signals(self, bs_ids: Sequence[int], frame: int, replica: str = "own",
                      every_tag: bool = False) -> FrameSignals:
        """Grids, waveforms and replicas of one frame (:class:`~.frames.FrameSource`; its grids
        carry the tags of the checked slots only, every slot's with ``every_tag``)."""
        return self.frames(bs_ids, frame, replica, every_tag)

    def _check(self, bs_ue: CIR, point: int, rng) -> None:
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
        if bs_ue.num_tx != self.num_bs or bs_ue.num_ant != self.element_pos.shape[0]:
            raise ValueError(f"Argument `bs_ue` must have {self.num_bs} link slots and "
                             f"{self.element_pos.shape[0]} antennas, not {bs_ue.num_tx} and {bs_ue.num_ant}")
        if not 0 <= point < bs_ue.num_points:
            raise ValueError(f"Argument `point` must be in [0, {bs_ue.num_points}), not {point}")

    def __call__(self, bs_ue: CIR, point: int, rng: np.random.Generator, *, frame: int = 0,
                 adversary: Adversary | None = None, plan: ChainPlan = FULL,
                 reference_azimuth=None, zenith=None) -> ChainResult:
        """Run the chain on trajectory point ``point``.

        :param bs_ue: CIR [num_points, num_bs] serving BS -> UE (slot 0 = reference)
        :param rng: numpy Generator for the noise (always explicit)
        :param frame: 32-bit frame counter (PRS encryption, tags)
        :param adversary: what the adversary transmits and its link (None: no adversary)
        :param plan: the stages to run (default: all)
        :param reference_azimuth: [num_bs] float64, rad, resolves the ULA mirror ambiguity
        :param zenith: [num_bs] float64, rad, known zenith of arrival (None: from the DL fix)
        """
        self._check(bs_ue, point, rng)
        given = plan.timing_from
        if given is not None and len(given.toa_estimates) != self.num_bs:
            raise ValueError(f"Argument `plan.timing_from` has {len(given.toa_estimates)} BSs, "
                             f"the chain {self.num_bs}")
        bs_ids = tuple(int(b) for b in bs_ue.tx_index[point])
        clock = _StageClock(self.stage_s)
        verifier = self.frames.setup(bs_ids).verifier if plan.tags else None
        sig = self.frames(bs_ids, frame, plan.replica)
        clock("waveform")
        dl = self.downlink.links(bs_ue, point, adversary)
        t0 = dl.timing_reference_s
        # with another chain's timing only the tags are left to do: the grid of the slots up to
        # the last checked one is enough (frequency domain)
        m = (max(self.checked_slots) + 1 if given is not None and self.channel.domain == "frequency"
             else len(self.slots))
        rx = self.downlink(dl, sig, rng, m, SignalKey(bs_ue, point, frame, plan.replica, m))
        clock("channel")
        replicas = sig.replicas if plan.replica == "own" else None
        if given is not None:
            tags = (self.tags(verifier, rx.grid, given.toa_estimates, frame, replicas, rx)
                    if verifier is not None else np.zeros(self.num_bs, dtype=bool))
            clock("tags")
            return replace(given, tags_valid=tags, tags_checked=verifier is not None)
        timing = self.timing(rx, sig.replicas, t0, sig.replica_occupied)
        bs_pos = bs_ue.tx_pos[point]
        ue_h = float(bs_ue.rx_pos[point, 2])
        clock("toa")
        fix = self.fix(timing, bs_pos, ue_h)
        clock("position")
        if plan.angles:
            zen = (zenith_from_fix(bs_pos, fix) if zenith is None
                   else np.broadcast_to(np.asarray(zenith, float), (self.num_bs,)))
            angles = self.angles(timing, zen, reference_azimuth)
            aoas, az = angles.aoa, angles.azimuth
        else:
            aoas, az = [None] * self.num_bs, np.full(self.num_bs, np.nan)
        clock("aoa")
        tags = (self.tags(verifier, rx.grid, timing.estimates, frame, replicas, rx)
                if verifier is not None else np.zeros(self.num_bs, dtype=bool))
        clock("tags")
        up = None
        if self.uplink is not None and plan.uplink:
            up = self.uplink(bs_ue, point, bs_pos, ue_h, rng)
        clock("uplink")
        log.debug("point %d: detected %s, fix %s", point, timing.detected, fix.status)
        ests = list(timing.estimates)
        return ChainResult(detected=timing.detected, toa_s=timing.toa_s, rstd_s=timing.rstd_s,
                           doppler_hz=np.array([e.doppler_hz for e in ests]),
                           peak_snr_db=np.array([e.peak_snr_db for e in ests]), position=fix,
                           aoa=aoas, azimuth=az, tags_valid=tags, tags_checked=verifier is not None,
                           uplink=up, tx_power_w=dl.tx_power_w, timing_reference_s=t0,
                           toa_estimates=ests)
