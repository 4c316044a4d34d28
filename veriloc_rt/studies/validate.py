"""Propagation validation (``veriloc-rt validate``): traced path loss beside published models.

:func:`run_validate` ray-traces the serving BS -> UE links of the config's trajectory (the
machinery and cache of ``veriloc-rt run``, its traced-power choice of the TRPs with
``topology.selection`` 'traced_power'; the adversary's links are not traced) and takes each
link's path loss as ``-10 lg sum |a|^2`` over its valid paths: the local-mean (incoherent) loss
between isotropic antennas. The UE's ULA elements see each path with a unit-modulus phase only,
so the sum is the same on every element (:meth:`~veriloc_rt.propagation.cir.CIR.path_power`
averages them). Links without a path are counted, not given an infinite loss.

Beside it, per link and per 2-D distance bin, the models of
:mod:`~veriloc_rt.propagation.pathloss_models` for the scene's own geometry: free space (at the
3-D distance), ITU-R P.1411 and COST-231 Walfisch-Ikegami over-rooftop NLoS (roof height =
building height, w = street width, b = block + street, phi per link from the UE's street and
the direct path, l = the part of the path over the street grid), TR 38.901 UMa and UMi - Street
Canyon NLOS. Offsets are traced - model per link (its own distance and phi), their median per
bin. Each model's stated range is checked and what lies outside it is reported, not hidden.

Files: ``validation.json``, ``validation.md``, ``validation_links.csv``,
``validation_pathloss.png``.
"""

from __future__ import annotations

import csv
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..config import Config
from .diagnostics import finite_percentiles
from ..errors import InputError
from ..fileio import atomic_output, atomic_write_text, json_text
from ..propagation import pathloss_models as plm
from ..propagation.uma_params import uma_table
from ..propagation.uma import uma_pathloss_db
from ..propagation.raytrace import trace
from ..sim.checks import check_materials
from ..world.geometry import build_geometry
from ..sim.engine import traced_power_serving
from ..report.validation_plot import plot_validation_pathloss

log = logging.getLogger(__name__)

__all__ = ["MODELS", "ValidationResult", "run_validate", "street_orientation_rad",
           "covered_length_m", "traced_pathloss_db", "bin_links", "format_validation"]

Progress = Callable[[str, int, int], None]

#: The models, in table order, with their label and source
MODELS = {
    "free_space": ("free space", "ITU-R P.525-4 (Friis), 3-D distance"),
    "p1411": ("P.1411", plm.P1411_EDITION + ", urban over-rooftop NLoS1"),
    "cost231_wi": ("COST-231 WI", "COST 231 final report ch. 4.4, Walfisch-Ikegami NLoS, "
                   "medium-sized city / suburban"),
    "uma_nlos": ("UMa NLOS", "TR 38.901 V18.0.0 Table 7.4.1-1 UMa NLOS"),
    "umi_nlos": ("UMi NLOS", "TR 38.901 V18.0.0 Table 7.4.1-1 UMi - Street Canyon NLOS"),
}
BIN_WIDTH_M = 50.0


def sigma_sf_db(name: str) -> float:
    """NLOS shadow-fading standard deviation of a statistical model (TR 38.901 Table 7.4.1-1,
    from the shipped tables): an offset within +-sigma is inside the model's own spread."""

    tab = uma_table() if name == "uma_nlos" else plm.umi_table()
    return float(tab["pathloss"]["sigma_sf_db"]["nlos"])


@dataclass
class ValidationResult:
    """What ``validate`` measured. ``links`` holds one entry per serving link (L = 3 x points):

    d_2d_m, d_3d_m : [L] float64, m;  pl_db : [L] float64, dB (NaN: no path)
    has_path, los : [L] bool;  num_paths : [L] int64;  point, bs : [L] int64
    phi_rad : [L] float64, rad (street orientation to the direct path)
    covered_m : [L] float64, m (part of the path over the street grid)
    excess_fs_bound_db : [L] float64, dB (10 lg num_paths)
    model_db : {model: [L] float64, dB}

    ``bins``: see :func:`bin_links`; ``flags``: {model: sentences on inputs outside its range}.
    """

    out_dir: Path | None
    inputs: dict
    links: dict
    bins: list
    summary: dict
    flags: dict
    timing_s: dict = field(default_factory=dict)


# -- geometry of each link --------------------------------------------------------------------
def street_orientation_rad(ue_xy, bs_xy, pitch: float,
                           street_width: float) -> tuple[np.ndarray, np.ndarray]:
    """phi of the over-rooftop models: angle between the UE's street and the direct path.

    Streets run along x and y with centre lines at multiples of ``pitch``. A UE within w/2 of
    an x = k pitch line is in a street along y, and so on; at an intersection it is in both and
    the street with the smaller L_ori (the stronger roof-to-street coupling) is taken. A UE in
    no street (off the grid) gets phi = 90 deg, COST 231's default for an unknown orientation.

    :param ue_xy, bs_xy: [L, 2] float64, m
    :returns: phi [L] float64, rad in [0, pi/2]; in_street [L] bool
    """
    ue, bs = np.asarray(ue_xy, float), np.asarray(bs_xy, float)
    v = np.abs(bs - ue)
    off = np.abs(ue - pitch * np.round(ue / pitch))
    along_y = off[:, 0] <= street_width / 2.0 + 1e-9     # near an x = k pitch centre line
    along_x = off[:, 1] <= street_width / 2.0 + 1e-9
    phi_y = np.arctan2(v[:, 0], v[:, 1])                  # to the y axis
    phi_x = np.arctan2(v[:, 1], v[:, 0])
    both = along_x & along_y
    pick_x = np.where(both, plm.street_orientation_loss_db(phi_x)
                      <= plm.street_orientation_loss_db(phi_y), along_x)
    phi = np.where(pick_x, phi_x, np.where(along_y, phi_y, np.pi / 2))
    return phi, along_x | along_y


def covered_length_m(ue_xy, bs_xy, half_extent: float) -> np.ndarray:
    """Length of each UE-BS segment inside the square |x|, |y| <= half_extent (Liang-Barsky).

    :param ue_xy, bs_xy: [L, 2] float64, m
    :returns: [L] float64, m
    """
    a, b = np.asarray(ue_xy, float), np.asarray(bs_xy, float)
    d = b - a
    t_lo, t_hi = np.zeros(len(a)), np.ones(len(a))
    for k in (0, 1):
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-half_extent - a[:, k]) / d[:, k], (half_extent - a[:, k]) / d[:, k]
        par = d[:, k] == 0.0
        inside = np.abs(a[:, k]) <= half_extent
        lo = np.where(par, np.where(inside, -np.inf, np.inf), np.minimum(ta, tb))
        hi = np.where(par, np.where(inside, np.inf, -np.inf), np.maximum(ta, tb))
        t_lo, t_hi = np.maximum(t_lo, lo), np.minimum(t_hi, hi)
    return np.clip(t_hi - t_lo, 0.0, 1.0) * np.linalg.norm(d, axis=1)


def traced_pathloss_db(cir) -> tuple[np.ndarray, np.ndarray]:
    """Incoherent path loss -10 lg sum_paths |a|^2 of every link slot.

    :returns: pl [num_points, num_tx] float64, dB (NaN where the link has no path);
        excess_bound [num_points, num_tx] float64, dB: 10 lg(number of valid paths), the most an
        incoherent sum of paths each no stronger than free space can beat free space by
    """
    has = cir.has_path()
    power = cir.path_power().sum(-1)
    with np.errstate(divide="ignore"):
        pl = np.where(has, -10.0 * np.log10(np.where(has, power, 1.0)), np.nan)
    n = cir.valid.sum(-1)
    return pl, 10.0 * np.log10(np.maximum(n, 1))


# -- models -----------------------------------------------------------------------------------
def _geometry(cfg: Config) -> plm.RooftopGeometry:
    sc = cfg.scene
    if not sc.is_canyon:
        raise InputError("scene.source", "validate sets the trace against over-rooftop models that "
                         "need the procedural canyon's roof height, street width and building "
                         f"separation; got the external scene {sc.source!r}")
    h_ue = cfg.trajectory.ue_height_m
    if sc.building_height_m <= h_ue:
        raise InputError("scene.building_height_m", f"got {sc.building_height_m}, expected a "
                         f"value > trajectory.ue_height_m ({h_ue}) for the over-rooftop models")
    return plm.RooftopGeometry(h_bs_m=cfg.topology.bs_height_m, h_ue_m=h_ue,
                               h_roof_m=sc.building_height_m, street_width_m=sc.street_width_m,
                               building_separation_m=sc.block_size_m + sc.street_width_m)


def model_db(name: str, d_2d, phi, covered, fc: float, geo: plm.RooftopGeometry) -> np.ndarray:
    """One model's path loss at horizontal distances ``d_2d`` [m] (phi [rad], covered [m])."""
    d_2d = np.maximum(np.asarray(d_2d, float), 1e-3)
    if name == "free_space":
        return plm.free_space_pathloss_db(np.hypot(d_2d, geo.h_bs_m - geo.h_ue_m), fc)
    if name == "p1411":
        # l >= one building row: the mobile stands among buildings
        ell = np.maximum(covered, geo.building_separation_m)
        return plm.p1411_nlos_db(d_2d, fc, geo, phi, ell)
    if name == "cost231_wi":
        return plm.cost231_wi_nlos_db(d_2d, fc, geo, phi)

    f = uma_pathloss_db if name == "uma_nlos" else plm.umi_pathloss_db
    return f(d_2d, geo.h_bs_m, geo.h_ue_m, fc, False)


# -- bins -------------------------------------------------------------------------------------
def _median(x) -> float | None:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.median(x)) if x.size else None


def bin_links(links: dict, width_m: float, fc: float, geo: plm.RooftopGeometry) -> list[dict]:
    """Per 2-D distance bin: link counts, traced p10/p50/p90, each model at the bin centre
    (median over the bin's links of the model at the centre distance with the link's phi and
    covered fraction) and the median per-link offset traced - model (links with a path)."""
    d = links["d_2d_m"]
    idx = np.floor(d / width_m).astype(int)
    out = []
    for k in np.unique(idx):
        m = idx == k
        has = m & links["has_path"]
        centre = (k + 0.5) * width_m
        frac = links["covered_m"][m] / np.maximum(d[m], 1e-9)
        row = {"d_lo_m": k * width_m, "d_hi_m": (k + 1) * width_m, "d_centre_m": centre,
               "links": int(m.sum()), "no_path": int((m & ~links["has_path"]).sum()),
               "los": int((m & links["los"]).sum()),
               "traced_db": finite_percentiles(links["pl_db"][has], (10, 50, 90)),
               "model_db": {}, "offset_db": {}}
        for name in MODELS:
            at_centre = model_db(name, np.full(m.sum(), centre), links["phi_rad"][m],
                                 frac * centre, fc, geo)
            row["model_db"][name] = _median(at_centre)
            row["offset_db"][name] = _median(links["pl_db"][has] - links["model_db"][name][has])
        out.append(row)
    return out


# -- the study --------------------------------------------------------------------------------
def run_validate(cfg: Config, out_dir: str | Path | None = None, progress: Progress | None = None,
                 bin_width_m: float = BIN_WIDTH_M) -> ValidationResult:
    """Trace the serving links of ``cfg`` and set their path loss beside the models.

    :param progress: called as ``progress(stage, done, total)``
    :param out_dir: where the files go (None: nothing written; the scene then goes to
        ``.veriloc-scene``)
    """

    if not np.isfinite(bin_width_m) or bin_width_m <= 0:
        raise ValueError(f"Argument `bin_width_m` must be > 0, not {bin_width_m!r}")
    geo = _geometry(cfg)
    timing: dict = {}
    t0 = time.perf_counter()
    out = Path(out_dir) if out_dir is not None else None
    geometry = build_geometry(cfg, (out / "scene") if out else Path(".veriloc-scene"))
    check_materials(cfg)  # traced whatever propagation.model says
    timing["geometry"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    if geometry.candidates is not None:
        # topology.selection 'traced_power': the run's choice (the strongest candidates)
        geometry, prop = traced_power_serving(cfg, geometry, progress, adversary=False)
    else:
        cb = (lambda d, n: progress("ray tracing", d, n)) if progress else None
        prop = trace(geometry, cfg.propagation, cfg.seed, progress=cb,
                     adversary_points=np.zeros(geometry.num_points, bool))
    timing["ray_tracing"] = time.perf_counter() - t1
    cir = prop.bs_ue
    fc = float(cir.carrier_frequency)
    pl, bound = traced_pathloss_db(cir)
    used = cir.tx_index != -1
    ue_xy = np.broadcast_to(cir.rx_pos[:, None, :2], cir.tx_pos[..., :2].shape)[used]
    bs_xy = cir.tx_pos[..., :2][used]
    canyon = geometry.full_canyon
    phi, in_street = street_orientation_rad(ue_xy, bs_xy, canyon.pitch, canyon.street_width)
    links = {"d_2d_m": np.linalg.norm(bs_xy - ue_xy, axis=1),
             "d_3d_m": np.linalg.norm(cir.tx_pos[used] - np.broadcast_to(
                 cir.rx_pos[:, None, :], cir.tx_pos.shape)[used], axis=1),
             "pl_db": pl[used], "has_path": cir.has_path()[used], "los": cir.los[used],
             "phi_rad": phi, "covered_m": covered_length_m(ue_xy, bs_xy, canyon.extent),
             "excess_fs_bound_db": bound[used], "num_paths": cir.valid.sum(-1)[used],
             "point": np.nonzero(used)[0], "bs": cir.tx_index[used]}
    links["model_db"] = {n: model_db(n, links["d_2d_m"], phi, links["covered_m"], fc, geo)
                         for n in MODELS}
    flags = {n: plm.validity_flags(n, fc, geo.h_bs_m, geo.h_ue_m, links["d_2d_m"]) for n in MODELS}
    if cfg.scene.height_jitter_m > 0:
        for n in ("p1411", "cost231_wi"):
            flags[n].append(f"building heights vary by +-{cfg.scene.height_jitter_m:g} m: the "
                            "model takes the mean roof height")
    frac = links["covered_m"] / np.maximum(links["d_2d_m"], 1e-9)
    partial = int(np.sum(frac < 0.99))
    if partial:
        for n in ("p1411", "cost231_wi"):
            flags[n].append(f"{partial} of {len(frac)} links run partly outside the street grid "
                            "(their median share over buildings "
                            f"{np.median(frac[frac < 0.99]):.2f})")
    if cfg.topology.selection == "traced_power":
        for n in MODELS:
            flags[n].append(f"each point's {cfg.topology.num_trps} links are the strongest of its "
                            "traced candidates (topology.selection traced_power): the traced "
                            "loss is biased low against a model's median")
    if not in_street.all():
        flags["p1411"].append(f"{int((~in_street).sum())} links with the UE off the street grid "
                              "(phi = 90 deg)")
    bins = bin_links(links, bin_width_m, fc, geo)
    has = links["has_path"]
    excess = links["pl_db"][has] - links["model_db"]["free_space"][has]
    summary = {
        "links": int(len(pl[used])), "with_path": int(has.sum()), "no_path": int((~has).sum()),
        "los": int(links["los"].sum()),
        "offset_db": {n: finite_percentiles(links["pl_db"][has] - links["model_db"][n][has],
                                            (10, 50, 90)) for n in MODELS},
        "excess_over_free_space_db_min": float(excess.min()) if excess.size else None,
        "raytrace_stats": prop.stats,
    }
    inputs = {"carrier_frequency_hz": fc, "h_bs_m": geo.h_bs_m, "h_ue_m": geo.h_ue_m,
              "h_roof_m": geo.h_roof_m, "street_width_m": geo.street_width_m,
              "building_separation_m": geo.building_separation_m, "bin_width_m": bin_width_m,
              "num_points": geometry.num_points, "seed": cfg.seed,
              "max_paths_per_link": cfg.propagation.raytrace.max_paths_per_link,
              "max_depth": cfg.propagation.raytrace.max_depth,
              "rays_per_source": cfg.propagation.raytrace.rays_per_source,
              "phi_deg_median": float(np.degrees(np.median(phi))),
              "covered_fraction_median": float(np.median(links["covered_m"]
                                                         / np.maximum(links["d_2d_m"], 1e-9)))}
    timing["total"] = time.perf_counter() - t0
    log.info("validate: %d links (%d with a path), traced - P.1411 median %s dB",
             summary["links"], summary["with_path"], summary["offset_db"]["p1411"]["p50"])
    res = ValidationResult(out, inputs, links, bins, summary, flags, timing)
    if out:
        write_validation(res)
    return res


# -- reporting --------------------------------------------------------------------------------
def _f(v, nd: int = 1) -> str:
    return "n/a" if v is None else f"{v:.{nd}f}"


def markdown_table(res: ValidationResult) -> str:
    """The per-bin table (markdown)."""
    names = list(MODELS)
    head = ("| d2D bin, m | links | no path | LoS | traced p10 / p50 / p90, dB | "
            + " | ".join(f"{MODELS[n][0]}, dB" for n in names) + " | "
            + " | ".join(f"traced - {MODELS[n][0]}, dB" for n in names[1:]) + " |")
    L = [head, "|" + " --- |" * (5 + 2 * len(names) - 1)]
    for b in res.bins:
        t = b["traced_db"]
        L.append(f"| {b['d_lo_m']:.0f}-{b['d_hi_m']:.0f} | {b['links']} | {b['no_path']} | "
                 f"{b['los']} | {_f(t['p10'])} / {_f(t['p50'])} / {_f(t['p90'])} | "
                 + " | ".join(_f(b["model_db"][n]) for n in names) + " | "
                 + " | ".join(_f(b["offset_db"][n]) for n in names[1:]) + " |")
    return "\n".join(L)


def reading(res: ValidationResult) -> list[str]:
    """Plain sentences: where the trace and the models disagree, and why they may."""
    s, inp = res.summary, res.inputs
    off = {n: s["offset_db"][n]["p50"] for n in MODELS}
    fc_ghz = inp["carrier_frequency_hz"] / 1e9
    L = [f"{s['links']} serving links, {s['with_path']} with a path ({s['no_path']} without, "
         f"counted apart), {s['los']} with a line-of-sight path."]
    if s["with_path"] == 0:
        return L + ["No link has a path: nothing to compare."]
    L.append(f"Traced - free space: median {_f(off['free_space'])} dB, lowest "
             f"{_f(s['excess_over_free_space_db_min'])} dB (rooftop diffraction and the street "
             "add loss; below 0 only by adding paths).")
    for n in ("p1411", "cost231_wi", "uma_nlos", "umi_nlos"):
        o = s["offset_db"][n]
        line = (f"Traced - {MODELS[n][0]}: median {_f(o['p50'])} dB "
                f"(p10 {_f(o['p10'])}, p90 {_f(o['p90'])}).")
        if n in ("uma_nlos", "umi_nlos") and o["p50"] is not None:
            sig = sigma_sf_db(n)
            line += (f" {'Within' if abs(o['p50']) <= sig else 'Beyond'} its shadow-fading "
                     f"sigma of {sig:g} dB; it is a statistical fit over many "
                     f"{'macro' if n == 'uma_nlos' else 'micro'} cells that knows no street "
                     "width, building separation or street orientation.")
        if res.flags[n]:
            line += " Outside the model's validity: " + "; ".join(res.flags[n]) + "."
        L.append(line)
    if off["p1411"] is not None:
        gap = _median(res.links["model_db"]["p1411"] - res.links["model_db"]["cost231_wi"])
        L.append(f"P.1411 lies {_f(gap)} dB above COST-231 WI (median over the links) though both "
                 "are Walfisch-Ikegami: P.1411's roof-to-street constant is -8.2 dB against "
                 f"COST's -16.9 dB, and at {fc_ghz:g} GHz P.1411 takes its f > 2 GHz "
                 "multi-screen coefficients (k_a = 71.4, k_f = -8) where COST extrapolates its "
                 "800-2000 MHz ones.")
    return L


def format_validation(res: ValidationResult) -> str:
    """Table and reading, as the CLI prints them."""
    inp = res.inputs
    head = (f"traced path loss vs models: f = {inp['carrier_frequency_hz'] / 1e9:g} GHz, "
            f"h_BS {inp['h_bs_m']:g} m, h_UE {inp['h_ue_m']:g} m, roofs {inp['h_roof_m']:g} m, "
            f"street {inp['street_width_m']:g} m, building separation "
            f"{inp['building_separation_m']:g} m, median phi {inp['phi_deg_median']:.0f} deg")
    return "\n".join([head, "", markdown_table(res), ""] + reading(res))


def write_validation(res: ValidationResult) -> dict:
    """validation.json, validation.md, validation_links.csv, validation_pathloss.png."""

    out = res.out_dir
    out.mkdir(parents=True, exist_ok=True)
    lk = res.links
    models = {n: {"label": MODELS[n][0], "source": MODELS[n][1], "outside_validity": res.flags[n]}
              for n in MODELS}
    files = {"json": out / "validation.json", "md": out / "validation.md",
             "csv": out / "validation_links.csv", "png": out / "validation_pathloss.png"}
    # every file through a temporary file renamed over it: a stopped validate leaves no half file
    atomic_write_text(files["json"], json_text(
        {"inputs": res.inputs, "models": models, "summary": res.summary, "bins": res.bins,
         "timing_s": res.timing_s}))
    inp = res.inputs
    atomic_write_text(
        files["md"],
        f"# Traced path loss against published models ({inp['num_points']} points, seed "
        f"{inp['seed']})\n\n" + format_validation(res) + "\n\nModels: " + "; ".join(
            f"{v['label']}: {v['source']}" for v in models.values()) + ".\n")
    with atomic_output(files["csv"]) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point", "bs", "d_2d_m", "d_3d_m", "has_path", "los", "num_paths", "phi_deg",
                    "covered_m", "pl_db"] + [f"{n}_db" for n in MODELS])
        for i in range(len(lk["d_2d_m"])):
            w.writerow([int(lk["point"][i]), int(lk["bs"][i]), lk["d_2d_m"][i], lk["d_3d_m"][i],
                        int(lk["has_path"][i]), int(lk["los"][i]), int(lk["num_paths"][i]),
                        np.degrees(lk["phi_rad"][i]),
                        lk["covered_m"][i], "" if np.isnan(lk["pl_db"][i]) else lk["pl_db"][i]]
                       + [lk["model_db"][n][i] for n in MODELS])
    plot_validation_pathloss(res, files["png"], MODELS, model_db)
    return files
