"""Published median path-loss models, to set a traced scene's path loss against.

* free space (Friis; ITU-R P.525-4, basic transmission loss between isotropic antennas,
  L_bf = 20 log(4 pi d / lambda));
* ITU-R P.1411 (the current edition, -13 (09/2025), keeps the section layout of -6 to -12 whose
  text this follows), section 4.2.2.1 "urban area": the over-rooftop, site-specific NLoS1
  model built on Walfisch-Bertoni and Ikegami: L = L_bf + L_rts + L_msd, with the
  roof-to-street term L_rts (street orientation L_ori) and the multiple-screen term L_msd
  blended between its settled-field form L1_msd (l > d_s) and its near-grazing form L2_msd
  (l < d_s) around d_bp;
* COST-231 Walfisch-Ikegami (COST Action 231 final report, "Digital mobile radio towards future
  generation systems", 1999, ch. 4.4), medium-sized city and suburban centres variant
  (``metropolitan=True``: metropolitan centres), NLoS;
* TR 38.901 Table 7.4.1-1 UMi - Street Canyon, with the UMa evaluator shared by
  :func:`~veriloc_rt.propagation.uma_params.uma_pathloss_db`.

Inputs are SI (m, Hz, rad); each formula converts to the units its source writes (MHz, km,
GHz, deg) inside. Every model is evaluated as written outside its stated range (no clipping):
:func:`validity_flags` says where an input lies outside it, so a report can show it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from ..constants import SPEED_OF_LIGHT

__all__ = ["RooftopGeometry", "free_space_pathloss_db", "street_orientation_loss_db",
           "cost231_wi_terms", "cost231_wi_nlos_db", "p1411_terms", "p1411_nlos_db",
           "breakpoint_distance", "tr38901_pathloss_db", "umi_pathloss_db", "umi_table",
           "VALIDITY", "validity_flags", "P1411_EDITION"]

#: The P.1411 edition found (its table of contents) and the text the formulas follow
P1411_EDITION = ("ITU-R P.1411-13 (09/2025), section 4.2.2.1; formula text as in P.1411-6 to -12 "
                 "(same section structure)")
#: P.1411 4.2.2.1 upsilon and chi: the widths of the tanh transition of L_msd around d_bp
P1411_UPSILON = 0.0417
P1411_CHI = 0.1


def _positive(name: str, value) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"Argument `{name}` must be finite and > 0, not {value!r}")
    return arr


def _out(x: np.ndarray):
    return float(x) if np.ndim(x) == 0 else x


@dataclass(frozen=True)
class RooftopGeometry:
    """What the over-rooftop models know of a scene (all m).

    :param h_bs_m: BS antenna height; :param h_ue_m: mobile antenna height (< h_roof_m)
    :param h_roof_m: (mean) roof height; :param street_width_m: width w of the mobile's street
    :param building_separation_m: b, centre-to-centre distance of the building rows
    """

    h_bs_m: float
    h_ue_m: float
    h_roof_m: float
    street_width_m: float
    building_separation_m: float

    def __post_init__(self) -> None:
        for name in ("h_bs_m", "h_ue_m", "h_roof_m", "street_width_m", "building_separation_m"):
            _positive(name, getattr(self, name))
        if self.h_ue_m >= self.h_roof_m:
            raise ValueError(f"Argument `h_ue_m` must be below the roofs (h_roof_m = "
                             f"{self.h_roof_m}), not {self.h_ue_m!r}")

    @property
    def dh_bs(self) -> float:
        """Delta h_b = h_b - h_r (P.1411 4.2.2.1), m."""
        return self.h_bs_m - self.h_roof_m

    @property
    def dh_ue(self) -> float:
        """Delta h_m = h_r - h_m (P.1411 4.2.2.1), m."""
        return self.h_roof_m - self.h_ue_m


def free_space_pathloss_db(d_m, fc_hz):
    """Free-space basic transmission loss, ITU-R P.525-4: 20 log10(4 pi d / lambda).

    (P.525 writes it 32.4 + 20 log f_MHz + 20 log d_km; the exact constant is 32.448.)

    :param d_m: [...] float64, m, distance between isotropic antennas (> 0)
    :returns: float or [...] float64, dB
    """
    d = _positive("d_m", d_m)
    fc = float(_positive("fc_hz", fc_hz))
    return _out(20.0 * np.log10(4.0 * np.pi * d * fc / SPEED_OF_LIGHT))


def street_orientation_loss_db(phi_rad):
    """L_ori, the street-orientation term of the roof-to-street loss.

    P.1411 4.2.2.1 and COST 231 ch. 4.4 (identical): with phi in degrees,
    -10 + 0.354 phi (0 <= phi < 35), 2.5 + 0.075 (phi - 35) (35 <= phi < 55),
    4.0 - 0.114 (phi - 55) (55 <= phi <= 90).

    :param phi_rad: [...] float64, rad, angle between the mobile's street and the horizontal
        direct path, in [0, pi/2]
    :returns: float or [...] float64, dB
    """
    phi = np.degrees(np.asarray(phi_rad, dtype=float))
    if not np.all(np.isfinite(phi)) or np.any(phi < -1e-9) or np.any(phi > 90.0 + 1e-9):
        raise ValueError(f"Argument `phi_rad` must lie in [0, pi/2], not {phi_rad!r}")
    out = np.where(phi < 35.0, -10.0 + 0.354 * phi,
                   np.where(phi < 55.0, 2.5 + 0.075 * (phi - 35.0), 4.0 - 0.114 * (phi - 55.0)))
    return _out(out)


def _rooftop_common(d_m, fc_hz, geo: RooftopGeometry, phi_rad, rts_const_db: float) -> dict:
    """L_bf (= COST's L_0), L_ori and L_rts, shared by both Walfisch-Ikegami forms."""
    d = _positive("d_m", d_m)
    fc = float(_positive("fc_hz", fc_hz))
    f_mhz = fc / 1e6
    l_ori = np.asarray(street_orientation_loss_db(phi_rad))
    l_bf = 32.4 + 20.0 * np.log10(d / 1000.0) + 20.0 * np.log10(f_mhz)
    l_rts = (rts_const_db - 10.0 * np.log10(geo.street_width_m) + 10.0 * np.log10(f_mhz)
             + 20.0 * np.log10(geo.dh_ue) + l_ori)
    return {"d": d, "f_mhz": f_mhz, "L_bf": l_bf, "L_ori": l_ori, "L_rts": l_rts}


def _settled_field_msd(x, f_mhz: float, geo: RooftopGeometry, high_f_coeffs: bool,
                       metropolitan: bool) -> dict:
    """L_bsh + k_a + k_d log(x/1000) + k_f log f - 9 log b (P.1411 L1_msd; COST 231).

    ``high_f_coeffs``: P.1411's f > 2000 MHz branches (k_a 71.4 / 73, k_f = -8); COST 231 has
    none and extrapolates its f <= 2000 MHz forms.
    """
    dhb, above = geo.dh_bs, geo.h_bs_m > geo.h_roof_m
    hi = high_f_coeffs and f_mhz > 2000.0
    base = 71.4 if hi else 54.0
    below_base = 73.0 if hi else 54.0
    if above:
        l_bsh, k_a = -18.0 * np.log10(1.0 + dhb), np.full_like(x, base)
        k_d = 18.0
    else:
        l_bsh = 0.0
        k_a = np.where(x >= 500.0, below_base - 0.8 * dhb, below_base - 1.6 * dhb * x / 1000.0)
        k_d = 18.0 - 15.0 * dhb / geo.h_roof_m
    if hi:
        k_f = -8.0
    else:
        k_f = -4.0 + (1.5 if metropolitan else 0.7) * (f_mhz / 925.0 - 1.0)
    l_msd = (l_bsh + k_a + k_d * np.log10(x / 1000.0) + k_f * np.log10(f_mhz)
             - 9.0 * np.log10(geo.building_separation_m))
    return {"L_bsh": l_bsh, "k_a": k_a, "k_d": k_d, "k_f": k_f, "L_msd": l_msd}


def cost231_wi_terms(d_m, fc_hz, geo: RooftopGeometry, phi_rad, *,
                     metropolitan: bool = False) -> dict:
    """COST-231 Walfisch-Ikegami NLoS, term by term (COST 231 final report, ch. 4.4).

    L_0 = 32.4 + 20 log d_km + 20 log f_MHz;
    L_rts = -16.9 - 10 log w + 10 log f_MHz + 20 log(h_Roof - h_Mobile) + L_ori;
    L_msd = L_bsh + k_a + k_d log d_km + k_f log f_MHz - 9 log b, with
    L_bsh = -18 log(1 + dh_Base) and k_a = 54, k_d = 18 for h_Base > h_Roof (else 0,
    54 - 0.8 dh_Base [x d_km / 0.5 below 500 m], 18 - 15 dh_Base / h_Roof),
    k_f = -4 + 0.7 (f_MHz / 925 - 1) (medium-sized city, suburban centres) or 1.5 (metropolitan);
    L_b = L_0 + L_rts + L_msd if L_rts + L_msd > 0, else L_0.

    :param d_m: [...] float64, m, horizontal BS-mobile distance
    :param phi_rad: [...] float64, rad, street orientation to the direct path (see
        :func:`street_orientation_loss_db`)
    :returns: {"L_bf" (L_0), "L_ori", "L_rts", "L_bsh", "k_a", "k_d", "k_f", "L_msd", "total"},
        dB except the k's
    """
    t = _rooftop_common(d_m, fc_hz, geo, phi_rad, -16.9)
    t.update(_settled_field_msd(t["d"], t["f_mhz"], geo, False, metropolitan))
    extra = t["L_rts"] + t["L_msd"]
    t["total"] = t["L_bf"] + np.where(extra > 0, extra, 0.0)
    del t["d"], t["f_mhz"]
    return t


def cost231_wi_nlos_db(d_m, fc_hz, geo: RooftopGeometry, phi_rad, *, metropolitan: bool = False):
    """COST-231 Walfisch-Ikegami NLoS path loss, dB (see :func:`cost231_wi_terms`)."""
    return _out(cost231_wi_terms(d_m, fc_hz, geo, phi_rad, metropolitan=metropolitan)["total"])


def _p1411_l2_msd(x, lam: float, f_mhz: float, geo: RooftopGeometry) -> np.ndarray:
    """L2_msd = -10 log Q_M^2 (P.1411 4.2.2.1), the three cases of h_b against h_r.

    The band h_r + dh_l <= h_b <= h_r + dh_u is "h_b about h_r". dh_u is where the first
    two Q_M forms meet (2.35 (dh_u/d sqrt(b/lambda))^0.9 = b/d). dh_l is an empirical fit
    in log f, read here with f in MHz, the unit of the rest of the section (in GHz its
    denominator would vanish at 1 GHz, inside the model's range, and the band would reach
    ~90 m below the roofs at 3.5 GHz; in MHz it is -0.28 m for b = 35 m).
    """
    dhb, b, h_b, h_r = geo.dh_bs, geo.building_separation_m, geo.h_bs_m, geo.h_roof_m
    dh_u = 10.0 ** (-np.log10(np.sqrt(b / lam)) - np.log10(x) / 9.0
                    + 10.0 / 9.0 * np.log10(b / 2.35))
    dh_l = ((0.00023 * b**2 - 0.1827 * b - 9.4978) / np.log10(f_mhz) ** 2.938
            + 0.000781 * b + 0.06923)
    theta = np.arctan(dhb / b)
    rho = np.hypot(dhb, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        q_high = 2.35 * (np.abs(dhb) / x * np.sqrt(b / lam)) ** 0.9
        q_low = b / (2 * np.pi * x) * np.sqrt(lam / rho) * (1.0 / theta - 1.0 / (2 * np.pi + theta))
    q = np.where(h_b > h_r + dh_u, q_high, np.where(h_b >= h_r + dh_l, b / x, q_low))
    return -10.0 * np.log10(q**2)


def p1411_terms(d_m, fc_hz, geo: RooftopGeometry, phi_rad, covered_m=None, *,
                metropolitan: bool = False) -> dict:
    """ITU-R P.1411 section 4.2.2.1 over-rooftop NLoS1 loss, term by term.

    L_NLoS1 = L_bf + L_rts + L_msd if L_rts + L_msd > 0, else L_bf, with
    L_bf = 32.4 + 20 log(d/1000) + 20 log f_MHz,
    L_rts = -8.2 - 10 log w + 10 log f_MHz + 20 log dh_m + L_ori, and L_msd:
    the settled-field distance d_s = lambda d^2 / dh_b^2 against the length l of the path
    covered by buildings picks L1_msd (l > d_s, the settled field) or L2_msd (l < d_s, Q_M),
    blended through tanh((log d - log d_bp) / chi) around d_bp = |dh_b| sqrt(l / lambda)
    between L_upp = L1_msd(d_bp) and L_low = L2_msd(d_bp); with dh_bp = L_upp - L_low < 0 the
    width is zeta = dh_bp upsilon (the "upper" and "lower" cases). l > d_s is the same as
    d < d_bp.

    :param d_m: [...] float64, m, horizontal BS-mobile distance
    :param phi_rad: [...] float64, rad, street orientation to the direct path
    :param covered_m: [...] float64, m, length l of the path over buildings (default: d)
    :param metropolitan: k_f of metropolitan centres (only used at f <= 2 GHz)
    :returns: {"L_bf", "L_ori", "L_rts", "d_s", "d_bp" (m), "L1_msd", "L2_msd", "L_upp", "L_low",
        "L_msd", "total"}, dB except the distances
    """
    t = _rooftop_common(d_m, fc_hz, geo, phi_rad, -8.2)
    d, f_mhz = t.pop("d"), t.pop("f_mhz")
    fc = f_mhz * 1e6
    lam = SPEED_OF_LIGHT / fc
    ell = d if covered_m is None else _positive("covered_m", covered_m)
    d, ell = np.broadcast_arrays(d, ell)
    dhb = geo.dh_bs

    def l1(x):
        return _settled_field_msd(x, f_mhz, geo, True, metropolitan)["L_msd"]

    def l2(x):
        return _p1411_l2_msd(x, lam, f_mhz, geo)

    l1_d, l2_d = l1(d), l2(d)
    if dhb == 0.0:   # d_s infinite, d_bp = 0: the dh_bp = 0 line of L_msd
        d_s = np.full_like(d, np.inf)
        d_bp = np.zeros_like(d)
        l_upp = l_low = np.full_like(d, np.nan)
        l_msd = l2_d
    else:
        d_s = lam * d**2 / dhb**2
        d_bp = abs(dhb) * np.sqrt(ell / lam)
        l_upp, l_low = l1(d_bp), l2(d_bp)
        dh_bp = l_upp - l_low
        l_mid = 0.5 * (l_upp + l_low)
        u = np.log10(d) - np.log10(d_bp)
        settled = ell > d_s
        with np.errstate(divide="ignore", invalid="ignore"):
            zeta = dh_bp * P1411_UPSILON
            pos = np.where(settled, -np.tanh(u / P1411_CHI) * (l1_d - l_mid) + l_mid,
                           np.tanh(u / P1411_CHI) * (l2_d - l_mid) + l_mid)
            neg = np.where(settled, l1_d - np.tanh(u / zeta) * (l_upp - l_mid) - l_upp + l_mid,
                           l2_d + np.tanh(u / zeta) * (l_mid - l_low) + l_mid - l_low)
        l_msd = np.where(dh_bp > 0, pos, np.where(dh_bp < 0, neg, l2_d))
    extra = t["L_rts"] + l_msd
    t.update({"d_s": d_s, "d_bp": d_bp, "L1_msd": l1_d, "L2_msd": l2_d, "L_upp": l_upp,
              "L_low": l_low, "L_msd": l_msd, "total": t["L_bf"] + np.where(extra > 0, extra, 0.0)})
    return t


def p1411_nlos_db(d_m, fc_hz, geo: RooftopGeometry, phi_rad, covered_m=None, *,
                  metropolitan: bool = False):
    """ITU-R P.1411 section 4.2.2.1 over-rooftop NLoS1 path loss, dB (see :func:`p1411_terms`)."""
    t = p1411_terms(d_m, fc_hz, geo, phi_rad, covered_m, metropolitan=metropolitan)
    return _out(t["total"])


# -- TR 38.901 Table 7.4.1-1 ------------------------------------------------------------------
def breakpoint_distance(h_bs_m, h_ut_m, fc_hz, h_e_m: float = 1.0) -> np.ndarray:
    """d'_BP = 4 h'_BS h'_UT fc / c (TR 38.901 Table 7.4.1-1 note 1), h' = h - h_E.

    c is :data:`SPEED_OF_LIGHT` (299 792 458 m/s, as Sionna); the spec text uses 3e8, which
    moves d'_BP by 0.07 % and the path loss by < 0.01 dB.

    :returns: [...] float64, m
    """
    h_bs, h_ut = np.asarray(h_bs_m) - h_e_m, np.asarray(h_ut_m) - h_e_m
    return 4.0 * h_bs * h_ut * fc_hz / SPEED_OF_LIGHT


def tr38901_pathloss_db(tab: dict, d_2d_m, h_bs_m, h_ut_m, fc_hz, los):
    """A TR 38.901 Table 7.4.1-1 row (UMa or UMi - Street Canyon), deterministic form.

    LOS: PL1 = a1 + b1 lg d3D + c1 lg fc for d2D <= d'BP, else
    PL2 = a2 + b2 lg d3D + c2 lg fc + e2 lg(d'BP^2 + (h_BS - h_UT)^2);
    NLOS: max(PL_LOS, a + b lg d3D + c lg fc + s (h_UT - 1.5)); fc in GHz, h_E fixed.

    :param tab: the row's coefficients (``"pathloss"`` of a shipped table: ``h_e_m``,
        ``los_pl1``, ``los_pl2``, ``nlos``)
    :param d_2d_m: [...] float64, m (>= 0); h_bs_m, h_ut_m: [...] float64, m (> h_E)
    :param los: bool (or [...] bool)
    :returns: float or [...] float64, dB
    """
    h_e = tab["h_e_m"]
    d2 = np.asarray(d_2d_m, dtype=float)
    if not np.all(np.isfinite(d2)) or np.any(d2 < 0):
        raise ValueError(f"Argument `d_2d_m` must be finite and >= 0, not {d_2d_m!r}")
    fc = float(_positive("fc_hz", fc_hz))
    hb = np.asarray(h_bs_m, dtype=float)
    hu = np.asarray(h_ut_m, dtype=float)
    for name, h in (("h_bs_m", hb), ("h_ut_m", hu)):
        if not np.all(np.isfinite(h)) or np.any(h <= h_e):
            raise ValueError(f"Argument `{name}` must be > h_E = {h_e} m, not {h!r}")
    los_arr = np.asarray(los)
    if los_arr.dtype != bool:
        raise TypeError(f"Argument `los` must be bool, not {type(los).__name__}")
    lf = np.log10(fc / 1e9)
    d3 = np.sqrt(d2**2 + (hb - hu) ** 2)
    d_bp = breakpoint_distance(hb, hu, fc, h_e)
    p1, p2, pn = tab["los_pl1"], tab["los_pl2"], tab["nlos"]
    pl1 = p1["const"] + p1["log_d3d"] * np.log10(d3) + p1["log_fc"] * lf
    pl2 = (p2["const"] + p2["log_d3d"] * np.log10(d3) + p2["log_fc"] * lf
           + p2["log_bp"] * np.log10(d_bp**2 + (hb - hu) ** 2))
    pl_los = np.where(d2 <= d_bp, pl1, pl2)
    pl_nlos = (pn["const"] + pn["log_d3d"] * np.log10(d3) + pn["log_fc"] * lf
               + pn["h_ut_slope"] * (hu - pn["h_ut_ref_m"]))
    return _out(np.where(los_arr, pl_los, np.maximum(pl_los, pl_nlos)))


@lru_cache(maxsize=1)
def umi_table() -> dict:
    """The shipped UMi - Street Canyon path-loss table (parsed JSON, cached; read-only)."""
    path = resources.files("veriloc_rt").joinpath("data", "umi_tr38901_v18.json")
    return json.loads(path.read_text())


def umi_pathloss_db(d_2d_m, h_bs_m, h_ut_m, fc_hz, los):
    """TR 38.901 V18.0.0 Table 7.4.1-1 UMi - Street Canyon (no shadowing), h_E = 1 m.

    LOS: 32.4 + 21 lg d3D + 20 lg fc up to d'BP, then 32.4 + 40 lg d3D + 20 lg fc
    - 9.5 lg(d'BP^2 + (h_BS - h_UT)^2); NLOS: max(PL_LOS, 22.4 + 35.3 lg d3D + 21.3 lg fc
    - 0.3 (h_UT - 1.5)); fc in GHz. Stated for 10 m <= d2D <= 5 km, h_BS = 10 m,
    1.5 <= h_UT <= 22.5 m; evaluated as is outside. Arguments as :func:`tr38901_pathloss_db`.
    """
    return tr38901_pathloss_db(umi_table()["pathloss"], d_2d_m, h_bs_m, h_ut_m, fc_hz, los)


# -- validity ---------------------------------------------------------------------------------
#: Stated ranges: (lo, hi) per input, lo == hi for a single default value. Frequencies in Hz,
#: distances and heights in m. TR 38.901: clause 7.4.1 (0.5-100 GHz) and Table 7.4.1-1 note;
#: COST 231 ch. 4.4 ("restrictions"); P.1411 section 4.2.2.1.
VALIDITY = {
    "free_space": {},
    "p1411": {"fc_hz": (0.8e9, 38e9), "d_m": (20.0, 5000.0), "h_bs_m": (4.0, 50.0),
              "h_ue_m": (1.0, 3.0)},
    "cost231_wi": {"fc_hz": (0.8e9, 2e9), "d_m": (20.0, 5000.0), "h_bs_m": (4.0, 50.0),
                   "h_ue_m": (1.0, 3.0)},
    "uma_nlos": {"fc_hz": (0.5e9, 100e9), "d_m": (10.0, 5000.0), "h_bs_m": (25.0, 25.0),
                 "h_ue_m": (1.5, 22.5)},
    "umi_nlos": {"fc_hz": (0.5e9, 100e9), "d_m": (10.0, 5000.0), "h_bs_m": (10.0, 10.0),
                 "h_ue_m": (1.5, 22.5)},
}


def _fmt(name: str, v: float) -> str:
    return f"{v / 1e9:g} GHz" if name == "fc_hz" else f"{v:g} m"


def validity_flags(model: str, fc_hz: float, h_bs_m: float, h_ue_m: float, d_m=None) -> list[str]:
    """Where the inputs lie outside ``model``'s stated range, as short sentences.

    e.g. ``"f = 3.5 GHz > 2 GHz"``, ``"h_BS = 25 m, the model's is 10 m"``,
    ``"12 of 360 links at d < 20 m"``. Empty when everything is inside.

    :param model: a key of :data:`VALIDITY`
    :param d_m: [...] float64, m, the distances evaluated (optional)
    """
    if model not in VALIDITY:
        raise ValueError(f"Argument `model` must be one of {', '.join(VALIDITY)}, not {model!r}")
    rng = VALIDITY[model]
    label = {"fc_hz": "f", "h_bs_m": "h_BS", "h_ue_m": "h_UE"}
    out = []
    for key, value in (("fc_hz", fc_hz), ("h_bs_m", h_bs_m), ("h_ue_m", h_ue_m)):
        if key not in rng:
            continue
        lo, hi = rng[key]
        if lo == hi and value != lo:
            out.append(f"{label[key]} = {_fmt(key, value)}, the model's is {_fmt(key, lo)}")
        elif value < lo:
            out.append(f"{label[key]} = {_fmt(key, value)} < {_fmt(key, lo)}")
        elif value > hi:
            out.append(f"{label[key]} = {_fmt(key, value)} > {_fmt(key, hi)}")
    if d_m is not None and "d_m" in rng:
        d = np.asarray(d_m, dtype=float).ravel()
        lo, hi = rng["d_m"]
        for n, rel, lim in ((int(np.sum(d < lo)), "<", lo), (int(np.sum(d > hi)), ">", hi)):
            if n:
                out.append(f"{n} of {d.size} links at d {rel} {lim:g} m")
    return out
