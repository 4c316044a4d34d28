"""Fidelity sweep (``veriloc-rt bench``): what each speed/accuracy setting costs and buys.

Every setting that trades time for accuracy (DESIGN.md, "Fidelity") is swept one knob at a time
from the config's own values, and each setting is compared with the *reference*, the highest
level of every knob of its group at once, except for the ray-tracing group of the full sweep,
whose reference is the converged setting :data:`RAYTRACE_REFERENCE` (with the largest crop
margin):

* ray tracing (group ``raytrace``): rays per source, maximum depth, diffraction, the edge
  candidates and their plane distance, scene crop margin, and diffuse scattering (a model
  choice: swept, but kept out of the reference, :data:`MODEL_KNOBS`). Cost: tracing seconds per serving link. Deviation from the reference, per link: the
  received power (dB), whether the strongest reference path is found, the first path's delay
  (m), its power relative to the strongest path and its azimuth of arrival (deg), the share of
  links whose path presence differs, and, through the config's chain on the same noise, the DL
  position and the detector decisions;
* waveform and receiver (group ``waveform``, on the CIRs of the config's own propagation
  setting): sample rate, slots per frame, time vs frequency domain, Doppler scan (on/off, step)
  and the delay-profile zero padding. Cost: the chain's CPU seconds per point (the least of
  :data:`TIMING_PASSES` passes, round robin over the
  frequency-domain settings). Deviation: estimated
  first-path delay and AoA per BS, DL position, decisions.

Decisions per point (benign): fix obtained, HMAC tags of every BS valid, ABSA (AoA against the
true geometry) and DL-UL handshake; the agreement is the share of (point, decision) pairs equal
to the reference's. Two settings see the same noise: the ray-tracing group's chains use the
run's noise streams (``stream(seed, "noise", 0, i)``, as ``veriloc-rt run``); the waveform
group's, whose settings differ in sample rate, domain and slots, draw the downlink noise as a
per-RE grid (:func:`~veriloc_rt.studies.diagnostics.benign_chain` with ``shared_noise``), the same on
every RE whatever the setting, and their time-domain settings receive with the OFDM front end
(``channel.time_front_end`` 'ofdm', the fast path's own receiver), so a deviation is the
setting's, not the noise's. A *noise floor* row (the config's setting with other noise draws)
shows how much deviation noise alone produces.

The Pareto front (time against :data:`PARETO_METRIC`: for ray tracing the share of links whose
received power is lost or more than 3 dB off the reference's, for the waveform the share of points
whose DL fix is lost, gained or more than 1 m off the reference's; costs within
:data:`COST_RTOL` count as equal, and one setting is more exact than another only by a sign
test on the units where one of them alone is off, :data:`ACCURACY_ALPHA`) is marked per group;
the chart, a CSV,
JSON and a markdown table are written by :func:`write_bench`.

With ``topology.selection`` 'traced_power' the config's own ray tracing chooses the TRPs of the
evaluated points once (:func:`~veriloc_rt.sim.engine.traced_power_serving`, the run's selection,
from the cache when the run traced them); every setting then traces those serving links.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..config import Config, config_to_dict
from ..constants import SPEED_OF_LIGHT
from ..fileio import atomic_output, atomic_write_text, json_text
from .diagnostics import BenignRun, benign_chain, finite_percentiles, wrap_deg
from ..propagation import link_metrics as lm
from ..world.geometry import build_geometry
from ..sim.engine import traced_power_serving
from .timing import timed_trace
from ..sim.run_folder import run_keys
from ..propagation.antenna import bs_antenna_links
from ..propagation.stochastic import uma_propagation
from ..report.plots import plot_pareto

log = logging.getLogger(__name__)

__all__ = ["Knob", "Setting", "BenchResult", "sweep_settings", "run_bench", "pareto_front", "with_bs_antenna",
           "more_exact", "write_bench", "patched_config", "chain_deviation", "channel_deviation",
           "position_off_units", "power_off_units"]

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class Knob:
    """One fidelity knob: a config field and the levels swept (the last is the highest)."""

    group: str
    name: str
    path: str
    levels: tuple


#: the sweep (full); ``quick`` keeps the levels marked in QUICK_LEVELS
KNOBS = (
    Knob("raytrace", "rays_per_source", "propagation.raytrace.rays_per_source",
         (1_000, 10_000, 50_000, 200_000, 1_000_000)),
    Knob("raytrace", "max_depth", "propagation.raytrace.max_depth", (1, 2, 3, 4, 5)),
    Knob("raytrace", "diffraction", "propagation.raytrace.diffraction", (False, True)),
    Knob("raytrace", "edge_candidates", "propagation.raytrace.edge_candidates",
         ("sampled", "exhaustive", "both")),
    Knob("raytrace", "candidate_plane_distance_m", "propagation.raytrace.candidate_plane_distance_m",
         (20.0, 30.0, 40.0)),
    Knob("raytrace", "scattering_coefficient", "propagation.raytrace.materials.scattering_coefficient",
         (0.0, 0.3)),
    Knob("raytrace", "margin_m", "scene.margin_m", (60.0, 150.0, 200.0, 300.0, 450.0)),
    Knob("waveform", "sample_rate_hz", "nr.sample_rate_hz", (None, 30.72e6, 61.44e6, 122.88e6)),
    Knob("waveform", "slots_per_frame", "nr.slots_per_frame", (2, 5, 10)),
    Knob("waveform", "domain", "channel.domain", ("frequency", "time")),
    Knob("waveform", "doppler_max_hz", "receiver.doppler_max_hz", (0.0, 400.0)),
    Knob("waveform", "doppler_scan", "receiver.doppler_scan", ("channel", "fixed")),
    Knob("waveform", "doppler_step_hz", "receiver.doppler_step_hz",
         (100.0, 50.0, 25.0, 12.5, 6.25)),
    Knob("waveform", "upsample", "receiver.upsample", (1, 2, 4, 8)),
)
#: the accuracy axis of each group's Pareto front: what the group's knobs act on, as the share
#: of units that come out different from the reference (resolution 1 / units). Ray tracing:
#: serving links whose received power is more than POWER_TOL_DB off the reference's, or lost or
#: gained (:func:`channel_deviation`). Power, not the first path's delay: a traced channel that
#: misses its strong paths (found only with many rays: roof-edge diffraction followed by
#: reflections between the street's walls) still has the same first path, so the delay axis
#: showed settings as converged whose per-link power was several dB short and whose strongest
#: path was missing. A share of links rather than a tail percentile of the deviation: a tail
#: percentile of one sample of tens to hundreds moves more between samples than the settings
#: differ (the worst first-path deviation moved from 3 to 82 m between two sweeps of the same
#: settings). With POWER_TOL_DB = 3 dB, "at most 10 % of links off" is the same statement as
#: "p90 |power deviation| <= 3 dB". Waveform and receiver: points whose DL fix is lost, gained or
#: more than POSITION_TOL_M off the reference's fix (the p95 DL deviation of ``upsample`` 1 went
#: from 0.58 m on 48 points to 5.69 m on 120 while the config's stayed at 3.3-3.4 m). Position
#: deviations are not used for ray tracing: they are dominated by the receiver's first-path
#: detection flipping on weak diffracted arrivals
PARETO_METRIC = {"raytrace": "power_off_pct", "waveform": "position_off_pct"}
#: what each Pareto metric is, for the chart's axes
PARETO_LABEL = {"raytrace": "links whose power is > 3 dB off the reference or lost, %",
                "waveform": "points whose DL fix is lost or > 1 m off the reference, %"}
#: a link whose received power is within this of the reference's counts as the same (the
#: accuracy target of the ray-tracing defaults: p90 |power deviation| within 3 dB)
POWER_TOL_DB = 3.0
#: a first path within this of the reference's counts as the same (1 m = 3.3 ns, 1/20 of a
#: sample at 15.36 MHz, below what the receiver resolves)
FIRST_PATH_TOL_M = 1.0
#: a DL fix within this of the reference's counts as the same (the same 1 m: 1/15 of the paper's
#: 15 m success threshold; a first-path decision that flips moves a fix by metres)
POSITION_TOL_M = 1.0
#: relative cost resolution of the front: costs closer than this count as equal. Rows that do
#: the same work (waveform rows that only change ``nr.sample_rate_hz``; ray-tracing crop margins,
#: whose cost does not grow with the crop in the default canyon) were timed up to 7 % apart
#: within one sweep (figures in docs/performance.md), so a setting less
#: than 10 % cheaper is not measurably cheaper on this machine
COST_RTOL = 0.10
#: passes over the points of each frequency-domain waveform setting, round robin over the
#: settings; its cost is the chain's CPU time per point in the least of them. Timed once on the
#: wall clock, the config (the first frequency-domain setting, right after the time-domain
#: reference) came out 4-8 % above the rows that do the same work (other sample rates) in each
#: of three sweeps of 120-240 points; with two passes back to back those rows still spread over
#: 0.090-0.103 s/point on a noisy day (docs/notes/performance-history.md)
TIMING_PASSES = 2
#: accuracy resolution of the front: one setting is more exact than another only if the units
#: off the reference for the other alone outnumber those off for it alone beyond chance, in an
#: exact one-sided sign test at this level (McNemar's test on the paired units: the same points
#: and noise, the same links; :func:`more_exact`). Shares a few units apart are not resolved by
#: a sample of 120: the share of fixes off flipped sign between zero paddings 2 and 4 from one
#: sweep to the next (docs/notes/performance-history.md)
ACCURACY_ALPHA = 0.05
#: time-domain settings apply the paths at sample_rate / TIME_DECIMATION (clipped by the chain to
#: the smallest FFT that holds the band)
TIME_DECIMATION = 8
#: what every time-domain setting adds: decimated path application, and the fast path's own OFDM
#: front end (the shared per-RE noise reaches only the FFT windows)
TIME_DOMAIN_PATCH = {"channel.time_decimation": TIME_DECIMATION, "channel.time_front_end": "ofdm"}
#: the ray-tracing reference of the full sweep: the most complete setting of the convergence
#: study (docs/convergence.md, benchmarks/bench_convergence.py): the exhaustive edge-diffraction
#: candidates together with 1e7 rays per source of Sionna's own, its sampled diffraction
#: included ('both'), at depth 4 (a path of five
#: interactions carries a few % of a link's power). Rays alone converge slowly: a strong path (a
#: roof-edge or corner diffraction, then reflections between the street's walls) is found only
#: by the few rays whose sampled diffraction point sees the BS. ``work_per_call`` lets a UE's
#: three serving links share one PathSolver call. The reference's tracing dominates the sweep's
#: time (``points`` scales it); ``quick`` keeps the highest quick levels instead, which are not
#: converged
RAYTRACE_REFERENCE = {"propagation.raytrace.rays_per_source": 10_000_000,
                      "propagation.raytrace.max_depth": 4,
                      "propagation.raytrace.edge_candidates": "both",
                      "propagation.raytrace.work_per_call": 120_000_000}
#: knobs that change the modelled physics rather than how closely it is computed: swept (their
#: cost and how far they move the channel and the chain), but the reference keeps the config's
#: own value. Diffuse scattering (Sionna RT's effective-roughness model, S^2 of the reflected
#: power scattered; docs/polarization.md) adds power a smooth-wall model does not have, so a
#: reference with it would count every smooth setting as wrong
MODEL_KNOBS = ("scattering_coefficient",)
#: what a scattering setting adds: diffuse tracing (rejected with S = 0), with the rays that
#: sample it (Sionna draws diffuse directions at random: with the default 1e3 rays the scattered
#: power is mostly missed and the row measured the smooth walls' dimming, -0.6 dB median;
#: docs/polarization.md measured the canyon's diffuse power with 5e4)
DIFFUSE_PATCH = {"propagation.raytrace.diffuse_reflection": True,
                 "propagation.raytrace.rays_per_source": 50_000}
QUICK_LEVELS = {
    "rays_per_source": (1_000, 10_000, 200_000),
    "max_depth": (3, 4),
    "candidate_plane_distance_m": (20.0, 30.0),
    "margin_m": (30.0, 60.0, 120.0),
    "sample_rate_hz": (None, 61.44e6, 122.88e6),
    "slots_per_frame": (5, 10),
    "doppler_step_hz": (25.0, 12.5, 6.25),
    "upsample": (2, 4, 8),
}


@dataclass
class Setting:
    """One swept setting and what it measured.

    time_s : cost per unit (``time_unit``: 'link' for ray tracing, 'point' for the chain)
    metrics : deviation statistics from the reference (None entries: not applicable)
    off_units : [U] bool, the units (links or points) off the reference on the group's Pareto
        axis (None: not measured)
    """

    group: str
    knob: str
    value: object
    patch: dict
    role: str = "sweep"            # 'config' | 'reference' | 'sweep' | 'noise floor'
    time_s: float = float("nan")
    time_unit: str = "point"
    metrics: dict = field(default_factory=dict)
    pareto: bool = False
    off_units: np.ndarray | None = None

    @property
    def label(self) -> str:
        if self.role in ("config", "reference", "noise floor"):
            return self.role
        v = self.value
        if isinstance(v, float) and v >= 1e6:
            v = f"{v / 1e6:g} MHz"
        elif v is None:
            v = "min"
        return f"{self.knob}={v}"

    @property
    def key(self) -> tuple[str, str]:
        """(group, label): what identifies the setting within a sweep."""
        return self.group, self.label


@dataclass
class BenchResult:
    settings: list
    meta: dict


def _get(d: dict, path: str):
    for k in path.split("."):
        d = d[k]
    return d


def patched_config(cfg: Config, patch: dict) -> Config:
    """``cfg`` with the fields of ``patch`` (dotted path -> value, as :attr:`Setting.patch`)
    replaced, validated again (:meth:`Config.updated`)."""
    return cfg.updated(patch)


def sweep_settings(cfg: Config, quick: bool = False, groups: tuple[str, ...] | None = None) -> list[Setting]:
    """The settings of the sweep: per group the config's own, the reference, one knob at a time.

    Ray-tracing knobs only when the config ray-traces; ``groups`` restricts the groups.
    """
    base = config_to_dict(cfg)
    avail = ("raytrace", "waveform") if cfg.propagation.model == "raytrace" else ("waveform",)
    groups = tuple(g for g in avail if groups is None or g in groups)
    out: list[Setting] = []
    for g in groups:
        knobs = [k for k in KNOBS if k.group == g]
        levels = {k.name: (QUICK_LEVELS.get(k.name, k.levels) if quick else k.levels) for k in knobs}
        ref_patch = {k.path: levels[k.name][-1] for k in knobs if k.name not in MODEL_KNOBS}
        if g == "waveform":
            # the time domain applies the paths at f_s / 8 after an ideal low-pass: exact inside
            # the band (tests/unit/test_channel.py) and ~8x cheaper with hundreds of paths
            ref_patch.update(TIME_DOMAIN_PATCH)
        if g == "raytrace" and not quick:
            ref_patch.update(RAYTRACE_REFERENCE)
        out.append(Setting(g, "", None, {}, role="config"))
        out.append(Setting(g, "", None, ref_patch, role="reference"))
        for k in knobs:
            own = _get(base, k.path)
            for v in levels[k.name]:
                if v == own:
                    continue  # the config's own setting is the 'config' row
                patch = {k.path: v}
                if k.name == "domain" and v == "time":
                    patch.update(TIME_DOMAIN_PATCH)
                if k.name == "scattering_coefficient" and v > 0:
                    patch.update(DIFFUSE_PATCH)
                out.append(Setting(g, k.name, v, patch))
        if g == "waveform":
            out.append(Setting(g, "noise seed", "other", {}, role="noise floor"))
    return out


# -- measurements ----------------------------------------------------------------------------
def _first_path(cir, point_idx: np.ndarray):
    """First valid path per link: delay [P, B] s and azimuth [P, B] rad (NaN: no path)."""
    d = np.where(cir.valid, cir.delays, np.inf)[point_idx]          # [P, B, paths]
    j = np.argmin(d, axis=-1)
    has = np.isfinite(np.take_along_axis(d, j[..., None], -1)[..., 0])
    tau = np.where(has, np.take_along_axis(d, j[..., None], -1)[..., 0], np.nan)
    az = np.where(has, np.take_along_axis(cir.aoa_az[point_idx], j[..., None], -1)[..., 0], np.nan)
    return tau, az


def _pct(x: np.ndarray) -> tuple[float | None, float | None]:
    q = finite_percentiles(x, (50, 95))
    return q["p50"], q["p95"]


def position_off_units(run: BenignRun, ref: BenignRun) -> np.ndarray:
    """[P] bool, the points whose DL fix is lost, gained or more than POSITION_TOL_M off the
    reference's."""
    fix, fix_r = np.isfinite(run.pos[:, 0]), np.isfinite(ref.pos[:, 0])
    off = fix != fix_r
    both = fix & fix_r
    off[both] |= np.linalg.norm(run.pos - ref.pos, axis=1)[both] > POSITION_TOL_M
    return off


def power_off_units(cir, ref_cir, points: np.ndarray) -> np.ndarray:
    """[L] bool, the serving links whose received power is more than POWER_TOL_DB off the
    reference's, or lost or gained (an infinite deviation)."""
    d = lm.link_deviation(lm.cir_link_arrays(cir, points), lm.cir_link_arrays(ref_cir, points))
    return np.abs(d["power_dev_db"]) > POWER_TOL_DB


def chain_deviation(run: BenignRun, ref: BenignRun) -> dict:
    """Deviation of a setting's chain outputs from the reference's on the same points: RSTD
    (``rstd_dev_m_p50``/``_p95``, m), AoA (``aoa_dev_deg_*``), position (``position_dev_m_*``
    over the points both fix), ``fix_mismatch_pct``, ``position_off_pct`` (fix lost, gained or
    more than POSITION_TOL_M off) and ``decision_agreement_pct``."""
    # ToA differences are only meaningful relative to a BS of the same point: compare RSTDs
    # (each BS against the reference BS 0), which is what positioning uses
    rstd = (run.toa - run.toa[:, :1]) - (ref.toa - ref.toa[:, :1])
    fp = np.abs(rstd[:, 1:]) * SPEED_OF_LIGHT
    aoa = wrap_deg(run.az - ref.az)
    both = np.isfinite(run.pos[:, 0]) & np.isfinite(ref.pos[:, 0])
    pos = np.linalg.norm(run.pos - ref.pos, axis=1)[both]
    out = {}
    out["rstd_dev_m_p50"], out["rstd_dev_m_p95"] = _pct(fp)
    out["aoa_dev_deg_p50"], out["aoa_dev_deg_p95"] = _pct(aoa)
    out["position_dev_m_p50"], out["position_dev_m_p95"] = _pct(pos)
    fix, fix_r = np.isfinite(run.pos[:, 0]), np.isfinite(ref.pos[:, 0])
    out["fix_mismatch_pct"] = float(100 * np.mean(fix != fix_r))
    off = position_off_units(run, ref)
    out["position_off_pct"] = float(100 * np.mean(off)) if off.size else None
    out["decision_agreement_pct"] = float(100 * np.mean(run.decisions == ref.decisions))
    return out


def channel_deviation(cir, ref_cir, points: np.ndarray) -> dict:
    """Deviation of the serving links' channels from the reference's, per link
    (:mod:`~veriloc_rt.propagation.link_metrics`):

    * received power: ``power_dev_db_p50`` the signed median of 10 log10(P / P_ref) (negative:
      power the setting misses), ``power_absdev_db_p90`` the p90 of its magnitude,
      ``power_off_pct`` the share of links more than POWER_TOL_DB off (a link that lost or
      gained all its paths counts as off, and as an infinite deviation in the percentiles);
    * ``strongest_found_pct``: share of the links with a reference path whose strongest
      reference path the setting has (same interaction sequence, same delay);
    * first path: delay deviation (m) and share lost, gained or more than FIRST_PATH_TOL_M off;
      its power relative to the link's strongest path (``first_rel_power_db_p50``, the
      setting's own median, dB) and that ratio's deviation from the reference's
      (``first_rel_power_absdev_db_p90``);
    * first-path AoA deviation, share of links whose path presence differs.
    """

    tau, az = _first_path(cir, points)
    tau_r, az_r = _first_path(ref_cir, points)
    out = {}
    out["first_path_dev_m_p50"], out["first_path_dev_m_p95"] = _pct(np.abs(tau - tau_r) * SPEED_OF_LIGHT)
    out["first_path_aoa_dev_deg_p50"], out["first_path_aoa_dev_deg_p95"] = _pct(wrap_deg(az - az_r))
    out["path_presence_mismatch_pct"] = float(100 * np.mean(np.isfinite(tau) != np.isfinite(tau_r)))
    # the worst link, a link that lost or gained its path counting as infinitely wrong
    dev = np.where(np.isfinite(tau) & np.isfinite(tau_r), np.abs(tau - tau_r) * SPEED_OF_LIGHT,
                   np.where(np.isfinite(tau) | np.isfinite(tau_r), np.inf, 0.0))
    out["first_path_dev_m_max"] = float(dev.max()) if dev.size else None
    out["first_path_off_pct"] = float(100 * np.mean(dev > FIRST_PATH_TOL_M)) if dev.size else None
    out["links_with_path_pct"] = float(100 * np.mean(np.isfinite(tau)))
    d = lm.link_deviation(lm.cir_link_arrays(cir, points), lm.cir_link_arrays(ref_cir, points))
    p = d["power_dev_db"]
    out["power_dev_db_p50"] = lm.quantile(p, 50)
    out["power_absdev_db_p90"] = lm.quantile(np.abs(p), 90)
    out["power_off_pct"] = float(100 * np.mean(np.abs(p) > POWER_TOL_DB)) if p.size else None
    found = d["strongest_found"]
    out["strongest_found_pct"] = float(100 * np.nanmean(found)) if np.isfinite(found).any() else None
    out["first_rel_power_db_p50"] = lm.quantile(d["first_rel_db"], 50)
    out["first_rel_power_absdev_db_p90"] = lm.quantile(np.abs(d["first_rel_db"] - d["first_rel_db_ref"]), 90)
    return out


def _geometry(cfg: Config, scene_root: Path):
    key = f"margin_{cfg.scene.margin_m:g}"
    return build_geometry(cfg, scene_root / key)


def _trace(cfg: Config, geometry, points: np.ndarray, repeats: int = 2):
    """The serving links' CIRs at ``points`` (the other points' links are not traced), through
    the config's BS antennas (:func:`with_bs_antenna`), and the warm cost per link: the fastest
    of ``repeats`` identical traces (:func:`timed_trace`)."""
    prop, best = timed_trace(geometry, cfg, points, adversary=False, repeats=repeats)
    return (with_bs_antenna(prop.bs_ue, cfg, geometry),
            best / (geometry.serving.shape[1] * np.unique(points).size))


def with_bs_antenna(bs_ue, cfg: Config, geometry):
    """The BS -> UE CIRs ``bs_ue`` through ``cfg.topology``'s BS antennas, as a run applies them
    (:func:`~veriloc_rt.propagation.antenna.bs_antenna_links`); isotropic: ``bs_ue`` itself."""
    return bs_antenna_links(bs_ue, geometry, cfg.topology)


def run_bench(cfg: Config, out_dir: str | Path, quick: bool = False, points: int | None = None,
              progress: Progress | None = None, groups: tuple[str, ...] | None = None) -> BenchResult:
    """Sweep the fidelity settings of ``cfg`` (see the module docstring).

    :param points: trajectory points evaluated (default: 6 with ``quick``, else 40; at most the
        config's trajectory)
    """

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    n_pts = points if points is not None else (6 if quick else 40)
    n_pts = int(min(n_pts, cfg.trajectory.num_points))
    if n_pts < 2:
        raise ValueError(f"Argument `points` must be >= 2, not {n_pts}")
    settings = sweep_settings(cfg, quick, groups)
    if not settings:
        raise ValueError(f"Argument `groups` {groups} selects no sweep for this config")
    timed_again = [s for s in settings if s.group == "waveform"
                   and patched_config(cfg, s.patch).channel.domain != "time"]
    total = len(settings) + (TIMING_PASSES - 1) * len(timed_again)
    geo0 = _geometry(cfg, out / "scenes")
    idx = np.unique(np.linspace(0, geo0.num_points - 1, n_pts).round().astype(int))
    if geo0.candidates is not None:
        # topology.selection 'traced_power': the config's own trace chooses the TRPs of the
        # evaluated points once; every setting then traces those links (the same TRPs)
        geo0, _ = traced_power_serving(cfg, geo0, points=idx, adversary=False)
        geo0 = replace(geo0, candidates=None)
    keys = run_keys(cfg, len(geo0.bs_pos))
    t_start = time.perf_counter()
    done = 0
    if progress:
        progress("bench", 0, total)

    def tick(label: str) -> None:
        nonlocal done
        done += 1
        if progress:
            progress("bench", done, total)
        log.info("bench %d/%d: %s", done, total, label)

    # the config's own propagation: the waveform group's CIRs
    if cfg.propagation.model == "raytrace":
        bs_ue0, t_link0 = _trace(cfg, geo0, idx)
    else:
        t = time.perf_counter()
        bs_ue0 = with_bs_antenna(uma_propagation(geo0, cfg.propagation, cfg.seed).bs_ue, cfg, geo0)
        t_link0 = (time.perf_counter() - t) / geo0.serving.size

    # each setting's CIRs and chain run, keyed by its (group, label): unique within a sweep
    runs: dict[tuple[str, str], BenignRun] = {}
    cirs: dict[tuple[str, str], object] = {}
    # ray-tracing group: trace, then the config's chain on the traced CIRs
    rt = [s for s in settings if s.group == "raytrace"]
    for s in sorted(rt, key=lambda s: s.role != "reference"):   # reference first
        c = patched_config(cfg, s.patch)
        geo = geo0
        if c.scene.margin_m != cfg.scene.margin_m:
            geo = replace(_geometry(c, out / "scenes"), serving=geo0.serving, candidates=None)
        if not np.allclose(geo.ue.pos, geo0.ue.pos):
            raise RuntimeError(f"{s.label}: the trajectory depends on the crop margin")
        if s.role == "config":
            bs_ue, t_link = bs_ue0, t_link0
        else:
            # the reference is traced once: its cost is only reported, and it is the sweep's
            # costliest setting by far
            bs_ue, t_link = _trace(c, geo, idx, repeats=1 if s.role == "reference" else 2)
        s.time_s, s.time_unit = t_link, "link"
        cirs[s.key] = bs_ue
        runs[s.key] = benign_chain(cfg, geo0, bs_ue, keys, idx)
        tick(s.label)
    if rt:
        ref = next(s for s in rt if s.role == "reference")
        for s in rt:
            s.metrics = channel_deviation(cirs[s.key], cirs[ref.key], idx)
            s.metrics.update(chain_deviation(runs[s.key], runs[ref.key]))
            s.off_units = power_off_units(cirs[s.key], cirs[ref.key], idx)
    # waveform group, on the config's CIRs
    wf = sorted((s for s in settings if s.group == "waveform"), key=lambda s: s.role != "reference")

    def chain_run(s: Setting) -> BenignRun:
        return benign_chain(patched_config(cfg, s.patch), geo0, bs_ue0, keys, idx, shared_noise=True,
                            noise="noise-floor" if s.role == "noise floor" else "noise")

    for s in wf:
        r = chain_run(s)
        s.time_s, s.time_unit = r.seconds_per_point, "point"
        runs[s.key] = r
        tick(s.label)
    # the settings near the front's cost (the frequency domain; the time domain costs tens of
    # times the config) run TIMING_PASSES - 1 more passes, round robin over the settings: a slow
    # spell of the machine then slows one pass of several settings, not every pass of one. The
    # cost is the least pass's; every pass must give the first one's results
    for _ in range(TIMING_PASSES - 1):
        for s in timed_again:
            r = chain_run(s)
            if not runs[s.key].same_results(r):
                raise RuntimeError(f"{s.label}: a later pass differs from the first: the chain "
                                   "keeps state from run to run")
            s.time_s = min(s.time_s, r.seconds_per_point)
            tick(f"{s.label} (timing pass)")
    ref = next((s for s in wf if s.role == "reference"), None)
    own = next((s for s in wf if s.role == "config"), None)
    for s in wf:
        # the noise floor is the config's setting against itself with other noise draws
        base = own if s.role == "noise floor" else ref
        s.metrics = chain_deviation(runs[s.key], runs[base.key])
        s.off_units = position_off_units(runs[s.key], runs[base.key])
    for g in {s.group for s in settings}:
        grp = [s for s in settings if s.group == g and s.role != "noise floor"]
        front = pareto_front([s.time_s for s in grp], [s.metrics.get(PARETO_METRIC[g]) for s in grp],
                             cost_rtol=COST_RTOL,
                             better=more_exact([s.off_units for s in grp], ACCURACY_ALPHA))
        for s, f in zip(grp, front):
            s.pareto = bool(f)
    meta = {"points": idx.tolist(), "num_points": int(idx.size), "quick": quick,
            "serving": geo0.serving[idx].tolist(),   # BS ids each evaluated point measures
            "propagation_model": cfg.propagation.model, "seed": cfg.seed,
            "wall_s": time.perf_counter() - t_start,
            "reference": {g: next(s.patch for s in settings if s.group == g and s.role == "reference")
                          for g in {s.group for s in settings}}}
    return BenchResult(settings, meta)


def pareto_front(cost, error, cost_rtol: float = 0.0, better=None) -> np.ndarray:
    """[n] bool, not dominated: no other point is at most as costly and at most as wrong, and
    strictly better in one. Points without an error (None/NaN) are never on the front; an
    error of 0 (the reference against itself) is a valid point.

    :param cost_rtol: relative cost resolution (>= 0): j is cheaper than i only if
        ``c_j * (1 + cost_rtol) < c_i``; costs closer than that count as equal, so j dominates i
        by cost only when clearly cheaper, or by error alone at an equal cost
    :param better: [n, n] bool, ``better[j, i]``: j is more exact than i (the accuracy
        resolution, :func:`more_exact`); None: a lower error. j dominates i when it is not less
        exact and either clearly cheaper or, at an equal cost, more exact
    """
    if not cost_rtol >= 0:
        raise ValueError(f"Argument `cost_rtol` must be >= 0, not {cost_rtol}")
    c = np.asarray(cost, dtype=float)
    e = np.asarray([np.nan if v is None else v for v in error], dtype=float)
    ok = np.isfinite(c) & np.isfinite(e)
    b = e[:, None] < e[None, :] if better is None else np.asarray(better, dtype=bool)
    if b.shape != (c.size, c.size):
        raise ValueError(f"Argument `better` must be [{c.size}, {c.size}], not {b.shape}")
    front = np.zeros(c.size, dtype=bool)
    for i in np.flatnonzero(ok):
        cheaper = c * (1 + cost_rtol) < c[i]
        same = ~cheaper & (c <= c[i] * (1 + cost_rtol))
        dom = ok & ~b[i, :] & (cheaper | (same & b[:, i]))
        front[i] = not np.any(dom)
    return front


def more_exact(off_units, alpha: float) -> np.ndarray:
    """[n, n] bool, ``[j, i]``: setting j is off the reference on fewer of the same units than
    setting i beyond chance. Of the units where exactly one of the two is off (the discordant
    pairs of McNemar's test), i alone is off on b and j alone on c; j is more exact when
    P(X >= b) < ``alpha`` for X ~ Binomial(b + c, 1/2) (the exact one-sided sign test,
    :func:`scipy.stats.binomtest`). Settings without units (None) are never more exact, nor
    less.

    :param off_units: per setting [U] bool (the same U units for all) or None
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"Argument `alpha` must be in (0, 1), not {alpha}")
    from scipy.stats import binomtest

    units = [None if u is None else np.asarray(u, dtype=bool) for u in off_units]
    n = len(units)
    out = np.zeros((n, n), dtype=bool)
    for j, fj in enumerate(units):
        for i, fi in enumerate(units):
            if i == j or fj is None or fi is None:
                continue
            if fj.shape != fi.shape:
                raise ValueError(f"settings {j} and {i} have {fj.shape} and {fi.shape} units")
            b, c = int(np.sum(fi & ~fj)), int(np.sum(fj & ~fi))
            out[j, i] = b > c and binomtest(b, b + c, 0.5, alternative="greater").pvalue < alpha
    return out


# -- reporting -------------------------------------------------------------------------------
CSV_FIELDS = ("group", "knob", "value", "role", "label", "time_s", "time_unit", "pareto",
              "power_dev_db_p50", "power_absdev_db_p90", "power_off_pct", "strongest_found_pct",
              "first_rel_power_db_p50", "first_rel_power_absdev_db_p90", "first_path_dev_m_p50",
              "first_path_dev_m_p95", "first_path_dev_m_max",
              "first_path_off_pct", "first_path_aoa_dev_deg_p50",
              "first_path_aoa_dev_deg_p95", "path_presence_mismatch_pct", "links_with_path_pct",
              "rstd_dev_m_p50", "rstd_dev_m_p95", "aoa_dev_deg_p50", "aoa_dev_deg_p95",
              "position_dev_m_p50", "position_dev_m_p95", "position_off_pct", "fix_mismatch_pct",
              "decision_agreement_pct")


def _row(s: Setting) -> dict:
    r = {"group": s.group, "knob": s.knob, "value": s.value, "role": s.role, "label": s.label,
         "time_s": s.time_s, "time_unit": s.time_unit, "pareto": s.pareto}
    r.update({k: s.metrics.get(k) for k in CSV_FIELDS if k not in r})
    # bench.json only: which units are off on the Pareto axis (1), to redo the front's tests
    r["off_units"] = None if s.off_units is None else np.asarray(s.off_units, dtype=int).tolist()
    return r


def _fmt(v, nd=2) -> str:
    if isinstance(v, float) and np.isinf(v):
        return "inf" if v > 0 else "-inf"   # a link lost or gained its paths
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else ""
    if isinstance(v, float):
        return f"{v:.{nd}f}"
    return str(v)


def _pair(a: str, b: str, nd: int = 2):
    return lambda s: f"{_fmt(s.metrics.get(a), nd)} / {_fmt(s.metrics.get(b), nd)}"


def _one(key: str, nd: int = 2):
    return lambda s: _fmt(s.metrics.get(key), nd)


#: markdown columns per group: (header, cell of a Setting)
_MD_COLUMNS = {
    "raytrace": [("setting", lambda s: s.label), ("s/link", lambda s: _fmt(s.time_s, 4)),
                 ("links with a path %", _one("links_with_path_pct", 1)),
                 ("power dev. p50 (signed) / p90 abs dB",
                  _pair("power_dev_db_p50", "power_absdev_db_p90", 1)),
                 ("power > 3 dB off or lost %", _one("power_off_pct", 1)),
                 ("strongest path found %", _one("strongest_found_pct", 1)),
                 ("first path off > 1 m or lost %", _one("first_path_off_pct", 1)),
                 ("first path dev. p95 / worst m", _pair("first_path_dev_m_p95", "first_path_dev_m_max")),
                 ("first / strongest p50 dB, dev. p90 dB", _pair("first_rel_power_db_p50",
                                                                 "first_rel_power_absdev_db_p90", 1)),
                 ("first-path AoA dev. p95 deg", _one("first_path_aoa_dev_deg_p95", 1)),
                 ("position dev. p50 / p95 m", _pair("position_dev_m_p50", "position_dev_m_p95")),
                 ("decisions agree %", _one("decision_agreement_pct", 1)),
                 ("Pareto", lambda s: _fmt(s.pareto))],
    "waveform": [("setting", lambda s: s.label), ("s/point", lambda s: _fmt(s.time_s, 3)),
                 ("RSTD dev. p95 m", _one("rstd_dev_m_p95")),
                 ("AoA dev. p95 deg", _one("aoa_dev_deg_p95", 1)),
                 ("position dev. p50 / p95 m", _pair("position_dev_m_p50", "position_dev_m_p95")),
                 ("fix lost or > 1 m off %", _one("position_off_pct", 1)),
                 ("decisions agree %", _one("decision_agreement_pct", 1)),
                 ("Pareto", lambda s: _fmt(s.pareto))],
}


def markdown_table(res: BenchResult) -> str:
    lines = []
    for g in ("raytrace", "waveform"):
        grp = [s for s in res.settings if s.group == g]
        if not grp:
            continue
        cols = _MD_COLUMNS[g]
        lines += ["| " + " | ".join(h for h, _ in cols) + " |", "|" + " --- |" * len(cols)]
        for s in grp:
            lines.append("| " + " | ".join(f(s) for _, f in cols) + " |")
        lines.append("")
    return "\n".join(lines)


def write_bench(res: BenchResult, out_dir: str | Path) -> dict:
    """bench.csv, bench.json, bench.md and bench_pareto.png in ``out_dir``; returns the paths."""
    import csv

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = [_row(s) for s in res.settings]
    # every file through a temporary file renamed over it: a stopped bench leaves no half file
    with atomic_output(out / "bench.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r[k] is None else r[k]) for k in CSV_FIELDS})
    atomic_write_text(out / "bench.json", json_text({"meta": res.meta, "settings": rows}))
    md = (f"# Fidelity sweep ({res.meta['num_points']} points, propagation "
          f"{res.meta['propagation_model']}, seed {res.meta['seed']})\n\n"
          "Deviations are from the reference (highest level of every knob of the group; for "
          "ray tracing outside --quick the converged setting of docs/convergence.md: "
          + ", ".join(f"{k.rsplit('.', 1)[-1]} {v if isinstance(v, str) else format(v, 'g')}"
                      for k, v in RAYTRACE_REFERENCE.items())
          + "). Power deviations are 10 log10(P / P_ref) per link: p50 signed, p90 of the "
          "magnitude. "
          "The noise-floor row is the config's setting against itself with other noise draws.\n\n"
          + markdown_table(res))
    atomic_write_text(out / "bench.md", md)
    plot_pareto(rows, out / "bench_pareto.png",
                {g: (PARETO_METRIC[g], PARETO_LABEL[g]) for g in PARETO_METRIC})
    return {k: out / k for k in ("bench.csv", "bench.json", "bench.md", "bench_pareto.png")}
