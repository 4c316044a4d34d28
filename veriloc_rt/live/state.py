"""What the live view shows, read from a run folder: progress, ETA, points, outcome shares, map.

A run (:mod:`~veriloc_rt.sim.engine`) writes ``run.json`` (status ``running``, then
``complete``), ``propagation_summary.json`` once the links exist, and one flushed CSV line per
point to ``<scenario>_results.csv``; it holds the folder's owner file while it works
(:mod:`~veriloc_rt.sim.run_folder`). :class:`RunFolderState` only reads these files: each CSV is
tailed from the last complete line it consumed (:class:`ResultsTail`), so a line the run is
still writing is read on the next poll. Columns are found by name, so columns added after the
documented ones change nothing here.

The outcome shares and correct-decision rates "so far" are
:func:`~veriloc_rt.report.results.scenario_metrics` over the points written so far: on a
finished folder they are exactly ``metrics.json``'s.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
import stat
import tempfile
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np

from ..config import config_from_dict
from ..detectors.outcomes import DETECTORS, OUTCOMES
from ..errors import InputError
from ..inputs import read_bytes
from ..report.results import CSV_COLUMNS, fields_to_row, results_path, scenario_metrics
from ..sim.run_folder import run_is_alive

log = logging.getLogger(__name__)

__all__ = ["ResultsTail", "RateMeter", "RunFolderState", "scene_layer", "read_json",
           "summary_serving", "MAX_MESH_TRIANGLES", "RATE_WINDOW_S", "MAX_JSON_FILE_BYTES"]

#: most roof triangles of a mesh scene sent to the page (the largest ones; a city mesh can
#: hold millions, and a top view needs the outlines only)
MAX_MESH_TRIANGLES = 20_000
#: seconds of progress observations the rate (and so the ETA) is measured over
RATE_WINDOW_S = 60.0
#: coordinates sent to the page are rounded to this, m (the page draws at metre scale)
COORD_STEP_M = 0.01
#: largest run.json or metrics.json read, bytes (a run's are a few tens of kB)
MAX_JSON_FILE_BYTES = 16 << 20


def read_json(path: Path):
    """The JSON in the regular file ``path``, or None when it is absent, not a regular file
    (a FIFO is not waited on: opened non-blocking), too large or not JSON."""
    try:
        return json.loads(read_bytes(path, str(path), "file", MAX_JSON_FILE_BYTES))
    except (InputError, ValueError, RecursionError):
        return None


class ResultsTail:
    """The rows of one ``<scenario>_results.csv`` as it grows.

    :meth:`poll` reads what was appended since the last call, up to the last complete line; a
    line that does not parse is left for the next poll. A file that was replaced (another
    inode, or shorter than what was read: a new or resumed run rewrites it) is read again from
    the start, and :attr:`generation` counts these restarts so that a client can drop its copy.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.rows: list = []
        self.generation = 0
        self._offset = 0
        self._inode: int | None = None
        self._header: list[str] | None = None

    def _reset(self) -> None:
        if self.rows or self._header is not None:
            self.generation += 1
        self.rows, self._offset, self._inode, self._header = [], 0, None, None

    def poll(self) -> int:
        """Read the lines appended since the last poll; returns how many rows were added."""
        try:
            st = os.stat(self.path)
        except OSError:   # absent (or not reachable)
            self._reset()
            return 0
        if not stat.S_ISREG(st.st_mode):   # a FIFO would block the read: nothing to show
            self._reset()
            return 0
        if st.st_ino != self._inode or st.st_size < self._offset:
            self._reset()
            self._inode = st.st_ino
        if st.st_size == self._offset:
            return 0
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError:
            return 0
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):   # replaced since the stat
                return 0
            data = os.pread(fd, st.st_size - self._offset, self._offset)
        finally:
            os.close(fd)
        cut = data.rfind(b"\n")
        if cut < 0:            # no complete line yet
            return 0
        try:
            lines = data[:cut + 1].decode("utf-8").splitlines()
            header = self._header
            if header is None:
                header = next(csv.reader([lines[0]]))
                missing = [c for c in CSV_COLUMNS if c not in header]
                if missing:
                    raise ValueError(f"not a results CSV: no column {missing[0]!r}")
                lines = lines[1:]
            new = []
            for fields in csv.reader(io.StringIO("\n".join(lines))):
                if len(fields) != len(header):
                    raise ValueError(f"a line of {len(fields)} fields, the header has {len(header)}")
                new.append(fields_to_row(dict(zip(header, fields))))
        except (ValueError, KeyError, UnicodeDecodeError) as exc:
            log.debug("%s: %s; read again at the next poll", self.path, exc)
            return 0
        self._header = header
        self.rows.extend(new)
        self._offset += cut + 1
        return len(new)


class RateMeter:
    """Points per second, measured from the latest observation at least ``window_s`` old (or
    the oldest one kept) to now. Observations of no point yet are not kept: the time a run
    spends before its first point (geometry, propagation) is not point time."""

    def __init__(self, window_s: float = RATE_WINDOW_S):
        self.window_s = window_s
        self._seen: deque = deque()

    def observe(self, wall_s: float, done: int) -> None:
        if self._seen and done < self._seen[-1][1]:   # a new run started over
            self._seen.clear()
        if done == 0:
            return
        if not self._seen or done != self._seen[-1][1]:
            self._seen.append((wall_s, done))
        while len(self._seen) > 2 and wall_s - self._seen[1][0] > self.window_s:
            self._seen.popleft()

    def rate(self, wall_s: float) -> float | None:
        """Points per second, or None before two distinct observations. The time since the
        last new point counts too, so a stalled run's rate falls."""
        if len(self._seen) < 2:
            return None
        (t0, d0), (_t1, d1) = self._seen[0], self._seen[-1]
        span = wall_s - t0
        return (d1 - d0) / span if span > 0 else None


def _num(x: float) -> float | None:
    """JSON number rounded to :data:`COORD_STEP_M`; None for NaN (no fix)."""
    return None if not math.isfinite(x) else round(float(x) / COORD_STEP_M) * COORD_STEP_M


def points_json(rows: list, start: int = 0) -> dict:
    """Columns of ``rows[start:]`` for the page: index, time_s, true and estimated x, y (None
    without a fix), outcome (index into :data:`OUTCOMES`), attack (0/1) and per detector 1
    valid / 0 invalid."""
    sel = rows[start:]
    return {
        "from": start,
        "index": [r.index for r in sel],
        "time_s": [r.time_s for r in sel],
        "x_true": [_num(r.true_xy[0]) for r in sel], "y_true": [_num(r.true_xy[1]) for r in sel],
        "x_est": [_num(r.est_xy[0]) for r in sel], "y_est": [_num(r.est_xy[1]) for r in sel],
        "outcome": [OUTCOMES.index(r.outcome) for r in sel],
        "attack": [int(r.attack) for r in sel],
        "verdicts": {d: [int(bool(r.verdicts[d])) for r in sel] for d in DETECTORS},
    }


def scene_layer(cfg) -> dict:
    """The map's fixed layer for config ``cfg``: the geometry rebuilt from the config (the same
    seed gives the same scene, BSs and trajectories as the run; nothing is traced).

    ``buildings``: [[x_min, y_min, x_max, y_max], ...] of the emitted canyon blocks and
    ``context``: those of the full grid the crop left out, or for a mesh scene ``triangles``:
    [[x0, y0, x1, y1, x2, y2], ...] of its roof triangles (up to :data:`MAX_MESH_TRIANGLES`);
    ``bs``: [[x, y], ...]; ``ue``, ``adversary``: [[x, y], ...] per point; ``attack``:
    [first, stop) point indices of the attack window (None when empty); m throughout.
    """
    from ..world.geometry import build_geometry

    # built in a daemon thread: a server stopped mid-build exits while the thread still writes
    # here, and the folder's removal at exit must not print a traceback for files it races
    with tempfile.TemporaryDirectory(prefix="veriloc-live-", ignore_cleanup_errors=True) as tmp:
        geo = build_geometry(cfg, tmp)
    r = lambda a: np.round(np.asarray(a, dtype=float) / COORD_STEP_M) * COORD_STEP_M  # noqa: E731
    out: dict = {"ready": True}
    scene = geo.scene
    if hasattr(scene, "footprints"):
        out["buildings"] = r(scene.footprints).tolist()
        if geo.full_canyon is not None:
            full = np.asarray(geo.full_canyon.footprints)
            kept = {tuple(f) for f in np.asarray(scene.footprints).tolist()}
            out["context"] = r([f for f in full.tolist() if tuple(f) not in kept]).tolist()
    else:
        out["triangles"] = _roof_triangles(np.asarray(scene.triangles, dtype=float))
    window = np.flatnonzero(cfg.run.attack_points(geo.num_points))
    out.update({
        "bs": r(geo.bs_pos[:, :2]).tolist(),
        "ue": r(geo.ue.pos[:, :2]).tolist(),
        "adversary": r(geo.adversary.pos[:, :2]).tolist(),
        "attack": [int(window[0]), int(window[-1]) + 1] if window.size else None,
        "num_points": int(geo.num_points),
    })
    return out


def summary_serving(summary) -> list[bool] | None:
    """[num_bs] bool from a run's ``propagation_summary.json`` (parsed): True for the BSs some
    point measures, where the run chose among candidate sites (its ``serving_bs`` ids), as the
    run's maps draw them apart (:func:`~veriloc_rt.report.plots.serving_mask`); None where it
    did not (every BS alike), before the file exists, or when it does not hold valid ids."""
    if not isinstance(summary, dict):
        return None
    ids, num = summary.get("serving_bs"), summary.get("num_bs")
    if (not isinstance(ids, list) or isinstance(num, bool) or not isinstance(num, int)
            or not all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i < num
                       for i in ids)):
        return None
    mask = [False] * num
    for i in ids:
        mask[i] = True
    return mask


def _roof_triangles(tri: np.ndarray) -> list:
    """[n, 6] top-view triangles of a mesh: faces with a projected area (not walls) whose top
    is above the lowest ground, largest first, at most :data:`MAX_MESH_TRIANGLES`.

    tri : [num_triangles, 3, 3] float64, m
    """
    a, b, c = tri[:, 0, :2], tri[:, 1, :2], tri[:, 2, :2]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                        - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))
    top = tri[:, :, 2].max(axis=1)
    keep = np.flatnonzero((area > 1e-6) & (top > tri[:, :, 2].min() + 1.0))
    keep = keep[np.argsort(-area[keep])][:MAX_MESH_TRIANGLES]
    xy = tri[keep][:, :, :2].reshape(len(keep), 6)
    return (np.round(xy / COORD_STEP_M) * COORD_STEP_M).tolist()


class RunFolderState:
    """The live state of one run folder, polled by the page (:meth:`state`).

    Thread-safe: the server's request threads share one instance. The map's layer
    (:func:`scene_layer`) is built once per config, in a background thread.

    :param folder: the run's ``--out`` folder (it may not exist yet)
    :param clock: wall clock, s (tests pass their own)
    """

    def __init__(self, folder: str | Path, clock=time.monotonic):
        self.folder = Path(folder)
        self.clock = clock
        self._lock = threading.Lock()
        self._tails: dict[str, ResultsTail] = {}
        #: per scenario ((generation, rows), scenario_metrics of those rows)
        self._metrics: dict[str, tuple] = {}
        self._meter = RateMeter()
        self._config_text: str | None = None
        self._cfg = None
        self._scene: dict | None = None
        self._scene_version = 0
        self._scene_thread: threading.Thread | None = None
        #: the realisations' states of a Monte Carlo folder, by folder
        self._children: dict[Path, RunFolderState] = {}
        #: set by whoever started the run (the editor): a callable -> (returncode or None, text)
        self.process_status = None
        #: (the summary file's identity, :func:`summary_serving` of it): read again when it changes
        self._serving: tuple = (None, None)

    # -- run.json ---------------------------------------------------------------------------
    def _run_info(self) -> dict | None:
        # absent, not a regular file, or (never: written atomically) partial: None
        info = read_json(self.folder / "run.json")
        return info if isinstance(info, dict) and "config" in info else None

    def run_config(self) -> dict | None:
        """The config in the folder's ``run.json`` (None without one)."""
        info = self._run_info()
        cfg = info["config"] if info is not None else None
        return cfg if isinstance(cfg, dict) else None

    def _update_config(self, info: dict | None) -> None:
        if info is None:
            return
        text = json.dumps(info["config"], sort_keys=True)
        if text == self._config_text:
            return
        try:
            cfg = config_from_dict(info["config"])
        except ValueError as exc:
            log.warning("%s/run.json: config not readable (%s)", self.folder, exc)
            return
        self._config_text, self._cfg, self._scene = text, cfg, None
        self._scene_version += 1
        version = self._scene_version
        self._scene_thread = threading.Thread(target=self._build_scene, args=(cfg, version),
                                              name="veriloc-live-scene", daemon=True)
        self._scene_thread.start()

    def _build_scene(self, cfg, version: int) -> None:
        try:
            layer = scene_layer(cfg)
        except Exception as exc:  # noqa: BLE001 - the map stays empty; the rest works
            log.warning("map of %s not available: %s", self.folder, exc)
            layer = {"ready": True, "error": f"{type(exc).__name__}: {exc}"}
        with self._lock:
            if version == self._scene_version:
                self._scene = layer

    def wait_scene(self, timeout: float | None = None) -> None:
        """Block until the map's layer of the current config (and of every realisation shown
        so far) is built (tests, screenshots)."""
        t = self._scene_thread
        if t is not None:
            t.join(timeout)
        for child in list(self._children.values()):
            child.wait_scene(timeout)

    # -- Monte Carlo: a folder of realisation folders ----------------------------------------
    def _realisation(self, info: dict | None) -> tuple["RunFolderState", dict] | None:
        """For a Monte Carlo folder (``run.json`` lists ``realisations``): the state of the
        realisation to show (the first one still running, else the last one begun) and
        ``{"done", "total", "following"}``; None for a single run."""
        listing = (info or {}).get("realisations")
        if not isinstance(listing, list) or not listing:
            return None
        dirs = [self.folder / str(r.get("dir", "")) for r in listing if isinstance(r, dict)]
        status = []
        for d in dirs:
            info = read_json(d / "run.json")
            status.append(info.get("status") if isinstance(info, dict) else None)
        begun = [i for i, st in enumerate(status) if st is not None]
        running = [i for i, st in enumerate(status) if st == "running"]
        pick = running[0] if running else (begun[-1] if begun else 0)
        if pick >= len(dirs):
            return None
        path = dirs[pick]
        with self._lock:
            child = self._children.get(path)
            if child is None:
                child = self._children[path] = RunFolderState(path, self.clock)
        return child, {"done": status.count("complete"), "total": len(dirs),
                       "following": path.name}

    def scene(self) -> dict:
        """The map's fixed layer (:func:`scene_layer`), ``{"ready": False}`` until it exists,
        ``{"ready": False, "run": False}`` while the folder holds no run (nothing to build: the
        page says so instead of waiting); of the realisation shown, for a Monte Carlo folder."""
        info = self._run_info()
        if info is None:
            return {"ready": False, "run": False, "version": self._scene_version}
        mc = self._realisation(info)
        if mc is not None:
            out = mc[0].scene()
            out["version"] = f"{mc[1]['following']}:{out['version']}"
            return out
        with self._lock:
            self._update_config(info)
            out = dict(self._scene) if self._scene is not None else {"ready": False}
            out["version"] = self._scene_version
            return out

    def _serving_mask(self) -> list[bool] | None:
        """:func:`summary_serving` of the folder's ``propagation_summary.json`` (read again
        only when the file changes); None too when its BS count is not the map's (the map's
        BSs rebuilt from the config are then not the ones the ids name)."""
        path = self.folder / "propagation_summary.json"
        try:
            st = os.stat(path)
            key = (st.st_ino, st.st_mtime_ns, st.st_size)
        except OSError:
            key = None
        if key != self._serving[0]:
            self._serving = (key, summary_serving(read_json(path)) if key is not None else None)
        mask = self._serving[1]
        bs = (self._scene or {}).get("bs")
        if mask is not None and bs is not None and len(bs) != len(mask):
            log.debug("%s: %d BSs in propagation_summary.json, %d on the map; drawn alike",
                      self.folder, len(mask), len(bs))
            return None
        return mask

    # -- polled state -----------------------------------------------------------------------
    def _scenarios(self) -> tuple[str, ...]:
        return self._cfg.run.scenarios if self._cfg is not None else ()

    def _status(self, info: dict | None) -> tuple[str, str]:
        """(status, stage): status 'waiting' (no run.json yet), 'running', 'stopped' (the run
        ended unfinished: ``--resume`` continues it; no run holds the folder, or its owner
        file names a process of this host that has ended, left by a run killed outright:
        :func:`~veriloc_rt.sim.run_folder.run_is_alive`), 'complete'; stage 'setup',
        'propagation', 'scenarios' or 'done'."""
        if info is None:
            return "waiting", "setup"
        if info.get("status") == "complete":
            return "complete", "done"
        status = "running" if run_is_alive(self.folder) else "stopped"
        stage = ("scenarios" if (self.folder / "propagation_summary.json").exists()
                 else "propagation")
        return status, stage

    def state(self, scenario: str | None = None, start: int = 0) -> dict:
        """The page's poll: status, progress and ETA of every scenario, the shares so far and
        the points of ``scenario`` from index ``start`` on.

        ``scenarios``: [{name, done, total, eta_s, generation, metrics}], in run order;
        ``metrics`` as :func:`~veriloc_rt.report.results.scenario_metrics` over the rows so far.
        ``eta_s``: seconds until the whole run ends, at the rate of the last
        :data:`RATE_WINDOW_S` (None before it is known). ``serving``: [num_bs] bool, the map's
        BSs some point measures, once a run that chose among candidate sites has chosen
        (:func:`summary_serving`), else None (every BS drawn alike). For a Monte Carlo
        folder: the state of the realisation shown (:meth:`_realisation`) with the folder's
        own status, ``montecarlo``: ``{"done", "total", "following"}`` and no overall ETA.
        """
        mc = self._realisation(self._run_info())
        if mc is not None:
            child, progress = mc
            out = child.state(scenario, start)
            with self._lock:
                status, _stage = self._status(self._run_info())
            tag = progress["following"]
            out.update(folder=str(self.folder), status=status, montecarlo=progress,
                       scene_version=f"{tag}:{out['scene_version']}")
            for sc in out["scenarios"]:
                sc["generation"] = f"{tag}:{sc['generation']}"
            if "points" in out:   # another realisation's points are another series
                out["points"]["generation"] = f"{tag}:{out['points']['generation']}"
            if status != "complete":
                out["eta_s"] = None
        else:
            out = self._single_state(scenario, start)
        if self.process_status is not None:
            code, text = self.process_status()
            out["process"] = {"returncode": code, "message": text}
        return out

    def _uninformative(self) -> dict:
        """``{scenario: uninformative_detectors}`` of a finished run's metrics.json ({} when it
        has none)."""
        try:
            scen = read_json(self.folder / "metrics.json")["scenarios"]
        except (KeyError, TypeError):
            return {}
        if not isinstance(scen, dict):
            return {}
        return {k: v["uninformative_detectors"] for k, v in scen.items()
                if isinstance(v, dict) and "uninformative_detectors" in v}

    def _single_state(self, scenario: str | None, start: int) -> dict:
        with self._lock:
            now = self.clock()
            info = self._run_info()
            self._update_config(info)
            status, stage = self._status(info)
            names = self._scenarios()
            total = (self._scene or {}).get("num_points") or (
                self._cfg.trajectory.num_points if self._cfg is not None else None)
            for name in names:
                tail = self._tails.setdefault(name, ResultsTail(results_path(self.folder, name)))
                tail.poll()
            done_all = sum(len(self._tails[n].rows) for n in names)
            self._meter.observe(now, done_all)
            rate = self._meter.rate(now) if status == "running" else None
            rows_left, scen = 0, []
            for name in names:
                tail = self._tails[name]
                done = len(tail.rows)
                rows_left += max((total or done) - done, 0)
                eta = 0.0 if total is not None and done >= total else (
                    rows_left / rate if rate else None)
                key = (tail.generation, done, status == "complete")
                if self._metrics.get(name, (None,))[0] != key:   # rows added, or run done
                    self._metrics[name] = (key, scenario_metrics(tail.rows, name))
                    if status == "complete":   # the ROC's flags, known once the run is done
                        flags = self._uninformative().get(name)
                        if flags is not None:
                            self._metrics[name][1]["uninformative_detectors"] = flags
                scen.append({"name": name, "done": done, "total": total, "eta_s": eta,
                             "generation": tail.generation, "metrics": self._metrics[name][1]})
            out = {
                "folder": str(self.folder), "status": status, "stage": stage,
                "num_points": total, "scenarios": scen,
                "eta_s": 0.0 if status == "complete" else (rows_left / rate if rate else None),
                "rate_points_per_s": rate,
                "detectors": list(DETECTORS), "outcomes": list(OUTCOMES),
                "scene_version": self._scene_version, "serving": self._serving_mask(),
            }
            sel = scenario if scenario in names else (names[0] if names else None)
            if sel is not None:
                tail = self._tails[sel]
                out["points"] = {"scenario": sel, "generation": tail.generation,
                                 **points_json(tail.rows, max(0, min(start, len(tail.rows))))}
        return out
