"""Receiver side of the tags: extract a BS's tag REs, estimate the channel, decode, verify.

No equalisation is assumed. Either per-RE channel estimates are given, or the channel on the tag
REs is estimated from the BS's own PRS REs of the same symbol (the receiver knows its PRS, and
for an encrypted PRS it holds the BS's AES key): least-squares estimates on the PRS REs, the
common delay ramp removed (the staggered comb covers every subcarrier, so the phase step between
adjacent subcarriers is unambiguous up to 1/SCS = 66.7 us at mu = 0), linear interpolation to the
tag subcarriers, ramp restored. The noise variance comes from the pilots' second differences.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...config.nr import NRConfig
from ...config.security import SecurityConfig
from ..channel import kept
from ..nr.grid import ReLayout
from ..nr.prs import SYMBOLS_PER_SLOT
from ..security.keys import BSKeys
from ..security.tag_modem import TagModem
from ..security.tags import check_tag, tag_message
from ..transmitter import prs_replica, serving_setup


#: :func:`_pilot_terms` by (layout, BS): a chain's layout and BSs are the same at every call
_PILOTS: dict = {}


@dataclass(frozen=True, eq=False)
class _Pilots:
    """What :func:`estimate_tag_channel` derives from the layout alone (read-only arrays).

    sym : [L, 1] int64, the PRS symbols; kp, kt : [L, n] int64, the BS's PRS and tag
    subcarriers; flat_k : [L n] int64, kp flattened; both : [N_sc - 1] bool, subcarrier pairs
    (k, k + 1) both carrying a pilot; xq, xp : [L n] int64, the tag subcarriers (clamped to
    their symbol's pilots) and the pilots, each symbol set apart on one axis
    """

    sym: np.ndarray
    kp: np.ndarray
    kt: np.ndarray
    flat_k: np.ndarray
    both: np.ndarray
    xq: np.ndarray
    xp: np.ndarray


def _pilot_terms(layout: ReLayout, bs: int) -> _Pilots:
    def make():
        kp = layout.prs_subcarriers(bs)
        kt = layout.tag_subcarriers(bs)
        n_sc, flat_k = layout.num_subcarriers, kp.ravel()
        count = np.bincount(flat_k, minlength=n_sc)
        both = (count[1:] > 0) & (count[:-1] > 0)
        # every symbol's interpolation in one call: the symbols' subcarriers set apart on one
        # axis (integers, so the differences and slopes are the per-symbol ones), the tag
        # subcarriers clamped to their symbol's pilots (np.interp holds the end values beyond)
        off = (2 * n_sc * np.arange(kp.shape[0]))[:, None]
        xq = (np.clip(kt, kp[:, :1], kp[:, -1:]) + off).ravel()
        xp = (kp + off).ravel()
        arrays = (layout.symbols[:, None], kp, kt, flat_k, both, xq, xp)
        for a in arrays:
            a.flags.writeable = False
        return _Pilots(*arrays)

    return kept(_PILOTS, (layout, int(bs)), make)


def estimate_tag_channel(rx: np.ndarray, layout: ReLayout, bs: int, replica: np.ndarray,
                         smoothing: int = 2) -> tuple[np.ndarray, float]:
    """Channel on BS ``bs``'s tag REs from its PRS REs, and the noise variance per RE.

    :param smoothing: half-width in pilots of the moving average applied to the de-rotated
        pilots of each symbol (2: 5 pilots, 30 subcarriers = 450 kHz at mu = 0 and comb 6, inside
        the coherence bandwidth of a 0.3 us rms delay spread); 0 disables it

    :param rx: [14, num_subcarriers] complex, received slot grid
    :param replica: [14, num_subcarriers] complex, the BS's PRS of that slot (unit modulus)
    :return: h : [num_symbols, res_per_symbol] complex128 on the tag REs (tag order);
        noise_var : float, per RE
    """
    pil = _pilot_terms(layout, bs)
    rx_p, rep_p = rx[pil.sym, pil.kp], replica[pil.sym, pil.kp]
    # the estimate reads these values alone: the same values (a DS-tagged chain's grid on the
    # standard chain's timing holds the same PRS REs) give the kept estimate
    key = (layout, int(bs), int(smoothing), rx_p.dtype.str, rep_p.dtype.str, rx_p.tobytes(),
           rep_p.tobytes())
    h, nv = kept(_ESTIMATES, key, lambda: _estimate(rx_p, rep_p, layout, pil, smoothing),
                 max_entries=ESTIMATES_KEPT)
    return h.copy(), nv


#: :func:`estimate_tag_channel`'s last results by their inputs' values
_ESTIMATES: dict = {}
#: results kept (a point's BSs and chains; the store is emptied when full)
ESTIMATES_KEPT = 16


def _estimate(rx_p: np.ndarray, rep_p: np.ndarray, layout: ReLayout, pil: _Pilots,
              smoothing: int) -> tuple[np.ndarray, float]:
    """:func:`estimate_tag_channel` from the received and replica values on the BS's PRS REs
    (rx_p, rep_p : [L, n] complex)."""
    kp, kt = pil.kp, pil.kt
    h_ls = rx_p * np.conj(rep_p)  # [L, n]
    # phase step per subcarrier from all symbols' pilots placed on one axis (staggered comb)
    # summed per subcarrier in the pilots' order (bincount adds as np.add.at does)
    n_sc, flat_k, flat_h = layout.num_subcarriers, pil.flat_k, h_ls.ravel()
    both = pil.both
    if np.any(both):
        full = np.empty(n_sc, dtype=np.complex128)
        full.real = np.bincount(flat_k, weights=flat_h.real, minlength=n_sc)
        full.imag = np.bincount(flat_k, weights=flat_h.imag, minlength=n_sc)
        step = np.angle(np.sum(full[1:][both] * np.conj(full[:-1][both])))
    else:  # comb covers only some subcarriers: use the within-symbol pilot spacing
        step = np.angle(np.sum(h_ls[:, 1:] * np.conj(h_ls[:, :-1]))) / layout.comb
    flat = h_ls * np.exp(-1j * step * kp)
    if smoothing > 0:
        # imported here: scipy.ndimage's import is 0.04 s of the start of every command, and
        # only a computed chain smooths
        from scipy.ndimage import uniform_filter1d

        w = 2 * smoothing + 1
        flat_s = (uniform_filter1d(flat.real, w, axis=1, mode="nearest")
                  + 1j * uniform_filter1d(flat.imag, w, axis=1, mode="nearest"))
    else:
        flat_s = flat
    xq, xp = pil.xq, pil.xp
    h = (np.interp(xq, xp, flat_s.real.ravel())
         + 1j * np.interp(xq, xp, flat_s.imag.ravel())).reshape(kt.shape)
    h *= np.exp(1j * step * kt)
    # the floor is relative to the pilots' power: the grid is in physical units (per-RE noise
    # ~1e-13 W), where an absolute floor would overstate the noise and flatten the LLRs
    power = float(np.mean(np.abs(flat) ** 2))
    if flat.shape[1] >= 3:
        d = flat[:, 1:-1] - 0.5 * (flat[:, :-2] + flat[:, 2:])
        noise_var = float(np.mean(np.abs(d) ** 2) / 1.5)  # var(n - (n1 + n2)/2) = 1.5 var(n)
    else:  # no second differences: assume 0 dB per RE
        noise_var = power
    return h, max(noise_var, 1e-12 * power, np.finfo(float).tiny)


@dataclass(frozen=True)
class TagCheck:
    """Outcome of one slot's tag: LDPC converged, and the tag verified."""

    decoded: bool
    valid: bool


class TagVerifier:
    """Checks the tags of the serving BSs in received slot grids (UE side).

    :param keys: by BS id; HMAC needs the shared key, DS only the public key, an encrypted PRS
        (used for channel estimation) the AES key
    :param smoothing: pilot moving-average half-width of :func:`estimate_tag_channel`
    """

    def __init__(self, nr: NRConfig, security: SecurityConfig, bs_ids: Sequence[int],
                 keys: Mapping[int, BSKeys], smoothing: int = 2):
        if security.tag_scheme == "none":
            raise ValueError("security.tag_scheme is 'none': there are no tags to verify")
        self.nr, self.security = nr, security
        self.layout = ReLayout.from_config(nr, True)
        self.setups = serving_setup(nr, security, bs_ids)
        self.keys = dict(keys)
        self.smoothing = smoothing
        self.modem = TagModem(security.tag_scheme, self.layout.num_symbols * self.layout.res_per_symbol,
                              security.tag_fill, security.ldpc_iterations, security.ldpc_method)

    def check(self, rx_slot: np.ndarray, bs: int, frame: int, slot: int,
              channel: np.ndarray | None = None, noise_var: float | None = None, *,
              tag_channel: np.ndarray | None = None) -> TagCheck:
        """Decode and verify BS ``bs``'s tag in one received slot.

        :param rx_slot: [14, num_subcarriers] complex, received grid of slot ``slot``
        :param channel: [14, num_subcarriers] complex per-RE channel estimate; None: from the PRS
        :param noise_var: noise variance per RE; None: estimated from the PRS REs
        :param tag_channel: [num_symbols, res_per_symbol] complex, the channel on the BS's tag
            REs alone (tag order, as :func:`estimate_tag_channel` gives it), in place of
            ``channel`` (its values there: the same check); needs ``noise_var``
        """
        rx_slot = np.asarray(rx_slot)
        if rx_slot.shape != (SYMBOLS_PER_SLOT, self.layout.num_subcarriers):
            raise ValueError(f"Argument `rx_slot` must have shape (14, {self.layout.num_subcarriers}), "
                             f"not {rx_slot.shape}")
        setup = self.setups[bs]
        keys = self.keys[setup.bs_id]
        pil = _pilot_terms(self.layout, bs)
        sym, kt = pil.sym, pil.kt
        nv_est = noise_var
        if tag_channel is not None:
            if channel is not None or noise_var is None:
                raise ValueError("Argument `tag_channel` needs `noise_var` and excludes `channel`")
            h = np.asarray(tag_channel)
            if h.shape != kt.shape:
                raise ValueError(f"Argument `tag_channel` must have shape {kt.shape}, not {h.shape}")
        elif channel is None:
            key = keys.aes_key if setup.prs.encrypted else None
            replica = prs_replica(self.layout, bs, setup, frame, [slot], key)[0]
            h, nv = estimate_tag_channel(rx_slot, self.layout, bs, replica, self.smoothing)
            nv_est = nv if noise_var is None else noise_var
        else:
            h = np.asarray(channel)[sym, kt]
            if nv_est is None:
                raise ValueError("Argument `noise_var` is needed with a given `channel`")
        tag, decoded = self.modem.demodulate(rx_slot[sym, kt].ravel(), h.ravel(), nv_est)
        msg = tag_message(self.security.tag_scheme, setup.bs_id, frame, slot, setup.prs)
        valid = check_tag(self.security.tag_scheme, keys, msg, tag)
        return TagCheck(decoded, valid)

    def __call__(self, rx_slot: np.ndarray, bs: int, frame: int, slot: int,
                 channel: np.ndarray | None = None, noise_var: float | None = None, *,
                 tag_channel: np.ndarray | None = None) -> bool:
        """True iff BS ``bs``'s tag in this slot verifies (see :meth:`check`)."""
        return self.check(rx_slot, bs, frame, slot, channel, noise_var,
                          tag_channel=tag_channel).valid
