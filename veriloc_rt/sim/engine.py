"""The main job: geometry -> propagation -> per-point chain and detectors -> results on disk.

:func:`run` builds the scene and trajectories, ray-traces (or draws) every link once, then
evaluates each configured scenario (``none``, ``fbs``, ``meaconing``, ``jamming``) point by
point with :class:`~veriloc_rt.sim.runner.ScenarioRunner`, writing each row to
``<scenario>_results.csv`` as soon as it exists, and each point's chain results to the run
folder's chain store (:mod:`~veriloc_rt.sim.chain_store`). ``resume=True`` keeps the rows and
chain results already on disk (the config must be the one that produced them) and continues
after them; the result is the same as an uninterrupted run. At the end it writes
``metrics.json`` (with the detection analysis of :mod:`~veriloc_rt.analysis.detection`: ROC, AUC,
fused decisions), ``roc.csv``, ``run.json`` and the plots. The folder's lock, the checks before a run writes
into it and ``run.json``: :mod:`~veriloc_rt.sim.run_folder`.

Executors: the detectors carry state from point to point and run here, in order; the chains of
the points ahead go to forked local processes (``workers``) or, in trajectory chunks, to a Dask
cluster (``scheduler``), with the serial run's numbers either way (see the executors in
:mod:`~veriloc_rt.sim.executors`). With either, the figures are drawn by one more forked process
while the run goes on (:mod:`~veriloc_rt.sim.background`). Monte Carlo over realisations:
:mod:`~veriloc_rt.sim.montecarlo`.
"""

from __future__ import annotations

import logging
import resource
import time
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..config import Config
from ..errors import InputError
from ..fileio import atomic_output, atomic_write_text, json_text
from ..inputs import read_text
from ..propagation.antenna import apply_bs_antenna, describe_bs_antenna
from ..propagation.models import PROPAGATION_REGISTRY
from ..propagation.raytrace import Propagation
from ..report import plots
from ..analysis.detection import analyse_detection
from ..report.roc_report import ROC_TITLE, plot_roc, write_roc_csv
from ..report.paper import PAPER_RATES
from ..report.propagation_summary import summarize
from ..report.link_budget import (link_arrays, link_budget_block, multipath_penalty_db,
                                  read_link_arrays)
from ..report.results import (ResultsWriter, links_path, parse_rows, results_path,
                              scenario_metrics)
from ..report.scene_plot import plot_top_view
from ..world.geometry import Geometry, build_geometry
from ..world.sites import strongest_serving
from .checks import check_run_inputs, warn_silent_bs, warn_unreachable
from .background import Figures
from .executors import DaskChains, ForkPool, LocalChains, check_workers, scheduler_client
from .chain_store import ChainStore, config_digest
from .run_folder import (CHAIN_FILE, MAX_RESULTS_BYTES, check_fresh, check_resume,
                         clear_run_files, locked, mark_stopped, run_keys, write_run_json)
from .plugins import check_plugin_names
from .progress import progress_callback
from .runner import ScenarioRunner

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True, eq=False)
class Results:
    """What a run produced.

    rows : {scenario: list of PointRow}; metrics : the content of ``metrics.json``
    """

    config: Config
    geometry: Geometry
    propagation: Propagation
    summary: dict
    timing_s: dict = field(default_factory=dict)
    out_dir: Path | None = None
    rows: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)


def compute_propagation(cfg: Config, geometry: Geometry, progress: Progress | None = None,
                        cache_dir: str | Path | None = "default",
                        workers: int = 1) -> Propagation:
    """CIRs of every link, from the model ``propagation.model`` names
    (:data:`~veriloc_rt.propagation.models.PROPAGATION_REGISTRY`; ray tracing in up to
    ``workers`` processes).

    Ray tracing traces the adversary's links (BS -> adversary, adversary -> UE) only where the
    run uses them, the attack window of an attack scenario: the adversary -> UE links are
    point-to-point, batch poorly, and were half the tracing time of the paper run when traced at
    every point. (UMa draws them everywhere: free, and the draws stay as they were.)

    The models give isotropic BS antennas; ``topology.bs_antenna`` then applies the BS panels
    to the links leaving a BS (:func:`~veriloc_rt.propagation.antenna.apply_bs_antenna`), the
    same transform for every model.
    """
    model = PROPAGATION_REGISTRY.get(cfg.propagation.model)()
    attacks = any(s != "none" for s in cfg.run.scenarios)
    window = cfg.run.attack_points(geometry.num_points) & attacks
    stage = "ray tracing" if model.traces else "propagation"
    cb = (lambda d, n: progress(stage, d, n)) if progress else None
    prop = model(geometry, cfg.propagation, cfg.seed, progress=cb, cache_dir=cache_dir,
                 adversary_points=window, workers=workers)
    return apply_bs_antenna(prop, geometry, cfg.topology)


def traced_power_serving(cfg: Config, geometry: Geometry, progress: Progress | None = None,
                         cache_dir: str | Path | None = "default", workers: int = 1,
                         points: np.ndarray | None = None,
                         adversary: bool = True) -> tuple[Geometry, Propagation]:
    """``topology.selection`` 'traced_power': every candidate site of each point
    (``geometry.candidates``) is traced to it, the point measures the ``num_trps`` candidates
    with the strongest received power (the links' total path gain, averaged over the UE's
    elements; every site transmits ``channel.bs_max_power_dbm``, so the gain orders the
    powers), and the adversary's links are then traced from the chosen sites. The candidates'
    links are cached as any others; the chosen BS -> UE links are those already traced.
    ``veriloc-rt run``, ``compare`` (its ray-tracing arm, through :func:`run`), ``bench`` and
    ``validate`` all choose here.

    :param points: indices of the points whose candidates are traced (None: every point); the
        others keep their nearest candidates (no path to order them) and no traced link
    :param adversary: False: no adversary link is traced (bench, validate)
    :returns: the geometry with the chosen serving sets (slot 0 the strongest), its links
    """
    model = PROPAGATION_REGISTRY.get(cfg.propagation.model)()
    cand = geometry.candidates
    P = geometry.num_points
    on = np.ones(P, bool)
    if points is not None:
        on = np.zeros(P, bool)
        on[np.asarray(points, dtype=int)] = True
    padded = np.where(cand >= 0, cand, cand[:, :1])   # a repeated link is traced once
    stage = "ray tracing"
    cb = (lambda d, n: progress(stage, d, n)) if progress else None
    t0 = time.perf_counter()
    cand_prop = model(replace(geometry, serving=padded), cfg.propagation, cfg.seed, progress=cb,
                      cache_dir=cache_dir, adversary_points=np.zeros(P, bool), workers=workers,
                      ue_points=on)
    # the BS antennas before the choice: a point measures the sites strongest through them
    cand_prop = apply_bs_antenna(cand_prop, geometry, cfg.topology)
    power = cand_prop.bs_ue.path_power().sum(axis=-1)            # [P, C] linear
    serving, col = strongest_serving(cand, power, cfg.topology.num_trps)
    chosen = replace(geometry, serving=serving)
    attacks = adversary and any(s != "none" for s in cfg.run.scenarios)
    window = cfg.run.attack_points(P) & attacks & on
    adv_prop = model(chosen, cfg.propagation, cfg.seed, progress=cb, cache_dir=cache_dir,
                     adversary_points=window, workers=workers, ue_points=np.zeros(P, bool))
    adv_prop = apply_bs_antenna(adv_prop, chosen, cfg.topology)
    bs_ue = cand_prop.bs_ue.take_slots(col, serving)
    # the two traces' counts summed (the keys a single trace reports), each trace's own too
    stats = {k: cand_prop.stats[k] + adv_prop.stats[k]
             for k in cand_prop.stats if isinstance(cand_prop.stats[k], (int, float))
             and isinstance(adv_prop.stats.get(k), (int, float))}
    reached = (cand_prop.bs_ue.has_path() & (cand >= 0)).sum(axis=1)[on]   # candidates
    stats.update(wall_s=time.perf_counter() - t0, candidate_links=int((cand[on] >= 0).sum()),
                 candidates_with_path=[int(np.min(reached)), float(np.median(reached)),
                                       int(np.max(reached))],
                 candidate_trace=cand_prop.stats, adversary_trace=adv_prop.stats)
    if "bs_antenna" in cand_prop.stats:   # its sector counts are over the candidate links
        stats["bs_antenna"] = cand_prop.stats["bs_antenna"]
    log.info("traced-power selection: %d candidate links over %d points (%.1f per point), "
             "%d sites; candidates with a path per point: min %d, median %g, max %d",
             stats["candidate_links"], int(on.sum()), stats["candidate_links"] / max(on.sum(), 1),
             len(geometry.bs_pos), *stats["candidates_with_path"])
    return chosen, Propagation(bs_ue=bs_ue, bs_adv=adv_prop.bs_adv, adv_ue=adv_prop.adv_ue,
                               stats=stats)


def propagation_summary(geometry: Geometry, prop: Propagation) -> dict:
    scene = geometry.scene
    return {
        "num_points": geometry.num_points,
        "num_bs": int(len(geometry.bs_pos)),
        # the sites some point measures (all of them unless the run chose among candidates)
        "num_bs_serving": int(plots.serving_mask(len(geometry.bs_pos), geometry.serving).sum()),
        # where the run chose among candidate sites: their ids (into the num_bs sites) that
        # some point measures, which the maps and the live view draw apart; null otherwise
        "serving_bs": (None if (mask := run_serving(geometry)) is None
                       else np.flatnonzero(mask).tolist()),
        "num_buildings": getattr(scene, "num_buildings", None),
        "num_triangles": int(scene.box_meshes()[1].shape[0] if hasattr(scene, "box_meshes")
                             else scene.triangles.shape[0]),
        "ue_path_length_m": float(geometry.ue.s[-1] - geometry.ue.s[0]),
        "ue_speed_mps_mean": float(np.linalg.norm(geometry.ue.vel, axis=1).mean()),
        "bs_to_ue": summarize(prop.bs_ue),
        "bs_to_adversary": summarize(prop.bs_adv),
        "adversary_to_ue": summarize(prop.adv_ue),
        "raytrace_stats": prop.stats,
    }


def _peak_rss_mib() -> dict:
    """Peak resident memory so far, MiB: this process and its largest finished child (a forked
    chain worker; workers are joined before this is read). Linux reports ru_maxrss in KiB."""
    return {"peak_rss_main_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "peak_rss_worker_mib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0}


def run(cfg: Config, out_dir: str | Path | None = None, progress: Progress | bool | None = None,
        resume: bool = False, workers: int = 1, scheduler=None, force: bool = False,
        cache_dir: str | Path | None = "default", save_cir: bool = False,
        geometry: Geometry | None = None) -> Results:
    """Run every configured scenario; with ``out_dir``, write results, metrics and plots there.

    One realisation: ``run.realisations`` is for :func:`veriloc_rt.sim.montecarlo.run_montecarlo`.

    The run holds ``out_dir``'s lock while it works (another run there is refused). A new run
    needs an empty ``out_dir`` or one holding an unfinished run of the same config with no
    finished point (started over), unless ``force``: finished results are never replaced
    without it (:func:`~veriloc_rt.sim.run_folder.check_fresh`); nothing in it changes before
    the inputs are checked and the geometry is built. A run that ends unfinished (an
    exception, Ctrl-C, SIGTERM) records the status ``stopped`` in ``run.json``.

    :param progress: called as ``progress(stage, done, total)`` (the CLI draws a bar); True:
        a progress bar per stage on stderr (tqdm), as the CLI shows
    :param resume: keep the rows and chain results already in ``out_dir`` and continue after
        them (also after a stop during ray tracing: ``run.json`` is written before it)
    :param workers: processes computing the per-point chains (forked; the detectors, which
        carry state from point to point, run in this process); same results for any number
    :param scheduler: compute the chains on a Dask cluster instead, in trajectory chunks: a
        scheduler address (``tcp://host:8786``) or a connected ``distributed.Client``; same
        results as the serial run. Not together with ``workers > 1``.
    :param force: write into a non-empty ``out_dir`` that holds no run of this config
    :param cache_dir: the ray tracer's cache folder: "default" is the config's
        ``propagation.raytrace.cache_dir`` (a relative one under this process's working
        directory), None none
    :param save_cir: also write the run's CIRs into ``out_dir``: ``cir_bs_to_ue.npz``,
        ``cir_bs_to_adversary.npz``, ``cir_adversary_to_ue.npz`` (:meth:`CIR.to_arrays`; read
        back with ``CIR.from_arrays(np.load(path))``, then ``.to_sionna(point)``)
    :param geometry: the run's geometry, built from this config's world by another run, with
        its serving sets as they are (no selection; ``compare``'s stochastic twin measures the
        TRPs its ray-tracing arm chose by traced power); ``run.json`` says so. None: built here
    :raises InputError: ``--out DIR: ...`` (locked, not empty, not a folder), ``--resume: ...``,
        ``<file>: ...`` (a file of the folder that is not a regular one, a damaged ``run.json``
        or results CSV on resume)
    """
    check_workers(workers, scheduler)
    check_plugin_names(cfg)   # before anything is touched
    bar = progress if progress is True else None
    progress = progress_callback(progress)
    if bar is not None:
        bar = progress
        try:
            return run(cfg, out_dir, progress, resume, workers, scheduler, force, cache_dir,
                       save_cir, geometry)
        finally:
            bar.close()
    # absolute, as a Monte Carlo's: run.json records the scene's path under it, which a
    # relative --out left relative to the caller's working directory
    out = Path(out_dir).resolve() if out_dir is not None else None
    if resume and out is None:
        raise ValueError("Argument `resume` needs `out_dir`")
    if resume:
        check_resume(out, cfg)   # before the lock creates a missing folder; again under it
    with ExitStack() as stack:
        # a bad address fails now, before the folder is touched
        client = stack.enter_context(scheduler_client(scheduler))
        if out is not None:
            stack.enter_context(locked(out))
            if resume:
                check_resume(out, cfg)
            else:
                check_fresh(out, cfg, force)
        # figures drawn by a forked process while the run goes on, when it runs in more
        # than one process anyway (waited for before it ends; stopped with it)
        figures = stack.enter_context(Figures(parallel=workers > 1 or client is not None))
        try:
            return _run(cfg, out, progress, resume, workers, client, cache_dir, save_cir,
                        geometry, figures)
        except BaseException:   # Ctrl-C, SIGTERM, a full disk, an error: resumable
            if out is not None:
                mark_stopped(out)
            raise


def _run(cfg: Config, out: Path | None, progress: Progress | None, resume: bool, workers: int,
         client, cache_dir: str | Path | None = "default", save_cir: bool = False,
         given: Geometry | None = None, figures: Figures | None = None) -> Results:
    """The run in ``out`` (locked and checked); its figures go to ``figures`` (None: drawn
    here)."""
    if figures is None:
        figures = Figures(parallel=False)
    timing: dict = {}     # seconds only
    resources: dict = {}  # workers, scheduler, peak memory
    t0 = time.perf_counter()
    scene_dir = (out / "scene") if out else Path(".veriloc-scene")
    # a given geometry's serving sets are already chosen (its candidates stay for the maps)
    geometry = build_geometry(cfg, scene_dir) if given is None else given
    check_run_inputs(cfg, geometry)  # every input checked now, before any tracing
    keys = run_keys(cfg, len(geometry.bs_pos))
    timing["geometry"] = time.perf_counter() - t0
    fields = {"scene_xml": str(geometry.scene_xml)}
    if given is not None:
        fields["serving"] = "given by the caller (compare: the ray-tracing arm's choice)"
    if out:
        if not resume:
            clear_run_files(out)
        # before tracing: a run stopped there can be resumed
        write_run_json(out, cfg, "running", timing, fields)
    if out and not (resume and (out / "scene_top_view.png").exists()):  # (a new run cleared it)
        figures.submit(plot_top_view, geometry, out / "scene_top_view.png",
                       serving=run_serving(geometry) if given is not None else None)
    t1 = time.perf_counter()
    if geometry.candidates is not None and given is None:
        geometry, prop = traced_power_serving(cfg, geometry, progress, cache_dir, workers)
        if out:   # drawn before the choice with every candidate alike: now the chosen apart
            # (after the first drawing: the figures are drawn in the order given)
            figures.submit(plot_top_view, geometry, out / "scene_top_view.png",
                           serving=run_serving(geometry))
    else:
        prop = compute_propagation(cfg, geometry, progress, cache_dir, workers=workers)
    timing["propagation"] = time.perf_counter() - t1
    warn_unreachable(prop.bs_ue.has_path())
    warn_silent_bs(prop.bs_ue.has_path(), geometry.serving)
    summary = propagation_summary(geometry, prop)
    if out:
        atomic_write_text(out / "propagation_summary.json", json_text(summary))
        if save_cir:
            for name, cir in (("bs_to_ue", prop.bs_ue), ("bs_to_adversary", prop.bs_adv),
                              ("adversary_to_ue", prop.adv_ue)):
                with atomic_output(out / f"cir_{name}.npz") as tmp:
                    np.savez_compressed(tmp, **cir.to_arrays())
        write_run_json(out, cfg, "running", timing, fields)

    runner = ScenarioRunner(cfg, geometry, prop, keys)
    pool = None
    store = ChainStore(out / CHAIN_FILE, config_digest(cfg), resume) if out else None
    try:
        if client is not None:
            pool = DaskChains(runner, client)
            resources["scheduler"] = client.scheduler.address
        elif workers > 1:
            pool = ForkPool(runner, workers)
        rows, metrics = _run_scenarios(cfg, runner, pool, out, resume, progress, timing, store,
                                       figures)
    except BaseException:
        if pool is not None:
            pool.terminate()
        raise
    finally:
        if store is not None:
            store.close()
    if pool is not None:
        pool.close()
    timing.update({f"{k}_total": v for k, v in runner.timing.items()})
    resources["workers"] = pool.threads if isinstance(pool, DaskChains) else workers
    timing["total"] = time.perf_counter() - t0
    resources.update(_peak_rss_mib())
    metrics["timing_s"] = timing
    metrics["resources"] = resources
    fields["resources"] = resources
    metrics["propagation_model"] = cfg.propagation.model
    metrics["doppler_hz"] = {"max_path": runner.max_doppler_hz, "scan": runner.doppler_scan_hz}
    metrics["link_budget"] = _link_budget(cfg, rows, out)
    analysis = analyse_detection(rows, cfg)
    if analysis is not None:
        metrics["roc"] = analysis.metrics
        for s, m in metrics["scenarios"].items():
            if s != "none":
                m["uninformative_detectors"] = list(analysis.uninformative)
    if out:
        atomic_write_text(out / "metrics.json", json_text(metrics))
        figures.submit(_write_plots, out, metrics)
        if analysis is not None:
            write_roc_csv(out / "roc.csv", analysis)
            figures.submit(plot_roc, analysis, out / "roc.png", title=ROC_TITLE)
        figures.close()
        write_run_json(out, cfg, "complete", timing, fields)
    return Results(cfg, geometry, prop, summary, timing, out, rows, metrics)


def _link_budget(cfg: Config, rows: dict, out: Path | None) -> dict:
    """The ``link_budget`` block (:func:`~veriloc_rt.report.link_budget.link_budget_block`) of
    the ``none`` scenario (else the first one), from its links CSV when the run has a folder (a
    resumed run's earlier points are only there), else from its rows."""
    scenario = "none" if "none" in rows else next(iter(rows), None)
    if scenario is None:
        return {}
    path = links_path(out, scenario) if out else None
    links = read_link_arrays(path) if path is not None and path.exists() else \
        link_arrays(rows[scenario])
    return link_budget_block(links, cfg.propagation.ue_array.num_elements,
                             multipath_penalty_db(cfg.propagation), scenario=scenario,
                             bs_antenna=describe_bs_antenna(cfg.topology))


def _saved_rows(out: Path, scenario: str, n: int) -> list:
    """The rows of ``scenario`` already in ``out`` (resume)."""
    path = results_path(out, scenario)
    if not path.exists():
        return []
    text = read_text(path, str(path), "results file", MAX_RESULTS_BYTES)
    try:
        done = parse_rows(text, path)[:n]
    except ValueError as exc:
        raise InputError(str(path), f"not a results CSV of this run ({exc}): delete it to "
                         "compute its points again with --resume, or use --force or a new "
                         "--out") from None
    if [r.index for r in done] != list(range(len(done))):
        raise InputError("--resume", f"{path} is not a prefix of this run's points; use a new "
                         "--out")
    return done


def _restore_chains(runner: ScenarioRunner, store: ChainStore, saved: dict) -> None:
    """The stored chain results a resumed run still needs, into ``runner`` (an attack point's
    result is used once: those of points already in their scenario's CSV are dropped)."""
    kept = 0
    for results in store.loaded:
        need = {ck: r for ck, r in results.items()
                if ck.scenario is None or ck.point >= len(saved.get(ck.scenario, ()))}
        runner.store_chains(need)
        kept += len(need)
    store.loaded.clear()
    log.info("resume: %d stored chain results reused", kept)


def _run_scenarios(cfg: Config, runner, pool, out: Path | None, resume: bool,
                   progress: Progress | None, timing: dict,
                   store: ChainStore | None = None,
                   figures: Figures | None = None) -> tuple[dict, dict]:
    """Every scenario point by point: chains from ``pool`` (None: here), detectors here; each
    point's new chain results go to ``store`` before its row is written; each scenario's
    figures go to ``figures`` (None: drawn here)."""
    if figures is None:
        figures = Figures(parallel=False)
    n = runner.geo.num_points
    rows: dict = {}
    metrics: dict = {"scenarios": {}}
    saved = ({s: _saved_rows(out, s, n) for s in cfg.run.scenarios} if resume else {})
    if store is not None and resume:
        _restore_chains(runner, store, saved)
    for scenario in cfg.run.scenarios:
        t_s = time.perf_counter()
        runner.reset()
        done: list = saved.pop(scenario, [])
        complete = len(done) == n
        if done:
            runner.replay(done)
            log.info("%s: resuming after %d of %d points", scenario, len(done), n)
        writer = (ResultsWriter(results_path(out, scenario), keep=done,
                                trps=cfg.trp_outputs, extra=cfg.detectors.extra)
                  if out else None)
        prev = done[-1].index if done else None
        todo = [i for i in range(len(done), n) if runner.needs_chains(scenario, i)]
        ahead = (pool or LocalChains(runner)).imap(scenario, todo)
        todo_set = set(todo)
        # progress in point-scenarios computed (a point of 'none' in the attack window also
        # computes the later attack scenarios there), so that the ETA follows the work
        work = {i: runner.chain_work(scenario, i) for i in todo}
        work_total, work_done = sum(work.values()), 0
        try:
            for i in range(len(done), n):
                if i in todo_set:
                    j, results, dt = next(ahead)
                    assert j == i
                    if store is not None:
                        store.append(results)
                    runner.store_chains(results)
                    for k, v in dt.items():
                        runner.timing[k] += v
                row = runner.point(scenario, i, prev)
                prev = i
                done.append(row)
                if writer:
                    writer.write(row)
                if progress and not work_total:   # nothing left to compute: the points
                    progress(scenario, i + 1, n)
                elif progress and i in work:
                    work_done += work[i]
                    progress(scenario, work_done, work_total)
        finally:
            if writer:
                writer.close()
        rows[scenario] = done
        # plots as soon as a scenario is done; a resumed run keeps those of a scenario that
        # was complete already (written by this run: a new run clears them)
        if out and not (complete and all((out / f"{scenario}_{k}.png").exists()
                                         for k in ("timeseries", "map"))):
            figures.submit(_scenario_plots, out, cfg, runner.geo, scenario)
        metrics["scenarios"][scenario] = scenario_metrics(done, scenario)
        timing[f"scenario_{scenario}"] = time.perf_counter() - t_s
    return rows, metrics


def _write_plots(out: Path, metrics: dict) -> None:
    """The run's summary plots (the scene's and each scenario's are written as they exist)."""
    plots.plot_outcomes(metrics, out / "outcomes.png")
    plots.plot_detection_rates(metrics, out / "detection_rates.png", reference=PAPER_RATES,
                               title="correct decisions (dashed: the paper, on UMa)")


def run_serving(geometry: Geometry) -> np.ndarray | None:
    """[num_bs] bool, the BSs some point measures, for the maps, where a run chose among
    candidate sites (``topology.selection`` 'traced_power'); None otherwise (every BS of the
    run serves some point)."""
    if geometry.candidates is None:
        return None
    return plots.serving_mask(len(geometry.bs_pos), geometry.serving)


def _scenario_plots(out: Path, cfg: Config, geometry: Geometry, scenario: str) -> list[Path]:
    """A finished scenario's time series and map, from its CSV."""
    window = cfg.run.attack_points(geometry.num_points)
    idx = np.flatnonzero(window)
    span = (int(idx[0]), int(idx[-1]) + 1) if idx.size else None  # 0-based, stop excluded
    files = [out / f"{scenario}_timeseries.png", out / f"{scenario}_map.png"]
    data = plots.read_results_csv(out / f"{scenario}_results.csv")
    plots.plot_time_series(data, files[0], span if scenario != "none" else None, title=scenario)
    plots.plot_trajectory_map(data, geometry.bs_pos, files[1],
                              adversary_xy=geometry.adversary.pos[:, :2], title=scenario,
                              buildings=plots.map_buildings(geometry),
                              serving=run_serving(geometry))
    return files
