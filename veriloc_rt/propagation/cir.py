"""The one channel-impulse-response type every propagation model produces.

Axis order, declared once here and kept everywhere downstream:
``[num_points, num_tx, ...]`` then the antenna axis (UE array elements) then ``num_paths``.
A *link slot* ``j`` of point ``k`` is the link from transmitter ``tx_index[k, j]`` to the
receiver at ``rx_pos[k]``. Paths are padded to a common ``num_paths``; ``valid`` masks them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..constants import SPEED_OF_LIGHT

#: Interaction codes (Sionna RT's ``InteractionType`` bit values)
INTERACTION_NONE = 0
INTERACTION_SPECULAR = 1
INTERACTION_DIFFUSE = 2
INTERACTION_REFRACTION = 4
INTERACTION_DIFFRACTION = 8

#: ``tx_index`` of an empty link slot, and of the adversary
NO_TX = -1
ADVERSARY_TX = -2


@dataclass(frozen=True, eq=False)
class CIR:
    """Multipath channel impulse responses for a set of links over a trajectory.

    Gains are passband path coefficients (amplitude and phase of the field, path loss included,
    carrier phase ``exp(-j 2 pi fc tau)`` *not* included) at each UE antenna element; the
    baseband coefficient is ``gains * exp(-2j*pi*fc*delays)``.

    delays : [num_points, num_tx, num_paths] float64, s (absolute propagation delay)
    gains : [num_points, num_tx, num_ant, num_paths] complex128, linear amplitude
    aoa_az, aoa_zen : [num_points, num_tx, num_paths] float64, rad (arrival at the receiver)
    aod_az, aod_zen : [num_points, num_tx, num_paths] float64, rad (departure at the transmitter)
    doppler : [num_points, num_tx, num_paths] float64, Hz
    interactions : [num_points, num_tx, num_paths, max_depth] uint8, ``INTERACTION_*`` codes
    valid : [num_points, num_tx, num_paths] bool
    tx_index : [num_points, num_tx] int64, transmitter id (NO_TX: empty slot, ADVERSARY_TX)
    tx_pos : [num_points, num_tx, 3] float64, m
    rx_pos : [num_points, 3] float64, m
    los : [num_points, num_tx] bool, the link has an unobstructed direct path
    carrier_frequency : float, Hz
    """

    delays: np.ndarray
    gains: np.ndarray
    aoa_az: np.ndarray
    aoa_zen: np.ndarray
    aod_az: np.ndarray
    aod_zen: np.ndarray
    doppler: np.ndarray
    interactions: np.ndarray
    valid: np.ndarray
    tx_index: np.ndarray
    tx_pos: np.ndarray
    rx_pos: np.ndarray
    los: np.ndarray
    carrier_frequency: float
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        p, t, n = self.delays.shape
        expect = {
            "gains": (p, t, self.gains.shape[2], n), "aoa_az": (p, t, n), "aoa_zen": (p, t, n),
            "aod_az": (p, t, n), "aod_zen": (p, t, n), "doppler": (p, t, n), "valid": (p, t, n),
            "tx_index": (p, t), "tx_pos": (p, t, 3), "rx_pos": (p, 3), "los": (p, t),
        }
        for name, shape in expect.items():
            got = getattr(self, name).shape
            if got != shape:
                raise ValueError(f"CIR.{name} has shape {got}, expected {shape}")
        if self.interactions.shape[:3] != (p, t, n):
            raise ValueError(f"CIR.interactions has shape {self.interactions.shape}, "
                             f"expected ({p}, {t}, {n}, max_depth)")

    # -- sizes -------------------------------------------------------------------------------
    @property
    def num_points(self) -> int:
        return self.delays.shape[0]

    @property
    def num_tx(self) -> int:
        return self.delays.shape[1]

    @property
    def num_ant(self) -> int:
        return self.gains.shape[2]

    @property
    def num_paths(self) -> int:
        return self.delays.shape[2]

    # -- derived quantities ------------------------------------------------------------------
    def baseband_gains(self) -> np.ndarray:
        """gains * exp(-j 2 pi fc tau), zero on invalid paths.

        :returns: [num_points, num_tx, num_ant, num_paths] complex128
        """
        phase = np.exp(-2j * np.pi * self.carrier_frequency * self.delays)[:, :, None, :]
        return np.where(self.valid[:, :, None, :], self.gains * phase, 0.0)

    def path_power(self) -> np.ndarray:
        """Power of each path averaged over antenna elements (0 where invalid).

        :returns: [num_points, num_tx, num_paths] float64, linear
        """
        return np.where(self.valid, np.mean(np.abs(self.gains) ** 2, axis=2), 0.0)

    def first_path_delay(self) -> np.ndarray:
        """Delay of the earliest valid path (NaN where a link has none).

        :returns: [num_points, num_tx] float64, s
        """
        d = np.where(self.valid, self.delays, np.inf)
        out = d.min(axis=-1)
        return np.where(np.isfinite(out), out, np.nan)

    def max_doppler_hz(self) -> float:
        """The largest |Doppler| of any valid path, Hz (0 without one)."""
        d = np.abs(self.doppler[self.valid])
        return float(d.max()) if d.size else 0.0

    def has_path(self) -> np.ndarray:
        """[num_points, num_tx] bool: the link has at least one valid path."""
        return self.valid.any(axis=-1) & (self.tx_index != NO_TX)

    def geometric_delay(self) -> np.ndarray:
        """Straight-line distance / c between each link's ends.

        :returns: [num_points, num_tx] float64, s
        """
        d = np.linalg.norm(self.tx_pos - self.rx_pos[:, None, :], axis=-1)
        return d / SPEED_OF_LIGHT

    def select(self, points: np.ndarray | slice) -> "CIR":
        """The CIR restricted to some trajectory points (same link slots)."""
        names = ("delays", "gains", "aoa_az", "aoa_zen", "aod_az", "aod_zen", "doppler",
                 "interactions", "valid", "tx_index", "tx_pos", "rx_pos", "los")
        return CIR(**{n: getattr(self, n)[points] for n in names},
                   carrier_frequency=self.carrier_frequency, meta=dict(self.meta))

    def take_slots(self, column: np.ndarray, tx_index: np.ndarray) -> "CIR":
        """The CIR with each point's link slots taken from columns of this one.

        :param column: [num_points, k] int64, the slot of this CIR each new slot comes from
        :param tx_index: [num_points, k] int64, the transmitter id of each new slot
        """
        col = np.asarray(column, dtype=np.int64)
        if col.shape[0] != self.num_points:
            raise ValueError(f"take_slots: {col.shape[0]} rows of columns for "
                             f"{self.num_points} points")

        def take(x: np.ndarray) -> np.ndarray:
            idx = col.reshape(col.shape + (1,) * (x.ndim - 2))
            return np.take_along_axis(x, idx, axis=1)

        names = ("delays", "gains", "aoa_az", "aoa_zen", "aod_az", "aod_zen", "doppler",
                 "interactions", "valid", "tx_pos", "los")
        return CIR(**{n: take(getattr(self, n)) for n in names}, rx_pos=self.rx_pos,
                   tx_index=np.asarray(tx_index, dtype=np.int64),
                   carrier_frequency=self.carrier_frequency, meta=dict(self.meta))

    def to_sionna(self, point: int, num_time_steps: int = 1, sampling_frequency: float = 1.0,
                  normalize_delays: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Point ``point``'s links as Sionna RT's ``Paths.cir(out_type="numpy")`` returns them
        for a synthetic array (Sionna RT 2.x, ``sionna.rt.Paths.cir``): ``(a, tau)`` with

        * ``a``: [num_rx=1, num_rx_ant=num_ant, num_tx, num_tx_ant=1, num_paths,
          num_time_steps] complex, the baseband coefficient
          ``a_i exp(-j 2 pi fc tau_i) exp(j 2 pi f_D,i t)`` at ``t = s / sampling_frequency``,
          s = 0 .. num_time_steps - 1; 0 on an invalid path;
        * ``tau``: [num_rx=1, num_tx, num_paths] float, s; -1 on an invalid path.

        As Sionna does, ``normalize_delays`` subtracts each link's first path delay from its
        paths before the carrier phase is applied (Sionna's default, True). The transmitters
        are this CIR's link slots (``tx_index[point]``), the receive antennas the UE's
        elements; a link slot without a transmitter has only invalid paths.
        """
        if not 0 <= point < self.num_points:
            raise IndexError(f"point {point} of a CIR of {self.num_points} points")
        valid = self.valid[point]                                   # [T, N]
        tau = np.where(valid, self.delays[point], np.inf)
        if normalize_delays:
            first = tau.min(axis=-1, keepdims=True)
            tau = tau - np.where(np.isfinite(first), first, 0.0)
        tau = np.where(valid & np.isfinite(tau), tau, -1.0)
        phase = np.exp(-2j * np.pi * self.carrier_frequency * np.where(tau == -1.0, 0.0, tau))
        a = np.where(valid[:, None, :], self.gains[point] * phase[:, None, :], 0.0)  # [T, A, N]
        t = np.arange(num_time_steps) / float(sampling_frequency)
        doppler = np.exp(2j * np.pi * self.doppler[point][..., None] * t)       # [T, N, S]
        a = a[..., None] * doppler[:, None, :, :]                                # [T, A, N, S]
        a = np.transpose(a, (1, 0, 2, 3))[None, :, :, None, :, :]                # [1, A, T, 1, N, S]
        return a, tau[None]

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Plain arrays (for ``np.savez``)."""
        names = ("delays", "gains", "aoa_az", "aoa_zen", "aod_az", "aod_zen", "doppler",
                 "interactions", "valid", "tx_index", "tx_pos", "rx_pos", "los")
        out = {n: getattr(self, n) for n in names}
        out["carrier_frequency"] = np.float64(self.carrier_frequency)
        return out

    @classmethod
    def from_arrays(cls, arrays: dict, meta: dict | None = None) -> "CIR":
        kw = {k: np.asarray(arrays[k]) for k in arrays if k != "carrier_frequency"}
        return cls(**kw, carrier_frequency=float(arrays["carrier_frequency"]), meta=meta or {})


def ula_element_positions(num_elements: int, spacing_m: float, axis_azimuth: float) -> np.ndarray:
    """Positions of a horizontal ULA's elements relative to its centre.

    :returns: [num_elements, 3] float64, m
    """
    offs = (np.arange(num_elements) - (num_elements - 1) / 2.0) * spacing_m
    axis = np.array([np.cos(axis_azimuth), np.sin(axis_azimuth), 0.0])
    return offs[:, None] * axis[None, :]


def unit_vector(azimuth: np.ndarray, zenith: np.ndarray) -> np.ndarray:
    """Unit vector of a direction (azimuth from +x counter-clockwise, zenith from +z).

    :returns: [..., 3] float64
    """
    s = np.sin(zenith)
    return np.stack([s * np.cos(azimuth), s * np.sin(azimuth), np.cos(zenith)], axis=-1)


def array_response(aoa_az: np.ndarray, aoa_zen: np.ndarray, element_pos: np.ndarray,
                   wavelength: float) -> np.ndarray:
    """Plane-wave phase of each element for arrivals from (aoa_az, aoa_zen).

    A wave arriving from direction u reaches element r earlier by r.u / c, so its phase is
    ``exp(+j 2 pi r.u / lambda)`` (the synthetic-array model Sionna RT uses).

    :param aoa_az, aoa_zen: [...] float64, rad
    :param element_pos: [num_ant, 3] float64, m
    :returns: [..., num_ant, ...] complex128, the antenna axis inserted before the last axis
    """
    u = unit_vector(aoa_az, aoa_zen)                       # [..., n, 3]
    phase = np.einsum("...nc,ac->...an", u, element_pos)  # [..., ant, n]
    return np.exp(2j * np.pi * phase / wavelength)


def doppler_shift(aoa_az, aoa_zen, aod_az, aod_zen, v_rx, v_tx, wavelength: float) -> np.ndarray:
    """Per-path Doppler from the receiver's and transmitter's velocities (static scene).

    f_D = (v_rx . u_arrival + v_tx . u_departure) / lambda, with u the unit vectors pointing
    from each end along the path (moving toward the other end raises the frequency).

    :param v_rx: [num_points, 3] float64, m/s; v_tx: [num_points, num_tx, 3] float64, m/s
    :returns: [num_points, num_tx, num_paths] float64, Hz
    """
    u_r = unit_vector(aoa_az, aoa_zen)
    u_t = unit_vector(aod_az, aod_zen)
    return (np.einsum("ptnc,pc->ptn", u_r, v_rx) + np.einsum("ptnc,ptc->ptn", u_t, v_tx)) / wavelength
