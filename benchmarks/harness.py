"""The benchmarks' shared harness: what every benchmark here repeated before it was factored.

* :func:`geometry`: a config's geometry (scene, BSs, drive) built in a folder, by default a
  temporary one removed afterwards;
* :func:`serving_links`, :func:`run_links`: the transmitter and receiver positions of the
  serving BS -> UE links of a range of trajectory points, or of every link a run traces there
  (serving BS -> UE, serving BS -> adversary, adversary -> UE);
* :func:`loaded_tracer`: a :class:`~veriloc_rt.propagation.raytrace.LinkTracer` with no cache
  and its scene already loaded (loading is not tracing), :func:`timed_links` the traced paths
  of given links and their wall seconds;
* :func:`timed_trace`: a run's propagation (``raytrace.trace``) on some points, no cache, with
  its wall seconds (the fastest of a few identical traces when asked): the package's own,
  :func:`veriloc_rt.studies.timing.timed_trace`, which ``veriloc-rt bench`` times with;
* :func:`power_deviation`: link by link, a trace's received power against a reference trace's;
* :func:`scenario_runner`: a :class:`~veriloc_rt.sim.runner.ScenarioRunner` of a config (of
  the installed package or of a copy under another name, for A/B timings);
* :func:`run_cli`: ``veriloc-rt run`` in its own process, its wall seconds and ``metrics.json``;
* :func:`kernel_cache`, :func:`kernel_count`: a kernel cache folder of the bench's own (Dr.Jit's,
  ``DRJIT_CACHE_DIR``, and the chain's Numba kernels', ``NUMBA_CACHE_DIR``), emptied for a cold
  run, and the Dr.Jit kernels it holds;
* :func:`machine_speed`, :func:`speed_line`: what four fixed workloads of the chain's kinds
  cost on this machine now (a transform, normals, a pass over a grid, the interpreter), to tell
  a slower hour from slower code when benches of different hours are compared.

The benchmarks import it as a sibling module (``python benchmarks/NAME.py`` puts this folder
first on ``sys.path``).
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from veriloc_rt.studies.timing import timed_trace  # noqa: F401 - the benchmarks' too

ROOT = Path(__file__).resolve().parents[1]
#: the file suffix of Dr.Jit's compiled LLVM kernels in its cache folder
KERNEL_SUFFIX = ".bin"


@contextlib.contextmanager
def geometry(cfg, folder: str | Path | None = None, package: str = "veriloc_rt"):
    """The geometry of ``cfg`` built in ``folder`` (None: a temporary folder, removed on exit)."""
    build = importlib.import_module(package + ".world.geometry").build_geometry
    if folder is not None:
        yield build(cfg, Path(folder))
        return
    with tempfile.TemporaryDirectory(prefix="vr_bench_scene_") as tmp:
        yield build(cfg, Path(tmp))


def _points(geo, points) -> np.ndarray:
    return np.arange(geo.num_points) if points is None else np.asarray(points, dtype=int)


def serving_links(geo, points=None) -> tuple[np.ndarray, np.ndarray]:
    """(tx [L, 3], rx [L, 3]) of the serving BS -> UE links of ``points`` (None: all), three a
    point, point-major (the order of a run's ``bs_ue`` links)."""
    sel = _points(geo, points)
    return geo.bs_pos[geo.serving[sel]].reshape(-1, 3), np.repeat(geo.ue.pos[sel], 3, axis=0)


def run_links(geo, points=None) -> tuple[np.ndarray, np.ndarray]:
    """(tx, rx) of every link a run traces at ``points``: serving BS -> UE, serving BS ->
    adversary, adversary -> UE, in that order."""
    sel = _points(geo, points)
    bs = geo.bs_pos[geo.serving[sel]].reshape(-1, 3)
    ue, adv = geo.ue.pos[sel], geo.adversary.pos[sel]
    return (np.concatenate([bs, bs, adv]),
            np.concatenate([np.repeat(ue, 3, axis=0), np.repeat(adv, 3, axis=0), ue]))


def loaded_tracer(scene_xml, cfg, seed: int | None = None):
    """A LinkTracer of ``cfg``'s ray-tracing fidelity on ``scene_xml``, no cache, scene loaded."""
    from veriloc_rt.propagation.raytrace import LinkTracer

    tracer = LinkTracer(scene_xml, cfg.propagation.carrier_frequency_hz, cfg.propagation.raytrace,
                        cfg.seed if seed is None else seed, cache_dir=None)
    tracer.sionna_tracer()   # loading the scene is not tracing
    return tracer


def timed_links(tracer, tx, rx, fid=None):
    """(raw paths, wall seconds) of tracing the links ``tx -> rx`` with ``tracer`` at its
    fidelity (``fid``: another ``RayTracingConfig`` for the direction and rays)."""
    from veriloc_rt.propagation.raytrace import trace_links

    fid = fid or tracer.fid
    kept, tracer.fid = tracer.fid, fid    # the tracer launches its fid's rays_per_source
    try:
        t0 = time.perf_counter()
        raw = trace_links(tracer, tx, rx, fid.direction == "reciprocal")
        return raw, time.perf_counter() - t0
    finally:
        tracer.fid = kept


def power_deviation(prop, ref, points) -> tuple[dict, np.ndarray, np.ndarray]:
    """Link by link at ``points``, ``prop`` against the reference propagation ``ref``: the
    serving links' deviations (``link_metrics.link_deviation``), their absolute received-power
    deviations, dB, and the adversary -> UE links' absolute power deviations, dB."""
    from veriloc_rt.propagation import link_metrics as lm

    def dev(a, b):
        return lm.link_deviation(lm.cir_link_arrays(a, points), lm.cir_link_arrays(b, points))

    d = dev(prop.bs_ue, ref.bs_ue)
    return d, np.abs(d["power_dev_db"]), np.abs(dev(prop.adv_ue, ref.adv_ue)["power_dev_db"])


def scenario_runner(config: str | Path | None, points: int | None, work: Path,
                    package: str = "veriloc_rt", changes: dict | None = None):
    """A ScenarioRunner of package ``package`` (importable under that name) on ``config``
    (None: the built-in default) with ``points`` trajectory points (None: the config's) and
    the config ``changes`` ({dotted path: value}); the scene is built under ``work``, the
    propagation computed in this process (a ray-traced config reads its default propagation
    cache)."""
    cfgm = importlib.import_module(package + ".config")
    eng = importlib.import_module(package + ".sim.engine")
    run = importlib.import_module(package + ".sim.runner")
    keys = importlib.import_module(package + ".sim.run_folder")
    cfg = cfgm.load_config(config)
    if changes:
        cfg = cfg.updated(changes)
    cfg = cfgm.with_overrides(cfg, points=points)
    geo = eng.build_geometry(cfg, work / ("scene_" + package))
    prop = eng.compute_propagation(cfg, geo, None, "default", workers=1)
    return run.ScenarioRunner(cfg, geo, prop, keys.run_keys(cfg, len(geo.bs_pos)))


def parse_assignments(items, what: str, as_json: bool) -> dict:
    """``NAME=VALUE`` command-line items as {NAME: VALUE} (VALUE read as JSON when ``as_json``);
    raises ValueError naming ``what`` for an item without ``=`` or, as JSON, an unreadable value."""
    out = {}
    for item in items or ():
        if "=" not in item:
            raise ValueError(f"{what}: {item!r} is not NAME=VALUE")
        k, v = item.split("=", 1)
        out[k] = json.loads(v) if as_json else v
    return out


def run_cli(cfg: dict, out: Path, *extra: str, env: dict | None = None) -> tuple[float, dict]:
    """``veriloc-rt run --out OUT/run EXTRA -- OUT/config.json`` in its own process (``-I``:
    nothing imported from the current folder), its stdout and stderr kept in OUT; returns
    (wall seconds, the run's metrics.json). ``env``: variables added to this process's."""
    out.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(out / "run", ignore_errors=True)
    cfg_path = out / "config.json"
    cfg_path.write_text(json.dumps(cfg, indent=2))
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-I", "-m", "veriloc_rt.cli", "run", "--out",
                           str(out / "run"), *extra, "--", str(cfg_path)],
                          capture_output=True, text=True, env={**os.environ, **(env or {})})
    wall = time.perf_counter() - t
    (out / "stdout.txt").write_text(proc.stdout)
    (out / "stderr.txt").write_text(proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"error: {out}: the run failed (exit {proc.returncode}); see "
                         f"{out / 'stderr.txt'}")
    return wall, json.loads((out / "run" / "metrics.json").read_text())


def kernel_cache(folder: Path, empty: bool = False) -> dict:
    """The environment that points the compiled-kernel caches at ``folder`` (created; emptied
    first when ``empty``): ``DRJIT_CACHE_DIR``, which Dr.Jit reads at start instead of
    ``~/.drjit``, and ``NUMBA_CACHE_DIR`` (``folder/numba``), where the chain's Numba kernels
    (``veriloc_rt/phy/jit.py``) are kept instead of beside their modules; and a home of the
    bench's own, ``folder/home`` (``HOME``, ``XDG_CACHE_HOME``, ``XDG_CONFIG_HOME`` and
    ``MPLCONFIGDIR`` under it), so that every per-user cache (matplotlib's font list among
    them) starts empty too: an emptied folder is a new user's first run, which compiles and
    builds them all."""
    if empty:
        shutil.rmtree(folder, ignore_errors=True)
    home = folder / "home"
    home.mkdir(parents=True, exist_ok=True)
    home = home.resolve()
    return {"DRJIT_CACHE_DIR": str(folder.resolve()), "NUMBA_CACHE_DIR": str((folder / "numba").resolve()),
            "HOME": str(home), "XDG_CACHE_HOME": str(home / ".cache"),
            "XDG_CONFIG_HOME": str(home / ".config"), "MPLCONFIGDIR": str(home / ".config" / "matplotlib")}


def kernel_count(folder: Path) -> int:
    """Compiled kernels in a Dr.Jit kernel cache folder (one file each)."""
    return sum(1 for p in folder.glob("*" + KERNEL_SUFFIX)) if folder.is_dir() else 0


#: the fixed workloads of :func:`machine_speed`, the kinds of work the chain's CPU goes to
#: (docs/performance.md, "the arithmetic's floor"): the ToA scan's transform (pocketfft, [135,
#: 1024] complex64), noise normals (PCG64 ziggurat, 200,000), one elementwise pass over the
#: paper config's grid (complex128 [5, 10, 14, 624] added in place) and the interpreter (a
#: Python loop of 50,000 additions)
SPEED_WORKLOADS = ("fft", "normals", "grid pass", "python")


def machine_speed(repeats: int = 25) -> dict[str, float]:
    """ms of CPU (thread time) a call of each of :data:`SPEED_WORKLOADS`: the median of
    ``repeats`` passes of 20 calls. The same work at every call, so two values of one workload
    differ only by the machine's speed at the time: the 2-core VM's varied up to 2x from hour
    to hour, and six probes in one minute spread by 3-5 % (transform, grid pass) and 15-20 %
    (normals, interpreter). About 3 s."""
    import scipy.fft

    rng = np.random.default_rng(0)
    spectra = (rng.standard_normal((135, 1024)) + 1j * rng.standard_normal((135, 1024))).astype(np.complex64)
    grid = np.zeros((5, 10, 14, 624), dtype=np.complex128)
    other = np.ones_like(grid)
    gen = np.random.Generator(np.random.PCG64(1))

    def python():
        total = 0
        for i in range(50_000):
            total += i
        return total

    work = {"fft": lambda: scipy.fft.ifft(spectra, axis=-1),
            "normals": lambda: gen.standard_normal(200_000),
            "grid pass": lambda: np.add(grid, other, out=grid),
            "python": python}
    out = {}
    for name in SPEED_WORKLOADS:
        passes = []
        for _ in range(repeats):
            t = time.thread_time()
            for _ in range(20):
                work[name]()
            passes.append(time.thread_time() - t)
        out[name] = 1000.0 * float(np.median(passes)) / 20
    return out


def speed_line(now: dict[str, float], before: dict[str, float] | None = None) -> str:
    """``machine: fft 0.52 ms, normals ...`` of :func:`machine_speed`'s values, and with
    ``before`` each one's change against it in per cent (positive: slower now)."""
    parts = []
    for name in SPEED_WORKLOADS:
        part = f"{name} {now[name]:.3g} ms"
        if before is not None and before.get(name):
            part += f" ({100.0 * (now[name] / before[name] - 1.0):+.0f} %)"
        parts.append(part)
    return "machine: " + ", ".join(parts)
