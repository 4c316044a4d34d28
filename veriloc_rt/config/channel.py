"""Config sections of the waveform chain: channel application and the positioning receiver.

:class:`ChannelConfig` says how CIRs are applied to waveforms (frequency- or time-domain, power
control, noise); :class:`ReceiverConfig` how the UE (and, for the uplink, the BSs) time, detect
and locate. Both are frozen and reject unknown keys through :func:`~veriloc_rt.config.fields.from_dict`.
Powers are in dBm and noise figures in dB only here, at the config boundary.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .fields import param
from ..errors import bad_value

#: Channel application domains
DOMAINS = ("frequency", "time")
TIME_FRONT_ENDS = ("correlator", "ofdm")
#: ToA rules: the paper's strongest correlation peak, or the first path above a threshold
TOA_METHODS = ("first_path", "strongest")
PRS_POWER_MODES = ("carrier", "occupied")
#: the reference IQ rate (122.88 MHz), over which ``noise_bandwidth_hz``'s power is spread
REFERENCE_SAMPLE_RATE_HZ = 122.88e6


@dataclass(frozen=True)
class ChannelConfig:
    """Applying CIRs to the transmitters' waveforms: power control, noise, domain."""

    domain: str = param("frequency", "'frequency': per resource element, H[k, l] = sum_p g_p "
                        "exp(-j 2 pi f_k tau_p) exp(j 2 pi f_D,p t_l) (exact while the delay "
                        "spread fits in the cyclic prefix and Doppler << SCS; fast); 'time': "
                        "IQ at the sample rate, exact fractional delays and Doppler (reference)",
                        choices=DOMAINS)
    time_front_end: str = param("correlator", "time domain only: 'correlator': per-symbol linear "
                                "correlation of the IQ with the replica waveform, cyclic prefix "
                                "included (a receiver that uses the CP's energy too); 'ofdm': CP "
                                "removal and FFT, then the frequency path's per-RE correlation "
                                "(the same receiver as the fast path, so a comparison isolates "
                                "the channel's fidelity)", choices=TIME_FRONT_ENDS)
    time_decimation: int = param(1, "time domain only: apply the paths at sample_rate / D after an "
                                 "ideal low-pass, then interpolate back (exact inside the band, "
                                 "drops the CP-OFDM out-of-band leakage; D times cheaper per path, "
                                 "for many-path links such as UMa fast fading); capped so the "
                                 "band still fits; 1: no decimation", lo=1, hi=64)
    bs_max_power_dbm: float = param(24.0, "largest serving-BS transmit power (paper: 24 dBm)",
                                    lo=-50.0, hi=80.0)
    power_control: bool = param(False, "false: every TRP broadcasts its PRS at the maximum "
                                "power (a broadcast signal is not power-controlled per UE); "
                                "true: the paper's idealised UE-specific power control, each "
                                "serving BS's power set so all arrive equally strong, the "
                                "weakest link at the maximum power")
    prs_power: str = param("carrier", "how a transmitter's power maps onto its REs: 'carrier': "
                           "P over the fully loaded carrier (energy per RE P / N_sc, as for "
                           "data); 'occupied': P over the REs it transmits in a PRS symbol (PRS, "
                           "plus tag REs when tags are sent; the muted REs' power moves to them, "
                           "PRS power boosting), e.g. +4.8 dB per RE for comb 6 with tags, "
                           "+7.8 dB without", choices=PRS_POWER_MODES)
    adversary_power_dbm: float = param(48.0, "adversary transmit power (paper: 48 dBm)",
                                       lo=-50.0, hi=90.0)
    ue_power_dbm: float = param(23.0, "UE uplink (SRS) transmit power", lo=-50.0, hi=40.0)
    ue_noise_figure_db: float = param(9.0, "UE receiver noise figure", lo=0.0, hi=30.0)
    bs_noise_figure_db: float = param(5.0, "BS receiver noise figure (uplink)", lo=0.0, hi=30.0)
    noise: bool = param(True, "add thermal noise (-174 dBm/Hz + noise figure over the sampled "
                        "band); false: noiseless (tests)")
    noise_bandwidth_hz: float | None = param(
        None, "null: thermal noise white over the sampled band, density k T0 F (physical). A "
        "bandwidth B: the noise power k T0 F B of a B-wide channel added to IQ sampled at "
        "122.88 MHz with no channel filter, i.e. density k T0 F B / 122.88 MHz (a simulator "
        "convention; the paper's benign tag rates fit B = 10 MHz, 10.9 dB below k T0 F). Every "
        "receiver: UE, relay, BS (uplink)", lo=0.0, lo_open=True, hi=REFERENCE_SAMPLE_RATE_HZ)
    timing_guard_s: float = param(0.25e-6, "the receiver's timing reference t0 sits this long "
                                  "before the earliest serving-link arrival", lo=0.0, hi=4e-6)

    @property
    def per_re_receiver(self) -> bool:
        """The receiver correlates per resource element (frequency domain, or the time domain
        with the OFDM front end) rather than the IQ buffer."""
        return self.domain == "frequency" or self.time_front_end == "ofdm"


@dataclass(frozen=True)
class ReceiverConfig:
    """Doppler and timing synchronisation, ToA, hearability, AoA and uplink reference."""

    toa_method: str = param("first_path", "'first_path': earliest correlation peak above the "
                            "noise- and peak-derived thresholds (for multipath); 'strongest': "
                            "the highest peak (the paper's rule)", choices=TOA_METHODS)
    search_window_s: float = param(12e-6, "ToA search window after the timing reference "
                                   "(12 us = 3.6 km of extra range)", lo=0.5e-6, hi=60e-6)
    upsample: int = param(4, "zero-padding factor of the coarse delay profile (frequency "
                          "domain); the time-domain profile is at the sample rate", lo=1, hi=64)
    refine_steps: int = param(4, "parabolic sub-sample refinement rounds (each evaluates the "
                              "correlation exactly at 3 delays and shrinks the step by 4)",
                              lo=0, hi=20)
    first_path_window: str = param("hann", "frequency window of the first-path profile "
                                   "(Hann: -31 dB sidelobes, so a strong late path does not "
                                   "fake an early one)", choices=("hann", "none"))
    false_alarm: float = param(1e-6, "per-delay-bin false-alarm probability of the noise-derived "
                               "first-path threshold", lo=1e-15, hi=0.1)
    first_path_rel_db: float = param(20.0, "first-path candidates must lie within this many dB "
                                     "of the strongest peak", lo=3.0, hi=60.0)
    hearability_db: float = param(8.0, "a BS is detected when its correlation peak exceeds the "
                                  "noise floor (mean noise-only metric) by this much; 8 dB with 5 "
                                  "antennas is a chi-square(10) tail of ~1e-9 per delay bin",
                                  lo=0.0, hi=60.0)
    detection_false_alarm: float = param(1e-3, "probability that noise alone is detected as a BS "
                                         "in one search (all delay bins and Doppler "
                                         "cells, 4 per Doppler resolution whatever the "
                                         "step); sets a chi-square(2 x antennas) "
                                         "threshold applied on top of hearability_db",
                                         lo=1e-12, hi=0.5)
    doppler_max_hz: float = param(400.0, "the largest Doppler scan half-range the UE supports "
                                  "(0 disables the scan); the run's scan: doppler_scan",
                                  lo=0.0, hi=5000.0)
    doppler_step_hz: float = param(25.0, "Doppler scan step (the frame's Doppler resolution is "
                                   "1 / frame length = 100 Hz; the thresholds do not depend on "
                                   "it, its straddle loss does: docs/performance.md)",
                                   lo=1.0, hi=1000.0, lo_open=False)
    doppler_scan: str = param("channel", "'channel': a run scans +-(its fastest Doppler + one "
                              "step), in whole steps and at most doppler_max_hz: the largest "
                              "|Doppler| of its BS -> UE and adversary -> UE paths, relayed ones "
                              "(the adversary's receive plus transmit Doppler) included; "
                              "'fixed': +-doppler_max_hz. A chain built alone scans "
                              "+-doppler_max_hz", choices=("channel", "fixed"))
    aoa_method: str = param("esprit", "AoA estimator", choices=("esprit", "music"))
    aoa_snapshots: str = param("peak", "'peak': per-antenna correlation at the ToA, one snapshot "
                               "per PRS symbol; 'subcarrier': per-RE channel estimates",
                               choices=("peak", "subcarrier"))
    aoa_num_sources: int = param(1, "ESPRIT/MUSIC model order (0: MDL)", lo=0, hi=3)
    tag_slots: tuple[int, ...] = param((0,), "slots whose tags are verified (a BS's verdict is "
                                       "valid only if all verify)")
    srs_n_id: int = param(0, "n_ID^SRS of the UE's uplink reference", lo=0, hi=1023)
    srs_comb: int = param(4, "SRS transmission comb K_TC", choices=(2, 4, 8))
    srs_symbols: tuple[int, ...] = param((10, 11, 12, 13), "SRS symbols of each slot")
    uplink: bool = param(True, "compute the uplink position (DL-UL handshake)")
    max_residual_m: float = param(10.0, "multilateration: largest accepted rms range residual "
                                  "(the unweighted fit's check)", lo=0.01, hi=1e4)
    fix_weighting: str = param("auto", "multilateration: 'equal' (every ToA the same variance, "
                               "the paper's fit, checked by max_residual_m), 'snr' (weighted "
                               "least squares, each ToA's variance from its correlation-peak "
                               "SNR by the CRLB plus range_std_floor_m; a fix covariance and "
                               "the chi-square integrity test with fault exclusion replace the "
                               "rms check), 'auto' ('equal' for 3 TRPs, 'snr' for more)",
                               choices=("auto", "equal", "snr"))
    range_std_floor_m: float = param(3.0, "weighted fit: std added (in quadrature) to each "
                                     "ToA's CRLB range std for what the CRLB leaves out "
                                     "(multipath, sub-sample interpolation): a stated choice, "
                                     "a tenth of the range resolution c/B of the 10 MHz PRS",
                                     lo=0.01, hi=1e3)
    integrity_false_alarm: float = param(0.01, "weighted fit: size of the chi-square(N - 3) "
                                         "test of the whitened RSTD residuals (the benign "
                                         "false-alarm rate it is designed for; a stated "
                                         "choice)", lo=1e-9, hi=0.5)
    range_error_model: str = param("auto", "weighted fit: each ToA's range std is 'crlb' (the "
                                   "CRLB from its peak SNR plus range_std_floor_m), or "
                                   "'overbound' (the larger of that and the Gaussian overbound "
                                   "of the measured first-arrival error in its peak-SNR bin, "
                                   "from the calibration table veriloc_rt/data/"
                                   "range_overbound.json: UMa fast fading, this simulator); "
                                   "'auto': 'crlb' on a channel without multipath (UMa/UMi "
                                   "uma_mode 'pathloss_only'), 'overbound' on every other "
                                   "(fast fading, ray tracing: late, heavy-tailed first "
                                   "arrivals the CRLB does not describe)",
                                   choices=("auto", "crlb", "overbound"))
    fault_exclusion: bool = param(True, "weighted fit: exclude the anchor whose removal best "
                                  "explains a failed test, and re-test, while a degree of "
                                  "freedom remains (RAIM-style FDE)")

    def validate(self, path: str = "receiver") -> None:
        p = f"{path}." if path else ""
        if not self.srs_symbols or any(not 0 <= s < 14 for s in self.srs_symbols):
            raise bad_value(f"{p}srs_symbols", self.srs_symbols, "symbols in 0..13")
        if not self.tag_slots:
            raise bad_value(f"{p}tag_slots", list(self.tag_slots), "at least one slot")
        if any(not 0 <= s < 20 for s in self.tag_slots):
            raise bad_value(f"{p}tag_slots", self.tag_slots, "slot indices in 0..19")
        if self.doppler_max_hz > 0 and self.doppler_step_hz > self.doppler_max_hz:
            raise bad_value(f"{p}doppler_step_hz", self.doppler_step_hz,
                            f"a value <= doppler_max_hz ({self.doppler_max_hz})")

    def scanned_for(self, max_doppler_hz: float) -> "ReceiverConfig":
        """This config with the Doppler scan fitted to a channel whose paths' |Doppler| is at
        most ``max_doppler_hz`` (``doppler_scan`` 'channel'; 'fixed' or no scan: unchanged).

        Half-range: the fastest Doppler rounded up to whole steps plus one step, so that the
        scan's maximum has a neighbour on each side for its parabolic refinement; never more
        than ``doppler_max_hz`` (the largest the UE supports).
        """
        if not math.isfinite(max_doppler_hz) or max_doppler_hz < 0:
            raise ValueError(f"Argument `max_doppler_hz` must be finite and >= 0, not {max_doppler_hz!r}")
        if self.doppler_scan != "channel" or self.doppler_max_hz <= 0:
            return self
        step = self.doppler_step_hz
        half = step * (math.ceil(max_doppler_hz / step - 1e-9) + 1)
        return dataclasses.replace(self, doppler_max_hz=float(min(half, self.doppler_max_hz)),
                                   doppler_scan="fixed")

    def __post_init__(self) -> None:
        self.validate("")  # from_dict names the section


def resolved_range_error_model(receiver: "ReceiverConfig", model: str, uma_mode: str) -> str:
    """``receiver.range_error_model`` with 'auto' resolved for the propagation ``model`` and its
    ``uma_mode``: 'crlb' where the channel has no multipath (a stochastic model's
    'pathloss_only'; the CRLB describes the ToA error there, docs/trps.md), else 'overbound'."""
    if receiver.range_error_model != "auto":
        return receiver.range_error_model
    return "crlb" if model in ("uma", "umi") and uma_mode == "pathloss_only" else "overbound"
