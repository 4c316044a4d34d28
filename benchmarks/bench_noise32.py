"""The UE noise's draw in double and in single precision (the shortcut ``noise32``), one process.

Times :func:`veriloc_rt.phy.channel.draw_grid_noise_on` on a grid of the paper config's shape
(5 antennas x 10 slots x 14 symbols x 624 subcarriers) with a share of its REs read (0.61: the
paper config's read REs, ``docs/equivalence.md``), the two precisions alternating pass by pass
(process CPU, the best of ``--passes`` passes of ``--draws`` draws each), and the normals alone
(``Generator.standard_normal`` in float64 and float32, the same count).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_noise32.py [--passes 5] [--draws 20]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from veriloc_rt.phy.channel import draw_grid_noise_on  # noqa: E402

SHAPE = (5, 10, 14, 624)
READ_SHARE = 0.61


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", type=int, default=5)
    ap.add_argument("--draws", type=int, default=20)
    args = ap.parse_args()
    read = np.random.default_rng(0).uniform(size=SHAPE[1:]) < READ_SHARE
    read.flags.writeable = False   # as the chain's kept mask (its REs' indices are kept)
    count = 2 * SHAPE[0] * int(np.count_nonzero(read))
    rng = np.random.default_rng(1)
    jobs = {
        "draw_grid_noise_on float64": lambda: draw_grid_noise_on(SHAPE, read, 1.0, rng, False),
        "draw_grid_noise_on float32": lambda: draw_grid_noise_on(SHAPE, read, 1.0, rng, True),
        "standard_normal float64": lambda: rng.standard_normal(count),
        "standard_normal float32": lambda: rng.standard_normal(count, dtype=np.float32),
    }
    best = dict.fromkeys(jobs, np.inf)
    for _ in range(args.passes):
        for name, job in jobs.items():
            t = time.process_time()
            for _ in range(args.draws):
                job()
            best[name] = min(best[name], (time.process_time() - t) / args.draws)
    print(f"grid {SHAPE}, {READ_SHARE:.0%} of the REs read: {count} normals a draw; "
          f"best of {args.passes} passes of {args.draws} draws (process CPU)")
    for name, s in best.items():
        print(f"  {name:28s} {1e3 * s:6.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
