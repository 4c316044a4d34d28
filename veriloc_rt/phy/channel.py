"""Applying CIRs to transmitted waveforms: power control, Doppler, thermal noise.

Every link (a serving BS, the adversary, or the UE on the uplink) is a set of paths with an
absolute delay ``tau_p``, a baseband complex gain per receive antenna ``g_ap`` (carrier phase
included, :meth:`CIR.baseband_gains`) and a Doppler ``f_D,p``. What reaches antenna ``a`` is

    y_a(t) = sum_links sqrt(P_link) sum_p g_ap exp(j 2 pi f_D,p t) x_link(t - tau_p) + n_a(t)

with ``t`` absolute time and every transmitter starting its frame at t = 0 (a synchronised
network). The receiver's buffer starts at the *timing reference* ``t0`` (its sync point, a guard
before the earliest serving arrival). Two implementations:

* :func:`apply_time`: IQ at any sample rate; each path delayed exactly by a phase ramp in the
  frequency domain over the whole (zero-padded) frame, then rotated by its Doppler sample by
  sample. The reference.
* :func:`apply_frequency`: per resource element, ``Y[l, k] = H[l, k] X[l, k]`` with
  ``H[l, k] = sum_p g_p exp(-j 2 pi f_k (tau_p - t0)) exp(j 2 pi f_D,p t_l)``, ``f_k`` the baseband
  frequency of subcarrier k and ``t_l`` the centre of symbol l's FFT window. Exact when every
  ``tau_p - t0`` lies in [0, CP] and Doppler << SCS (no ISI, no ICI); it ignores both otherwise.

Power convention: a grid with unit-energy REs on all ``num_subcarriers`` is transmitted at power
P when scaled by ``sqrt(P N_fft / N_sc)`` (the OFDM transform is unitary), so P is the total power
of a fully loaded carrier and the energy per RE is P / (N_sc SCS). Noise is kT F over the sampled
band: variance ``k T F f_s`` per sample, which is also the variance per RE. The SNR per RE,
``P |H|^2 / (k T F N_sc SCS)``, is therefore the same at every sample rate.
(``ChannelConfig.noise_bandwidth_hz`` scales the density down: :func:`receiver_noise_variance`.)
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ..config.channel import REFERENCE_SAMPLE_RATE_HZ, ChannelConfig
from ..constants import BOLTZMANN, REFERENCE_TEMPERATURE, SPEED_OF_LIGHT, dbm_to_watt
from .channel_kernels import (add_response, add_response_base, add_response_on, place_scaled,
                              scatter_add)
from .nr.ofdm import OFDM
from .shortcuts import reference
from ..propagation.cir import CIR, array_response

__all__ = ["Links", "dbm_to_watt", "draw_noise", "draw_grid_noise_on", "draw_grid_noise_slots", "thermal_noise_variance", "receiver_noise_variance", "equal_arrival_powers",
           "re_amplitude", "occupied_power_factor", "symbol_times", "frequency_response", "delay_groups", "delay_factors",
           "grouped_frequency_response", "occupancy_groups",
           "group_index", "REPlan", "apply_frequency", "apply_time",
           "add_noise", "standard_normals", "timing_reference", "symbol_layout", "subcarrier_frequencies"]


def thermal_noise_variance(sample_rate_hz: float, noise_figure_db: float) -> float:
    """k T0 F f_s: noise power over the sampled band = variance per sample and per RE, W."""
    return float(BOLTZMANN * REFERENCE_TEMPERATURE * 10.0 ** (noise_figure_db / 10.0) * sample_rate_hz)


def receiver_noise_variance(channel: ChannelConfig, sample_rate_hz: float, noise_figure_db: float) -> float:
    """Variance per sample and per RE of a receiver's noise under ``channel``'s noise settings, W:
    0 without noise; :func:`thermal_noise_variance`, scaled by ``noise_bandwidth_hz / 122.88 MHz``
    when that convention is set."""
    if not channel.noise:
        return 0.0
    scale = 1.0 if channel.noise_bandwidth_hz is None else channel.noise_bandwidth_hz / REFERENCE_SAMPLE_RATE_HZ
    return thermal_noise_variance(sample_rate_hz, noise_figure_db) * scale


@dataclass(frozen=True, eq=False)
class Links:
    """Paths of a set of links to one receiver.

    delays : [num_links, num_paths] float64, s, absolute (0 on invalid paths)
    gains : [num_links, num_ant, num_paths] complex128, baseband (carrier phase included), 0 on
        invalid paths
    doppler : [num_links, num_paths] float64, Hz
    valid : [num_links, num_paths] bool
    """

    delays: np.ndarray
    gains: np.ndarray
    doppler: np.ndarray
    valid: np.ndarray

    def __post_init__(self) -> None:
        n_l, n_p = self.delays.shape
        if self.gains.shape[0] != n_l or self.gains.shape[2] != n_p:
            raise ValueError(f"Links.gains has shape {self.gains.shape}, expected [{n_l}, A, {n_p}]")
        if self.doppler.shape != (n_l, n_p) or self.valid.shape != (n_l, n_p):
            raise ValueError("Links.doppler and Links.valid must match Links.delays")

    @property
    def num_links(self) -> int:
        return self.delays.shape[0]

    @property
    def num_ant(self) -> int:
        return self.gains.shape[1]

    @classmethod
    def from_cir(cls, cir: CIR, point: int, slots=None) -> "Links":
        """Links of trajectory point ``point`` (all link slots, or those in ``slots``)."""
        sl = slice(None) if slots is None else np.asarray(slots)
        valid = cir.valid[point, sl] & (cir.tx_index[point, sl] != -1)[..., None]
        delays = cir.delays[point, sl]
        gains = cir.gains[point, sl] * np.exp(-2j * np.pi * cir.carrier_frequency * delays)[:, None, :]
        return cls(np.where(valid, cir.delays[point, sl], 0.0), np.where(valid[:, None], gains, 0.0),
                   np.where(valid, cir.doppler[point, sl], 0.0), valid)

    @classmethod
    def uplink_from_cir(cls, cir: CIR, point: int, element_pos: np.ndarray) -> list["Links"]:
        """Reciprocal uplinks of point ``point``: one single-antenna link per link slot.

        The UE transmits from one antenna at the array centre: its gain is the element gain with
        the element's plane-wave phase removed, ``g_e conj(a_e)``, averaged over elements.
        """
        down = cls.from_cir(cir, point)
        wavelength = SPEED_OF_LIGHT / cir.carrier_frequency
        a = array_response(cir.aoa_az[point], cir.aoa_zen[point], element_pos, wavelength)
        centre = np.mean(down.gains * np.conj(a), axis=1)                   # [links, paths]
        centre = np.where(down.valid, centre, 0.0)
        return [cls(down.delays[j:j + 1], centre[j:j + 1, None, :], down.doppler[j:j + 1],
                    down.valid[j:j + 1]) for j in range(down.num_links)]

    def power_gain(self) -> np.ndarray:
        """Sum over paths of |g|^2, averaged over antennas: [num_links] float64, linear."""
        return np.sum(np.mean(np.abs(self.gains) ** 2, axis=1), axis=-1)

    def first_delay(self) -> np.ndarray:
        """Earliest valid delay per link (NaN without paths): [num_links] float64, s."""
        d = np.where(self.valid, self.delays, np.inf).min(axis=-1)
        return np.where(np.isfinite(d), d, np.nan)


def timing_reference(links: Links, guard_s: float) -> float:
    """The receiver's sync point t0: ``guard_s`` before the earliest valid arrival, s (0 if none)."""
    first = links.first_delay()
    return float(np.nanmin(first) - guard_s) if np.any(np.isfinite(first)) else 0.0


def equal_arrival_powers(power_gain: np.ndarray, max_power_w: float, enabled: bool = True) -> np.ndarray:
    """Idealised power control: every link arrives as strong as the weakest at full power.

    :param power_gain: [num_links] float64, linear channel power gains (0: no path)
    :returns: [num_links] float64, W; links without a path get the maximum
    """
    g = np.asarray(power_gain, dtype=float)
    p = np.full(g.shape, float(max_power_w))
    ok = g > 0
    if enabled and np.any(ok):
        p[ok] = max_power_w * g[ok].min() / g[ok]
    return p


def re_amplitude(power_w, ofdm: OFDM) -> np.ndarray:
    """Scale of a unit-RE grid transmitted at ``power_w``: sqrt(P N_fft / N_sc)."""
    return np.sqrt(np.asarray(power_w, dtype=float) * ofdm.fft_size / ofdm.num_subcarriers)


def occupied_power_factor(mode: str, num_subcarriers: int, comb: int, with_tag: bool) -> float:
    """Factor on a PRS transmitter's power per RE: 1 for ``mode`` 'carrier'; for 'occupied' its
    power is spread over the REs it sends per PRS symbol (``num_subcarriers / comb`` PRS REs,
    twice that ``with_tag``) instead of the carrier's ``num_subcarriers``."""
    if mode == "carrier":
        return 1.0
    if mode != "occupied":
        raise ValueError(f"Argument `mode` must be 'carrier' or 'occupied', not {mode!r}")
    if not 1 <= comb <= num_subcarriers:
        raise ValueError(f"Argument `comb` must be in [1, {num_subcarriers}], not {comb}")
    return num_subcarriers / (num_subcarriers // comb * (2 if with_tag else 1))


#: entries a :func:`kept` store holds before it is emptied (a run uses a handful of keys)
KEPT_MAX = 64


def kept(store: dict, key, make, max_entries: int = KEPT_MAX):
    """``store[key]``, made by ``make()`` the first time ``key`` is asked for; a store holding
    more than ``max_entries`` entries is emptied first (the layouts, patterns and plans a run
    derives from its config; fewer for large values)."""
    try:
        return store[key]
    except KeyError:
        if len(store) > max_entries:
            store.clear()
        value = store[key] = make()
        return value


def kept_by_id(store: dict, objects: tuple, make, key: tuple = (), max_entries: int = KEPT_MAX):
    """:func:`kept` under the identities of ``objects`` (read-only arrays whose values ``make()``
    derives from) and ``key``, without reading their values; an entry holds the objects, so no
    other object takes their ids while it is kept."""
    return kept(store, tuple(id(o) for o in objects) + tuple(key), lambda: (objects, make()),
                max_entries)[1]


_LAYOUTS: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def symbol_layout(ofdm: OFDM, slots) -> tuple[np.ndarray, np.ndarray]:
    """CP start and CP length of every symbol (cached per numerology, FFT size and slots).

    :returns: starts, cps : [num_slots, 14] int64, samples
    """
    def make():
        starts = ofdm.symbol_starts(slots)
        cps = np.stack([ofdm.cp_lengths(int(s)) for s in slots])
        starts.flags.writeable = False
        cps.flags.writeable = False
        return starts, cps

    return kept(_LAYOUTS, (ofdm.numerology, ofdm.fft_size, tuple(int(s) for s in slots)), make)


def symbol_times(ofdm: OFDM, slots, t0: float) -> np.ndarray:
    """Centre of each symbol's FFT window in a buffer starting at t0 (absolute time).

    :returns: t : [num_slots, 14] float64, s
    """
    starts, cps = symbol_layout(ofdm, slots)
    return t0 + (starts + cps + (ofdm.fft_size - 1) / 2.0) / ofdm.sample_rate_hz


def subcarrier_frequencies(ofdm: OFDM) -> np.ndarray:
    """f_k = (k - N_sc/2) SCS: [num_subcarriers] float64, Hz (subcarrier k at FFT bin k - N_sc/2)."""
    return (np.arange(ofdm.num_subcarriers) - ofdm.num_subcarriers // 2) * ofdm.subcarrier_spacing_hz


def frequency_response(links: Links, freqs: np.ndarray, times: np.ndarray, t0: float,
                       grouped: bool = False, groups: list | None = None) -> np.ndarray:
    """H[link, a, t, k] = sum_p g_ap exp(-j 2 pi f_k (tau_p - t0)) exp(j 2 pi f_D,p t).

    With ``grouped`` (the shortcut ``delays`` of :mod:`veriloc_rt.phy.shortcuts`) the sum runs
    over each link's distinct delays: paths of one delay (the rays of a TR 38.901 cluster or
    sub-cluster share theirs) share the factor exp(-j 2 pi f_k (tau - t0)), so
    H = sum_tau exp(-j 2 pi f_k (tau - t0)) sum_{p: tau_p = tau} g_ap exp(j 2 pi f_D,p t):
    the same sum (each path's factors are the same numbers), added in another order, which
    changes the last bits only (:func:`grouped_frequency_response`). Without it, or when no link
    has two valid paths at one delay (ray-traced links: nothing to group), path by path (the
    reference, to the bit).

    :param freqs: [K] float64, Hz; times: [T] float64, s (absolute)
    :param groups: with ``grouped``, each link's :func:`delay_groups` when the caller has them
    :returns: [num_links, num_ant, T, K] complex128
    """
    if grouped:
        if groups is None:
            groups = [delay_groups(links.delays[li], links.valid[li]) for li in range(links.num_links)]
        if any(taus.size < paths.size for taus, paths, _ in groups):
            return grouped_frequency_response(links, freqs, times, t0, groups)
    rel = np.where(links.valid, links.delays - t0, 0.0)
    e_f = np.exp(-2j * np.pi * rel[:, :, None] * freqs[None, None, :])          # [L, P, K]
    e_t = np.exp(2j * np.pi * links.doppler[:, :, None] * times[None, None, :])  # [L, P, T]
    gd = links.gains[:, :, None, :] * np.swapaxes(e_t, 1, 2)[:, None]           # [L, A, T, P]
    return gd @ e_f[:, None]                                                     # [L, A, T, K]


def delay_groups(delays: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One link's valid paths grouped by their delay (equal floats: the rays of a TR 38.901
    cluster or sub-cluster).

    :param delays, valid: [P] float64, bool
    :returns: (distinct delays [U] float64 increasing, the valid paths ordered by delay [V] int64,
        where each delay's run of paths starts in that order [U] int64)
    """
    paths = np.flatnonzero(valid)
    d = delays[paths]
    order = np.argsort(d, kind="stable")
    paths, d = paths[order], d[order]
    starts = np.flatnonzero(np.concatenate([[True], d[1:] != d[:-1]])) if d.size else np.zeros(0, np.int64)
    return d[starts], paths, starts


def grouped_frequency_response(links: Links, freqs: np.ndarray, times: np.ndarray, t0: float,
                               groups: list | None = None) -> np.ndarray:
    """:func:`frequency_response` summed over each link's distinct delays
    (:func:`delay_groups`): G[a, t, u] = sum_{p: tau_p = tau_u} g_ap exp(j 2 pi f_D,p t), then
    H = G @ exp(-j 2 pi (tau_u - t0) f_k). The product costs A T U K instead of A T P K
    (TR 38.901 UMa: U ~ 20-30 distinct delays for P ~ 400 rays); each path's two exponentials
    are the reference's numbers.

    :param freqs: [K] float64, Hz; times: [T] float64, s (absolute)
    :param groups: each link's :func:`delay_groups` when the caller has them
    :returns: [num_links, num_ant, T, K] complex128
    """
    out = np.zeros((links.num_links, links.num_ant, times.size, freqs.size), dtype=np.complex128)
    for li in range(links.num_links):
        group = (delay_groups(links.delays[li], links.valid[li]) if groups is None
                 else groups[li])
        if group[1].size == 0:
            continue
        np.matmul(*delay_factors(links, li, freqs, times, t0, group), out=out[li])
    return out


def delay_factors(links: Links, li: int, freqs: np.ndarray, times: np.ndarray, t0: float,
                  group: tuple) -> tuple[np.ndarray, np.ndarray]:
    """The two factors of link ``li``'s response over the delays of ``group`` (``(taus, paths,
    starts)`` as :func:`delay_groups` gives them; one path a delay: its valid paths, ``starts``
    0..V-1): G[a, t, u] = sum_{p: tau_p = tau_u} g_ap exp(j 2 pi f_D,p t) [A, T, U] and
    exp(-j 2 pi (tau_u - t0) f_k) [U, K], complex128; H = G @ that."""
    taus, paths, starts = group
    e_t = np.exp(2j * np.pi * links.doppler[li, paths][:, None] * times[None, :])   # [V, T]
    gd = links.gains[li][:, None, paths] * e_t.T[None]                              # [A, T, V]
    g = np.add.reduceat(gd, starts, axis=-1) if 0 < starts.size < paths.size else gd
    return g, np.exp(-2j * np.pi * (taus - t0)[:, None] * freqs[None, :])          # [U, K]


def occupancy_groups(occ: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """Rows of a boolean matrix grouped by their pattern (the symbols of a grid by the
    subcarriers they occupy, the blocks of a replica by their bins).

    :param occ: [R, C] bool
    :returns: list of (row indices, column indices of the True entries), rows without one left
        out; None when every entry is True
    """
    if occ.all():
        return None
    used = np.flatnonzero(occ.any(axis=1))
    if used.size == 0:
        return []
    packed = np.ascontiguousarray(np.packbits(occ[used], axis=1))
    rows = packed.view(np.dtype((np.void, packed.shape[1])))[:, 0]
    _, first, inv = np.unique(rows, return_index=True, return_inverse=True)
    inv = inv.ravel()
    return [(used[inv == g], np.flatnonzero(occ[used[i]])) for g, i in enumerate(first)]


def as_slice(idx: np.ndarray):
    """``idx`` (increasing int64) as a slice when evenly spaced (a comb's subcarriers), else
    ``idx`` itself: both select the same entries, and a slice gathers and scatters several
    times faster than an index array."""
    if idx.size == 1:
        return slice(int(idx[0]), int(idx[0]) + 1)
    step = int(idx[1] - idx[0])
    if step > 0 and np.all(np.diff(idx) == step):
        return slice(int(idx[0]), int(idx[-1]) + 1, step)
    return idx


def group_index(rows: np.ndarray, cols: np.ndarray) -> tuple:
    """Index of the block ``rows x cols`` of a matrix (a group of :func:`occupancy_groups`):
    ``(rows, slice)`` when ``cols`` is an arithmetic progression (a comb's subcarriers), else
    ``(rows[:, None], cols[None, :])``. Both select the same [len(rows), len(cols)] entries;
    one index array and a slice gather and scatter several times faster than two arrays.

    :param rows, cols: [R], [C] int64, increasing
    """
    ix = as_slice(cols)
    return (rows, ix) if isinstance(ix, slice) else (rows[:, None], cols[None, :])


def apply_frequency(links: Links, grids: np.ndarray, amplitudes: np.ndarray, ofdm: OFDM, slots,
                    t0: float, occupied: np.ndarray | None = None,
                    base: np.ndarray | None = None) -> np.ndarray:
    """Received resource grid, noiseless: sum over links of a_l H_l X_l (plus ``base``).

    H_l is evaluated only on the REs its grid occupies (:func:`occupancy_groups`; a comb-6 PRS
    with tags: 2/6 of the subcarriers of 12 of 14 symbols), which is exact: elsewhere
    H_l X_l = 0; summed over each link's distinct delays (:func:`grouped_frequency_response`)
    unless ``VERILOC_RT_REFERENCE`` names the shortcut ``delays`` (read at each call). The
    groups' REs form one flat index per occupancy pattern (:class:`REPlan`, kept), and the
    response on them one array (:meth:`_LinkResponses.on`, kept): one gather, product and
    scatter a link (the scatter's additions compiled, :func:`~.channel_kernels.scatter_add`),
    the same values as group by group. A link of one distinct delay (path loss only) is applied
    in one compiled pass instead, its response formed RE by RE (:data:`FUSE_MAX_DELAYS`), unless
    ``VERILOC_RT_REFERENCE`` names the shortcut ``jitchannel`` (read at each call).

    :param grids: [num_links, num_slots, 14, num_subcarriers] complex, transmitted unit-RE grids
    :param amplitudes: [num_links] float64, RE scale of each transmitter (:func:`re_amplitude`)
    :param occupied: [num_links, num_slots, 14, num_subcarriers] bool, ``grids != 0`` when the
        caller knows it (a transmitter's REs: :meth:`PRSTransmitter.occupied`), else None
    :param base: [num_ant, num_slots, 14, num_subcarriers] complex128 added to the sum (the
        other signals at the receiver), the bits of ``y = apply_frequency(...); y += base``;
        one link of a dense grid under ``jitchannel`` adds it in the pass that applies the
        link (:func:`~.channel_kernels.add_response_base`), else it is added after the sum
    :returns: [num_ant, num_slots, 14, num_subcarriers] complex128 (a new array)
    """
    grids = np.asarray(grids)
    if occupied is not None and occupied.shape != grids.shape:
        raise ValueError(f"Argument `occupied` {occupied.shape} must have the shape of `grids` {grids.shape}")
    if grids.shape[0] != links.num_links:
        raise ValueError(f"Argument `grids` has {grids.shape[0]} links, `links` {links.num_links}")
    t = symbol_times(ofdm, slots, t0)
    f = subcarrier_frequencies(ofdm)
    k_n = ofdm.num_subcarriers
    shape = (links.num_ant, t.size, k_n)
    out = None   # made by the first link: a dense one's product is it (no zeros to add to)
    flat_t = t.ravel()
    grouped = not reference("delays")
    fused = not reference("jitchannel")
    if base is not None:
        base = np.asarray(base)
        if base.shape != (links.num_ant, *t.shape, k_n):
            raise ValueError(f"Argument `base` {base.shape} must have the output's shape "
                             f"{(links.num_ant, *t.shape, k_n)}")
    # the base added in the one link's pass (its sum is that link's product alone)
    fuse_base = base if links.num_links == 1 else None
    for li, amp in enumerate(np.asarray(amplitudes, dtype=float)):
        x = grids[li].reshape(t.size, k_n)
        one = Links(links.delays[li:li + 1], links.gains[li:li + 1], links.doppler[li:li + 1],
                    links.valid[li:li + 1])
        response = _LinkResponses(one, t0, grouped)
        # a dense grid (a jammer's noise) gains nothing from groups
        occ = x != 0 if occupied is None else occupied[li].reshape(t.size, k_n)
        plan = _plan_of(occ)
        if fused and response.num_delays() <= FUSE_MAX_DELAYS:   # the shortcut jitchannel
            out = _add_fused(out, shape, response, plan, f, flat_t, amp, x, fuse_base)
            if fuse_base is not None and response.num_delays() > 0:
                return out.reshape(links.num_ant, *t.shape, k_n)   # base added
            continue
        if plan is None:
            v = response(f, flat_t, amp) * x[None]         # (amp * h) * x
            if out is None:   # 0 + v: v with -0.0 made +0.0
                out = np.add(v, 0.0, out=v)
            else:
                out += v
            continue
        if out is None:
            out = np.zeros(shape, dtype=np.complex128)
        idx = plan.index
        # a H X on the link's REs, group by group: the values of (amp * h) * x
        v = response.on(plan, f, flat_t, amp) * x.reshape(-1)[idx][None]        # [A, n]
        # out += v there, in place (out is 0 where no link has added: 0 + v); the plan's
        # index is the REs of a [T, K] mask, each once
        scatter_add(out.reshape(links.num_ant, -1), idx, v)
    if out is None:
        out = np.zeros(shape, dtype=np.complex128)
    out = out.reshape(links.num_ant, *t.shape, k_n)
    if base is not None:
        out += base
    return out


#: distinct delays a link may have for the shortcut ``jitchannel`` to apply it (a path-loss-only
#: link has one): its response is then one complex product an RE and antenna, formed in the pass
#: that applies it, cheaper than evaluating and keeping it; with more, the loop over the delays
#: costs more than reading a kept response (measured: 0.7, 2.4 and 15 ms for 1, 2 and 25 delays
#: on a [5, 140, 624] grid), and a fused pass over the kept response did not pay on the 9-TRP
#: fast-fading chain (in-process A/B 1.004): those links take the reference path, bit for bit
FUSE_MAX_DELAYS = 1


def _add_fused(out: np.ndarray | None, shape: tuple, response: "_LinkResponses",
               plan: "REPlan | None", f: np.ndarray, t: np.ndarray, amp: float,
               x: np.ndarray, base: np.ndarray | None = None) -> np.ndarray:
    """``out + (amp H) x`` of one link of at most :data:`FUSE_MAX_DELAYS` distinct delays in one
    compiled pass (:mod:`.channel_kernels`; ``out`` None: a new grid, ``(amp H) x``), on the REs
    of ``plan`` (None: every RE), H formed RE by RE from its factors
    (:meth:`_LinkResponses.factors`).

    :param shape: (A, T, K) of ``out``; x: [T, K] the link's grid; f: [K]; t: [T]
    :param base: with ``out`` None, a new grid ``(amp H) x + base`` (the output's shape), the
        bits of ``(0 + (amp H) x) + base``: dense, :func:`~.channel_kernels.add_response_base`;
        on the REs of ``plan``, :func:`~.channel_kernels.add_response_on` into ``base + 0``
        (``q + (b + 0)`` is ``q + b`` for every q but -0, which ``0 + v`` never is, and
        ``-0 + (b + 0)`` is ``+0 + b``); else unused
    """
    a = shape[0]
    if response.num_delays() == 0:   # no path: H = 0
        return np.zeros(shape, dtype=np.complex128) if out is None else out
    xf = np.ascontiguousarray(x, dtype=np.complex128).view()
    xf.flags.writeable = False   # (a read-only view: one compilation for every caller's grids)
    g, e_f = response.factors(f, t)
    if plan is None:
        first = out is None
        if first:
            out = np.empty(shape, dtype=np.complex128)
        if first and base is not None:
            bf = np.ascontiguousarray(base, dtype=np.complex128).reshape(shape).view()
            bf.flags.writeable = False   # (one compilation, as xf)
            add_response_base(out, g, e_f, float(amp), xf, bf)
            return out
        add_response(out, g, e_f, float(amp), xf, first)
        return out
    if out is None:
        out = (np.zeros(shape, dtype=np.complex128) if base is None
               else np.add(np.reshape(base, shape), 0.0))   # 0 + base off the link's REs
    add_response_on(out.reshape(a, -1), plan.index, plan.rows, plan.cols, g, e_f, float(amp),
                    xf.reshape(-1))
    return out


#: per thread (a chain may run in several threads of a Dask worker): the frequency responses
#: of the last links applied, by link and then by REs (:class:`_LinkResponses`)
KEPT_RESPONSES = threading.local()
#: links whose responses are kept (a point applies a few tens: its serving links, the
#: adversary's link to the UE and from the serving BSs, the uplinks; with 9 TRPs 28, which
#: a store of 16 dropped before the point's last chain came back to them)
RESPONSES_MAX = 64
#: bytes of kept responses above which the least recently used links' are dropped (a point of
#: the paper config or of 9 TRPs at 52 PRBs keeps 15 MiB, at 273 PRBs about 5 times that)
RESPONSES_MAX_BYTES = 256 * 2 ** 20


class _LinkResponses:
    """The frequency responses of one link (:func:`frequency_response`, summed over its distinct
    delays when ``grouped``) on the REs asked for, times a transmitter's RE amplitude, kept by
    the link's paths, t0, the summation, the times, the frequencies and the amplitude (the same
    numbers give the same response): the chains of a point
    (standard, DS-tagged and encrypted PRS, on the same REs) and the adversary's scenarios apply
    the same links to the same REs, and compute each response once. A kept response is
    read-only. The links are kept least recently used first out (:data:`RESPONSES_MAX`,
    :data:`RESPONSES_MAX_BYTES`); the link's delay groups are found once for all its REs."""

    def __init__(self, one: Links, t0: float, grouped: bool = False):
        local = KEPT_RESPONSES
        store = getattr(local, "links", None)
        if store is None:
            store = local.links = {}
            local.nbytes, local.total = {}, 0
        key = (one.delays.tobytes(), one.gains.tobytes(), one.doppler.tobytes(),
               one.valid.tobytes(), float(t0), bool(grouped))
        self.one, self.t0, self.grouped = one, float(t0), bool(grouped)
        self.key = key
        self._delay_groups = None
        kept = store.pop(key, None)   # put back last: the most recently used
        if kept is None:
            while len(store) >= RESPONSES_MAX:
                self._drop(next(iter(store)))   # the least recently used link
            kept = {}
            local.nbytes[key] = 0
        store[key] = kept
        self.kept = kept

    @staticmethod
    def _drop(key) -> None:
        local = KEPT_RESPONSES
        local.links.pop(key)
        local.total -= local.nbytes.pop(key)

    def _keep(self, key, h: np.ndarray) -> np.ndarray:
        h.flags.writeable = False
        local = KEPT_RESPONSES
        if self.key not in local.links:   # dropped meanwhile (another link's bytes): back in
            local.links[self.key] = self.kept
            local.nbytes[self.key] = sum(a.nbytes for a in self.kept.values())
            local.total += local.nbytes[self.key]
        self.kept[key] = h
        local.nbytes[self.key] += h.nbytes
        local.total += h.nbytes
        while local.total > RESPONSES_MAX_BYTES and len(local.links) > 1:
            oldest = next(iter(local.links))
            self._drop(oldest if oldest != self.key else list(local.links)[1])
        return h

    def _groups(self) -> list | None:
        """The link's :func:`delay_groups` (``grouped`` only), found at the first need."""
        if not self.grouped:
            return None
        if self._delay_groups is None:
            self._delay_groups = [delay_groups(self.one.delays[0], self.one.valid[0])]
        return self._delay_groups

    def num_delays(self) -> int:
        """U: the link's distinct delays (``grouped``) or valid paths."""
        return self._groups()[0][0].size if self.grouped else int(np.count_nonzero(self.one.valid))

    def factors(self, freqs: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The response's factors (kept, read-only): G[a, t, u] = sum_{p: tau_p =
        tau_u} g_ap exp(j 2 pi f_D,p t) [A, T, U] and exp(-j 2 pi f_k (tau_u - t0)) [K, U],
        complex128, u over the link's distinct delays (``grouped``) or its valid paths;
        H = sum_u of their products (:func:`frequency_response`'s factors)."""
        kg, ke = ("g", times.tobytes()), ("e_f", freqs.tobytes())
        g, e_f = self.kept.get(kg), self.kept.get(ke)
        if g is not None and e_f is not None:
            return g, e_f
        if self.grouped:
            group = self._groups()[0]
        else:
            paths = np.flatnonzero(self.one.valid[0])
            group = (self.one.delays[0, paths], paths, np.arange(paths.size))
        g, e_f = delay_factors(self.one, 0, freqs, times, self.t0, group)
        return (self._keep(kg, np.ascontiguousarray(g)),
                self._keep(ke, np.ascontiguousarray(e_f.T)))                           # [K, U]

    def __call__(self, freqs: np.ndarray, times: np.ndarray, scale: float) -> np.ndarray:
        """``scale`` H[a, t, k] of the link: [A, T, K] complex128 (read-only; the values of
        ``np.multiply(H, scale)``)."""
        key = (times.tobytes(), freqs.tobytes(), float(scale))
        h = self.kept.get(key)
        if h is None:
            h = self._keep(key, np.multiply(frequency_response(self.one, freqs, times, self.t0,
                                                               self.grouped, self._groups())[0],
                                            scale))
        return h

    def on(self, plan: "REPlan", freqs: np.ndarray, times: np.ndarray, scale: float) -> np.ndarray:
        """``scale`` H of the link on the REs of ``plan``, in its index's order: [A, n]
        complex128 (read-only), each group's block the values :meth:`__call__` gives it
        (``freqs``: [K], ``times``: [T], the grid's)."""
        key = (plan, times.tobytes(), freqs.tobytes(), float(scale))
        h = self.kept.get(key)
        if h is None:
            a = self.one.num_ant
            groups = self._groups()
            parts = [np.multiply(frequency_response(self.one, freqs[sc], times[sym], self.t0,
                                                    self.grouped, groups)[0], scale).reshape(a, -1)
                     for sym, sc in plan.groups]
            h = self._keep(key, np.concatenate(parts, axis=1) if parts
                           else np.zeros((a, 0), dtype=np.complex128))
        return h


class REPlan:
    """The occupied REs of a grid [T, K] as :func:`occupancy_groups` groups them, and as one
    flat index into the T K plane, group after group, each group row-major (the order
    ``x[group_index(rows, cols)].ravel()`` reads them in).

    groups : list of (rows [R] int64, cols [C] int64); index : [n] int64, read-only; rows,
    cols : [n] int64, read-only, each RE's row (symbol) and column (subcarrier)
    """

    __slots__ = ("groups", "index", "rows", "cols")

    def __init__(self, groups: list, num_cols: int):
        self.groups = groups
        idx = (np.concatenate([(rows[:, None] * num_cols + cols[None, :]).ravel()
                               for rows, cols in groups]) if groups else np.zeros(0, np.int64))
        self.rows, self.cols = np.divmod(idx, num_cols)
        for a in (idx, self.rows, self.cols):
            a.flags.writeable = False
        self.index = idx


_GROUPS: dict[bytes, REPlan | None] = {}
#: the plans of read-only masks by the array owning their memory and where they lie in it
_GROUPS_BY_MEMORY: dict[tuple, tuple] = {}


def _plan_of(occ: np.ndarray) -> REPlan | None:
    """The :class:`REPlan` of ``occ`` [T, K] (None: more than half of it occupied, a dense
    grid: no groups), kept per pattern (a run's grids share a few: the PRS and tag REs of each
    BS, fixed by the config). A read-only mask (a transmitter's kept one: the same memory at
    every call) is found by its memory, without reading its pattern."""
    def make():
        if 2 * np.count_nonzero(occ) > occ.size:
            return None
        groups = occupancy_groups(occ)
        return REPlan(groups, occ.shape[1]) if groups is not None else None

    owner = occ if occ.base is None else occ.base
    by_value = lambda: kept(_GROUPS, occ.tobytes() + str(occ.shape).encode(), make)  # noqa: E731
    if occ.flags.writeable or not isinstance(owner, np.ndarray) or owner.flags.writeable:
        return by_value()
    return kept_by_id(_GROUPS_BY_MEMORY, (owner,), by_value,
                      key=(occ.__array_interface__["data"][0], occ.shape, occ.strides))


def apply_time(links: Links, waveforms: np.ndarray, amplitudes: np.ndarray, sample_rate_hz: float,
               t0: float, num_out: int, decimation: int = 1) -> np.ndarray:
    """Received IQ, noiseless: exact fractional delays (FFT phase ramp) and per-sample Doppler.

    Sample n of the output is absolute time t0 + n / f_s. Each input waveform starts at t = 0
    and is zero outside its samples (the FFT is zero-padded so nothing wraps into the output).
    Cost: one full-length inverse FFT per path.

    With ``decimation`` D > 1 the waveforms are ideally low-passed to |f| < f_s / (2 D), the paths
    are applied at f_s / D and the sum is interpolated back to f_s (spectrum zero-padding). Delay
    and Doppler (<< f_s / D) keep a band-limited signal band-limited, so this is exact for the
    waveform's content inside f_s / (2 D) and drops only what lies outside (the CP-OFDM
    out-of-band leakage, which a transmit filter removes anyway); D times cheaper per path.

    :param waveforms: [num_links, num_in] complex, baseband at ``sample_rate_hz``
    :param amplitudes: [num_links] float64
    :param decimation: int >= 1, D
    :returns: [num_ant, num_out] complex128
    """
    x = np.asarray(waveforms)
    if x.ndim != 2 or x.shape[0] != links.num_links:
        raise ValueError(f"Argument `waveforms` must be [{links.num_links}, num_in], not {x.shape}")
    if not isinstance(decimation, (int, np.integer)) or decimation < 1:
        raise ValueError(f"Argument `decimation` must be an int >= 1, not {decimation!r}")
    fs = float(sample_rate_hz)
    rel = np.where(links.valid, links.delays - t0, 0.0)
    lead = int(np.ceil(max(0.0, -rel.min()) * fs)) + 64
    span = int(np.ceil(max(0.0, rel.max()) * fs)) + 64
    need = max(x.shape[1] + span, num_out) + lead + 64
    n_low = sfft.next_fast_len(-(-need // decimation))
    n_low += n_low % 2
    nfft = n_low * decimation
    keep = np.concatenate([np.arange(n_low // 2), np.arange(nfft - n_low // 2, nfft)])
    f = sfft.fftfreq(nfft, 1.0 / fs)[keep]
    fs_low = fs / decimation
    n_keep = n_low if decimation > 1 else min(num_out, n_low)
    t = t0 + np.arange(n_keep) / fs_low
    low = np.zeros((links.num_ant, n_low), dtype=np.complex128)
    for li in range(links.num_links):
        if not np.any(links.valid[li]) or amplitudes[li] == 0:
            continue
        spec = sfft.fft(x[li], nfft)[keep] / decimation
        for p in np.flatnonzero(links.valid[li]):
            d = sfft.ifft(spec * np.exp(-2j * np.pi * f * rel[li, p]))[:n_keep]
            if links.doppler[li, p] != 0.0:
                d = d * np.exp(2j * np.pi * links.doppler[li, p] * t)
            low[:, :n_keep] += (amplitudes[li] * links.gains[li, :, p])[:, None] * d[None, :]
    if decimation == 1:
        out = low
    else:  # band-limited interpolation back to fs
        spec = np.zeros((links.num_ant, nfft), dtype=np.complex128)
        spec[:, keep] = sfft.fft(low, axis=-1) * decimation
        out = sfft.ifft(spec, axis=-1)
    out = out[:, :num_out]
    return out if out.shape[1] == num_out else np.pad(out, ((0, 0), (0, num_out - out.shape[1])))


def add_noise(x: np.ndarray, variance: float, rng: np.random.Generator, major_axis: int = 0,
              single: bool = False) -> np.ndarray:
    """x + circular complex Gaussian noise of the given variance (a new array).

    :param major_axis: the axis the draws run along outermost: the noise of the leading entries
        of that axis does not depend on its length (a received grid [A, S, 14, K] with axis 1:
        the first slots' noise is the same whether the grid has them alone or every slot)
    :param single: the normals drawn in single precision (:func:`standard_normals`)
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"Argument `rng` must be a numpy.random.Generator, not {type(rng).__name__}")
    if variance <= 0:
        return np.array(x, dtype=np.complex128)
    n = draw_noise(x.shape, variance, rng, major_axis, single)
    n += x
    return n


def standard_normals(rng: np.random.Generator, count: int, scale: float,
                     single: bool = False) -> np.ndarray:
    """``count`` circular complex normals of variance ``2 scale^2`` (real and imaginary parts
    i.i.d. N(0, scale^2)): complex128 [count].

    :param single: the N(0, 1) draws in single precision (``Generator.standard_normal`` with
        ``dtype=float32``: NumPy's float32 ziggurat, other numbers from the same distribution
        to 24 bits, about a third cheaper to draw; the shortcut ``noise32`` of
        :mod:`veriloc_rt.phy.shortcuts`), scaled in float64; else float64 draws scaled in
        place (the reference)
    """
    if not single:
        n = rng.standard_normal((count, 2)).view(np.complex128)[:, 0]
        n *= scale
        return n
    z = rng.standard_normal((count, 2), dtype=np.float32)
    n = np.empty(count, dtype=np.complex128)
    np.multiply(z, scale, out=n.view(np.float64).reshape(count, 2), dtype=np.float64)
    return n


def draw_noise(shape: tuple, variance: float, rng: np.random.Generator, major_axis: int = 0,
               single: bool = False) -> np.ndarray:
    """Circular complex Gaussian noise CN(0, variance) of ``shape``, drawn as :func:`add_noise`
    draws it (the noise :func:`add_noise` adds, without the signal): complex128, ``major_axis``
    outermost in the draws; ``single``: single-precision normals (:func:`standard_normals`)."""
    order = (shape[major_axis],) + tuple(np.delete(shape, major_axis))
    if single:
        n = standard_normals(rng, int(np.prod(order)), np.sqrt(variance / 2.0), True).reshape(order)
        return np.moveaxis(n, 0, major_axis)
    n = rng.standard_normal(order + (2,)).view(np.complex128)[..., 0]
    n = np.moveaxis(n, 0, major_axis)
    n *= np.sqrt(variance / 2.0)
    return n


def draw_grid_noise_slots(shape: tuple, read: np.ndarray | None, variance: float,
                          rng: np.random.Generator, single: bool = False) -> tuple[np.ndarray, list]:
    """The noise :func:`draw_grid_noise_on` draws (``read`` given) or :func:`draw_noise` with
    ``major_axis`` 1 (``read`` None: every RE), the same values from the same generator state,
    drawn one slot after the other, and the generator's state after each slot's draws: the
    noise of the first S' slots of a grid is the first S' slots of this, and the generator
    moved past them is the state after slot S' - 1 (the draws run slot-major, and NumPy's
    normals carry nothing from one call to the next but the generator's state).

    :param shape: (A, S, 14, K), the grid's
    :param read: [S', 14, K] bool with S' >= S (its first S slots count), or None
    :param single: single-precision normals (:func:`standard_normals`)
    :returns: noise [A, S, 14, K] complex128 (a view of slot-major memory, as the two give
        it); states: [S] the generator's state (``bit_generator.state``) after each slot
    """
    a, s = shape[0], shape[1]
    rest = tuple(shape[2:])
    per_slot = a * int(np.prod(rest))
    if read is None:
        idx = None
        bounds = np.arange(s + 1) * per_slot
    else:
        idx = _read_index(read, s, a, rest)
        bounds = np.searchsorted(idx, np.arange(s + 1) * per_slot)
    total = int(bounds[-1])
    scale = np.sqrt(variance / 2.0)
    z = np.empty((total, 2), dtype=np.float32 if single else np.float64)
    states = []
    for i in range(s):
        if bounds[i + 1] > bounds[i]:
            if single:
                rng.standard_normal(dtype=np.float32, out=z[bounds[i]:bounds[i + 1]])
            else:
                rng.standard_normal(out=z[bounds[i]:bounds[i + 1]])
        states.append(rng.bit_generator.state)
    if idx is not None:   # scaled as below, onto the read REs (0 elsewhere), in one pass
        out = np.empty((s, a) + rest, dtype=np.complex128)
        place_scaled(out.reshape(-1), idx, z, float(scale), not single)
        return np.moveaxis(out, 0, 1), states
    # as standard_normals scales them: float32 draws times scale into float64, float64 in place
    if single:
        n = np.empty(total, dtype=np.complex128)
        np.multiply(z, scale, out=n.view(np.float64).reshape(total, 2), dtype=np.float64)
    else:
        n = z.view(np.complex128)[:, 0]
        n *= scale
    return np.moveaxis(n.reshape((s, a) + rest), 0, 1), states


#: the flat indices of read masks, by the mask's memory (read-only masks only)
_READ_INDEX: dict = {}


def _read_index(read: np.ndarray, s: int, a: int, rest: tuple) -> np.ndarray:
    """Flat indices (C order) of the REs of ``read[:s]`` in a grid [s, a, *rest] laid out slot,
    antenna, symbol, subcarrier: kept for a read-only mask (a chain's kept one: the same memory
    at every call), computed again for a writeable one. An integer scatter is about three times
    faster than the boolean one of the same REs."""
    def make():
        mask = np.broadcast_to(np.asarray(read, dtype=bool)[:s, None], (s, a) + rest)
        idx = np.flatnonzero(mask)
        idx.flags.writeable = False
        return idx

    owner = read if not isinstance(read, np.ndarray) or read.base is None else read.base
    if (not isinstance(read, np.ndarray) or read.flags.writeable
            or not isinstance(owner, np.ndarray) or owner.flags.writeable):
        return make()
    return kept_by_id(_READ_INDEX, (owner,), make,
                      key=(read.__array_interface__["data"][0], read.shape, read.strides,
                           read.dtype.str, s, a, rest), max_entries=8)


def draw_grid_noise_on(shape: tuple, read: np.ndarray, variance: float,
                       rng: np.random.Generator, single: bool = False) -> np.ndarray:
    """Circular complex Gaussian noise CN(0, variance) on the REs ``read`` of a grid, 0 elsewhere.

    The draws run as :func:`draw_noise`'s with ``major_axis`` 1 (slot, then antenna, symbol,
    subcarrier) over the REs of ``read`` alone: with every RE read, the values are
    :func:`draw_noise`'s; the first slots' noise does not depend on the number of slots. Each
    read RE's noise has the distribution :func:`draw_noise` gives it (i.i.d. CN(0, variance)),
    so a receiver that reads no other RE sees the same statistics.

    :param shape: (A, S, 14, K), the grid's
    :param read: [S', 14, K] bool with S' >= S (its first S slots count)
    :param single: single-precision normals (:func:`standard_normals`)
    :returns: [A, S, 14, K] complex128
    """
    a, s = shape[0], shape[1]
    idx = _read_index(read, s, a, tuple(shape[2:]))
    out = np.empty((s, a) + tuple(shape[2:]), dtype=np.complex128)
    # the flat indices of the mask's REs in C order (the order a boolean mask fills them in),
    # each given standard_normals' draw, scaled as it scales them (place_scaled: exact)
    z = rng.standard_normal((idx.size, 2), dtype=np.float32 if single else np.float64)
    place_scaled(out.reshape(-1), idx, z, float(np.sqrt(variance / 2.0)), not single)
    return np.moveaxis(out, 0, 1)
