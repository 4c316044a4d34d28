"""In-process A/B of the per-point chains' CPU between two versions of the package.

Whole runs minutes apart differ by 10 % on a shared machine, so a change worth a few per cent
cannot be timed by running the code before and after. This exports git revision OLD (and NEW,
by default the working tree) as importable copies of the package under other names in a
temporary folder, builds each one's ``ScenarioRunner`` on the same config (scene, propagation
from the same cache), and computes every point's chains (``ScenarioRunner.compute_chains``:
each chain of each scenario the point needs) with the two versions alternating point by point,
in thread CPU time, over ``--passes`` passes (the order swapped each pass), after one untimed
benign and one attack-window point per version (one-time costs). Each point's results are
compared (ToA, detection, fix, tag verdicts) and the differing points counted.

    .venv/bin/python benchmarks/ab_chains.py OLD [--new REV] [CONFIG] [--points 60] [--start 0]
        [--passes 2]

The copies import their own modules (the package imports its parts relatively); data files come
from the installed package (``importlib.resources``), so a change to ``veriloc_rt/data`` is not
compared. Ray-traced configs read the propagation cache: fill it with one run of the config.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import io  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import harness  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def export(rev: str | None, dest: Path, name: str) -> None:
    """The package at git revision ``rev`` (None: the working tree) as ``dest/name``."""
    if rev is None:
        shutil.copytree(ROOT / "veriloc_rt", dest / name, ignore=shutil.ignore_patterns("__pycache__"))
        return
    blob = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "veriloc_rt"],
                          check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(dest, filter="data")
    (dest / "veriloc_rt").rename(dest / name)


def same(a: dict, b: dict) -> bool:
    """The two versions' chain results of one point agree."""
    if [(k.chain, k.point, k.scenario) for k in a] != [(k.chain, k.point, k.scenario) for k in b]:
        return False
    for ra, rb in zip(a.values(), b.values()):
        if not (np.array_equal(ra.toa_s, rb.toa_s, equal_nan=True)
                and np.array_equal(ra.detected, rb.detected)
                and np.array_equal(ra.tags_valid, rb.tags_valid)
                and np.array_equal(ra.position.position, rb.position.position, equal_nan=True)):
            return False
    return True


def warm_up(runners: dict) -> None:
    """Each version's one-time costs (imports such as the tag decoder's package, tables built at
    a chain's first call) paid untimed, on a benign and an attack-window point: without it the
    version timed first paid them, and a copy compared with itself read 0.88."""
    window = next(iter(runners.values())).window
    warm = {int(np.flatnonzero(~window)[0]) if (~window).any() else 0,
            int(np.flatnonzero(window)[0]) if window.any() else 0}
    for r in runners.values():
        for i in sorted(warm):
            r.compute_chains("none", i)
            r.clear_cache()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", help="git revision of the code before")
    ap.add_argument("config", nargs="?", help="JSON config (default: the built-in default)")
    ap.add_argument("--new", default=None, help="git revision of the code after (default: the working tree)")
    ap.add_argument("--trajectory-points", type=int, default=None,
                    help="the config's trajectory length (default: the config's)")
    ap.add_argument("--points", type=int, default=60, help="points timed")
    ap.add_argument("--start", type=int, default=0, help="first point timed")
    ap.add_argument("--passes", type=int, default=2)
    args = ap.parse_args()
    names = ("vr_ab_old", "vr_ab_new")
    with tempfile.TemporaryDirectory(prefix="ab_chains_") as tmp:
        work = Path(tmp)
        export(args.old, work, names[0])
        export(args.new, work, names[1])
        sys.path.insert(0, str(work))
        runners = {n: harness.scenario_runner(args.config, args.trajectory_points, work, n)
                   for n in names}
        last = runners[names[0]].geo.num_points
        if not 0 <= args.start < args.start + args.points <= last:
            print(f"error: --start/--points: points {args.start}..{args.start + args.points - 1} "
                  f"outside the trajectory's 0..{last - 1}", file=sys.stderr)
            return 2
        warm_up(runners)
        cpu = dict.fromkeys(names, 0.0)
        differ = set()
        for p in range(args.passes):
            for i in range(args.start, args.start + args.points):
                out = {}
                for n in (names if (i + p) % 2 == 0 else names[::-1]):
                    t = time.thread_time()
                    out[n] = runners[n].compute_chains("none", i)
                    cpu[n] += time.thread_time() - t
                    runners[n].clear_cache()
                if not same(out[names[0]], out[names[1]]):
                    differ.add(i)
            print(f"pass {p + 1}: old {cpu[names[0]]:.1f} s, new {cpu[names[1]]:.1f} s (cumulative)",
                  flush=True)
    old, new = cpu[names[0]], cpu[names[1]]
    print(f"{args.points} points from {args.start}, {args.passes} passes: old {old:.1f} s, new "
          f"{new:.1f} s of chain CPU, new/old {new / old:.3f}; points whose results differ: "
          f"{len(differ)}" + (f" (first {min(differ)})" if differ else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
