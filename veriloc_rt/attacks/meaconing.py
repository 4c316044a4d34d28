"""Meaconing: the adversary relays the composite signal it receives, amplified and delayed.

Paper Sec. "Meaconing": the relay adds a common processing delay delta to every BS's component,
so ``rstd_ij(UE) = (t_i + delta) - (t_j + delta) = rstd_ij(adversary)``: the UE sees the RSTD
geometry of the adversary's position. The relay is a pure function of the signal received at the
adversary, which already contains the adversary's own receiver noise (added by the channel stage).

Gain: automatic gain control to the transmit power, ``g = sqrt(P_tx / mean|r|^2)`` over the whole
input (signal plus the adversary's noise, which it cannot separate), optionally capped at
``max_gain_db``. Power convention: mean |x|^2 of the baseband samples in W.

Delay: exact fractional delay by a linear phase in the frequency domain on a zero-padded copy
(no wrap-around of the signal; the band-limited interpolation tails of a fractional delay are
what a sinc interpolator gives). The output keeps the input's length: samples pushed past the end
of the window are dropped, the first ``delay`` of the window is (nearly) empty.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.attacks import MeaconingConfig
from ..constants import dbm_to_watt

__all__ = ["MeaconingConfig", "Meaconer", "meacon", "fractional_delay"]


def fractional_delay(x, delay_s: float, sample_rate_hz: float) -> np.ndarray:
    """x delayed by ``delay_s`` (band-limited interpolation), same length.

    :param x: [..., num_samples] complex128
    :return: [..., num_samples] complex128
    """
    x = np.asarray(x, dtype=np.complex128)
    n = x.shape[-1]
    shift = delay_s * sample_rate_hz
    pad = int(math.ceil(shift)) + 64
    m = n + pad
    spec = np.fft.fft(x, n=m, axis=-1)
    f = np.fft.fftfreq(m)  # cycles per sample
    y = np.fft.ifft(spec * np.exp(-2j * np.pi * f * shift), axis=-1)
    return y[..., :n]


def meacon(rx, sample_rate_hz: float, power_w: float, delay_s: float,
           max_gain_db: float | None = None) -> tuple[np.ndarray, float]:
    """Relay the adversary's received signal.

    :param rx: [..., num_samples] complex128, composite baseband at the adversary (its noise
        included), power as mean |x|^2 in W; the mean is over all axes (one AGC for all antennas)
    :param sample_rate_hz: sample rate, Hz
    :param power_w: transmit power, W
    :param delay_s: processing delay, s (>= 0)
    :return: (tx : [..., num_samples] complex128, gain : float, amplitude gain applied)
    """
    r = np.asarray(rx, dtype=np.complex128)
    if r.ndim < 1 or r.shape[-1] == 0:
        raise ValueError(f"Argument `rx` must be a non-empty array, not shape {r.shape}")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"Argument `sample_rate_hz` must be > 0, not {sample_rate_hz!r}")
    if not (math.isfinite(power_w) and power_w >= 0):
        raise ValueError(f"Argument `power_w` must be >= 0, not {power_w!r}")
    if not (math.isfinite(delay_s) and delay_s >= 0):
        raise ValueError(f"Argument `delay_s` must be >= 0, not {delay_s!r}")
    p_in = float(np.mean(np.abs(r) ** 2))
    gain = math.sqrt(power_w / p_in) if p_in > 0 else 0.0
    if max_gain_db is not None:
        gain = min(gain, 10.0 ** (max_gain_db / 20.0))
    return gain * fractional_delay(r, delay_s, sample_rate_hz), gain


class Meaconer:
    """Configured meaconing relay; ``meaconer(rx, sample_rate_hz) -> (tx, gain)``."""

    def __init__(self, config: MeaconingConfig | None = None):
        self.config = config if config is not None else MeaconingConfig()

    @property
    def power_w(self) -> float:
        return float(dbm_to_watt(self.config.power_dbm))

    def __call__(self, rx, sample_rate_hz: float) -> tuple[np.ndarray, float]:
        return meacon(rx, sample_rate_hz, self.power_w, self.config.processing_delay_s,
                      self.config.max_gain_db)
