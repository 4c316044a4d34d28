"""The chain's floor: what the library kernels of a config's chains cost a point, alone.

The per-point chains (``ScenarioRunner.compute_chains``: every chain of every scenario a point
needs) spend part of their CPU in library kernels whose work the results depend on value for
value: the noise's normals (NumPy's PCG64 ziggurat), the ToA search's transforms (pocketfft,
through ``scipy.fft``'s public functions, whose dispatch of a few microseconds a call counts),
the tag decoder's belief propagation (the ``ldpc`` package). This runs the chains on a few
benign points and a few attack-window points with those entry points wrapped (the calls only
recorded: the results are the unwrapped code's), then replays every recorded call alone, in a
tight loop on arrays of the recorded shapes (the decoder on the recorded inputs), and prints
what the kernels cost a point against the chain as it runs and against a wall-time target on
``--cores`` cores: the floor a chain that spent nothing else (no interpreter, no copies, no
elementwise NumPy) would still have.

    .venv/bin/python benchmarks/bench_floor.py [CONFIG] [--points 20] [--target-s 60] [--cores 2]
        [--set FIELD=JSON ...]

``--set nr.num_prb=24`` (and 52, 104) separates what grows with the band from what does not: the
chain's CPU a point against the PRBs is close to a line, whose intercept is the per-point work
that batching points could at most remove (interpreter, NumPy dispatch, and the arithmetic of
fixed size: the fix, the tags' words, the signatures).

Not counted (so the floor is a lower bound): BLAS products, signatures, AES, NumPy's own
FFTs, and the elementwise products the model is made of (the channel applied per RE, the
cross-spectra); a ray-traced config reads its propagation cache (fill it with one run).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.fft  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


#: the issue's bound on the default preset's chain CPU a point against this floor (issue 42)
FLOOR_RATIO_BOUND = 1.5


class Recorder:
    """The kernel calls made while ``on``, by kind."""

    def __init__(self):
        self.on = False
        self.normals: list[tuple] = []   # (size, dtype)
        self.fft: list[tuple] = []       # (name, shape, dtype, positional args after the array, keywords)
        self.bp: list[tuple] = []        # (decoder, channel probabilities, hard decisions)


REC = Recorder()


class RecordingGenerator(np.random.Generator):
    """A Generator that records the sizes of its normal draws (the same numbers)."""

    def standard_normal(self, size=None, dtype=np.float64, out=None):
        if REC.on:
            REC.normals.append((size if out is None else out.shape, np.dtype(dtype)))
        return super().standard_normal(size, dtype, out)


class RecordingDecoder:
    """A belief-propagation decoder that records each decode's inputs (the same results)."""

    def __init__(self, real):
        self._real = real
        self._probs = None

    def update_channel_probs(self, probs):
        self._probs = np.array(probs)
        self._real.update_channel_probs(probs)

    def decode(self, hard):
        if REC.on:
            REC.bp.append((self._real, self._probs, np.array(hard)))
        return self._real.decode(hard)

    @property
    def converge(self):
        return self._real.converge


#: the transforms the chains call, through scipy.fft's public functions (the chain's modules
#: look them up on ``scipy.fft`` at each call)
TRANSFORMS = ("fft", "ifft", "rfft", "irfft")
REAL: dict = {}   # the unwrapped transforms


def install_hooks() -> None:
    """Wrap the kernels' entry points (before any chain is built)."""
    import ldpc

    real_rng = np.random.default_rng

    def default_rng(seed=None):
        if isinstance(seed, np.random.Generator):
            return real_rng(seed)
        bg = seed if isinstance(seed, np.random.BitGenerator) else np.random.PCG64(seed)
        return RecordingGenerator(bg)

    np.random.default_rng = default_rng

    real_bp = ldpc.BpDecoder
    ldpc.BpDecoder = lambda *a, **k: RecordingDecoder(real_bp(*a, **k))

    for name in TRANSFORMS:
        REAL[name] = real = getattr(scipy.fft, name)

        def wrapped(x, *args, _real=real, _name=name, **kwargs):
            if REC.on:
                x = np.asarray(x)
                REC.fft.append((_name, x.shape, x.dtype, args, kwargs))
            return _real(x, *args, **kwargs)

        setattr(scipy.fft, name, wrapped)


def chain_cpu(r, points) -> float:
    """Thread CPU seconds of the chains of ``points``."""
    t = time.thread_time()
    for i in points:
        r.compute_chains("none", i)
        r.clear_cache()
    return time.thread_time() - t


def replay(repeats: int = 3) -> dict[str, float]:
    """Thread CPU seconds of the recorded calls alone, by kind (the fastest of ``repeats``
    passes). A transform runs on an array of its recorded shape and type (one per shape: the
    cost does not depend on the values), with the recorded arguments."""
    rng = np.random.Generator(np.random.PCG64(0))
    arrays: dict = {}

    def array(shape, dtype):
        if (shape, dtype) not in arrays:
            a = rng.standard_normal(shape)
            if dtype.kind == "c":
                a = a + 1j * rng.standard_normal(shape)
            arrays[shape, dtype] = a.astype(dtype)
        return arrays[shape, dtype]

    ffts = []
    for name, shape, dtype, args, kwargs in REC.fft:
        if kwargs.get("overwrite_x"):
            # in place on a kept array: the unitary norm keeps it from shrinking call after call
            # (the same single scaling pass as the recorded norm)
            kwargs = dict(kwargs, norm="ortho")
        ffts.append((REAL[name], array(shape, dtype), args, kwargs))
    best = {"normals": np.inf, "fft": np.inf, "bp": np.inf}
    for _ in range(repeats):
        t = time.thread_time()
        for size, dtype in REC.normals:
            rng.standard_normal(size, dtype)
        best["normals"] = min(best["normals"], time.thread_time() - t)
        t = time.thread_time()
        for fn, a, args, kwargs in ffts:
            fn(a, *args, **kwargs)
        best["fft"] = min(best["fft"], time.thread_time() - t)
        t = time.thread_time()
        for dec, probs, hard in REC.bp:
            dec.update_channel_probs(probs)
            dec.decode(hard)
        best["bp"] = min(best["bp"], time.thread_time() - t)
    return best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config", nargs="?", default=str(ROOT / "configs" / "paper-uma.json"))
    ap.add_argument("--points", type=int, default=20, help="points of each range (benign, attack window)")
    ap.add_argument("--target-s", type=float, default=60.0, help="the run's wall-time target [s]")
    ap.add_argument("--cores", type=int, default=2, help="cores the run's workers share")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=JSON",
                    help="a config change (dotted path), e.g. nr.num_prb=24")
    args = ap.parse_args()
    if args.points < 1 or args.cores < 1 or args.target_s <= 0:
        print("error: --points, --cores, --target-s: must be positive", file=sys.stderr)
        return 2
    import harness   # this folder's
    try:
        changes = harness.parse_assignments(args.set, "--set", as_json=True)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from veriloc_rt.errors import InputError

    install_hooks()
    with tempfile.TemporaryDirectory() as tmp:
        try:
            r = harness.scenario_runner(args.config, None, Path(tmp), changes=changes)
        except InputError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        return measure(r, args)


def measure(r, args) -> int:
    """Time the chains and their kernels on ``args.points`` benign and attack-window points."""
    n = len(r.window)
    inside = np.flatnonzero(r.window)
    outside = np.flatnonzero(~r.window)
    share = inside.size / n
    ranges = {"benign": outside[outside.size // 4:][:args.points],
              "attack window": inside[inside.size // 2:][:args.points]}
    rows = {}
    for label, pts in ranges.items():
        # warm, untimed, on the same points: the chain's first calls build its tables, and each
        # compiled kernel (phy/jit.py) is compiled or loaded from its cache at the first call
        # with new argument types, which a later point of the range can be the first to make
        chain_cpu(r, pts)
        cpu = chain_cpu(r, pts)
        REC.on = True
        chain_cpu(r, pts)
        REC.on = False
        calls = {"normals": len(REC.normals), "fft": len(REC.fft), "bp": len(REC.bp)}
        kernels = replay()
        rows[label] = (pts, cpu / pts.size, {k: (calls[k] / pts.size, kernels[k] / pts.size) for k in kernels})
        REC.normals.clear(); REC.fft.clear(); REC.bp.clear()
        print(f"{label}: points {pts[0]}-{pts[-1]}, chain {1000 * cpu / pts.size:.1f} ms a point", flush=True)

    weight = {"benign": 1.0 - share, "attack window": share}
    names = {"normals": "normals (NumPy PCG64 ziggurat)", "fft": "transforms (pocketfft)",
             "bp": "tag decoder's belief propagation (ldpc)"}
    per_point = lambda f: sum(weight[k] * f(v) for k, v in rows.items())   # noqa: E731
    budget = args.target_s * args.cores / n
    print(f"\n{Path(args.config).name}: {n} points, {100 * share:.0f} % in the attack window; "
          f"ms a point, CPU (calls a point)")
    print(f"| | benign | attack window | the run's mean | the run on {args.cores} cores, s |")
    print("| --- | --- | --- | --- | --- |")
    for k, name in names.items():
        b, w = rows["benign"][2][k], rows["attack window"][2][k]
        mean = per_point(lambda v: v[2][k][1])
        print(f"| {name} | {1000 * b[1]:.1f} ({b[0]:.0f}) | {1000 * w[1]:.1f} ({w[0]:.0f}) | {1000 * mean:.1f} | "
              f"{mean * n / args.cores:.0f} |")
    floor = per_point(lambda v: sum(x[1] for x in v[2].values()))
    chain = per_point(lambda v: v[1])
    print(f"| **the kernels** | | | **{1000 * floor:.1f}** | **{floor * n / args.cores:.0f}** |")
    print(f"| the chain as it runs | {1000 * rows['benign'][1]:.1f} | {1000 * rows['attack window'][1]:.1f} | "
          f"{1000 * chain:.1f} | {chain * n / args.cores:.0f} |")
    print(f"\nthe target: {args.target_s:g} s on {args.cores} cores = {1000 * budget:.1f} ms of CPU a point; "
          f"the kernels alone {100 * floor / budget:.0f} % of it, leaving {1000 * (budget - floor):.1f} ms a point "
          f"for everything else, which takes {1000 * (chain - floor):.1f} ms now")
    print(f"the chain against its kernels: {chain / floor:.2f}x (the issue's bound for the default "
          f"preset: {FLOOR_RATIO_BOUND:g}x)" if floor > 0 else "the chain against its kernels: no kernel calls")
    return 0


if __name__ == "__main__":
    sys.exit(main())
