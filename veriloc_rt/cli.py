"""The ``veriloc-rt`` command. Thin: parsing, progress and printing; the work is in the library.

Exit codes: 0 success, 2 bad input (one line ``error: <field>: <problem>``), 1 anything else,
130 a run stopped by Ctrl-C, 143 one stopped by SIGTERM (resumable alike).
"""

from __future__ import annotations

import os

# one BLAS thread: the chain's matrices are small, and multithreaded BLAS on them was measured
# ~10x slower on a shared 2-core machine (benchmarks/bench_chain.py); set before numpy loads
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import errno
import gc
import logging
import sys
import time
from pathlib import Path

from .errors import InputError
from .fileio import json_text
from .report.summary import format_metrics, format_montecarlo
from .sim.progress import NoProgress, ProgressBar

#: most BSs ``keys`` writes a set for: the BS id is 24 bits in the AES-CTR counter block
MAX_KEY_SETS = 2**24


def _bar(args):
    """The progress callback of a command: bars on stderr, or none with ``-q/--no-progress``."""
    return NoProgress() if getattr(args, "no_progress", False) else ProgressBar()


def _load(config_path: str | None, points: int | None = None, seed: int | None = None,
          default: str | None = None):
    """CONFIG: a JSON file or a preset's name; None: preset ``default`` (``run``: the default
    preset), or the built-in ``Config()``."""
    from .config import with_overrides
    from .config.presets import load_config_or_preset

    cfg = load_config_or_preset(config_path, default)
    if points is not None or seed is not None:
        cfg = with_overrides(cfg, points=points, seed=seed)
    return cfg


def _out(path: str) -> Path:
    """``--out``, checked: a folder that exists or can be created, and is writable."""
    from .inputs import check_out_dir

    return check_out_dir(path, "--out")


def _port(port: int | None) -> int | None:
    """``--port`` checked; None when not given (the default port, or a free one when taken:
    a port given is used or is an error)."""
    if port is None:
        return None
    if not 0 <= port <= 65535:
        raise InputError("--port", f"got {port}, expected 0..65535 (0: any free port)")
    return port


def _open_browser(url: str, args) -> None:
    if not args.no_browser:
        import webbrowser

        webbrowser.open(url)


def cmd_run(args) -> int:
    from .config.presets import DEFAULT_PRESET

    cfg = _load(args.config, args.points, args.seed, default=DEFAULT_PRESET)
    out = _out(args.out)
    if args.workers is not None and args.workers < 1:
        raise InputError("--workers", f"got {args.workers}, expected an integer >= 1")
    if args.scheduler is not None and args.workers is not None:
        raise InputError("--workers", "not with --scheduler (the cluster's workers compute)")
    if not args.live and (args.port is not None or args.no_browser):
        raise InputError("--port" if args.port is not None else "--no-browser",
                         "only with --live")
    if not args.live:
        return _run(cfg, out, args)
    from .live.server import start_view_process

    port = _port(args.port)
    view = start_view_process(out, port)
    try:
        print(f"live view: {view.url}", flush=True)
        _open_browser(view.url, args)
        code = _run(cfg, out, args)
        print(f"live view stays at {view.url} (Ctrl-C to stop)", flush=True)
        try:
            view.wait()
        except KeyboardInterrupt:
            pass
        return code
    finally:
        view.stop()


def _run(cfg, out: Path, args) -> int:
    from .sim.engine import run

    _freeze_heap(args)   # the modules just imported live to the end

    workers = (1 if args.scheduler is not None else args.workers if args.workers is not None
               else min(2, os.cpu_count() or 1))
    if args.verbose < 2 and (args.scheduler is not None
                             or (cfg.run.realisations > 1 and workers > 1)):
        import distributed  # noqa: F401 - its import sets its loggers to INFO

        # Dask's start-up and connection lines only with -vv
        logging.getLogger("distributed").setLevel(logging.WARNING)
    if cfg.run.realisations > 1:
        if args.save_cir:
            raise InputError("--save-cir", "a single run's only (run.realisations 1): run a "
                             "realisation's config from its run.json with --save-cir")
        return _run_montecarlo(cfg, out, args, workers)
    bar = _bar(args)
    try:
        res = run(cfg, out, progress=bar, resume=args.resume, workers=workers,
                  scheduler=args.scheduler, force=args.force, save_cir=args.save_cir)
    finally:
        bar.close()     # a stopped or failed run's message then starts a line of its own
    s = res.summary
    what = (f"{s['num_buildings']} buildings" if s["num_buildings"] is not None
            else f"{s['num_triangles']} triangles")
    sites = (f"{s['num_bs_serving']} serving BSs" if s["num_bs_serving"] == s["num_bs"] else
             f"{s['num_bs_serving']} serving BSs of {s['num_bs']} candidate sites")
    print(f"scene: {what}, {sites}, "
          f"{s['num_points']} points, UE path {s['ue_path_length_m']:.0f} m "
          f"(mean speed {s['ue_speed_mps_mean']:.1f} m/s), propagation: {cfg.propagation.model}")
    for name in ("bs_to_ue", "bs_to_adversary", "adversary_to_ue"):
        d = s[name]
        line = (f"{name:16s} links {d['links']:5d}  with path "
                f"{100 * d['links_with_path_share']:5.1f} %")   # fractions, printed in %
        if "los_share" in d:
            line += (f"  LoS {100 * d['los_share']:5.1f} %  paths/link "
                     f"{d['paths_per_link_mean']:5.1f}"
                     f"  DS p50 {d['delay_spread_ns_p50']:6.1f} ns")
        print(line)
    print(format_metrics(res.metrics))
    t = res.timing_s
    print(f"time: propagation {t['propagation']:.1f} s, total {t['total']:.1f} s (wall); CPU: "
          f"chain {t.get('chain_total', 0):.1f} s, adversary {t.get('adversary_total', 0):.1f} s "
          f"(summed over workers), detectors {t.get('detectors_total', 0):.1f} s")
    from .phy.chain import STAGES

    print("chain by stage (CPU s, summed over workers): " + ", ".join(
        f"{k} {t[f'{k}_total']:.1f}" for k in STAGES if f"{k}_total" in t))
    r = res.metrics["resources"]
    print(f"peak memory: {r['peak_rss_main_mib']:.0f} MiB main process, "
          f"{r['peak_rss_worker_mib']:.0f} MiB largest worker")
    print(f"wrote {out}/ (metrics.json, <scenario>_results.csv, run.json, *.png, scene/)")
    return 0


def _run_montecarlo(cfg, out: Path, args, workers: int) -> int:
    from .sim.montecarlo import run_montecarlo

    n = cfg.run.realisations
    where = (f"on the Dask cluster at {args.scheduler}" if args.scheduler is not None
             else f"on a local Dask cluster of {min(workers, n)} processes" if workers > 1
             else "one after the other")
    print(f"Monte Carlo: {n} realisations of {cfg.trajectory.num_points} points, {where}",
          flush=True)
    bar = _bar(args)
    try:
        res = run_montecarlo(cfg, out, progress=bar, workers=workers,
                             scheduler=args.scheduler, resume=args.resume, force=args.force)
    finally:
        bar.close()
    print(format_montecarlo(res.metrics))
    t = res.timing_s
    print(f"time: {t['total']:.1f} s wall, {t['realisations_total']:.1f} s summed over the "
          f"realisations")
    print(f"wrote {out}/ (metrics.json, montecarlo.csv, montecarlo_detection_rates.png, "
          f"outcomes.png, run.json; realisation_*/ hold each realisation's run)")
    return 0


def cmd_scene(args) -> int:
    from .report.scene_plot import plot_top_view
    from .world.geometry import build_geometry

    cfg = _load(args.config)
    if cfg.scene.osm or args.osm is not None or args.bbox is not None or args.radius is not None:
        return _scene_osm(cfg, args)
    out = _out(args.out)
    geo = build_geometry(cfg, out)
    png = plot_top_view(geo, out / "scene_top_view.png")
    nb = getattr(geo.scene, "num_buildings", None)
    print(f"wrote {geo.scene_xml}" + (f" ({nb} buildings)" if nb is not None else "")
          + f" and {png}")
    return 0


def _scene_osm(cfg, args) -> int:
    """``scene --osm FILE``: import the extract (the config's scene.osm_* fields, overridden by
    --bbox and --radius) and write the scene, scene.json, streets.json and a top view."""
    from .config import config_from_dict, config_to_dict
    from .report.osm_plot import plot_osm_top_view
    from .world.scene.osm import read_osm
    from .world.scene.osm_write import write_osm_scene

    data = config_to_dict(cfg)
    for key, flag, value in (("osm", "--osm", args.osm), ("osm_bbox_deg", "--bbox", args.bbox),
                             ("osm_radius_m", "--radius", args.radius)):
        if value is not None:
            data["scene"][key] = value
            data["scene"]["source"] = "canyon"
    try:
        sc = config_from_dict(data).scene
    except InputError as exc:   # name the flag that set the field
        flags = {"scene.osm": args.osm, "scene.osm_bbox_deg": args.bbox,
                 "scene.osm_radius_m": args.radius}
        names = {"scene.osm": "--osm", "scene.osm_bbox_deg": "--bbox",
                 "scene.osm_radius_m": "--radius"}
        if flags.get(exc.field) is None:
            raise
        raise InputError(names[exc.field], exc.problem) from None
    if not sc.osm:
        raise InputError("--osm", "--bbox and --radius crop an extract: give it with --osm FILE "
                         "(or scene.osm in the config)")
    out = _out(args.out)
    t = time.perf_counter()
    city = read_osm(sc.osm, "--osm" if args.osm is not None else "scene.osm",
                    bbox_deg=sc.osm_bbox_deg or None, radius_m=sc.osm_radius_m,
                    storey_m=sc.osm_storey_m, default_height_m=sc.osm_default_height_m)
    t_read = time.perf_counter() - t
    xml = write_osm_scene(city, out, ground_material=sc.ground_material,
                          thickness_m=sc.material_thickness_m,
                          meta={"source": sc.osm, "bbox_deg": list(sc.osm_bbox_deg) or None,
                                "radius_m": sc.osm_radius_m})
    t_write = time.perf_counter() - t - t_read
    png = plot_osm_top_view(city, out / "scene_top_view.png")
    rules = {r: int((city.height_rules == r).sum()) for r in ("height", "levels", "default")}
    mats = ", ".join(f"{m} {int((city.materials == m).sum())}"
                     for m in sorted(set(city.materials.tolist())))
    print(f"{city.num_buildings} buildings (height from: tag {rules['height']}, levels "
          f"{rules['levels']}, default {rules['default']}; {mats}), {len(city.street_nodes)} "
          f"street nodes, {len(city.street_edges)} edges; read in {t_read:.2f} s (with the parser's "
          f"import), meshed and written in {t_write:.2f} s")
    print(f"wrote {xml}, {out / 'scene.json'}, {out / 'streets.json'} and {png}")
    return 0


def cmd_keys(args) -> int:
    import tempfile

    from .world.geometry import build_geometry
    from .phy.security.keys import generate_keys

    cfg = _load(args.config)
    out = _out(args.out)
    if args.num_bs is not None:
        if not 1 <= args.num_bs <= MAX_KEY_SETS:
            raise InputError("--num-bs", f"got {args.num_bs}, expected an integer in 1.."
                             f"{MAX_KEY_SETS} (the 24-bit BS id of the AES-CTR counter block)")
        num_bs = args.num_bs
    else:
        with tempfile.TemporaryDirectory() as tmp:
            num_bs = len(build_geometry(cfg, tmp).bs_pos)
    files = generate_keys(out, range(num_bs), aes_bits=cfg.security.aes_key_bits,
                          overwrite=args.force)
    print(f"wrote {len(files)} key files for BSs 0..{num_bs - 1} into {args.out}; "
          f'set "security": {{"keys_dir": "{args.out}"}} to use them')
    return 0


def cmd_bench(args) -> int:
    from .config import TrajectoryConfig
    from .config.fields import check_value
    from .studies.bench import markdown_table, run_bench, sweep_settings, write_bench

    cfg = _load(args.config)
    if args.points is not None:
        check_value(TrajectoryConfig, "num_points", args.points, "--points")
    if args.only and not sweep_settings(cfg, args.quick, tuple(args.only)):
        raise InputError("--only", f"{' '.join(args.only)}: no knob of these groups applies to "
                         f"propagation.model {cfg.propagation.model!r} (the ray-tracing knobs "
                         "need 'raytrace')")
    _out(args.out)
    t = time.perf_counter()
    res = run_bench(cfg, args.out, quick=args.quick, points=args.points, progress=_bar(args),
                    groups=tuple(args.only) if args.only else None)
    files = write_bench(res, args.out)
    print(markdown_table(res))
    print(f"{res.meta['num_points']} points, {len(res.settings)} settings in "
          f"{time.perf_counter() - t:.0f} s; wrote " + ", ".join(str(f) for f in files.values()))
    return 0


def cmd_compare(args) -> int:
    from .studies.compare import format_comparison, run_compare

    cfg = _load(args.config, args.points, args.seed)
    _out(args.out)
    workers = args.workers if args.workers is not None else min(2, os.cpu_count() or 1)
    if workers < 1:
        raise InputError("--workers", f"got {workers}, expected an integer >= 1")
    res = run_compare(cfg, args.out, progress=_bar(args), workers=workers,
                      match_pathloss=args.match_pathloss)
    print(format_comparison(res))
    print(f"wrote {args.out}/ (comparison.md, comparison.json, comparison_*.csv, *.png, "
          f"raytrace/, {res.models[1]}/)")
    return 0


def cmd_findings(args) -> int:
    from .studies.findings import PRESETS, generate_findings, preset_configs

    root = Path(args.root)
    configs = None
    if args.config:
        configs = {Path(c).stem: Path(c) for c in args.config}
    # checked before any work: --points, --seed, the presets' files
    _load(None, args.points, args.seed)
    configs = preset_configs(root, args.preset or None, configs)
    workers = args.workers if args.workers is not None else min(2, os.cpu_count() or 1)
    if workers < 1:
        raise InputError("--workers", f"got {workers}, expected an integer >= 1")
    _out(args.out)
    docs = Path(args.docs) if args.docs else root / "docs"
    if not docs.is_dir():
        raise InputError("--docs", f"{docs} is not a folder")
    done = generate_findings(args.out, docs, root, presets=args.preset or None, configs=configs,
                             points=args.points, seed=args.seed, workers=workers,
                             models=tuple(args.models) if args.models else None,
                             progress=_bar(args))
    for p in done:
        print(f"{p.name}: {', '.join(p.models)} in {p.wall_s:.0f} s")
    wrote = "findings.md" + (", compare.md's tables" if all(p.compare_md for p in done) else "")
    print(f"wrote {docs}/ ({wrote}); runs in {args.out}/ (presets: "
          f"{', '.join(p.name for p in done) or ', '.join(PRESETS)})")
    return 0


def cmd_validate(args) -> int:
    from .studies.validate import format_validation, run_validate

    cfg = _load(args.config, args.points)
    _out(args.out)
    res = run_validate(cfg, args.out, progress=_bar(args))
    print(format_validation(res))
    st = res.summary["raytrace_stats"]
    print(f"ray tracing {res.timing_s['ray_tracing']:.1f} s ({st['cache_hits']} of "
          f"{st['cache_hits'] + st['calls']} tracer calls from the cache); wrote {args.out}/ "
          "(validation.json, validation.md, validation_links.csv, validation_pathloss.png, scene/)")
    return 0


def _serve(server, args, page: str = "") -> int:
    """Serve ``server`` until Ctrl-C (or, with ``--watch-stdin``, until stdin closes); print
    and open its URL, which holds the session token."""
    print(f"live view of {server.view.folder}: {server.page_url(page)}", flush=True)
    _open_browser(server.page_url(page), args)
    if getattr(args, "watch_stdin", False):
        import threading

        def watch():
            sys.stdin.buffer.read()     # returns at EOF: the process that started this ended
            server.shutdown()

        threading.Thread(target=watch, daemon=True).start()
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


def cmd_view(args) -> int:
    from .inputs import check_path
    from .live.server import LiveServer

    try:
        folder = check_path(args.dir, args.dir)
        if folder.exists() and not folder.is_dir():
            raise InputError(args.dir, "not a folder (give a run's --out folder)")
        # run --live (--watch-stdin) views the folder its run is about to create
        if not folder.exists() and not args.watch_stdin:
            raise InputError(args.dir, "does not exist (give a run's --out folder)")
        server = LiveServer(folder, port=_port(args.port))
    except InputError as exc:
        if not args.watch_stdin:
            raise
        # for run --live, which reads this process's first output line
        print(f"error: {exc}", flush=True)
        return 2
    return _serve(server, args)


def cmd_edit(args) -> int:
    from .live.editor import editor_config
    from .live.server import LiveServer

    if args.config is not None and Path(args.config).exists():
        editor_config(args.config)    # a bad file: the one-line error now, not in the page
    return _serve(LiveServer(args.out, config_path=args.config, port=_port(args.port),
                             edit=True), args, "edit")


def cmd_config(args) -> int:
    from .config import config_schema, config_to_dict

    if args.action == "schema":
        print(json_text(config_schema()))
    elif args.action == "presets":
        from .config.presets import DEFAULT_PRESET, PRESETS, preset_names

        for name in preset_names():
            mark = " (default of run)" if name == DEFAULT_PRESET else ""
            print(f"{name}{mark}: {PRESETS[name]}")
    elif args.action == "check":
        import tempfile

        from .sim.checks import check_inputs

        cfg = _load(args.config, args.points, args.seed)
        with tempfile.TemporaryDirectory() as tmp:
            geo = check_inputs(cfg, tmp)
            print(f"ok: {geo.num_points} points, {len(geo.bs_pos)} BSs, scene "
                  f"{cfg.scene.source}, trajectory {cfg.trajectory.source}")
    else:
        print(json_text(config_to_dict(_load(args.config))))
    return 0


def cmd_export(args) -> int:
    from .report.tables import export_mat, export_parquet, load_run

    tables = load_run(args.dir)
    out = Path(args.out)
    if args.format == "parquet":
        if out.exists() and not out.is_dir():
            raise InputError("--out", f"{out} is not a folder (Parquet: one file per table)")
        written = export_parquet(tables, out)
    else:
        if out.is_dir():
            raise InputError("--out", f"{out} is a folder (MATLAB: one .mat file)")
        if out.suffix != ".mat":
            raise InputError("--out", f"{out}: the MATLAB file's name ends with .mat")
        written = [export_mat(tables, out)]
    rows = ", ".join(f"{k} {len(v)}" for k, v in tables.tables().items())
    print(f"wrote {', '.join(str(w) for w in written)} (rows: {rows})")
    return 0


def cmd_plot(args) -> int:
    from .report.replot import replot

    written = replot(args.dir, args.out, args.plot_format, args.dpi)
    print(f"wrote {len(written)} figures into {args.out}/ ({args.plot_format}, {args.dpi} dpi)")
    return 0


def cmd_diff(args) -> int:
    from .report.postprocess import EXACT, diff_runs

    exact = EXACT if args.exact is None else tuple(c for c in args.exact.split(",") if c)
    report = diff_runs(args.run_a, args.run_b, exact)
    print("\n".join(report.lines))
    return 0 if report.ok else 1


def cmd_roc(args) -> int:
    from .report.postprocess import format_roc, roc_of_run

    metrics = roc_of_run(args.dir, args.out, args.set)
    if metrics is None:
        print("no analysis: the run needs a 'none' scenario, an attack scenario and statistic "
              "columns", file=sys.stderr)
        return 1
    print(format_roc(metrics))
    print(f"wrote {args.out}/ (roc.csv, roc.png, roc_metrics.json)")
    return 0


def cmd_paper_table(args) -> int:
    from .report.postprocess import paper_table, read_metrics

    text, good, total = paper_table(read_metrics(args.metrics))
    print(text)
    print(f"\n{good} of {total} cells within the acceptance band (✗: outside)")
    return 0


class ArgumentParser(argparse.ArgumentParser):
    """argparse with the one-line error of every other bad input: ``error: <flag>: <problem>``,
    exit code 2 (argparse's own prints the usage first). Subparsers inherit the class."""

    def error(self, message: str):
        field, problem = argparse_field(message)
        self.exit(2, f"error: {InputError(field, problem)}\n")


def argparse_field(message: str) -> tuple[str, str]:
    """(flag, problem) from one of argparse's error messages."""
    if message.startswith("argument ") and ": " in message:
        field, problem = message[len("argument "):].split(": ", 1)
        return field, problem
    for lead in ("the following arguments are required: ", "unrecognized arguments: ",
                 "ambiguous option: "):
        if message.startswith(lead):
            rest = message[len(lead):]
            first = rest.replace(",", " ").replace("=", " ").split()[0] if rest.strip() else "arguments"
            return first, lead.rstrip(": ").replace("the following arguments are ", "") + ": " + rest
    return "arguments", message


def script_main(work) -> int:
    """The exit code of a script of ``scripts/`` that does ``work()``: the line it returns is
    printed; bad input (:class:`InputError`) is the one line ``error: <field>: <problem>`` on
    stderr and exit code 2, as for every command (its parser: :class:`ArgumentParser`)."""
    try:
        text = work()
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(text)
    return 0


def _browser_flags(p: argparse.ArgumentParser, port_help: str,
                   browser_help: str = "do not open a browser") -> None:
    """``--port`` and ``--no-browser`` of the commands that serve a page (run --live, view, edit)."""
    p.add_argument("--port", type=int, help=port_help)
    p.add_argument("--no-browser", action="store_true", help=browser_help)


def _version() -> str:
    from . import __version__

    return __version__


def _quiet_flag(p: argparse.ArgumentParser, default=argparse.SUPPRESS) -> None:
    """``-q/--no-progress``, before or after the command's name."""
    p.add_argument("-q", "--no-progress", dest="no_progress", action="store_true",
                   default=default, help="no progress bars (the results are printed as usual)")


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="veriloc-rt", description=__doc__.splitlines()[0])
    p.add_argument("-v", "--verbose", action="count", default=0, help="more logging (-vv: debug)")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    _quiet_flag(p, False)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a scenario (no CONFIG: the default preset)")
    r.add_argument("config", nargs="?", help="JSON config file or a preset's name "
                   "(`veriloc-rt config presets`); none: the default preset")
    r.add_argument("--out", default="results", help="output folder (default: results)")
    r.add_argument("--points", type=int, help="number of trajectory points")
    r.add_argument("--seed", type=int, help="override the config's seed")
    r.add_argument("--workers", type=int, help="processes for the per-point chains "
                   "(default: 2, or 1 on a one-core machine); with run.realisations > 1, "
                   "the processes of a local Dask cluster; results do not depend on it")
    r.add_argument("--scheduler", metavar="ADDR", help="compute on the Dask cluster at ADDR "
                   "(tcp://host:8786): realisations as tasks, or trajectory chunks of a single "
                   "run; results do not depend on it")
    r.add_argument("--resume", action="store_true",
                   help="keep the points already in --out (same config) and continue after them")
    r.add_argument("--force", action="store_true",
                   help="write into a non-empty --out: replace a finished run there (or "
                   "the points of an unfinished one), or write beside other files")
    r.add_argument("--save-cir", action="store_true", help="also write the run's channel "
                   "impulse responses into --out (cir_<links>.npz; CIR.to_sionna gives Sionna "
                   "RT's (a, tau) layout)")
    r.add_argument("--live", action="store_true", help="serve the live view of --out on "
                   "127.0.0.1 while the run goes (in its own process; it stays until Ctrl-C)")
    _browser_flags(r, "--live: port (default 8765, or a free one)",
                   "--live: do not open a browser")
    _quiet_flag(r)
    r.set_defaults(func=cmd_run)
    w = sub.add_parser("view", help="serve the live view of a running or finished run folder "
                       "on 127.0.0.1")
    w.add_argument("dir", help="the run's --out folder")
    _browser_flags(w, "port (default 8765, or a free one when taken; 0: any free one)")
    w.add_argument("--watch-stdin", action="store_true", help=argparse.SUPPRESS)
    w.set_defaults(func=cmd_view)
    e = sub.add_parser("edit", help="edit a config in the browser (fields, ranges, defaults), "
                       "validate, save it and start a run with its live view")
    e.add_argument("config", nargs="?", help="JSON config file to edit, the only file it saves "
                   "to (a new file starts from the built-in default); default: the built-in "
                   "default, saved to the new file OUT.json beside --out (refused if it exists)")
    e.add_argument("--out", default="results", help="output folder of the runs it starts, the "
                   "only one (default: results)")
    _browser_flags(e, "port (default 8765, or a free one when taken)")
    e.set_defaults(func=cmd_edit)
    s = sub.add_parser("scene", help="write the scene (XML + PLY) and a top-view PNG")
    s.add_argument("config", nargs="?", help="JSON config file")
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--osm", metavar="FILE", help="import a local OpenStreetMap extract (.osm XML "
                   "or .osm.pbf) instead (scene.osm); also writes scene.json and streets.json")
    s.add_argument("--bbox", type=float, nargs=4,
                   metavar=("LON_MIN", "LAT_MIN", "LON_MAX", "LAT_MAX"),
                   help="crop the extract to this box, degrees (scene.osm_bbox_deg)")
    s.add_argument("--radius", type=float, metavar="M", help="keep the buildings within M "
                   "metres of the frame's centre (scene.osm_radius_m)")
    s.set_defaults(func=cmd_scene)
    k = sub.add_parser("keys", help="generate key files (AES, HMAC, Ed25519) for every BS")
    k.add_argument("config", nargs="?", help="JSON config file (decides how many BSs)")
    k.add_argument("--out", required=True, help="output folder")
    k.add_argument("--num-bs", type=int, help="number of BSs (default: those the config uses)")
    k.add_argument("--force", action="store_true", help="overwrite existing key files")
    k.set_defaults(func=cmd_keys)
    cp = sub.add_parser("compare", help="the same topology, trajectory and attacks through ray "
                        "tracing and through its TR 38.901 twin (UMa for rooftop sites, UMi "
                        "for street-level sites: propagation.stochastic_twin)")
    cp.add_argument("config", nargs="?", help="JSON config file (its propagation.model is ignored)")
    cp.add_argument("--out", required=True, help="output folder")
    cp.add_argument("--points", type=int, help="number of trajectory points")
    cp.add_argument("--seed", type=int, help="override the config's seed")
    cp.add_argument("--workers", type=int, help="processes for the per-point chains (default 2)")
    cp.add_argument("--match-pathloss", action="store_true", help="shift the twin's path loss "
                    "so that its median equals the traced one, LoS and NLoS links apart "
                    "(separates mean loss from multipath structure)")
    _quiet_flag(cp)
    cp.set_defaults(func=cmd_compare)
    fd = sub.add_parser("findings", help="run the presets on ray tracing and their stochastic "
                        "twins and regenerate docs/findings.md and docs/compare.md's tables "
                        "(each stamped with the package, config and model versions)")
    fd.add_argument("--out", required=True, help="folder for the runs (one sub-folder per preset)")
    fd.add_argument("--preset", action="append", help="only this preset (repeatable; default: "
                    "every preset of veriloc_rt.studies.findings.PRESETS)")
    fd.add_argument("--config", action="append", metavar="FILE", help="this config instead of "
                    "the presets (repeatable; named by its file name)")
    fd.add_argument("--points", type=int, help="trajectory points of every preset (default: "
                    "each preset's own)")
    fd.add_argument("--seed", type=int, help="override the presets' seed")
    fd.add_argument("--workers", type=int, help="processes for the per-point chains (default 2)")
    fd.add_argument("--models", nargs="+", choices=("raytrace", "uma", "umi"), help="only these "
                    "models, no comparison (compare.md untouched): try the generator without "
                    "ray tracing")
    fd.add_argument("--root", default=".", help="the repository checkout (its configs/ and "
                    "docs/; default: the current folder)")
    fd.add_argument("--docs", help="write findings.md and compare.md's tables here (default: "
                    "ROOT/docs)")
    _quiet_flag(fd)
    fd.set_defaults(func=cmd_findings)
    b = sub.add_parser("bench", help="sweep the fidelity settings: time vs accuracy table and "
                       "chart with the Pareto front")
    b.add_argument("config", nargs="?", help="JSON config file (default: the built-in default)")
    b.add_argument("--out", required=True, help="output folder")
    b.add_argument("--quick", action="store_true", help="fewer levels and 6 points (a few "
                   "minutes; for CI)")
    b.add_argument("--points", type=int, help="trajectory points evaluated (default 6 with "
                   "--quick, else 40)")
    b.add_argument("--only", nargs="+", choices=("raytrace", "waveform"),
                   help="sweep only these groups of knobs")
    _quiet_flag(b)
    b.set_defaults(func=cmd_bench)
    v = sub.add_parser("validate", help="the scene's traced path loss against distance beside "
                       "ITU-R P.1411, COST-231 Walfisch-Ikegami, TR 38.901 UMa/UMi NLOS and free "
                       "space for the same geometry: table and chart")
    v.add_argument("config", nargs="?", help="JSON config file with the procedural canyon "
                   "(its propagation.model is ignored: the links are ray traced)")
    v.add_argument("--out", required=True, help="output folder")
    v.add_argument("--points", type=int, help="number of trajectory points")
    _quiet_flag(v)
    v.set_defaults(func=cmd_validate)
    c = sub.add_parser("config", help="print the config schema or a resolved config")
    c.add_argument("action", choices=("schema", "show", "check", "presets"),
                   help="schema: the JSON schema; show: the resolved config; check: every check "
                   "of a run's inputs (config, scene, trajectory, key files), nothing computed; "
                   "presets: the named presets")
    c.add_argument("config", nargs="?", help="JSON config file or a preset's name (for show "
                   "and check)")
    c.add_argument("--points", type=int, help="check: number of trajectory points")
    c.add_argument("--seed", type=int, help="check: override the config's seed")
    c.set_defaults(func=cmd_config)
    x = sub.add_parser("export", help="a run folder's tables (points, per-TRP links, metrics, "
                       "ROC) as Parquet files or one MATLAB .mat file")
    x.add_argument("dir", help="the run's --out folder (a Monte Carlo's too)")
    x.add_argument("--format", choices=("parquet", "mat"), required=True,
                   help="parquet: one <table>.parquet per table in the folder --out; mat: one "
                   "MATLAB v5 file --out with a struct per table")
    x.add_argument("--out", required=True, help="output folder (parquet) or .mat file (mat); "
                   "never inside the run's own files: pick a new name")
    x.set_defaults(func=cmd_export)
    pl = sub.add_parser("plot", help="a finished run's summary figures again (outcomes, "
                        "detection rates, ROC, time series, maps) in another format and resolution")
    pl.add_argument("dir", help="the run's --out folder")
    pl.add_argument("--out", required=True, help="output folder (not the run's own)")
    pl.add_argument("--plot-format", choices=("png", "pdf", "svg"), default="pdf",
                    help="file format (default pdf)")
    pl.add_argument("--dpi", type=int, default=300, help="resolution of PNG figures, dots per "
                    "inch (default 300; the run writes 110)")
    pl.set_defaults(func=cmd_plot)
    df = sub.add_parser("diff", help="compare two run folders' results CSVs column by column "
                        "(exit 1 when an --exact column differs)")
    df.add_argument("run_a", help="a run's --out folder")
    df.add_argument("run_b", help="another run's --out folder")
    df.add_argument("--exact", help="comma-separated columns that must be identical "
                    "(default: the decisions, outcomes, attack flag, index and time)")
    df.set_defaults(func=cmd_diff)
    ro = sub.add_parser("roc", help="a finished run's detection analysis (ROC, AUC, fused "
                        "decisions) again, with detector settings overridden")
    ro.add_argument("dir", help="the run's --out folder")
    ro.add_argument("--out", required=True, help="output folder for roc.csv, roc.png, "
                    "roc_metrics.json (not the run's own: its files are never overwritten)")
    ro.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="override a config field with a JSON value, e.g. "
                    "detectors.fusion.false_alarm=0.01 (the analysis fields detectors.fusion.* "
                    "and detectors.min_benign_accept; the verdicts stay the run's)")
    ro.set_defaults(func=cmd_roc)
    pt = sub.add_parser("paper-table", help="a run's metrics beside the paper's figures "
                        "(markdown), cells within the acceptance band counted")
    pt.add_argument("metrics", help="the run's metrics.json (or its --out folder)")
    pt.set_defaults(func=cmd_paper_table)
    return p


def _freeze_heap(args) -> None:
    """Exempt every object alive now from the cyclic garbage collector (``gc.freeze``), when
    this command is the whole process (``main()`` without ``argv``): what a command has
    imported and built lives until the process ends, so scanning it again in every full
    collection, and once more while the interpreter shuts down, frees nothing. Objects are
    still freed by reference counting; only garbage cycles among the frozen ones stay until
    the process exits. Not for a caller that runs commands in-process (``main(argv)``)."""
    if getattr(args, "whole_process", False):
        gc.freeze()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    args.whole_process = argv is None
    code = _main(args)
    _freeze_heap(args)   # the interpreter's shutdown then skips the collection of the heap
    return code


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread as Ctrl-C is (:func:`_on_sigterm`): the run stops the
    same way, keeping what it finished, and exits with 128 + 15."""


#: exit code of a run stopped by Ctrl-C (SIGINT) or SIGTERM: 128 + the signal's number, as a
#: shell reports a process a signal ended
EXIT_SIGINT, EXIT_SIGTERM = 128 + 2, 128 + 15


def _on_sigterm(main_pid: int):
    """The SIGTERM handler: raise :class:`Terminated` in this process; a process forked from it
    (a chain worker, a ray-tracing worker) that still has the handler ends at once, silently,
    as SIGTERM's default action would have ended it."""
    import signal

    def handler(signum, frame):
        if os.getpid() != main_pid:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        raise Terminated
    return handler


def _install_sigterm() -> None:
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _on_sigterm(os.getpid()))


def _main(args) -> int:
    level = [logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)]
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    if getattr(args, "whole_process", False):
        _install_sigterm()
    try:
        return args.func(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print("\ninterrupted; finished ray-tracing batches are kept in the cache, finished "
              "points and chain results in --out: add --resume to continue", file=sys.stderr)
        return EXIT_SIGTERM if isinstance(exc, Terminated) else EXIT_SIGINT
    except Exception as exc:  # noqa: BLE001 - one line for the user, details with -vv
        from .backend import BackendError
        from .fileio import DISK_FULL

        if isinstance(exc, BackendError):
            print(f"error: {exc}", file=sys.stderr)
            return 1
        if args.verbose >= 2:
            raise
        if isinstance(exc, OSError) and exc.filename is not None:
            problem = ("no space left on device" if exc.errno == errno.ENOSPC
                       else "disk quota exceeded" if exc.errno == errno.EDQUOT
                       else (exc.strerror or str(exc)).lower())
            hint = ("; finished points are kept in --out: free space, then add --resume"
                    if exc.errno in DISK_FULL and args.func is cmd_run else "")
            print(f"error: {InputError(exc.filename, problem + hint)}", file=sys.stderr)
            return 1
        print(f"error: {type(exc).__name__}: {exc} (run with -vv for the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
