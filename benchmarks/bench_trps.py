"""What each added TRP costs the chain: seconds per point of the benign standard-PRS chain
(waveform, channel, ToA, fix, AoA, tags, uplink) for several ``topology.num_trps``.

Builds each config's geometry and UMa links (``propagation.model`` 'uma'), then calls the
chain (:class:`~veriloc_rt.phy.chain.PositioningChain`) on the first ``--points`` points in
this process, one after the other, and prints the median seconds per point, the stages' shares
and the least-squares slope over the TRP counts (seconds per added TRP). A benchmark, not a
test: the figures depend on the machine and its load.

    .venv/bin/python benchmarks/bench_trps.py [--trps 3 6 9 12 18] [--points 10] [--mode pathloss_only]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import harness  # noqa: E402
import numpy as np  # noqa: E402

from veriloc_rt.config import config_from_dict  # noqa: E402
from veriloc_rt.errors import InputError  # noqa: E402
from veriloc_rt.phy.chain import STAGES, PositioningChain  # noqa: E402
from veriloc_rt.phy.security.keys import simulated_keys  # noqa: E402
from veriloc_rt.sim.engine import compute_propagation  # noqa: E402


def per_point(n: int, points: int, mode: str) -> tuple[float, dict]:
    """Median seconds per point of the chain with ``n`` TRPs, and its stages' seconds."""
    cfg = config_from_dict({"propagation": {"model": "uma", "uma_mode": mode},
                            "topology": {"num_trps": n}, "channel": {"power_control": False},
                            "trajectory": {"num_points": max(points, 2)}})
    with harness.geometry(cfg) as geo:
        prop = compute_propagation(cfg, geo)
    keys = simulated_keys(range(len(geo.bs_pos)), np.random.default_rng(0))
    chain = PositioningChain(cfg.nr, cfg.security, cfg.channel, cfg.receiver,
                             cfg.propagation.ue_array, cfg.propagation.carrier_frequency_hz, keys)
    chain(prop.bs_ue, 0, np.random.default_rng([1, 0]))      # warm-up: replicas, caches
    before = dict(chain.stage_s)
    times = []
    for k in range(points):
        t = time.perf_counter()
        chain(prop.bs_ue, k, np.random.default_rng([1, k]), frame=k + 1)
        times.append(time.perf_counter() - t)
    return float(np.median(times)), {s: (chain.stage_s[s] - before[s]) / points for s in STAGES}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trps", type=int, nargs="+", default=[3, 6, 9, 12, 18])
    ap.add_argument("--points", type=int, default=10)
    ap.add_argument("--mode", default="pathloss_only", choices=("pathloss_only", "fast_fading"))
    args = ap.parse_args(argv)
    if args.points < 1:
        print("error: --points: at least 1", file=sys.stderr)
        return 2
    rows = []
    try:
        for n in args.trps:
            s, stages = per_point(n, args.points, args.mode)
            rows.append((n, s))
            top = ", ".join(f"{k} {v * 1e3:.0f}" for k, v in sorted(stages.items(),
                                                                       key=lambda kv: -kv[1])[:4])
            print(f"{n:3d} TRPs: {s * 1e3:7.1f} ms per point   (stages, ms: {top})", flush=True)
    except InputError as exc:
        print(f"error: {exc.field}: {exc.problem}", file=sys.stderr)
        return 2
    if len(rows) >= 2:
        n, s = np.array(rows, dtype=float).T
        slope, icept = np.polyfit(n, s, 1)
        print(f"per added TRP: {slope * 1e3:.1f} ms per point (least squares over "
              f"{len(rows)} TRP counts; {icept * 1e3:.1f} ms at zero TRPs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
