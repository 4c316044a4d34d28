"""Ray tracing against its TR 38.901 stochastic twin (UMa or UMi) on the same topology,
trajectory and attacks.

:func:`run_compare` runs the config twice with :func:`veriloc_rt.sim.engine.run`, once with
``propagation.model = 'raytrace'`` and once with the stochastic twin (the config's
``uma_mode``), into ``<out>/raytrace`` and ``<out>/<twin>``; geometry, keys, noise streams and
adversary draws are the same, only the channel differs. With ``topology.selection``
'traced_power' the ray-tracing arm chooses each point's TRPs by traced power
(:func:`~veriloc_rt.sim.engine.traced_power_serving`) and the twin measures the same TRPs
(its run is given that geometry; ``comparison.json``'s ``"twin"`` says so).

The twin (``propagation.stochastic_twin``): 'uma' or 'umi' as given, or 'auto': UMi - Street
Canyon when the median BS antenna height lies below the scene's median roof height (street-level
sites, TR 38.901 Table 7.2-1's UMi: BSs 10 m, below the rooftops), UMa otherwise (rooftop
sites). The decision, with its two heights, is in ``comparison.json`` under ``"twin"``.

With ``match_pathloss`` (``veriloc-rt compare --match-pathloss``) the twin's serving-link path
loss is shifted by a constant per LoS state so that its median equals the traced median of the
links in the same state (the all-links offset where one arm has no link in that state): what
then differs is the multipath structure, not the mean loss. The offsets are the config's
``propagation.stochastic_pathloss_offset_{los,nlos}_db`` of the twin run (its draws are
unchanged: the same seed gives the same clusters and rays).

Both arms get the config's BS antennas (``topology.bs_antenna``) by the same transform after
propagation (:func:`~veriloc_rt.propagation.antenna.apply_bs_antenna`). With sector panels
('tr38901') the links' "path loss" below is the coupling loss, path loss minus the BS antenna
gain towards each path, in both arms (the match too), while the TR 38.901 table's path loss
is of isotropic antennas: set the config's ``topology.bs_antenna`` to 'isotropic' to compare
path loss with the table.

It then reports, side by side:

* channel statistics of the serving links, over all links and for LoS and NLoS links
  separately (share, paths per link, incoherent path loss, rms delay spread, circular azimuth
  and zenith spreads of arrival (TR 38.901 Annex A.1), Ricean K-factor of LoS links) next to
  the twin's TR 38.901 values (Table 7.4.1-1 path loss and Table 7.5-6 medians at the links'
  median distance and the carrier);
* benign-chain errors per point (:func:`veriloc_rt.studies.diagnostics.benign_chain`, the
  ``none`` scenario's chain): ToA bias against the straight-line delay (all, LoS and NLoS
  links), RSTD error, AoA error, DL position error (CDFs);
* the detectors' correct-decision rates and outcome shares per scenario from both runs.

Files: ``comparison.md``, ``comparison.json``, ``comparison_points.csv`` (per point and BS),
``comparison_channel.csv``, ``comparison_cdf.png``, ``comparison_detectors.png``.
"""

from __future__ import annotations

import csv
import dataclasses
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..config import Config
from ..fileio import atomic_output, atomic_write_text, json_text
from .diagnostics import BenignRun, benign_chain, finite_percentiles
from .validate import traced_pathloss_db
from ..report.propagation_summary import rms_delay_spread
from ..propagation import tr38901
from ..propagation.antenna import apply_bs_antenna
from ..propagation.stochastic import stochastic_propagation
from ..sim.engine import run
from ..sim.run_folder import run_keys
from ..detectors.outcomes import DETECTORS, OUTCOMES
from ..report.plots import plot_comparison_cdfs, plot_comparison_detectors

log = logging.getLogger(__name__)

__all__ = ["ComparisonResult", "run_compare", "channel_statistics", "uma_reference_statistics",
           "reference_statistics", "choose_twin", "scene_roof_heights", "pathloss_offsets",
           "format_comparison"]

#: the stochastic twins compare can set against ray tracing
TWINS = tr38901.SCENARIOS
#: link conditions the channel tables are split by
CONDITIONS = ("all", "los", "nlos")
Progress = Callable[[str, int, int], None]


@dataclass
class ComparisonResult:
    out_dir: Path
    channel: dict        # {model: {cond: stats}}, plus "tr38901_table": {"los": .., "nlos": ..}
    errors: dict         # {model: {quantity: {p50, p95, ...}}}
    detectors: dict      # {model: metrics.json "scenarios"}
    benign: dict         # {model: BenignRun}
    timing_s: dict
    twin: dict = dataclasses.field(default_factory=dict)   # model, rule, heights, offsets

    @property
    def models(self) -> tuple[str, str]:
        """("raytrace", the twin's model name)."""
        return ("raytrace", self.twin.get("model", "uma"))


def scene_roof_heights(scene) -> np.ndarray:
    """Roof height of every building of the scene (canyon blocks or mesh building shapes), m."""
    if hasattr(scene, "heights"):
        return np.asarray(scene.heights, dtype=float)
    return np.array([float(s.bounds[1][2]) for s in getattr(scene, "buildings", ())])


def choose_twin(cfg: Config, geometry) -> dict:
    """The stochastic twin of ``cfg`` on ``geometry`` (see the module docstring).

    :returns: {"model": "uma"|"umi", "rule": str, "bs_height_m": median BS z,
        "roof_height_m": median roof height (None without buildings)}
    """
    setting = cfg.propagation.stochastic_twin
    bs_h = float(np.median(geometry.bs_pos[:, 2]))
    roofs = scene_roof_heights(geometry.scene)
    roof = float(np.median(roofs)) if roofs.size else None
    if setting != "auto":
        model, rule = setting, "propagation.stochastic_twin"
    elif roof is None or bs_h > roof:
        model, rule = "uma", "auto: BSs above the median roof (rooftop sites)"
    else:
        model, rule = "umi", "auto: BSs at or below the median roof (street-level sites)"
    return {"model": model, "rule": rule, "bs_height_m": bs_h, "roof_height_m": roof}


def _circular_spread_deg(w: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """TR 38.901 Annex A.1 circular angle spread, deg: sqrt(-2 ln |sum_n w_n e^{j phi_n}|)."""
    r = np.abs(np.sum(w * np.exp(1j * ang), axis=-1))
    return np.degrees(np.sqrt(-2.0 * np.log(np.clip(r, 1e-300, 1.0))))


def channel_statistics(cir, mask: np.ndarray | None = None) -> dict:
    """Per-link statistics of the serving links that have a path (within ``mask``).

    :param mask: optional [num_points, num_tx] bool, the links to describe (e.g. ``cir.los``)
    :returns: {"links", "links_with_path_share", "los_share" (fractions), "paths_per_link_mean",
        "pathloss_db": {p10, p50, p90} (incoherent, -10 lg sum |a|^2 per element),
        "ds_ns": .., "asa_deg": .., "zsa_deg": .., "k_db": .. (LoS links)}
    """
    used = cir.tx_index != -1
    if mask is not None:
        used = used & mask
    has = cir.has_path() & used
    out = {"links": int(used.sum()),
           "links_with_path_share": float(has.sum()) / max(int(used.sum()), 1)}
    if not has.any():
        return out
    pw = cir.path_power()[has]                                   # [L, paths]
    w = pw / pw.sum(-1, keepdims=True)
    tau = np.where(cir.valid[has], cir.delays[has], 0.0)
    ds = rms_delay_spread(cir)[has]
    asa = _circular_spread_deg(w, cir.aoa_az[has])
    zsa = _circular_spread_deg(w, cir.aoa_zen[has])
    los = cir.los[has]
    pl = traced_pathloss_db(cir)[0][has]
    # K-factor of LoS links: the path at the straight-line delay against the rest
    geo = cir.geometric_delay()[has]
    direct = cir.valid[has] & np.isclose(tau, geo[:, None], rtol=0, atol=1e-12)
    p_dir = (pw * direct).sum(-1)
    rest = pw.sum(-1) - p_dir
    ok = los & (p_dir > 0)
    with np.errstate(divide="ignore"):
        k_db = 10 * np.log10(p_dir[ok] / np.maximum(rest[ok], 1e-300))

    def q(x):
        return finite_percentiles(x, (10, 50, 90))

    out.update({"los_share": float(los.mean()),
                "paths_per_link_mean": float(cir.valid[has].sum(-1).mean()),
                "pathloss_db": q(pl), "ds_ns": q(ds * 1e9), "asa_deg": q(asa),
                "zsa_deg": q(zsa), "k_db": q(k_db)})
    return out


def _conditioned(cir) -> dict:
    """:func:`channel_statistics` over all, LoS and NLoS serving links."""
    return {"all": channel_statistics(cir), "los": channel_statistics(cir, cir.los),
            "nlos": channel_statistics(cir, ~cir.los)}


def reference_statistics(scenario: str, fc_hz: float, d_2d_m: float = 200.0,
                         h_ut_m: float = 1.5, h_bs_m: float | None = None) -> dict:
    """TR 38.901 medians of ``scenario``, LoS and NLoS: Table 7.4.1-1 path loss (no shadowing)
    and Table 7.5-6 medians (10^mu of the lg parameters; K in dB) at ``d_2d_m``.

    :param h_bs_m: BS height, m (default: the table's own, 25 m UMa / 10 m UMi)
    """
    if h_bs_m is None:
        h_bs_m = tr38901.scenario_table(scenario)["pathloss"]["validity"]["h_bs_m"]
    out = {"scenario": scenario, "d_2d_m": float(d_2d_m), "h_bs_m": float(h_bs_m)}
    for los in (True, False):
        mu, sd = tr38901.lsp_statistics(scenario, los, fc_hz, [d_2d_m], h_ut_m, h_bs_m)
        out["los" if los else "nlos"] = {
            "pathloss_db": float(tr38901.pathloss_db(scenario, d_2d_m, h_bs_m, h_ut_m, fc_hz,
                                                     los)),
            "ds_ns": float(10 ** mu[0, 2] * 1e9), "asa_deg": float(10 ** mu[0, 4]),
            "zsa_deg": float(10 ** mu[0, 6]),
            "k_db": float(mu[0, 1]) if los else None}
    return out


def _reference_for(traced_cir, scenario: str, h_bs_m: float, fc_hz: float) -> dict:
    """The table's values for the traced serving links: LoS entries at the median distance of
    the traced LoS links, NLoS entries at that of the NLoS links (all links where a state has
    none), UE height the trajectory's median."""
    d2 = np.linalg.norm(traced_cir.tx_pos[..., :2] - traced_cir.rx_pos[:, None, :2], axis=-1)
    used = traced_cir.tx_index != -1
    h_ut = float(np.median(traced_cir.rx_pos[:, 2]))
    out = {"scenario": scenario, "h_bs_m": float(h_bs_m), "d_2d_m": {}}
    for name, sel in (("los", traced_cir.los), ("nlos", ~traced_cir.los)):
        d = d2[used & sel] if np.any(used & sel) else d2[used]
        ref = reference_statistics(scenario, fc_hz, float(np.median(d)), h_ut, h_bs_m)
        out[name], out["d_2d_m"][name] = ref[name], ref["d_2d_m"]
    return out


def uma_reference_statistics(fc_hz: float, d_2d_m: float = 200.0, h_ut_m: float = 1.5) -> dict:
    """TR 38.901 Table 7.5-6 UMa medians (10^mu of the lg parameters; K in dB), LoS and NLoS."""
    return reference_statistics("uma", fc_hz, d_2d_m, h_ut_m)


def _median(x) -> float | None:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.median(x)) if x.size else None


def pathloss_offsets(traced_cir, twin_cir) -> dict:
    """Per-LoS-state path-loss offsets that put the twin's median serving-link path loss on the
    traced one: {"los": dB, "nlos": dB, "all": dB, "basis": {"los": "los"|"all", ...}}.

    A state in which either arm has no link with a path takes the all-links offset.
    """
    pl_t, pl_s = traced_pathloss_db(traced_cir)[0], traced_pathloss_db(twin_cir)[0]
    used_t, used_s = traced_cir.tx_index != -1, twin_cir.tx_index != -1
    base_t, base_s = _median(pl_t[used_t]), _median(pl_s[used_s])
    overall = 0.0 if base_t is None or base_s is None else base_t - base_s
    out = {"all": overall, "basis": {}}
    for name, mt, ms in (("los", traced_cir.los, twin_cir.los),
                         ("nlos", ~traced_cir.los, ~twin_cir.los)):
        a, b = _median(pl_t[used_t & mt]), _median(pl_s[used_s & ms])
        if a is None or b is None:
            out[name], out["basis"][name] = overall, "all"
        else:
            out[name], out["basis"][name] = a - b, name
    return out


def _q(x) -> dict:
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    return {"n": int(x.size), **finite_percentiles(x, (50, 95)),
            "mean": float(x.mean()) if x.size else None}


def error_statistics(b: BenignRun, los: np.ndarray | None = None) -> dict:
    """Benign-chain error percentiles; with ``los`` ([P, B] bool, the links' LoS state at
    ``b.points``) the ToA bias also for LoS and NLoS links apart."""
    out = {"toa_bias_m": _q(b.toa_bias_m), "rstd_error_m": _q(b.rstd_error_m),
           "rstd_abs_error_m": _q(np.abs(b.rstd_error_m)),
           "aoa_error_deg": _q(b.aoa_error_deg), "position_error_m": _q(b.position_error_m),
           "fix_rate": float(np.mean(np.isfinite(b.pos[:, 0]))) if len(b.pos) else None}
    if los is not None:
        bias = np.asarray(b.toa_bias_m, float)
        n = min(bias.shape[1], los.shape[1])
        out["toa_bias_los_m"] = _q(bias[:, :n][los[:, :n]])
        out["toa_bias_nlos_m"] = _q(bias[:, :n][~los[:, :n]])
    return out


def run_compare(cfg: Config, out_dir: str | Path, progress: Progress | None = None,
                workers: int = 1, match_pathloss: bool = False) -> ComparisonResult:
    """Run ``cfg`` on ray tracing and on its stochastic twin and compare (see the module
    docstring)."""
    import time

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    timing: dict = {}
    channel, errors, detectors, benign = {}, {}, {}, {}
    twin: dict = {}
    traced_cir = None
    for arm in ("raytrace", "twin"):
        if arm == "raytrace":
            model, prop = "raytrace", dataclasses.replace(cfg.propagation, model="raytrace")
        else:
            model = twin["model"]
            prop = dataclasses.replace(cfg.propagation, model=model,
                                       stochastic_pathloss_offset_los_db=0.0,
                                       stochastic_pathloss_offset_nlos_db=0.0)
            twin["match_pathloss"] = bool(match_pathloss)
            if match_pathloss:
                # with the BS antennas, as the traced links have them (like for like)
                probe = apply_bs_antenna(stochastic_propagation(geometry, prop, cfg.seed),
                                         geometry, cfg.topology).bs_ue
                off = pathloss_offsets(traced_cir, probe)
                twin["pathloss_offset_db"] = off
                prop = dataclasses.replace(prop, stochastic_pathloss_offset_los_db=off["los"],
                                           stochastic_pathloss_offset_nlos_db=off["nlos"])
        given, topo = None, cfg.topology
        if arm == "twin" and cfg.topology.selection == "traced_power":
            # the twin measures the TRPs the traced arm chose (only the channel differs); its
            # own config cannot select by traced power (nothing is traced)
            given, topo = geometry, dataclasses.replace(cfg.topology, selection="power")
            twin["serving"] = "the ray-tracing arm's (topology.selection traced_power)"
        c = cfg.replace(propagation=prop, topology=topo)
        t = time.perf_counter()
        # its own sub-folders: replaced by every compare into this --out, as its other files
        res = run(c, out / model, progress=progress, workers=workers, force=True,
                  geometry=given)
        timing[f"run_{model}"] = time.perf_counter() - t
        if arm == "raytrace":
            geometry, traced_cir = res.geometry, res.propagation.bs_ue
            twin.update(choose_twin(cfg, geometry))
        else:
            timing[f"propagation_{model}_per_link_s"] = (
                res.propagation.stats["wall_s"] / max(res.propagation.stats["links"], 1))
        keys = run_keys(c, len(res.geometry.bs_pos))
        t = time.perf_counter()
        cb = (lambda d, n, m=model: progress(f"chain {m}", d, n)) if progress else None
        pts = np.arange(res.geometry.num_points)
        b = benign_chain(c, res.geometry, res.propagation.bs_ue, keys, pts, progress=cb)
        timing[f"diagnostics_{model}"] = time.perf_counter() - t
        cir = res.propagation.bs_ue
        channel[model] = _conditioned(cir)
        errors[model] = error_statistics(b, cir.los[b.points])
        detectors[model] = res.metrics["scenarios"]
        benign[model] = b
    if not np.allclose(benign["raytrace"].truth, benign[twin["model"]].truth):
        raise RuntimeError("the two runs have different trajectories")
    channel["tr38901_table"] = _reference_for(traced_cir, twin["model"], twin["bs_height_m"],
                                              cfg.propagation.carrier_frequency_hz)
    result = ComparisonResult(out, channel, errors, detectors, benign, timing, twin)
    _write(result, cfg)
    return result


# -- reporting -------------------------------------------------------------------------------
def _f(v, nd=1) -> str:
    return "n/a" if v is None else f"{v:.{nd}f}"


def _pc(v) -> str:
    """A share (a fraction in metrics.json) in percent."""
    return "n/a" if v is None else f"{100 * v:.1f}"


def _twin_label(res: ComparisonResult) -> str:
    return f"TR 38.901 {tr38901.SCENARIO_NAMES[res.models[1]]}"


def _channel_table(res: ComparisonResult, cond: str) -> list[str]:
    rt_m, tw_m = res.models
    ch = res.channel
    rt, tw = ch[rt_m][cond], ch[tw_m][cond]
    tab = ch["tr38901_table"]
    ref_col = cond in ("los", "nlos")
    head = ("| statistic | ray tracing | " + f"{tw_m.upper()} (drawn) |"
            + (f" {tw_m.upper()} table |" if ref_col else ""))
    L = [head, "| --- | --- | --- |" + (" --- |" if ref_col else "")]
    tail = " |" if ref_col else ""
    L.append(f"| links | {rt.get('links')} | {tw.get('links')} |" + tail)
    L.append(f"| links with a path, % | {_pc(rt.get('links_with_path_share'))} | "
             f"{_pc(tw.get('links_with_path_share'))} |" + tail)
    if cond == "all":
        L.append(f"| LoS links, % | {_pc(rt.get('los_share'))} | {_pc(tw.get('los_share'))} |")
    L.append(f"| paths per link (mean) | {_f(rt.get('paths_per_link_mean'))} | "
             f"{_f(tw.get('paths_per_link_mean'))} |" + tail)
    for key, name in (("pathloss_db", "path loss, dB"), ("ds_ns", "rms delay spread, ns"),
                      ("asa_deg", "azimuth spread of arrival, deg"),
                      ("zsa_deg", "zenith spread of arrival, deg"),
                      ("k_db", "K-factor (LoS links), dB")):
        if key == "k_db" and cond == "nlos":
            continue
        a, b = rt.get(key) or {}, tw.get(key) or {}
        row = (f"| {name}, p50 [p10, p90] | {_f(a.get('p50'))} [{_f(a.get('p10'))}, "
               f"{_f(a.get('p90'))}] | {_f(b.get('p50'))} [{_f(b.get('p10'))}, {_f(b.get('p90'))}] |")
        if ref_col:
            row += f" {_f(tab[cond][key])} |"
        L.append(row)
    return L


def markdown(res: ComparisonResult) -> str:
    er, dt = res.errors, res.detectors
    rt_m, tw_m = res.models
    tab = res.channel["tr38901_table"]
    tw = res.twin
    L = [f"Stochastic twin: {_twin_label(res)} ({tw.get('rule')}; median BS height "
         f"{_f(tw.get('bs_height_m'))} m, median roof height {_f(tw.get('roof_height_m'))} m).", ""]
    if tw.get("match_pathloss"):
        off = tw["pathloss_offset_db"]
        L += [f"Median path loss matched to the trace: {_f(off['los'], 2)} dB added to the "
              f"twin's LoS links (basis: {off['basis']['los']} links), {_f(off['nlos'], 2)} dB "
              f"to its NLoS links (basis: {off['basis']['nlos']} links).", ""]
    L += ["## Channel of the serving links", "", "### All links", ""]
    L += _channel_table(res, "all")
    for cond, title in (("los", "LoS links"), ("nlos", "NLoS links")):
        L += ["", f"### {title}", ""] + _channel_table(res, cond)
    L += ["", f"Table columns: TR 38.901 {tr38901.SCENARIO_NAMES[tw_m]} (Table 7.4.1-1 path loss "
          f"without shadowing, Table 7.5-6 medians 10^mu) at the traced links' median distance "
          f"(LoS {_f(tab['d_2d_m']['los'])} m, NLoS {_f(tab['d_2d_m']['nlos'])} m), h_BS "
          f"{_f(tab['h_bs_m'])} m, at the carrier. Ray tracing "
          "calls a link LoS when its straight line is unobstructed; the twin draws the state "
          "(Table 7.4.2-1).", "",
          "## Benign chain errors (scenario none, standard PRS)", "",
          f"| quantity | ray tracing p50 / p95 | {tw_m.upper()} p50 / p95 |", "| --- | --- | --- |"]
    for key, name in (("position_error_m", "DL position error, m"),
                      ("toa_bias_m", "ToA bias vs LoS delay, m"),
                      ("toa_bias_los_m", "ToA bias, LoS links, m"),
                      ("toa_bias_nlos_m", "ToA bias, NLoS links, m"),
                      ("rstd_abs_error_m", "\\|RSTD error\\|, m"), ("aoa_error_deg", "AoA error, deg")):
        a, b = er[rt_m].get(key), er[tw_m].get(key)
        if a is None or b is None:
            continue
        L.append(f"| {name} | {_f(a['p50'], 2)} / {_f(a['p95'], 2)} | "
                 f"{_f(b['p50'], 2)} / {_f(b['p95'], 2)} |")
    L.append(f"| DL fix rate, % | {_pc(er[rt_m]['fix_rate'])} | {_pc(er[tw_m]['fix_rate'])} |")
    L += ["", "## Detectors (correct-decision rate, %) and outcomes (standard PRS, %)", "",
          "| scenario | model | " + " | ".join(DETECTORS) + " | " + " | ".join(OUTCOMES) + " |",
          "| --- | --- | " + " | ".join("---" for _ in DETECTORS + OUTCOMES) + " |"]
    for scen in dt[rt_m]:
        for model in res.models:
            m = dt[model].get(scen) or {}
            if not m.get("num_points"):
                continue
            uninf = set(m.get("uninformative_detectors") or ())   # no detection to show
            rates = " | ".join("uninf." if d in uninf else _pc(m["correct_decision_rate"].get(d))
                               for d in DETECTORS)
            outs = " | ".join(_pc(m["outcomes"].get(o)) for o in OUTCOMES)
            L.append(f"| {scen} | {model} | {rates} | {outs} |")
    L += ["", "`uninf.`: a detector that accepts under `detectors.min_benign_accept` of the "
          "benign fixes; its rejections under attack are no detections."]
    return "\n".join(L) + "\n"


def format_comparison(res: ComparisonResult) -> str:
    return markdown(res)


def _write(res: ComparisonResult, cfg: Config) -> None:
    out = res.out_dir
    rt_m, tw_m = res.models
    # every file through a temporary file renamed over it: a stopped compare leaves no half file
    atomic_write_text(
        out / "comparison.md",
        f"# Ray tracing vs {_twin_label(res)} ({len(res.benign[rt_m].points)} points, seed "
        f"{cfg.seed}, mode {cfg.propagation.uma_mode})\n\n" + markdown(res))
    atomic_write_text(out / "comparison.json", json_text(
        {"twin": res.twin, "channel": res.channel, "errors": res.errors,
         "detectors": res.detectors, "timing_s": res.timing_s}))
    with atomic_output(out / "comparison_points.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["model", "point", "bs", "toa_bias_m", "rstd_error_m", "aoa_error_deg",
                    "position_error_m"])
        for model in res.models:
            b = res.benign[model]
            rstd = np.concatenate([np.full((len(b.points), 1), np.nan), b.rstd_error_m], axis=1)
            for r, i in enumerate(b.points):
                for j in range(b.toa.shape[1]):
                    w.writerow([model, int(i), j, b.toa_bias_m[r, j], rstd[r, j],
                                b.aoa_error_deg[r, j], b.position_error_m[r]])
    with atomic_output(out / "comparison_channel.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["condition", "statistic", "quantile", "raytrace", "twin", "twin_model",
                    "tr38901_table"])
        tab = res.channel["tr38901_table"]
        for cond in CONDITIONS:
            a, b = res.channel[rt_m][cond], res.channel[tw_m][cond]
            for key in ("pathloss_db", "ds_ns", "asa_deg", "zsa_deg", "k_db"):
                for qn in ("p10", "p50", "p90"):
                    ref = tab[cond][key] if cond != "all" and qn == "p50" else ""
                    w.writerow([cond, key, qn, (a.get(key) or {}).get(qn),
                                (b.get(key) or {}).get(qn), tw_m, "" if ref is None else ref])
            for key in ("links", "links_with_path_share", "los_share", "paths_per_link_mean"):
                w.writerow([cond, key, "", a.get(key), b.get(key), tw_m, ""])
    label = tr38901.SCENARIO_NAMES[tw_m]
    plot_comparison_cdfs({m: res.benign[m] for m in res.models}, out / "comparison_cdf.png",
                         title=f"benign errors: ray tracing vs {label}")
    plot_comparison_detectors(res.detectors, out / "comparison_detectors.png",
                              title=f"correct decisions: ray tracing (plain) vs {label} (hatched)")
