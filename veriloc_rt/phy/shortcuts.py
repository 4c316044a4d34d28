"""The chain's statistically exact shortcuts and the switch back to the reference path.

A shortcut changes the random numbers a chain draws, or the rounding of its arithmetic, but not
the distribution of anything the receiver reads, so a run's outcome shares, error distributions
and detector statistics are the same distributions (``benchmarks/equivalence.py`` tests them
against the reference path and states its power; the reports are in ``docs/equivalence.md``).
The shortcuts, by name:

* ``noise``: the UE's thermal noise drawn only on the REs its receiver reads (the PRS replicas'
  REs, every RE of the symbols the noise estimate reads and of the slots whose tags are checked),
  frequency domain (:class:`~veriloc_rt.phy.chain.downlink.DownlinkChannel`).
* ``delays``: a link's frequency response summed over its distinct path delays instead of its
  paths (:func:`~veriloc_rt.phy.channel.grouped_frequency_response`): the same sum in another
  order (float64 rounding only), about 16 times fewer products for TR 38.901 links, whose rays
  share their cluster's delay.
* ``noise32``: the UE's thermal noise from single-precision normals
  (``Generator.standard_normal(dtype=float32)``, scaled in float64:
  :func:`~veriloc_rt.phy.channel.draw_grid_noise_on`), other draws from the same N(0, 1).
* ``ulnoise``: the serving BSs' thermal noise in the uplink drawn only on the REs their receiver
  reads (the SRS's REs, which its cross-spectra read, and every RE of the symbols its noise
  estimate reads), frequency domain
  (:class:`~veriloc_rt.phy.receiver.uplink.UplinkPositioner`). A name of its own, not ``noise``
  extended: ``VERILOC_RT_REFERENCE=noise`` keeps giving the files it gave before, and each
  shortcut's equivalence report tests that shortcut alone.
* ``ulnoisevar``: the uplink receiver's noise estimate (the mean of ``|Y|^2`` over the symbols
  without SRS, noise alone there) drawn directly from its distribution, Gamma(M, sigma^2 / M)
  for M REs of i.i.d. CN(0, sigma^2), instead of from M drawn REs; those REs are then not
  drawn (:class:`~veriloc_rt.phy.receiver.uplink.UplinkPositioner`).
* ``relaytags``: the meaconer's received grid carries a stand-in QPSK symbol on the tag REs of
  the slots the UE does not check instead of those slots' own tags, which are then not computed:
  those REs reach only the relay's AGC, whose input power there, ``abs(h x + n)^2`` with
  circularly symmetric noise n, has the same distribution for every unit-modulus x, and REs the
  UE never reads (:class:`~veriloc_rt.attacks.threats.MeaconingThreat`).
* ``toa32``: the ToA search's zero-padded delay profiles (the Doppler-compensated profile whose
  peak detects a TRP and the first path's windowed profile) transformed in single precision
  (:class:`~veriloc_rt.phy.receiver.toa.ToAEstimator`), as its Doppler scan and delay-Doppler
  map already are: the same sums, rounded to 2^-24 relative instead of 2^-53; the ToA's
  sub-sample refinement, the peak and the snapshots stay in double precision.
* ``dofherk``: the spatial covariance R = sum x x^H behind the noise's degrees of freedom (of
  the PRS REs' cross-spectra and of the free symbols) and the free symbols' mean power (tr R
  over their count) by BLAS's Hermitian rank-k update ``zherk`` (one triangle, no conjugated
  copy of the samples) instead of the products ``x @ x.conj().T`` and a separate mean of
  ``|x|^2`` (:func:`~veriloc_rt.phy.receiver.toa.spatial_covariance_stats`): the same sums in
  another order (float64 rounding only).
* ``spectra32``: the ToA search's sums of the cross-spectra over the blocks (at a Doppler) and
  over the bins (at a lag: the per-block correlations, the AoA's snapshots) taken on the
  single-precision copy of the spectra its Doppler scan already makes, half the memory read of
  the double-precision spectra (:class:`~veriloc_rt.phy.receiver.toa.ToAEstimator`): the same
  sums of the products rounded to 2^-24 relative; results in double precision.
* ``jitchannel``: a link of one distinct delay (a path-loss-only link, TR 38.901 UMa
  ``pathloss_only``) added into the received grid, ``Y += (a H) X`` on the REs its grid
  occupies, in one compiled pass (:func:`~veriloc_rt.phy.channel.apply_frequency`,
  :mod:`~veriloc_rt.phy.channel_kernels`), its response formed RE by RE from its two factors,
  G[a, t] exp(-j 2 pi f_k (tau - t0)), instead of evaluated symbol group by symbol group, kept,
  and applied by NumPy's gather, product and scatter: the same products and sums in the
  reference's order, rounded without the fused multiply-add of NumPy's complex product (the
  last bit). Links of more delays take the reference path.

The environment variable ``VERILOC_RT_REFERENCE`` selects the reference path of the shortcuts it
names (comma separated; ``all``: every one), read when a chain is built: the same config and
seed then give the reference path's files, as before the shortcut.
"""

from __future__ import annotations

import os

__all__ = ["ENV", "SHORTCUTS", "reference"]

#: the environment variable naming the shortcuts to leave out
ENV = "VERILOC_RT_REFERENCE"
#: the shortcuts (module docstring)
SHORTCUTS = ("noise", "delays", "noise32", "ulnoise", "ulnoisevar", "relaytags", "toa32", "dofherk",
             "spectra32", "jitchannel")


def reference(name: str) -> bool:
    """Whether the shortcut ``name`` is left out (``VERILOC_RT_REFERENCE`` names it or ``all``)."""
    if name not in SHORTCUTS:
        raise ValueError(f"Argument `name` must be one of {SHORTCUTS}, not {name!r}")
    named = {p.strip() for p in os.environ.get(ENV, "").split(",") if p.strip()}
    return name in named or "all" in named
