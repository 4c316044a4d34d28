"""What the chain's compiled kernels (``veriloc_rt.phy.jit``: the ToA search's, the channel
stage's, the tag decoder's) cost before they run: compiled from an empty Numba cache (a fresh
clone's first run), then loaded from the on-disk cache (every later process: a run's workers,
the next run).

Each measurement is a child process with ``NUMBA_CACHE_DIR`` on a new temporary folder (so
neither the kernels' default cache beside the package nor another process interferes): it
imports Numba (timed apart), builds CONFIG's scenario runner and computes the chains of one
benign and one attack-window point; ``veriloc_rt.phy.jit.first_calls`` then gives the first
call of every kernel signature (compile or load, and one run of microseconds). A second child
on the same folder loads what the first compiled. The chains' own one-time costs are not
counted.

    .venv/bin/python benchmarks/bench_jit_compile.py [CONFIG] [--reference] [--kernels]

``--reference``: also with ``VERILOC_RT_REFERENCE=all`` (the reference path's signatures).
``--kernels``: each kernel's seconds too.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, sys, tempfile, time
from pathlib import Path
t = time.perf_counter()
import numba  # noqa: F401
numba_import = time.perf_counter() - t
sys.path.insert(0, str(Path(sys.argv[2]) / "benchmarks"))
import numpy as np
import harness
from veriloc_rt.phy.jit import first_calls
config = None if sys.argv[1] == "default" else sys.argv[1]
r = harness.scenario_runner(config, 40, Path(tempfile.mkdtemp()))
for i in (int(np.flatnonzero(~r.window)[0]), int(np.flatnonzero(r.window)[0])):
    r.compute_chains("none", i)
    r.clear_cache()
first = first_calls()
print(json.dumps({"numba_import_s": numba_import,
                  "signatures": sum(len(v) for v in first.values()),
                  "kernels_s": sum(sum(v) for v in first.values()),
                  "per_kernel_s": {k: sum(v) for k, v in sorted(first.items())}}))
"""


def child(config: str, cache: Path, env_extra: dict) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), **env_extra)
    r = subprocess.run([sys.executable, "-c", CHILD, config, str(ROOT)],
                       env=env, capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default="configs/paper-uma.json")
    ap.add_argument("--reference", action="store_true",
                    help="also with VERILOC_RT_REFERENCE=all")
    ap.add_argument("--kernels", action="store_true", help="each kernel's seconds too")
    args = ap.parse_args()
    envs = [("default", {})] + ([("reference", {"VERILOC_RT_REFERENCE": "all"})]
                                if args.reference else [])
    print("| path | cache | numba import, s | kernel signatures | their first calls, s |")
    print("| --- | --- | --- | --- | --- |")
    for label, extra in envs:
        with tempfile.TemporaryDirectory(prefix="numba_cache_") as tmp:
            for state in ("empty (compile)", "filled (load)"):
                out = child(args.config, Path(tmp), extra)
                print(f"| {label} | {state} | {out['numba_import_s']:.2f} | {out['signatures']} | "
                      f"{out['kernels_s']:.2f} |", flush=True)
                if args.kernels:
                    print("|  |  |  | " + ", ".join(f"{k} {v:.2f}" for k, v in
                                                   out["per_kernel_s"].items()) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
