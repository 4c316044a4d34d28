"""BS antenna patterns, sectors and electrical downtilt, applied to CIRs after propagation.

Every propagation model (ray tracing and the stochastic TR 38.901 arms) produces the links of
isotropic BS antennas, with each path's departure direction (``CIR.aod_az`` / ``aod_zen``). This
module multiplies each path's gain by the field pattern of a sector panel in the direction the
path leaves the site, so both arms get the same antenna by the same transform and the trace
cache keeps isotropic paths (a sector is never re-traced).

The panel (``topology.bs_antenna`` "tr38901"):

* element: TR 38.901 clause 7.3, Table 7.3-1, power pattern in dB in the element's local
  frame (zenith theta' and azimuth phi', degrees)::

      A_V(theta') = -min(12 ((theta' - 90) / theta_3dB)^2, SLA_V)
      A_H(phi')   = -min(12 (phi' / phi_3dB)^2, A_max)
      A(theta', phi') = G_E,max - min(-(A_V + A_H), A_max)

  with theta_3dB = phi_3dB = 65 deg, SLA_V = A_max = 30 dB, G_E,max = 8 dBi; the field of the
  element's polarisation is sqrt(A) (eq. 7.3-4 with polarisation slant 0: theta-hat);
* column: M elements stacked vertically at d_V wavelengths, fed with the electrical-tilt
  weights of TR 36.873 clause 7.1.1 as recalled (not checked against the text; TR 38.901
  Table 7.8-1's calibration panel is "10 coupled elements in elevation" on one port, as
  QuaDRiGa's calibration scripts transcribe it), ``w_m = exp(-j 2 pi m d_V cos(theta_etilt))
  / sqrt(M)``; an element at height ``m d_V lambda`` above the column's centre radiates towards
  zenith theta with the phase ``exp(+j 2 pi m d_V cos theta)``, so the column's array factor is

      AF(theta) = (1 / sqrt(M)) sum_m exp(j 2 pi m d_V (cos theta - cos theta_etilt))

  (m = -(M-1)/2 .. (M-1)/2: the column's centre is the site position the links were computed
  from, so AF is real), peak sqrt(M) (10 log10 M dB) at theta = theta_etilt. The panel's field
  is ``sqrt(A(theta', phi')) AF(theta')``; on boresight along the tilt its gain is
  G_E,max - 12 ((theta_etilt - 90) / 65)^2 + 10 log10 M (17.6 dBi for M = 10 at 102 deg). The
  power-normalised weights conserve the radiated power exactly only for isotropic elements half
  a wavelength apart; as in the standard's model, the product is not renormalised;
* sectors: ``topology.sectors`` panels per site, boresights 360 / sectors deg apart, no
  mechanical tilt (the local frame is the global one turned by the boresight azimuth,
  TR 38.901 clause 7.1.3 with bearing alpha = boresight, downtilt beta = 0, slant gamma = 0).

The three sectors of a site share its position, so a UE gains no geometry from hearing more
than one: each link (point, site) is given the sector whose pattern delivers the most received
power over the link's paths (the UE measures the site's strongest sector), and only its pattern
is applied (:func:`apply_sectors`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .cir import CIR

__all__ = ["ElementPattern", "SectorPanel", "element_pattern_db", "column_array_factor",
           "apply_sectors", "sector_boresights", "site_first_boresight", "panel_of",
           "apply_bs_antenna", "bs_antenna_links", "sector_setup", "describe_bs_antenna", "TR38901_ELEMENT",
           "TABLE_7_8_1_FIRST_BORESIGHT_DEG", "HEX_CELL_DIRECTION_DEG"]

#: TR 38.901 Table 7.8-1 sector boresights 30, 150, 270 deg: the first (a sites CSV without
#: azimuths)
TABLE_7_8_1_FIRST_BORESIGHT_DEG = 30.0
#: the hexagonal layout (veriloc_rt.world.topology) puts each site at a hexagon vertex at polar
#: angle 30, 150 or 270 deg from its cell's centre; the three cells around the vertex lie at 90,
#: 210 and 330 deg from it (before the layout's rotation): the first sector points at 90 deg
HEX_CELL_DIRECTION_DEG = 90.0


@dataclass(frozen=True)
class ElementPattern:
    """TR 38.901 Table 7.3-1 element parameters (degrees, dB, dBi)."""

    theta_3db_deg: float = 65.0
    phi_3db_deg: float = 65.0
    sla_v_db: float = 30.0
    a_max_db: float = 30.0
    g_max_dbi: float = 8.0


#: the Table 7.3-1 element
TR38901_ELEMENT = ElementPattern()


def element_pattern_db(theta_deg, phi_deg, element: ElementPattern = TR38901_ELEMENT):
    """The element's power pattern A(theta', phi'), dBi (module docstring).

    :param theta_deg: zenith angle in the element's frame, degrees in [0, 180]
    :param phi_deg: azimuth from boresight, degrees (any value; wrapped to [-180, 180))
    """
    theta = np.asarray(theta_deg, dtype=float)
    phi = (np.asarray(phi_deg, dtype=float) + 180.0) % 360.0 - 180.0
    a_v = -np.minimum(12.0 * ((theta - 90.0) / element.theta_3db_deg) ** 2, element.sla_v_db)
    a_h = -np.minimum(12.0 * (phi / element.phi_3db_deg) ** 2, element.a_max_db)
    return element.g_max_dbi - np.minimum(-(a_v + a_h), element.a_max_db)


def column_array_factor(theta_rad, num_elements: int, spacing_wavelengths: float,
                        tilt_rad: float) -> np.ndarray:
    """AF(theta) of the tilted vertical column (module docstring), complex (real up to
    rounding: the phase reference is the column's centre).

    :param theta_rad: zenith angle of the departure, rad
    """
    theta = np.asarray(theta_rad, dtype=float)
    m = np.arange(num_elements) - (num_elements - 1) / 2.0
    psi = 2.0 * np.pi * spacing_wavelengths * (np.cos(theta) - math.cos(tilt_rad))
    return np.exp(1j * psi[..., None] * m).sum(axis=-1) / math.sqrt(num_elements)


@dataclass(frozen=True)
class SectorPanel:
    """One sector's panel: a column of TR 38.901 elements with electrical downtilt."""

    num_elements: int = 10
    spacing_wavelengths: float = 0.5
    tilt_deg: float = 102.0
    element: ElementPattern = TR38901_ELEMENT

    def field(self, zenith_rad, azimuth_rad) -> np.ndarray:
        """Field amplitude (complex) towards (zenith, azimuth), the azimuth measured from the
        sector's boresight, rad; |field|^2 is the panel's power gain (linear)."""
        a_db = element_pattern_db(np.rad2deg(zenith_rad), np.rad2deg(azimuth_rad), self.element)
        af = column_array_factor(zenith_rad, self.num_elements, self.spacing_wavelengths,
                                 math.radians(self.tilt_deg))
        return np.sqrt(10.0 ** (a_db / 10.0)) * af

    def peak_gain_dbi(self) -> float:
        """Gain at boresight and the tilt direction, dBi."""
        g = np.abs(self.field(np.array(math.radians(self.tilt_deg)), np.array(0.0))) ** 2
        return float(10.0 * np.log10(g))


def sector_boresights(first_rad: np.ndarray, num_sectors: int) -> np.ndarray:
    """Boresight azimuths of each site's sectors: ``first + k 2 pi / num_sectors``.

    :param first_rad: [num_bs] float64, the first sector's boresight per site, rad
    :returns: [num_bs, num_sectors] float64, rad
    """
    k = np.arange(num_sectors) * (2.0 * np.pi / num_sectors)
    return np.asarray(first_rad, dtype=float)[:, None] + k[None, :]


def apply_sectors(cir: CIR, panel: SectorPanel, boresights: np.ndarray) -> tuple[CIR, np.ndarray]:
    """``cir`` with each link's gains multiplied by the field of its site's strongest sector.

    For link slot (point k, slot j) from site ``b = cir.tx_index[k, j]`` and each of its
    sectors s (boresight ``boresights[b, s]``), the received power through the sector is
    ``sum over valid paths of mean_ant |g|^2 |F_s(aod_zen, aod_az - boresight)|^2``; the sector
    with the largest is chosen (ties: the first) and every path's gain (valid or not) is
    multiplied by its field. Empty slots (``tx_index`` < 0) are left unchanged.

    :param boresights: [num_bs, num_sectors] float64, rad (:func:`sector_boresights`)
    :returns: the new CIR, and [num_points, num_tx] int64 the chosen sector (-1: empty slot)
    """
    tx = cir.tx_index
    site = np.where(tx >= 0, tx, 0)
    bore = np.asarray(boresights, dtype=float)[site]                     # [P, T, S]
    rel_az = cir.aod_az[:, :, None, :] - bore[..., None]                  # [P, T, S, N]
    zen = np.broadcast_to(cir.aod_zen[:, :, None, :], rel_az.shape)
    field = panel.field(zen, rel_az)                                      # [P, T, S, N]
    power = (np.abs(field) ** 2 * cir.path_power()[:, :, None, :]).sum(axis=-1)  # [P, T, S]
    best = np.argmax(power, axis=-1)                                      # [P, T]
    chosen = np.take_along_axis(field, best[:, :, None, None], axis=2)[:, :, 0, :]  # [P, T, N]
    chosen = np.where((tx >= 0)[..., None], chosen, 1.0)
    gains = cir.gains * chosen[:, :, None, :]
    out = dataclasses.replace(cir, gains=gains, meta={**cir.meta, "bs_antenna": "tr38901"})
    return out, np.where(tx >= 0, best, -1).astype(np.int64)


def site_first_boresight(geometry) -> np.ndarray:
    """The first sector's boresight per site, rad: towards a cell the site serves on the
    hexagonal layout (:data:`HEX_CELL_DIRECTION_DEG` + the layout's rotation), else the sites
    CSV's azimuth, else :data:`TABLE_7_8_1_FIRST_BORESIGHT_DEG`.

    :returns: [num_bs] float64, rad
    """
    n = len(geometry.bs_pos)
    az = getattr(geometry, "bs_azimuth", None)
    layout = getattr(geometry, "layout", None)
    if az is not None:
        az = np.asarray(az, dtype=float)
        return np.where(np.isfinite(az), az, math.radians(TABLE_7_8_1_FIRST_BORESIGHT_DEG))
    if layout is not None:
        return np.full(n, math.radians(HEX_CELL_DIRECTION_DEG) + layout.rotation)
    return np.full(n, math.radians(TABLE_7_8_1_FIRST_BORESIGHT_DEG))


def panel_of(topology) -> SectorPanel | None:
    """The sector panel ``topology`` (a :class:`~veriloc_rt.config.TopologyConfig`) asks for;
    None for isotropic BS antennas."""
    if topology.bs_antenna == "isotropic":
        return None
    return SectorPanel(num_elements=topology.bs_antenna_elements,
                       spacing_wavelengths=topology.bs_antenna_spacing_wavelengths,
                       tilt_deg=topology.bs_antenna_tilt_deg)


def sector_setup(geometry, topology) -> tuple[SectorPanel, np.ndarray] | None:
    """The panel of ``topology`` and its sectors' boresights at ``geometry``'s sites
    (:func:`sector_boresights`), None for isotropic BS antennas."""
    panel = panel_of(topology)
    if panel is None:
        return None
    return panel, sector_boresights(site_first_boresight(geometry), topology.sectors)


def bs_antenna_links(bs_ue: CIR, geometry, topology) -> CIR:
    """The BS -> UE CIRs ``bs_ue`` through ``topology``'s BS antennas, each link its site's
    strongest sector, as :func:`apply_bs_antenna` applies them; isotropic: ``bs_ue`` itself."""
    setup = sector_setup(geometry, topology)
    return bs_ue if setup is None else apply_sectors(bs_ue, *setup)[0]


def apply_bs_antenna(prop, geometry, topology):
    """``prop`` (a :class:`~veriloc_rt.propagation.raytrace.Propagation`) with the BS antennas
    of ``topology`` applied to the links that leave a BS (BS -> UE, BS -> adversary:
    :func:`apply_sectors`, each link its site's strongest sector at that receiver); the
    adversary's own links (adversary -> UE) keep its antenna. Isotropic BS antennas return
    ``prop`` itself (bit for bit).
    """
    setup = sector_setup(geometry, topology)
    if setup is None:
        return prop
    panel, bore = setup
    bs_ue, sec_ue = apply_sectors(prop.bs_ue, panel, bore)
    bs_adv, _ = apply_sectors(prop.bs_adv, panel, bore)
    used = sec_ue[sec_ue >= 0]
    stats = {**prop.stats, "bs_antenna": {
        "link_gain_db": _link_gain_percentiles(prop.bs_ue, bs_ue),
        "model": "tr38901", "sectors": int(topology.sectors),
        "elements": int(panel.num_elements),
        "spacing_wavelengths": float(panel.spacing_wavelengths),
        "tilt_deg": float(panel.tilt_deg), "peak_gain_dbi": round(panel.peak_gain_dbi(), 3),
        "bs_ue_links_per_sector": [int(np.sum(used == s)) for s in range(topology.sectors)]}}
    return dataclasses.replace(prop, bs_ue=bs_ue, bs_adv=bs_adv, stats=stats)


def _link_gain_percentiles(before: CIR, after: CIR) -> dict:
    """p5 / p50 / p95 over the links with a path of the antenna's power gain on the link,
    10 lg(sum of path powers after / before), dB (None without such a link)."""
    p0, p1 = before.path_power().sum(-1), after.path_power().sum(-1)
    ok = before.has_path() & (p0 > 0)
    g = 10.0 * np.log10(p1[ok] / p0[ok]) if ok.any() else np.zeros(0)
    return {f"p{q}": (round(float(np.percentile(g, q)), 3) if g.size else None)
            for q in (5, 50, 95)}


def describe_bs_antenna(topology) -> str:
    """The BS antennas of ``topology`` in a few words, with the panel's peak gain."""
    panel = panel_of(topology)
    if panel is None:
        return "isotropic 0 dBi"
    return (f"TR 38.901 {topology.sectors}-sector panels ({panel.num_elements} x "
            f"{panel.spacing_wavelengths:g} wavelengths, tilt {panel.tilt_deg:g} deg), peak "
            f"{panel.peak_gain_dbi():.1f} dBi")
