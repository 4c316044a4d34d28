"""The channel stage's compiled kernels (``veriloc_rt/phy/channel_kernels.py``) against the NumPy
code (what compiling them costs: ``benchmarks/bench_jit_compile.py``, every kernel of the chain).

Kernels (in-process, thread CPU, the best of ``--passes`` passes of ``--reps`` calls each,
the two versions alternating pass by pass, after a warm-up call that compiles), on the paper
config's shapes (5 antennas, 10 slots of 14 symbols, 624 subcarriers; three TRPs' comb-6 PRS
with HMAC tags, their masks read-only as a transmitter's are):

* ``apply_frequency``, the three TRPs' links (one path each, as ``uma_mode: pathloss_only``;
  ``--delays U``: U distinct delays a link) and a dense grid's link (a jammer's or the
  meaconer's), with the shortcut ``jitchannel`` and with ``VERILOC_RT_REFERENCE=jitchannel``;
  a link's response computed (the first chain of a point) and kept (the other chains);
* ``draw_grid_noise_on`` on the UE's read REs (the paper chain's: every TRP's PRS REs, the
  symbols without PRS and the slot whose tags are checked, 61 %), float32 and float64 normals:
  the compiled placement (``place_scaled``) against NumPy's scaling and scatter, written out
  here as it was; the normals themselves are the same in both.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_jitchannel.py [--passes 5]
        [--reps 10] [--delays 1]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # as in the engine's worker processes

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

SHAPE = (5, 10, 14, 624)


def best(jobs: dict, passes: int, reps: int, prepare=None) -> dict:
    """{name: best per-call thread CPU ms}, the jobs alternating pass by pass; ``prepare()``
    (untimed) before each call."""
    for f in jobs.values():
        f()
    out = {k: np.inf for k in jobs}
    for p in range(passes):
        for name in (list(jobs) if p % 2 == 0 else list(jobs)[::-1]):
            spent = 0.0
            for _ in range(reps):
                if prepare is not None:
                    prepare()
                t = time.thread_time()
                jobs[name]()
                spent += time.thread_time() - t
            out[name] = min(out[name], 1e3 * spent / reps)
    return out


def paper_frame(tags: str = "hmac"):
    """Three TRPs' PRS grids [3, 10, 14, 624] (``tags``: their tag scheme), their read-only
    masks, a dense grid."""
    from veriloc_rt.config.nr import NRConfig
    from veriloc_rt.config.security import SecurityConfig
    from veriloc_rt.phy.channel import add_noise
    from veriloc_rt.phy.security.keys import simulated_keys
    from veriloc_rt.phy.transmitter import PRSTransmitter

    nr = NRConfig()
    keys = simulated_keys((1, 2, 3), np.random.default_rng(0))
    tx = PRSTransmitter(nr, SecurityConfig(tag_scheme=tags), (1, 2, 3), keys)
    slots = range(SHAPE[1])
    grids, occ = tx(0, slots), tx.occupied(slots)[0]
    dense = add_noise(np.zeros((1,) + grids.shape[1:]), 1.0, np.random.default_rng(1))
    return nr, slots, grids, occ, dense


def bench_apply(passes: int, reps: int, delays: int) -> None:
    from veriloc_rt.phy import channel as ch
    from veriloc_rt.phy.nr.ofdm import OFDM

    nr, slots, grids, occ, dense = paper_frame()
    ofdm = OFDM(nr)
    assert grids.shape[2:] == SHAPE[2:], grids.shape
    rng = np.random.default_rng(2)
    p = delays
    d = 1e-6 + rng.uniform(0, 2e-6, (4, p))
    links = ch.Links(d, rng.standard_normal((4, SHAPE[0], p)) + 1j * rng.standard_normal((4, SHAPE[0], p)),
                     rng.uniform(-150, 150, (4, p)), np.ones((4, p), dtype=bool))
    trps = ch.Links(links.delays[:3], links.gains[:3], links.doppler[:3], links.valid[:3])
    adv = ch.Links(links.delays[3:], links.gains[3:], links.doppler[3:], links.valid[3:])
    amps = np.array([1.0, 0.7, 0.4])
    dense_occ = np.ones(dense.shape, dtype=bool)

    def job(which, env):
        def run():
            if env:
                os.environ["VERILOC_RT_REFERENCE"] = "jitchannel"
            else:
                os.environ.pop("VERILOC_RT_REFERENCE", None)
            if which == "trps":
                ch.apply_frequency(trps, grids, amps, ofdm, slots, 0.9e-6, occ)
            else:
                ch.apply_frequency(adv, dense, np.array([0.3]), ofdm, slots, 0.9e-6, dense_occ)
            os.environ.pop("VERILOC_RT_REFERENCE", None)
        return run

    def forget():   # the first chain of a point: the links' responses computed
        ch.KEPT_RESPONSES.__dict__.clear()

    print(f"apply_frequency, links of {delays} distinct delay(s), ms a call (thread CPU, best of "
          f"{passes} x {reps}; reference: VERILOC_RT_REFERENCE=jitchannel, NumPy's products):")
    for which, label in (("trps", "3 TRPs' PRS (sparse)"), ("dense", "a dense grid's link")):
        for kept in (False, True):
            r = best({"numpy": job(which, True), "jit": job(which, False)}, passes, reps,
                     None if kept else forget)
            print(f"  {label:22s} response {'kept    ' if kept else 'computed'}: reference {r['numpy']:6.2f}, "
                  f"jitchannel {r['jit']:6.2f}, ratio {r['jit'] / r['numpy']:.3f}")


def numpy_grid_noise_on(shape, read_index, variance, rng, single):
    """draw_grid_noise_on as written before its placement was compiled: the normals scaled
    (standard_normals), then scattered onto a zeroed grid."""
    from veriloc_rt.phy.channel import standard_normals

    a, s = shape[0], shape[1]
    out = np.zeros((s, a) + tuple(shape[2:]), dtype=np.complex128)
    out.reshape(-1)[read_index] = standard_normals(rng, read_index.size, np.sqrt(variance / 2.0), single)
    return np.moveaxis(out, 0, 1)


def bench_noise(passes: int, reps: int) -> None:
    from veriloc_rt.phy import channel as ch

    # the chain's read mask: every replica's PRS REs, the two symbols without PRS (the noise
    # estimate's) and the slot whose tags are checked
    _, _, _, occ, _ = paper_frame("none")
    read = np.logical_or.reduce(occ) | ~np.logical_or.reduce(occ).any(axis=-1, keepdims=True)
    read[0] = True
    read.flags.writeable = False
    idx = np.flatnonzero(np.broadcast_to(read[:, None], (SHAPE[1], SHAPE[0]) + read.shape[1:]))
    share = read.mean()
    for single in (True, False):
        a = ch.draw_grid_noise_on(SHAPE, read, 2.0, np.random.default_rng(3), single)
        b = numpy_grid_noise_on(SHAPE, idx, 2.0, np.random.default_rng(3), single)
        assert a.strides == b.strides and np.array_equal(a.view(np.int64), b.view(np.int64))
        rngs = {"numpy": np.random.default_rng(4), "jit": np.random.default_rng(4)}
        r = best({"numpy": lambda: numpy_grid_noise_on(SHAPE, idx, 2.0, rngs["numpy"], single),
                  "jit": lambda: ch.draw_grid_noise_on(SHAPE, read, 2.0, rngs["jit"], single)},
                 passes, reps)
        z = np.empty((idx.size, 2), dtype=np.float32 if single else np.float64)
        g = np.random.default_rng(5)
        normals = best({"n": lambda: g.standard_normal(out=z, dtype=z.dtype)}, passes, reps)["n"]
        print(f"draw_grid_noise_on {'float32' if single else 'float64'} ({share:.0%} of the REs read; "
              f"the same bits): NumPy {r['numpy']:.2f} ms, compiled placement {r['jit']:.2f} ms, "
              f"ratio {r['jit'] / r['numpy']:.3f}; the normals alone {normals:.2f} ms")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", type=int, default=5)
    ap.add_argument("--reps", type=int, default=10)
    ap.add_argument("--delays", type=int, default=1)
    args = ap.parse_args()
    bench_apply(args.passes, args.reps, args.delays)
    bench_noise(args.passes, args.reps)
    return 0


if __name__ == "__main__":
    sys.exit(main())
