"""The uplink's noise and noise estimate a BS, with and without the shortcuts ``ulnoise`` and
``ulnoisevar``, one process.

Builds the config's :class:`~veriloc_rt.phy.receiver.uplink.UplinkPositioner` three times (the
reference path ``VERILOC_RT_REFERENCE=ulnoise,ulnoisevar``; ``ulnoisevar``: the noise on the
REs read, the estimate from the grid; the default: both shortcuts) and times what the
shortcuts change for one BS: its received grid's noise (:meth:`UplinkPositioner.receive` of a
link without paths, so no channel arithmetic) and the noise estimate
(:meth:`UplinkPositioner.noise_estimate`), the three alternating pass by pass (thread CPU, the
best of ``--passes`` passes of ``--calls`` calls each). A run's point times this once per
serving BS (the uplink is computed once a point).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_ulnoise.py [CONFIG] [--passes 5] \\
        [--calls 20]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from veriloc_rt.config import config_from_dict  # noqa: E402
from veriloc_rt.phy.channel import Links  # noqa: E402
from veriloc_rt.phy.receiver.uplink import UplinkPositioner  # noqa: E402
from veriloc_rt.phy.shortcuts import ENV  # noqa: E402

VERSIONS = {"reference": "ulnoise,ulnoisevar", "ulnoise": "ulnoisevar", "ulnoise + ulnoisevar": ""}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default="configs/paper-uma.json")
    ap.add_argument("--passes", type=int, default=5)
    ap.add_argument("--calls", type=int, default=20)
    args = ap.parse_args()
    with open(args.config) as f:
        cfg = config_from_dict(json.load(f))
    kept = os.environ.get(ENV)
    positioners = {}
    try:
        for name, env in VERSIONS.items():
            os.environ[ENV] = env
            positioners[name] = UplinkPositioner(cfg.nr, cfg.channel, cfg.receiver)
    finally:
        if kept is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = kept
    empty = Links(np.zeros((1, 1)), np.zeros((1, 1, 1), complex), np.zeros((1, 1)), np.zeros((1, 1), bool))
    rng = np.random.default_rng(1)
    best = dict.fromkeys(positioners, float("inf"))
    for _ in range(args.passes):
        for name, p in positioners.items():
            start = time.thread_time()
            for _ in range(args.calls):
                y = p.receive(empty, 0.0, rng)
                p.noise_estimate(y if y.ndim == 4 else p.ofdm.demodulate(y, p.slots), rng)
            best[name] = min(best[name], (time.thread_time() - start) / args.calls)
    grid = positioners["reference"].grid
    print(f"{args.config}: a BS's SRS grid {grid.shape[0]} slots x 14 symbols x {grid.shape[2]} "
          f"subcarriers, {cfg.nr.num_bs} serving BSs")
    for name, p in positioners.items():
        share = 1.0 if p.read is None else float(p.read.mean())
        print(f"{name:>22}: noise on {share:6.1%} of the REs, estimate "
              f"{'drawn' if p.direct_variance else 'from the grid'}: {best[name] * 1e3:.2f} ms a BS")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
