"""In-process A/B of the adversary's CPU between two versions of the package.

``benchmarks/ab_chains.py`` times ``ScenarioRunner.compute_chains``, which in the attack window
includes every attack scenario's adversary grid (``AdversarySignal.__call__``: the false BS's
replicas, the relay's received and amplified grid, the jammer's noise). This times those calls
alone, inside the same ``compute_chains`` calls: each version's ``AdversarySignal.__call__`` is
wrapped to add its thread CPU time, the versions alternating point by point over two passes (the
order swapped each pass) after the same untimed warm-up, as ab_chains does.

    .venv/bin/python benchmarks/ab_adversary.py OLD [CONFIG] [--new REV] [--points 20]
        [--start S]

``--start`` must lie in the attack window (``run.attack_start_fraction`` of the trajectory) for
there to be an adversary: e.g. 300 on ``configs/paper-uma.json``'s 1200 points.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import importlib  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import ab_chains  # noqa: E402
import harness  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", help="git revision of the code before")
    ap.add_argument("config", nargs="?", help="JSON config (default: the built-in default)")
    ap.add_argument("--new", default=None, help="git revision of the code after (default: the working tree)")
    ap.add_argument("--points", type=int, default=20, help="points timed")
    ap.add_argument("--start", type=int, default=0, help="first point timed")
    args = ap.parse_args()
    names = ("vr_ab_old", "vr_ab_new")
    with tempfile.TemporaryDirectory(prefix="ab_adversary_") as tmp:
        work = Path(tmp)
        ab_chains.export(args.old, work, names[0])
        ab_chains.export(args.new, work, names[1])
        sys.path.insert(0, str(work))
        runners = {n: harness.scenario_runner(args.config, None, work, n) for n in names}
        last = runners[names[0]].geo.num_points
        if not 0 <= args.start < args.start + args.points <= last:
            print(f"error: --start/--points: points {args.start}..{args.start + args.points - 1} "
                  f"outside the trajectory's 0..{last - 1}", file=sys.stderr)
            return 2
        ab_chains.warm_up(runners)
        adv = dict.fromkeys(names, 0.0)
        chain = dict.fromkeys(names, 0.0)
        for n in names:
            cls = importlib.import_module(n + ".attacks.adversary").AdversarySignal

            def timed(self, *a, _call=cls.__call__, _n=n, **k):
                t = time.thread_time()
                try:
                    return _call(self, *a, **k)
                finally:
                    adv[_n] += time.thread_time() - t

            cls.__call__ = timed
        for p in range(2):
            for i in range(args.start, args.start + args.points):
                for n in (names if (i + p) % 2 == 0 else names[::-1]):
                    t = time.thread_time()
                    runners[n].compute_chains("none", i)
                    chain[n] += time.thread_time() - t
                    runners[n].clear_cache()
    k = 2 * args.points
    o, w = names
    print(f"{args.points} points from {args.start}, 2 passes, ms a point: adversary old "
          f"{adv[o] / k * 1e3:.1f}, new {adv[w] / k * 1e3:.1f} (new/old {adv[w] / adv[o]:.3f}); "
          f"compute_chains old {chain[o] / k * 1e3:.1f}, new {chain[w] / k * 1e3:.1f}"
          if adv[o] > 0 else "no adversary in these points (start them in the attack window)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
