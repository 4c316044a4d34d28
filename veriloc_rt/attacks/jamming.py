"""Wideband jamming: complex Gaussian noise over the PRS band at the jammer's transmit power.

Paper Sec. "Jamming Attack". Power convention: mean |x|^2 of the baseband samples in W.

* time domain (:func:`jamming_iq`): white complex Gaussian noise on the FFT bins of the band
  ``[band_lo_hz, band_hi_hz)`` (baseband frequencies), zero elsewhere, transformed to time
  (unitary FFT). The band limitation is circular over the block (no filter transient). Expected
  power ``power_w``; a realisation's power is a sum of ``n_occ`` exponential bin powers, so it
  scatters by ``1/sqrt(n_occ)`` relative.
* per resource element (:func:`jamming_grid`): i.i.d. CN(0, s2) on every RE with
  ``s2 = power_w * fft_size / num_subcarriers``. With the package's unitary OFDM
  (:mod:`veriloc_rt.phy.nr.ofdm`) a grid of that variance on all ``num_subcarriers`` gives time
  samples of power ``power_w`` (cyclic prefixes repeat samples, power unchanged).

The PRS band of an :class:`~veriloc_rt.config.nr.NRConfig` is :func:`prs_band_hz`: subcarrier
``k`` sits at ``(k - N_sc/2) * scs`` and occupies +- scs/2 around it.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.attacks import JammingConfig
from ..constants import dbm_to_watt
from ..config.nr import NRConfig

__all__ = ["JammingConfig", "Jammer", "jamming_iq", "jamming_grid", "prs_band_hz"]




def prs_band_hz(nr: NRConfig) -> tuple[float, float]:
    """(lo, hi) in Hz, baseband edges of the occupied subcarriers of ``nr``."""
    scs, n = nr.subcarrier_spacing_hz, nr.num_subcarriers
    return (-(n // 2) - 0.5) * scs, (n - n // 2 - 0.5) * scs


def _check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")


def jamming_iq(num_samples: int, sample_rate_hz: float, band_hz: tuple[float, float],
               power_w: float, rng: np.random.Generator) -> np.ndarray:
    """Band-limited complex Gaussian noise.

    :param band_hz: (lo, hi), Hz, baseband band edges, -fs/2 <= lo < hi <= fs/2
    :return: x : [num_samples] complex128, mean |x|^2 = power_w (expected), W
    """
    _check_rng(rng)
    if int(num_samples) != num_samples or num_samples < 1:
        raise ValueError(f"Argument `num_samples` must be a positive integer, not {num_samples!r}")
    lo, hi = (float(v) for v in band_hz)
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"Argument `sample_rate_hz` must be > 0, not {sample_rate_hz!r}")
    if not (-sample_rate_hz / 2 <= lo < hi <= sample_rate_hz / 2):
        raise ValueError(f"Argument `band_hz` must satisfy -fs/2 <= lo < hi <= fs/2, not {band_hz!r}")
    if not (math.isfinite(power_w) and power_w >= 0):
        raise ValueError(f"Argument `power_w` must be >= 0, not {power_w!r}")
    n = int(num_samples)
    f = np.fft.fftfreq(n, d=1.0 / sample_rate_hz)
    occ = (f >= lo) & (f < hi)
    n_occ = int(occ.sum())
    if n_occ == 0:
        raise ValueError(f"band {band_hz!r} holds no FFT bin of a {n}-sample block")
    s2 = power_w * n / n_occ
    spec = np.zeros(n, dtype=np.complex128)
    spec[occ] = math.sqrt(s2 / 2.0) * (rng.standard_normal(n_occ) + 1j * rng.standard_normal(n_occ))
    return np.fft.ifft(spec, norm="ortho")


def jamming_grid(shape, power_w: float, fft_size: int, rng: np.random.Generator) -> np.ndarray:
    """Per-RE jamming noise for a grid whose last axis is the ``num_subcarriers`` occupied ones.

    :param shape: grid shape [..., num_subcarriers]
    :param fft_size: OFDM FFT size the grid is modulated with
    :return: n : [shape] complex128, variance ``power_w * fft_size / num_subcarriers`` per RE
    """
    _check_rng(rng)
    shape = tuple(int(s) for s in shape)
    if not shape or shape[-1] < 1 or shape[-1] > fft_size:
        raise ValueError(f"Argument `shape` must end with 1..fft_size subcarriers, not {shape}")
    if not (math.isfinite(power_w) and power_w >= 0):
        raise ValueError(f"Argument `power_w` must be >= 0, not {power_w!r}")
    s2 = power_w * fft_size / shape[-1]
    scale = math.sqrt(s2 / 2.0)
    out = np.empty(shape, dtype=np.complex128)   # scale (re + j im), without its temporaries
    out.real = rng.standard_normal(shape)
    out.imag = rng.standard_normal(shape)
    out *= scale
    return out


class Jammer:
    """Configured jammer over the PRS band of ``nr``."""

    def __init__(self, nr: NRConfig, config: JammingConfig | None = None):
        self.config = config if config is not None else JammingConfig()
        self.nr = nr
        self.band_hz = prs_band_hz(nr)

    @property
    def power_w(self) -> float:
        return float(dbm_to_watt(self.config.power_dbm))

    def iq(self, num_samples: int, rng: np.random.Generator) -> np.ndarray:
        """x : [num_samples] complex128 at ``nr.resolved_sample_rate_hz``, W."""
        return jamming_iq(num_samples, self.nr.resolved_sample_rate_hz, self.band_hz, self.power_w, rng)

    def grid(self, shape, rng: np.random.Generator) -> np.ndarray:
        """Per-RE noise, [shape] complex128 (see :func:`jamming_grid`)."""
        return jamming_grid(shape, self.power_w, self.nr.fft_size, rng)
