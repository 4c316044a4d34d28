"""Ray tracing against TR 38.901 UMa on the same topology, trajectory and attacks.

:func:`run_compare` runs the config twice with :func:`veriloc_rt.sim.engine.run`, once with
``propagation.model = 'raytrace'`` and once with ``'uma'`` (the config's ``uma_mode``), into
``<out>/raytrace`` and ``<out>/uma``; geometry, keys, noise streams and adversary draws are the
same, only the channel differs. It then reports, side by side:

* channel statistics of the serving links (LoS share, paths per link, rms delay spread, circular
  azimuth and zenith spreads of arrival (TR 38.901 Annex A.1), Ricean K-factor of LoS links)
  next to the TR 38.901 UMa values (Table 7.5-6 medians at the carrier);
* benign-chain errors per point (:func:`veriloc_rt.studies.diagnostics.benign_chain`, the ``none``
  scenario's chain): ToA bias against the straight-line delay, RSTD error, AoA error, DL
  position error (CDFs);
* the detectors' correct-decision rates and outcome shares per scenario from both runs.

Files: ``comparison.md``, ``comparison.json``, ``comparison_points.csv`` (per point and BS),
``comparison_channel.csv``, ``comparison_cdf.png``, ``comparison_detectors.png``.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..config import Config
from ..fileio import atomic_output, atomic_write_text
from .diagnostics import BenignRun, benign_chain, finite_percentiles
from ..report.propagation_summary import rms_delay_spread
from ..propagation.uma_params import lsp_statistics
from ..sim.engine import run
from ..sim.run_folder import run_keys
from ..detectors.outcomes import DETECTORS, OUTCOMES
from ..report.plots import plot_comparison_cdfs, plot_comparison_detectors

log = logging.getLogger(__name__)

__all__ = ["ComparisonResult", "run_compare", "channel_statistics", "uma_reference_statistics",
           "format_comparison"]

MODELS = ("raytrace", "uma")
Progress = Callable[[str, int, int], None]


@dataclass
class ComparisonResult:
    out_dir: Path
    channel: dict        # {model: stats}, plus "uma_table": {"los": .., "nlos": ..}
    errors: dict         # {model: {quantity: {p50, p95, ...}}}
    detectors: dict      # {model: metrics.json "scenarios"}
    benign: dict         # {model: BenignRun}
    timing_s: dict


def _circular_spread_deg(w: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """TR 38.901 Annex A.1 circular angle spread, deg: sqrt(-2 ln |sum_n w_n e^{j phi_n}|)."""
    r = np.abs(np.sum(w * np.exp(1j * ang), axis=-1))
    return np.degrees(np.sqrt(-2.0 * np.log(np.clip(r, 1e-300, 1.0))))


def channel_statistics(cir) -> dict:
    """Per-link statistics of the serving links that have a path.

    :returns: {"links", "links_with_path_pct", "los_pct", "paths_per_link_mean",
        "ds_ns": {p10, p50, p90}, "asa_deg": .., "zsa_deg": .., "k_db": .. (LoS links)}
    """
    used = cir.tx_index != -1
    has = cir.has_path() & used
    out = {"links": int(used.sum()),
           "links_with_path_pct": 100.0 * float(has.sum()) / max(int(used.sum()), 1)}
    if not has.any():
        return out
    pw = cir.path_power()[has]                                   # [L, paths]
    w = pw / pw.sum(-1, keepdims=True)
    tau = np.where(cir.valid[has], cir.delays[has], 0.0)
    ds = rms_delay_spread(cir)[has]
    asa = _circular_spread_deg(w, cir.aoa_az[has])
    zsa = _circular_spread_deg(w, cir.aoa_zen[has])
    los = cir.los[has]
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

    out.update({"los_pct": 100.0 * float(los.mean()),
                "paths_per_link_mean": float(cir.valid[has].sum(-1).mean()),
                "ds_ns": q(ds * 1e9), "asa_deg": q(asa), "zsa_deg": q(zsa), "k_db": q(k_db)})
    return out


def uma_reference_statistics(fc_hz: float, d_2d_m: float = 200.0, h_ut_m: float = 1.5) -> dict:
    """TR 38.901 Table 7.5-6 UMa medians (10^mu of the lg parameters; K in dB), LoS and NLoS."""

    out = {}
    for los in (True, False):
        mu, sd = lsp_statistics(los, fc_hz, [d_2d_m], h_ut_m)
        out["los" if los else "nlos"] = {
            "ds_ns": float(10 ** mu[0, 2] * 1e9), "asa_deg": float(10 ** mu[0, 4]),
            "zsa_deg": float(10 ** mu[0, 6]),
            "k_db": float(mu[0, 1]) if los else None}
    return out


def _q(x) -> dict:
    x = np.asarray(x, float).ravel()
    x = x[np.isfinite(x)]
    return {"n": int(x.size), **finite_percentiles(x, (50, 95)),
            "mean": float(x.mean()) if x.size else None}


def error_statistics(b: BenignRun) -> dict:
    return {"toa_bias_m": _q(b.toa_bias_m), "rstd_error_m": _q(b.rstd_error_m),
            "rstd_abs_error_m": _q(np.abs(b.rstd_error_m)),
            "aoa_error_deg": _q(b.aoa_error_deg), "position_error_m": _q(b.position_error_m),
            "fix_rate_pct": float(100 * np.mean(np.isfinite(b.pos[:, 0]))) if len(b.pos) else None}


def run_compare(cfg: Config, out_dir: str | Path, progress: Progress | None = None,
                workers: int = 1) -> ComparisonResult:
    """Run ``cfg`` on ray tracing and on UMa and compare (see the module docstring)."""
    import time

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    timing: dict = {}
    channel, errors, detectors, benign = {}, {}, {}, {}
    for model in MODELS:
        c = cfg.replace(propagation=dataclasses.replace(cfg.propagation, model=model))
        t = time.perf_counter()
        # its own sub-folders: replaced by every compare into this --out, as its other files
        res = run(c, out / model, progress=progress, workers=workers, force=True)
        timing[f"run_{model}"] = time.perf_counter() - t
        keys = run_keys(c, len(res.geometry.bs_pos))
        t = time.perf_counter()
        cb = (lambda d, n, m=model: progress(f"chain {m}", d, n)) if progress else None
        b = benign_chain(c, res.geometry, res.propagation.bs_ue, keys,
                         np.arange(res.geometry.num_points), progress=cb)
        timing[f"diagnostics_{model}"] = time.perf_counter() - t
        channel[model] = channel_statistics(res.propagation.bs_ue)
        errors[model] = error_statistics(b)
        detectors[model] = res.metrics["scenarios"]
        benign[model] = b
    if not np.allclose(benign["raytrace"].truth, benign["uma"].truth):
        raise RuntimeError("the two runs have different trajectories")
    channel["uma_table"] = uma_reference_statistics(cfg.propagation.carrier_frequency_hz)
    result = ComparisonResult(out, channel, errors, detectors, benign, timing)
    _write(result, cfg)
    return result


# -- reporting -------------------------------------------------------------------------------
def _f(v, nd=1) -> str:
    return "n/a" if v is None else f"{v:.{nd}f}"


def markdown(res: ComparisonResult) -> str:
    ch, er, dt = res.channel, res.errors, res.detectors
    tab = ch["uma_table"]
    L = ["## Channel of the serving links", "",
         "| statistic | ray tracing | UMa (drawn) | TR 38.901 UMa LoS | TR 38.901 UMa NLoS |",
         "| --- | --- | --- | --- | --- |"]
    L.append(f"| links with a path, % | {_f(ch['raytrace'].get('links_with_path_pct'))} | "
             f"{_f(ch['uma'].get('links_with_path_pct'))} | | |")
    L.append(f"| LoS links, % | {_f(ch['raytrace'].get('los_pct'))} | {_f(ch['uma'].get('los_pct'))} | | |")
    L.append(f"| paths per link (mean) | {_f(ch['raytrace'].get('paths_per_link_mean'))} | "
             f"{_f(ch['uma'].get('paths_per_link_mean'))} | | |")
    for key, name in (("ds_ns", "rms delay spread, ns"), ("asa_deg", "azimuth spread of arrival, deg"),
                      ("zsa_deg", "zenith spread of arrival, deg"), ("k_db", "K-factor (LoS links), dB")):
        rt, um = ch["raytrace"].get(key) or {}, ch["uma"].get(key) or {}
        L.append(f"| {name}, p50 [p10, p90] | {_f(rt.get('p50'))} [{_f(rt.get('p10'))}, {_f(rt.get('p90'))}] | "
                 f"{_f(um.get('p50'))} [{_f(um.get('p10'))}, {_f(um.get('p90'))}] | "
                 f"{_f(tab['los'][key])} | {_f(tab['nlos'][key])} |")
    L += ["", "TR 38.901 columns: Table 7.5-6 medians (10^mu of the lg parameters) at the carrier.", "",
          "## Benign chain errors (scenario none, standard PRS)", "",
          "| quantity | ray tracing p50 / p95 | UMa p50 / p95 |", "| --- | --- | --- |"]
    for key, name in (("position_error_m", "DL position error, m"), ("toa_bias_m", "ToA bias vs LoS delay, m"),
                      ("rstd_abs_error_m", "|RSTD error|, m"), ("aoa_error_deg", "AoA error, deg")):
        a, b = er["raytrace"][key], er["uma"][key]
        L.append(f"| {name} | {_f(a['p50'], 2)} / {_f(a['p95'], 2)} | {_f(b['p50'], 2)} / {_f(b['p95'], 2)} |")
    L.append(f"| DL fix rate, % | {_f(er['raytrace']['fix_rate_pct'])} | {_f(er['uma']['fix_rate_pct'])} |")
    L += ["", "## Detectors (correct-decision rate, %) and outcomes (standard PRS, %)", "",
          "| scenario | model | " + " | ".join(DETECTORS) + " | " + " | ".join(OUTCOMES) + " |",
          "| --- | --- | " + " | ".join("---" for _ in DETECTORS + OUTCOMES) + " |"]
    for scen in dt["raytrace"]:
        for model in MODELS:
            m = dt[model].get(scen) or {}
            if not m.get("num_points"):
                continue
            rates = " | ".join(_f(m["correct_decision_rate"].get(d)) for d in DETECTORS)
            outs = " | ".join(_f(m["outcomes"].get(o)) for o in OUTCOMES)
            L.append(f"| {scen} | {model} | {rates} | {outs} |")
    return "\n".join(L) + "\n"


def format_comparison(res: ComparisonResult) -> str:
    return markdown(res)


def _write(res: ComparisonResult, cfg: Config) -> None:
    out = res.out_dir
    # every file through a temporary file renamed over it: a stopped compare leaves no half file
    atomic_write_text(
        out / "comparison.md",
        f"# Ray tracing vs TR 38.901 UMa ({len(res.benign['raytrace'].points)} points, seed "
        f"{cfg.seed}, UMa mode {cfg.propagation.uma_mode})\n\n" + markdown(res))
    atomic_write_text(out / "comparison.json", json.dumps(
        {"channel": res.channel, "errors": res.errors, "detectors": res.detectors,
         "timing_s": res.timing_s}, indent=2))
    with atomic_output(out / "comparison_points.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["model", "point", "bs", "toa_bias_m", "rstd_error_m", "aoa_error_deg",
                    "position_error_m"])
        for model in MODELS:
            b = res.benign[model]
            rstd = np.concatenate([np.full((len(b.points), 1), np.nan), b.rstd_error_m], axis=1)
            for r, i in enumerate(b.points):
                for j in range(b.toa.shape[1]):
                    w.writerow([model, int(i), j, b.toa_bias_m[r, j], rstd[r, j],
                                b.aoa_error_deg[r, j], b.position_error_m[r]])
    with atomic_output(out / "comparison_channel.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["statistic", "quantile", "raytrace", "uma", "tr38901_los", "tr38901_nlos"])
        tab = res.channel["uma_table"]
        for key in ("ds_ns", "asa_deg", "zsa_deg", "k_db"):
            for qn in ("p10", "p50", "p90"):
                w.writerow([key, qn, (res.channel["raytrace"].get(key) or {}).get(qn),
                            (res.channel["uma"].get(key) or {}).get(qn),
                            tab["los"][key] if qn == "p50" else "", tab["nlos"][key] if qn == "p50" else ""])
        for key in ("links_with_path_pct", "los_pct", "paths_per_link_mean"):
            w.writerow([key, "", res.channel["raytrace"].get(key), res.channel["uma"].get(key), "", ""])
    plot_comparison_cdfs({m: res.benign[m] for m in MODELS}, out / "comparison_cdf.png")
    plot_comparison_detectors(res.detectors, out / "comparison_detectors.png")
