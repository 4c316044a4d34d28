#!/usr/bin/env python3
"""Benchmark: cold ray tracing of a few points' links of a config, as one tracing process does it.

Traces every link of trajectory points [--start, --start + --points) of the config (the serving
BS -> UE, BS -> adversary and adversary -> UE links, each distinct link once, reciprocal
direction as configured), with no cache, Dr.Jit on one thread (as each of the ``--workers 2``
tracing processes of a run), after loading the scene. Prints the wall and CPU seconds, the time
per distinct link, the share spent enumerating the exhaustive edge candidates and in their
occlusion tests; ``--out`` keeps the traced paths, ``--compare`` checks them against an earlier
``--out`` bit for bit (run the two versions of the code alternately: the machine's speed varies).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_trace_links.py --points 40 --out a.npz
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_trace_links.py --points 40 --compare a.npz
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time

import harness
import numpy as np


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/paper-raytrace.json")
    ap.add_argument("--start", type=int, default=0, help="first trajectory point")
    ap.add_argument("--points", type=int, default=40, help="trajectory points")
    ap.add_argument("--threads", type=int, default=1, help="Dr.Jit threads")
    ap.add_argument("--out", help="save the traced paths (.npz)")
    ap.add_argument("--compare", help="an earlier --out: report whether the paths are the same")
    ap.add_argument("--profile", help="write a cProfile of the tracing here and print its top")
    args = ap.parse_args()

    from veriloc_rt.backend import import_sionna
    from veriloc_rt.config import load_config

    import_sionna()
    import drjit as dr

    from veriloc_rt.propagation import street_solver
    from veriloc_rt.propagation.sionna_rt import RawPaths

    dr.set_thread_count(args.threads)
    cfg = load_config(args.config)
    with harness.geometry(cfg) as geo:
        tx, rx = harness.run_links(geo, range(args.start, min(args.start + args.points,
                                                              geo.num_points)))
        tracer = harness.loaded_tracer(geo.scene_xml, cfg)
        spent = {"candidates": 0.0, "occlusion": 0.0, "segments": 0}
        enumerate_, visible = street_solver.street_candidates, \
            street_solver.StreetCandidateGenerator._visible

        def timed_candidates(*a, **k):
            t = time.perf_counter()
            try:
                return enumerate_(*a, **k)
            finally:
                spent["candidates"] += time.perf_counter() - t

        def timed_visible(self, a, b):
            t = time.perf_counter()
            try:
                return visible(self, a, b)
            finally:
                spent["occlusion"] += time.perf_counter() - t
                spent["segments"] += len(a)

        street_solver.street_candidates = timed_candidates
        street_solver.StreetCandidateGenerator._visible = timed_visible
        prof = cProfile.Profile() if args.profile else None
        c0 = time.process_time()
        if prof:
            prof.enable()
        raw, wall = harness.timed_links(tracer, tx, rx)
        if prof:
            prof.disable()
        cpu = time.process_time() - c0
    n = tracer.stats["links_traced"]
    print(f"{len(tx)} links ({n} distinct, {tracer.stats['calls']} PathSolver calls): "
          f"{wall:.2f} s wall, {cpu:.2f} s CPU, {1e3 * wall / n:.1f} ms a distinct link; "
          f"candidates {spent['candidates']:.2f} s, of it occlusion tests {spent['occlusion']:.2f} s "
          f"({spent['segments']} segments); {int(raw.valid.sum())} valid paths")
    if args.out:
        np.savez(args.out, **raw.to_npz())
    if args.compare:
        with np.load(args.compare) as ref:
            same = all(ref[f].shape == getattr(raw, f).shape
                       and np.array_equal(ref[f], getattr(raw, f)) for f in RawPaths.FIELDS)
            print(f"against {args.compare}: {'the same paths, bit for bit' if same else 'DIFFERENT'}"
                  f" ({int(ref['valid'].sum())} valid paths there)")
    if prof:
        prof.dump_stats(args.profile)
        pstats.Stats(args.profile).sort_stats("tottime").print_stats(25)
    return 0


if __name__ == "__main__":
    sys.exit(main())
