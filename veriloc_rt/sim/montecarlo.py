"""Monte Carlo over topology realisations, serially or as tasks on Dask (``dask.distributed``).

``run.realisations = n`` runs the config ``n`` times; realisation ``r`` is a complete run
(:func:`veriloc_rt.sim.engine.run`) of :func:`realisation_config`: BS layout
``topology.iteration + r`` and, for ``r >= 1``, its own seed derived from ``(seed,
topology.iteration + r)``, so its trajectory (a new drive, when generated), building heights
(with ``scene.height_jitter_m`` > 0), propagation, noise, adversary and key draws are new as
well, and the realisations are independent samples. Scene variants of the procedural canyon:
``run.street_width_variants_m`` and ``run.height_jitter_variants_m`` give realisation ``r``
entry ``r mod len`` of each list. Realisation 0 is exactly the plain run of the config (with
the first scene variant, when listed). Every draw still comes from the one config seed.

Each realisation is one task and writes a single run's files into ``out/realisation_NNN/``
(its ``run.json`` holds the realisation's resolved config: it reproduces alone). The numbers
do not depend on where a realisation runs: serially (``workers=1``), on a local cluster
(``workers > 1``) or on an existing one (``scheduler``; its workers must see ``out`` and
any input files under the same paths). At the end ``out/`` gets:

* ``metrics.json``: a single run's keys, each value the mean over the realisations where it
  is defined, plus per scenario ``ci95`` (Student-t 95 % half-width, None below two
  realisations) and ``realisations_defined`` with the same layout, and ``realisations``
  (``position_error_m``: the mean of the realisations' percentiles, not a pooled percentile);
  every share's ``<key>_ci95`` is ``[mean - half, mean + half]`` clipped to [0, 1] (the spread
  between the realisations; each realisation's own metrics.json holds its binomial interval
  over its points); ``roc``: per attack and decision the mean AUC, detection rate at the
  target false alarm and operating point, each with a bootstrap interval over the
  realisations;
* ``montecarlo.csv``: one row per realisation and scenario with the headline numbers;
* ``montecarlo_detection_rates.png`` (mean correct-decision rates with CI bars),
  ``outcomes.png`` (mean outcomes) and ``run.json``.
"""

from __future__ import annotations

import csv
import logging
import math
import time
import uuid
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..config import Config
from ..detectors.outcomes import DETECTORS, OUTCOMES
from ..errors import InputError
from ..fileio import atomic_output, atomic_write_text, json_text
from ..inputs import parse_json, read_text
from ..report import plots
from ..analysis.intervals import CI_SUFFIX, bootstrap_mean_ci, ci_suffix
from ..rng import stream
from .engine import Progress, run
from .blas import one_blas_thread
from .executors import check_workers, local_cluster, named_failures, scheduler_client
from .run_folder import (MAX_RUN_JSON_BYTES, check_fresh, check_resume, check_run_files,
                         clear_run_files, locked, mark_stopped, read_run_json, same_config,
                         write_run_json)

log = logging.getLogger(__name__)

__all__ = ["MonteCarloResults", "run_montecarlo", "realisation_config", "mean_ci",
           "aggregate", "client_cache_dir"]

#: distributions the Monte Carlo ``run.json`` records besides a run's
MC_VERSIONS = ("dask", "distributed")
#: confidence level of the ``ci95`` intervals
CI_LEVEL = 0.95
#: metric groups of a scenario ({name: number or None}) that are averaged
GROUPS = ("outcomes", "outcomes_encrypted", "correct_decision_rate", "position_error_m",
          "benign_phase_false_alarm_rate")
CSV_COLUMNS = ("realisation", "seed", "topology_iteration", "scenario", *OUTCOMES,
               *(f"{o}_enc" for o in OUTCOMES), *DETECTORS,
               "error_p50_m", "error_p95_m", "error_p999_m")


@dataclass(frozen=True, eq=False)
class MonteCarloResults:
    """What a Monte Carlo run produced.

    realisations : per realisation ``{"index", "seed", "topology_iteration", "dir", "metrics"}``
    metrics : the aggregated ``metrics.json``
    """

    config: Config
    out_dir: Path
    realisations: list
    metrics: dict
    timing_s: dict = field(default_factory=dict)


def realisation_config(cfg: Config, r: int) -> Config:
    """The single-run config of realisation ``r`` (``r = 0``: ``cfg`` itself, one realisation,
    with the first scene variant when ``run.street_width_variants_m`` or
    ``run.height_jitter_variants_m`` lists any): its own seed (so its own drive, heights,
    noise, adversary and keys), BS layout ``topology.iteration + r`` and scene variant
    ``r mod`` the length of each variant list. The variant lists are cleared in the result (a
    realisation is a single run)."""
    k = cfg.topology.iteration + r
    seed = cfg.seed if r == 0 else int(stream(cfg.seed, "realisation", k).integers(0, 2**63 - 1))
    scene = cfg.scene
    widths, jitters = cfg.run.street_width_variants_m, cfg.run.height_jitter_variants_m
    if widths:
        scene = replace(scene, street_width_m=widths[r % len(widths)])
    if jitters:
        scene = replace(scene, height_jitter_m=jitters[r % len(jitters)])
    return replace(cfg, seed=seed, scene=scene, topology=replace(cfg.topology, iteration=k),
                   run=replace(cfg.run, realisations=1, street_width_variants_m=(),
                               height_jitter_variants_m=()))


def mean_ci(values, level: float = CI_LEVEL) -> tuple[float | None, float | None, int]:
    """Mean and Student-t half-width of ``values`` (None entries skipped) -> (mean, half, n).

    half = t_{(1+level)/2, n-1} * s / sqrt(n) with the sample standard deviation s (ddof 1);
    None when fewer than two values (mean None when none).
    """
    from scipy.stats import t

    x = np.array([float(v) for v in values if v is not None], dtype=float)
    n = int(x.size)
    if n == 0:
        return None, None, 0
    mean = float(x.mean())
    if n < 2:
        return mean, None, 1
    half = float(t.ppf(0.5 + level / 2.0, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return mean, half, n


def aggregate(per_realisation: list[dict], level: float = CI_LEVEL, seed: int = 0) -> dict:
    """Mean and CI over the ``metrics.json`` dicts of the realisations (same scenarios); every
    share's ``<key>_ci95`` is its Student-t interval over the realisations clipped to [0, 1]
    (null below two realisations), the ``roc`` block's (:func:`_aggregate_roc`) a bootstrap
    over the realisations seeded from ``seed``."""
    n = len(per_realisation)
    out: dict = {"scenarios": {}, "realisations": n, "confidence_level": level}
    for s in per_realisation[0]["scenarios"]:
        ms = [m["scenarios"][s] for m in per_realisation]
        agg: dict = {}
        for key in ("num_points", "num_evaluated"):
            vals = [m.get(key, 0) for m in ms]
            agg[key] = vals[0] if len(set(vals)) == 1 else float(np.mean(vals))
        ci, defined = {}, {}
        for g in GROUPS:
            if not any(m.get(g) for m in ms):
                continue
            names = list(dict.fromkeys(k for m in ms for k in (m.get(g) or {})
                                       if not k.endswith(CI_SUFFIX)))
            agg[g], ci[g], defined[g] = {}, {}, {}
            for k in names:
                agg[g][k], ci[g][k], defined[g][k] = mean_ci([(m.get(g) or {}).get(k)
                                                              for m in ms], level)
                if g != "position_error_m":   # a share: its interval over the realisations
                    agg[g][ci_suffix(k)] = _clipped(agg[g][k], ci[g][k])
        flagged = [d for d in dict.fromkeys(d for m in ms
                                            for d in m.get("uninformative_detectors") or ())]
        if any("uninformative_detectors" in m for m in ms):
            # flagged in any realisation: its mean attack rate mixes in no-detections
            agg["uninformative_detectors"] = flagged
        agg["realisations"] = n
        agg["ci95"] = ci
        agg["realisations_defined"] = defined
        out["scenarios"][s] = agg
    roc = _aggregate_roc(per_realisation, seed, level)
    if roc:
        out["roc"] = roc
    budget = _aggregate_link_budget(per_realisation, level)
    if budget:
        out["link_budget"] = budget
    return out


def _aggregate_link_budget(per_realisation: list[dict], level: float) -> dict:
    """The ``link_budget`` block of a Monte Carlo: the realisations' constants (thresholds,
    penalty, antennas, scenario), ``links`` summed, each share the mean over the realisations
    with its ``_ci95`` (Student-t, clipped to [0, 1], as the scenarios' shares) and each
    percentile the mean of the realisations' (not a pooled percentile); empty when no
    realisation has one."""
    blocks = [m.get("link_budget") for m in per_realisation if m.get("link_budget")]
    if not blocks:
        return {}
    first = blocks[0]
    out: dict = {k: first[k] for k in ("scenario", "rx_antennas", "tag_threshold_db",
                                       "multipath_penalty_db", "bs_antenna") if k in first}
    out["links"] = int(sum(b.get("links", 0) for b in blocks))
    out["realisations"] = len(blocks)
    for k, v in first.items():
        if k in out or k.endswith(CI_SUFFIX):
            continue
        if isinstance(v, dict) and all(q in v for q in ("p5", "p50", "p95")):
            out[k] = {q: mean_ci([(b.get(k) or {}).get(q) for b in blocks], level)[0]
                      for q in ("p5", "p50", "p95")}
        elif k.endswith("_share"):
            mean, half, _ = mean_ci([b.get(k) for b in blocks], level)
            out[k], out[ci_suffix(k)] = mean, _clipped(mean, half)
    return out


def _clipped(mean: float | None, half: float | None) -> list[float] | None:
    """``[mean - half, mean + half]`` clipped to [0, 1] (a share); None without a half-width."""
    if mean is None or half is None:
        return None
    return [max(0.0, mean - half), min(1.0, mean + half)]


def _aggregate_roc(per_realisation: list[dict], seed: int, level: float) -> dict:
    """The ``roc`` block of a Monte Carlo: per attack and decision the mean over the
    realisations of ``auc``, ``pd_at_false_alarm``, ``benign_accept`` and ``attack_reject``,
    each with ``<key>_ci95``, a percentile bootstrap of the mean over the realisations
    (:func:`~veriloc_rt.analysis.intervals.bootstrap_mean_ci`, stream
    ``("bootstrap-realisations", attack, decision)`` of the seed); ``uninformative``: the
    decisions flagged in any realisation; empty when no realisation has a ``roc`` block."""
    rocs = [m.get("roc") for m in per_realisation if m.get("roc")]
    if not rocs:
        return {}
    attacks = list(dict.fromkeys(a for r in rocs for a in r.get("attacks", {})))
    out: dict = {"realisations": len(rocs),
                 "false_alarm": rocs[0].get("fusion", {}).get("false_alarm"),
                 "uninformative": list(dict.fromkeys(d for r in rocs
                                                     for d in r.get("uninformative") or ())),
                 "attacks": {}}
    for ai, a in enumerate(attacks):
        names = list(dict.fromkeys(d for r in rocs for d in r["attacks"].get(a, {})))
        per: dict = {}
        for di, d in enumerate(names):
            entries = [r["attacks"].get(a, {}).get(d) or {} for r in rocs]
            e: dict = {}
            for key in ("auc", "pd_at_false_alarm", "benign_accept", "attack_reject"):
                vals = [x.get(key) for x in entries]
                mean, _, k = mean_ci(vals, level)
                e[key] = mean
                e[ci_suffix(key)] = (bootstrap_mean_ci(
                    vals, stream(seed, "bootstrap-realisations", ai, di), level=level)
                    if k >= 2 else None)
            per[d] = e
        out["attacks"][a] = per
    return out


def _realisation(cfg: Config, out_dir: str, resume: bool, progress: Progress | None = None,
                 force: bool = False, cache_dir: str | None = "default") -> dict:
    """One realisation (a task): its metrics.json content. With ``resume``, a realisation
    already complete with this config is read back; a partial one continues. ``cache_dir``:
    as :func:`~veriloc_rt.sim.engine.run`'s."""
    out = Path(out_dir)
    info = out / "run.json"
    if resume and info.exists():
        check_run_files(out)    # a FIFO would block the reads
        if (read_run_json(info).get("status") == "complete" and same_config(info, cfg)
                and (out / "metrics.json").exists()):
            log.info("%s: complete, kept", out)
            path = out / "metrics.json"
            metrics = parse_json(read_text(path, str(path), "metrics file", MAX_RUN_JSON_BYTES),
                                 str(path))
            if not isinstance(metrics, dict) or not isinstance(metrics.get("scenarios"), dict):
                raise InputError(str(path), "not a run's metrics.json: delete it to compute the "
                                 "realisation again with --resume")
            return metrics
        return run(cfg, out, progress=progress, resume=True, cache_dir=cache_dir).metrics
    return run(cfg, out, progress=progress, force=force, cache_dir=cache_dir).metrics


def _dask_realisation(cfg: Config, out_dir: str, resume: bool, force: bool,
                      cache_dir: str | None) -> dict:
    """One realisation as a Dask task: BLAS pinned to one thread first, as the command line
    pins it (:func:`~veriloc_rt.sim.blas.one_blas_thread`; a worker started without that
    computes other last bits, and slower)."""
    one_blas_thread()
    return _realisation(cfg, out_dir, resume, None, force, cache_dir)


def client_cache_dir(cfg: Config) -> str | None:
    """The ray tracer's cache folder as this process sees it, for a task on another process:
    the config's ``propagation.raytrace.cache_dir`` made absolute against this working
    directory (a worker's is elsewhere: it would trace again, and write its cache there);
    None when caching is off. The config itself keeps the relative path (it is part of the
    config the run folder records and compares)."""
    cache = cfg.propagation.raytrace.cache_dir
    return str(Path(cache).resolve()) if cache else None


def run_montecarlo(cfg: Config, out_dir: str | Path, progress: Progress | None = None,
                   workers: int = 1, scheduler=None, resume: bool = False,
                   force: bool = False) -> MonteCarloResults:
    """Run the ``cfg.run.realisations`` realisations and aggregate them (module docstring).

    :param progress: ``progress(stage, done, total)``: per scenario and point when serial,
        realisations done on Dask
    :param workers: 1: one realisation after the other here; more: a local Dask cluster of
        that many processes (at most one per realisation)
    :param scheduler: an existing Dask cluster instead: address or connected
        ``distributed.Client`` (not together with ``workers > 1``)
    :param resume: keep the complete realisations in ``out_dir`` and continue the others
    :param force: write into a non-empty ``out_dir`` that holds no run of this config (as
        :func:`~veriloc_rt.sim.engine.run`; so do the realisations)
    """
    check_workers(workers, scheduler)
    out = Path(out_dir).resolve()
    if resume:
        check_resume(out, cfg)   # before the lock creates a missing folder; again under it
    # a bad address fails now, before the folder is touched
    with scheduler_client(scheduler) as client, locked(out):
        if resume:
            check_resume(out, cfg)
        else:
            check_fresh(out, cfg, force)
        try:
            return _montecarlo(cfg, out, progress, workers, client, resume, force,
                               "--scheduler" if scheduler is not None else "--workers")
        except BaseException:   # Ctrl-C, SIGTERM, a full disk, an error: resumable
            mark_stopped(out)
            raise


def _montecarlo(cfg: Config, out: Path, progress: Progress | None, workers: int, client,
                resume: bool, force: bool, flag: str = "--scheduler") -> MonteCarloResults:
    n = cfg.run.realisations
    width = max(3, len(str(n - 1)))
    reals = [{"index": r, "config": realisation_config(cfg, r),
              "dir": out / f"realisation_{r:0{width}d}"} for r in range(n)]
    t0 = time.perf_counter()
    if not resume:
        clear_run_files(out)
    write_run_json(out, cfg, "running", {}, _listing(reals), versions=MC_VERSIONS)
    if client is not None:
        metrics = _on_dask(client, reals, resume, progress, force, flag)
    elif workers > 1:
        with local_cluster(min(workers, n)) as own:
            metrics = _on_dask(own, reals, resume, progress, force, flag)
    else:
        metrics = []
        for real in reals:
            cb = ((lambda s, d, t, r=real["index"]: progress(f"{r + 1}/{n} {s}", d, t))
                  if progress else None)
            metrics.append(_realisation(real["config"], str(real["dir"]), resume, cb, force))
            log.info("realisation %d of %d done", real["index"] + 1, n)
    agg = aggregate(metrics, seed=cfg.seed)
    timing = _timing(metrics, time.perf_counter() - t0)
    resources = {"workers": (sum(client.nthreads().values()) if client is not None
                             else min(workers, n))}
    if client is not None:
        resources["scheduler"] = client.scheduler.address
    agg["timing_s"] = timing
    agg["resources"] = resources
    agg["propagation_model"] = cfg.propagation.model
    for real, m in zip(reals, metrics):
        real["metrics"] = m
    atomic_write_text(out / "metrics.json", json_text(agg))
    write_csv(out / "montecarlo.csv", reals)
    _write_plots(out, cfg, agg)
    write_run_json(out, cfg, "complete", timing, {**_listing(reals), "resources": resources},
                   versions=MC_VERSIONS)
    summary = [{"index": real["index"], "seed": real["config"].seed,
                "topology_iteration": real["config"].topology.iteration, "dir": real["dir"],
                "metrics": real["metrics"]} for real in reals]
    return MonteCarloResults(cfg, out, summary, agg, timing)


def _on_dask(client, reals: list[dict], resume: bool, progress: Progress | None,
             force: bool = False, flag: str = "--scheduler") -> list[dict]:
    """Every realisation as one task on ``client``'s cluster -> metrics, in realisation order.

    :raises InputError: ``<flag>: ...`` when the cluster fails (no workers, the scheduler
        gone, tasks cancelled; :func:`~veriloc_rt.sim.executors.dask_failure`)
    """
    from distributed import as_completed

    tag = uuid.uuid4().hex[:8]
    cache_dir = client_cache_dir(reals[0]["config"])
    futures = [client.submit(_dask_realisation, real["config"], str(real["dir"]), resume, force,
                             cache_dir,
                             key=f"veriloc-realisation-{real['index']}-{tag}", pure=False)
               for real in reals]
    index = {f.key: real["index"] for f, real in zip(futures, reals)}
    metrics: list = [None] * len(reals)
    if progress:
        progress("realisations", 0, len(reals))
    try:
        with named_failures(flag):
            for done, f in enumerate(as_completed(futures, loop=client.loop), 1):
                metrics[index[f.key]] = f.result()
                log.info("realisation %d done (%d of %d)", index[f.key] + 1, done, len(reals))
                if progress:
                    progress("realisations", done, len(reals))
    except BaseException:
        try:
            client.cancel(futures)
        except Exception as exc:  # noqa: BLE001 - a scheduler gone cancels nothing
            log.debug("Dask: cancelling the realisations failed (%s)", exc)
        raise
    return metrics


def _timing(metrics: list[dict], wall_s: float) -> dict:
    """Stage times summed over the realisations; ``total``: the Monte Carlo's wall time."""
    out: dict = {}
    for m in metrics:
        for k, v in m.get("timing_s", {}).items():
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                out[k] = out.get(k, 0.0) + float(v)
    out["realisations_total"] = out.pop("total", 0.0)
    out["total"] = wall_s
    return out


def _listing(reals: list[dict]) -> dict:
    """The ``realisations`` entry of the Monte Carlo ``run.json``."""
    return {"realisations": [{"index": real["index"], "seed": real["config"].seed,
                              "topology_iteration": real["config"].topology.iteration,
                              "dir": real["dir"].name} for real in reals]}


def _f(v) -> str:
    return "" if v is None else repr(float(v))


def write_csv(path: Path, reals: list[dict]) -> Path:
    """``montecarlo.csv``: one row per realisation and scenario (:data:`CSV_COLUMNS`)."""
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for real in reals:
            for s, m in real["metrics"]["scenarios"].items():
                o, e = m.get("outcomes") or {}, m.get("outcomes_encrypted") or {}
                rates, err = m.get("correct_decision_rate") or {}, m.get("position_error_m") or {}
                c = real["config"]
                w.writerow([real["index"], c.seed, c.topology.iteration, s,
                            *(_f(o.get(k)) for k in OUTCOMES), *(_f(e.get(k)) for k in OUTCOMES),
                            *(_f(rates.get(d)) for d in DETECTORS),
                            *(_f(err.get(k)) for k in ("p50", "p95", "p999"))])
    return path


def _write_plots(out: Path, cfg: Config, agg: dict) -> None:
    n = agg["realisations"]
    plots.plot_rates_ci(agg, out / "montecarlo_detection_rates.png",
                  title=f"correct decisions, mean and 95 % CI over {n} realisations")
    plots.plot_outcomes(agg, out / "outcomes.png", title=f"outcomes, mean over {n} realisations",
                        threshold_m=cfg.run.success_threshold_m)
