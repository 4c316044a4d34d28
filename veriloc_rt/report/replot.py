"""A finished run's summary figures again, from its files, in another format and resolution.

``veriloc-rt plot RUN_DIR --out DIR --plot-format pdf --dpi 300`` (paper-ready figures):
``outcomes``, ``detection_rates`` (uninformative detectors without an attack bar), ``roc`` and
each scenario's ``<scenario>_timeseries`` and ``<scenario>_map`` (the buildings under the
paths; the geometry rebuilt from the run's config, nothing traced; after a traced-power choice
the BSs the run measured, from its links CSVs, apart from the candidates never chosen), drawn
from ``metrics.json``, ``run.json`` and the ``<scenario>_results.csv`` files into ``DIR``
(never into the run folder, whose PNGs stay as the run wrote them).
"""

from __future__ import annotations

import csv
import json
import tempfile
from pathlib import Path

import numpy as np

from ..config import config_from_dict
from ..errors import InputError
from . import plots
from ..analysis.detection import analyse_detection
from .paper import PAPER_RATES
from .results import links_path, read_rows, results_path
from .roc_report import ROC_TITLE, plot_roc

__all__ = ["PLOT_FORMATS", "replot", "run_serving_mask"]

#: the file formats ``--plot-format`` takes (matplotlib's writers for them need nothing else)
PLOT_FORMATS = ("png", "pdf", "svg")


def run_serving_mask(run_dir: str | Path, scenarios: list[str], num_bs: int
                     ) -> np.ndarray | None:
    """[num_bs] bool, the BSs some point of the run measured: the ``bs_id`` column of its
    scenarios' ``<scenario>_links.csv`` (a traced-power choice is not in the config: rebuilding
    the geometry gives only the candidates); None without a links file.

    :raises InputError: naming the links file whose ``bs_id`` is not a BS id of the run
    """
    ids: list[int] = []
    found = False
    for s in scenarios:
        path = links_path(run_dir, s)
        if not path.is_file():
            continue
        found = True
        with open(path, newline="") as fh:
            for line, row in enumerate(csv.DictReader(fh), start=2):
                try:
                    b = int(row["bs_id"])
                except (KeyError, TypeError, ValueError):
                    raise InputError(f"{path}:{line}", "no integer bs_id") from None
                if not 0 <= b < num_bs:
                    raise InputError(f"{path}:{line}", f"bs_id {b} is not a BS of the run "
                                     f"(0..{num_bs - 1})")
                ids.append(b)
    return plots.serving_mask(num_bs, ids) if found else None


def replot(run_dir: str | Path, out_dir: str | Path, fmt: str = "png",
           dpi: int = plots.DEFAULT_DPI) -> list[Path]:
    """Draw the figures (module docstring) of ``run_dir`` into ``out_dir``; the files written.

    :raises InputError: ``--plot-format``, ``--dpi``, ``--out`` or ``RUN_DIR`` problems
    """
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    if fmt not in PLOT_FORMATS:
        raise InputError("--plot-format", f"got {fmt!r}, expected one of "
                         + ", ".join(PLOT_FORMATS))
    if not 10 <= dpi <= 2400:
        raise InputError("--dpi", f"got {dpi}, expected a value >= 10 and <= 2400")
    for name in ("run.json", "metrics.json"):
        if not (run_dir / name).is_file():
            raise InputError(str(run_dir), f"not a finished run folder (no {name} in it)")
    if out_dir.resolve() == run_dir.resolve():
        raise InputError("--out", f"{out_dir} is the run's own folder; give another one")
    metrics = json.loads((run_dir / "metrics.json").read_text())
    cfg = config_from_dict(json.loads((run_dir / "run.json").read_text())["config"])
    written = []
    with plots.figure_dpi(dpi):
        written.append(plots.plot_outcomes(metrics, out_dir / f"outcomes.{fmt}"))
        written.append(plots.plot_detection_rates(
            metrics, out_dir / f"detection_rates.{fmt}", reference=PAPER_RATES,
            title="correct decisions (dashed: the paper, on UMa)"))
        rows = {s: read_rows(results_path(run_dir, s)) for s in metrics.get("scenarios", {})
                if results_path(run_dir, s).exists()}
        analysis = analyse_detection(rows, cfg)
        if analysis is not None:
            written.append(plot_roc(analysis, out_dir / f"roc.{fmt}", title=ROC_TITLE))
        for s, r in rows.items():
            window = np.flatnonzero(cfg.run.attack_points(len(r)))
            span = (int(window[0]), int(window[-1]) + 1) if window.size and s != "none" else None
            data = plots.read_results_csv(results_path(run_dir, s))
            written.append(plots.plot_time_series(data, out_dir / f"{s}_timeseries.{fmt}", span,
                                                  title=s))
        if rows:
            from ..world.geometry import build_geometry

            with tempfile.TemporaryDirectory(prefix="veriloc-plot-") as tmp:
                geo = build_geometry(cfg, tmp)   # the run's seed: the run's scene and paths
            buildings = plots.map_buildings(geo)
            serving = (run_serving_mask(run_dir, list(rows), len(geo.bs_pos))
                       if geo.candidates is not None else None)
            for s in rows:
                data = plots.read_results_csv(results_path(run_dir, s))
                written.append(plots.plot_trajectory_map(
                    data, geo.bs_pos, out_dir / f"{s}_map.{fmt}",
                    adversary_xy=geo.adversary.pos[:, :2], title=s, buildings=buildings,
                    serving=serving))
    return written
