"""Benchmark of the per-point positioning chain (issue 4): speed and accuracy, default vs reference.

1. Seconds per trajectory point of the full chain (3 BSs, HMAC tags, AoA, uplink) at the default
   fidelity (frequency-domain channel and receiver, smallest sample rate) and at the reference
   (time-domain IQ at 122.88 MHz), on the same CIRs and the same noise seeds; the DL position
   deviation between the two (p50/p95). For UMa fast_fading (~400 paths per link) the
   reference applies the paths at 122.88/8 MHz (``ChannelConfig.time_decimation``).
2. Benign DL and UL position error (p50/p95) of the default chain on TR 38.901 UMa
   (pathloss_only and fast_fading) along a simple synthetic trajectory: 3 BSs at alternate
   vertices of a hexagon (R = 289 m, 25 m high), the UE on a 100 m circle at 10 m/s.
3. With ``--rt-cache``: the same on ray-traced CIRs of the default scenario (100 points). They
   come from ``trace(...)`` with that cache directory: it reuses the cache when the scene, config
   and ray-tracing fidelity match what was cached, and otherwise TRACES (30-60 s of CPU), e.g.
   after a change of the default ray-tracing fidelity.

BLAS is limited to one thread (as in the engine's one-process-per-core executors): on a shared
2-core machine multithreaded BLAS on these small matrices is ~10x slower.

Usage: python benchmarks/bench_chain.py [--uma-points 100] [--ref-points 5]
           [--rt-cache out/rt-cache [--rt-scene out/scene100] --rt-points 100]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import harness  # noqa: E402
import numpy as np  # noqa: E402

from veriloc_rt.phy.channel import add_noise  # noqa: E402
from veriloc_rt.phy.noise import NoiseSource, WhiteNoise  # noqa: E402
from veriloc_rt.config.channel import ChannelConfig, ReceiverConfig  # noqa: E402
from veriloc_rt.config import ArrayConfig  # noqa: E402
from veriloc_rt.config.nr import NRConfig  # noqa: E402
from veriloc_rt.propagation.cir import ula_element_positions  # noqa: E402
from veriloc_rt.propagation.uma import uma_cir  # noqa: E402
from veriloc_rt.phy.chain import PositioningChain  # noqa: E402
from veriloc_rt.config.security import SecurityConfig  # noqa: E402
from veriloc_rt.constants import SPEED_OF_LIGHT  # noqa: E402
from veriloc_rt.phy.security.keys import simulated_keys  # noqa: E402

FC = 3.5e9
SEED = 2024


def synthetic_uma(num_points: int, mode: str, seed: int):
    r = 289.0
    bs = np.array([[r * np.cos(a), r * np.sin(a), 25.0] for a in np.deg2rad([90, 210, 330])])
    phi = 0.1 * np.arange(num_points)
    ue = np.stack([100 * np.cos(phi), 100 * np.sin(phi), np.full(num_points, 1.5)], axis=-1)
    vel = np.stack([-10 * np.sin(phi), 10 * np.cos(phi), np.zeros(num_points)], axis=-1)
    ep = ula_element_positions(5, 0.5 * SPEED_OF_LIGHT / FC, 0.0)
    cir = uma_cir(np.broadcast_to(bs, (num_points, 3, 3)).copy(), ue, vel, np.zeros((num_points, 3, 3)),
                  np.tile([0, 1, 2], (num_points, 1)), FC, ep, np.random.default_rng(seed), mode)
    return cir, ue


def make_chain(domain: str, rate: float | None, bs_ids, noise: bool = True, decimation: int = 1,
               source: NoiseSource | None = None, receiver: ReceiverConfig | None = None,
               front_end: str = "correlator") -> PositioningChain:
    keys = simulated_keys(sorted(set(int(b) for b in bs_ids)), np.random.default_rng(7))
    return PositioningChain(NRConfig(sample_rate_hz=rate), SecurityConfig(),
                            ChannelConfig(domain=domain, noise=noise, time_decimation=decimation,
                                          time_front_end=front_end),
                            receiver or ReceiverConfig(), ArrayConfig(), FC, keys, noise=source)


def run(chain: PositioningChain, cir, points, seed: int = SEED) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """DL fixes, UL fixes [n, 3] (NaN when not ok), ok flags and seconds per point."""
    dl = np.full((len(points), 3), np.nan)
    ul = np.full((len(points), 3), np.nan)
    chain(cir, int(points[0]), np.random.default_rng([seed, int(points[0])]))  # warm-up (caches)
    t0 = time.perf_counter()
    for i, k in enumerate(points):
        res = chain(cir, int(k), np.random.default_rng([seed, int(k)]))
        if res.position.ok:
            dl[i] = res.position.position
        if res.uplink is not None and res.uplink.position.ok:
            ul[i] = res.uplink.position.position
    return dl, ul, np.isfinite(dl[:, 0]), (time.perf_counter() - t0) / len(points)


def pct(err: np.ndarray) -> str:
    e = err[np.isfinite(err)]
    if e.size == 0:
        return "no fixes"
    return f"p50 {np.percentile(e, 50):7.2f} m  p95 {np.percentile(e, 95):7.2f} m  ({e.size} fixes)"


class RecordingNoise(WhiteNoise):
    """The reference's: keeps the downlink noise it drew (IQ [A, N]) for the default chain."""

    last_noise: np.ndarray | None = None

    def __call__(self, x, variance, rng):
        n = add_noise(np.zeros_like(x), variance, rng)   # the library's draw, unchanged
        self.last_noise = n
        return x + n


class GivenNoise(WhiteNoise):
    """The default's: adds a given noise grid [A, S, 14, K] instead of drawing one."""

    given: np.ndarray | None = None

    def __call__(self, x, variance, rng):
        return super().__call__(x, variance, rng) if self.given is None else x + self.given


def project_noise(ref: PositioningChain, fast: PositioningChain, noise_iq: np.ndarray) -> np.ndarray:
    """The reference's noise IQ as the default chain's grid sees it: the reference's own OFDM
    demodulation (same symbol windows, same subcarriers), rescaled from the reference's per-RE
    variance (N0 F fs_ref, orthonormal FFT) to the default's (N0 F fs_fast)."""
    if ref.ofdm.num_subcarriers != fast.ofdm.num_subcarriers:
        raise ValueError("the two chains must have the same subcarriers")
    g = ref.ofdm.demodulate(noise_iq, ref.slots)
    return g * np.sqrt(fast.ofdm.sample_rate_hz / ref.ofdm.sample_rate_hz)


def run_pair(fast: PositioningChain, ref: PositioningChain, given: GivenNoise, recorded: RecordingNoise,
             cir, points, seed: int = SEED):
    """Both chains point by point on the same CIRs; with noise, the default gets the reference's
    noise realisation projected on its REs. DL fixes [n, 3] (NaN when not ok), s/point each."""
    dl_f = np.full((len(points), 3), np.nan)
    dl_r = np.full((len(points), 3), np.nan)
    t_f = t_r = 0.0
    fast(cir, int(points[0]), np.random.default_rng(0))  # warm-up (caches)
    ref(cir, int(points[0]), np.random.default_rng(0))
    for i, k in enumerate(points):
        t = time.perf_counter()
        r = ref(cir, int(k), np.random.default_rng([seed, int(k)]))
        t_r += time.perf_counter() - t
        given.given = (project_noise(ref, fast, recorded.last_noise[:, :ref.frame_samples])
                       if ref.noise_var > 0 else None)
        t = time.perf_counter()
        f = fast(cir, int(k), np.random.default_rng([seed, int(k)]))
        t_f += time.perf_counter() - t
        given.given = None
        if r.position.ok:
            dl_r[i] = r.position.position
        if f.position.ok:
            dl_f[i] = f.position.position
    return dl_f, dl_r, t_f / len(points), t_r / len(points)


def compare(name: str, cir, truth: np.ndarray, ref_points: int, decimation: int = 1,
            front_ends=("correlator",), noises=(False, True)) -> None:
    """Default vs reference on the same CIRs and, with noise, the same noise realisation (the
    reference draws white noise at 122.88 MHz; the default receives its projection on the PRS
    grid, i.e. exactly the noise the reference's own FFT windows see on those REs)."""
    ids = np.unique(cir.tx_index[cir.tx_index >= 0])
    pts = np.arange(min(ref_points, cir.num_points))
    for front_end, noise in ((f, n) for f in front_ends for n in noises):
        given, recorded = GivenNoise(), RecordingNoise()
        fast = make_chain("frequency", None, ids, noise, source=given)
        ref = make_chain("time", 122.88e6, ids, noise, decimation, source=recorded,
                         front_end=front_end)
        dl_f, dl_r, t_f, t_r = run_pair(fast, ref, given, recorded, cir, pts)
        dev = np.linalg.norm(dl_f[:, :2] - dl_r[:, :2], axis=1)
        both = np.isfinite(dl_f[:, 0]) == np.isfinite(dl_r[:, 0])
        tag = ("same noise" if noise else "noiseless") + f", reference front end {front_end}"
        print(f"[{name}, {tag}] seconds per point: default (frequency, "
              f"{fast.ofdm.sample_rate_hz / 1e6:.2f} MHz) {t_f:.3f} s, reference (time, 122.88 MHz, "
              f"paths applied at 122.88/{ref.downlink.decimation} MHz) "
              f"{t_r:.3f} s, speed-up {t_r / t_f:.1f}x over {len(pts)} points")
        print(f"[{name}, {tag}] DL deviation default vs reference: {pct(dev)}; "
              f"fix / no-fix agree on {100 * both.mean():.0f} % of points")
        print(f"[{name}, {tag}] DL error default:   {pct(np.linalg.norm(dl_f[:, :2] - truth[pts, :2], axis=1))}")
        print(f"[{name}, {tag}] DL error reference: {pct(np.linalg.norm(dl_r[:, :2] - truth[pts, :2], axis=1))}")


def accuracy(name: str, cir, truth: np.ndarray) -> None:
    ids = np.unique(cir.tx_index[cir.tx_index >= 0])
    chain = make_chain("frequency", None, ids)
    pts = np.arange(cir.num_points)
    dl, ul, ok, t = run(chain, cir, pts)
    print(f"[{name}] {len(pts)} points, {t:.3f} s/point, DL fix rate {100 * ok.mean():.0f}%")
    print(f"[{name}] DL error: {pct(np.linalg.norm(dl[:, :2] - truth[:, :2], axis=1))}")
    print(f"[{name}] UL error: {pct(np.linalg.norm(ul[:, :2] - truth[:, :2], axis=1))}")


def load_rt(cache: str, scene: str, num_points: int):
    from veriloc_rt.config import config_from_dict
    cfg = config_from_dict({"trajectory": {"num_points": num_points}})
    with harness.geometry(cfg, scene) as geo:
        prop, _ = harness.timed_trace(geo, cfg, cache_dir=cache)
    return prop.bs_ue, prop.bs_ue.rx_pos


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uma-points", type=int, default=100)
    ap.add_argument("--ref-points", type=int, default=5)
    ap.add_argument("--rt-cache", default=None)
    ap.add_argument("--rt-scene", default=None, help="folder of the scene (default: temporary)")
    ap.add_argument("--rt-points", type=int, default=100)
    ap.add_argument("--compare", nargs="*", default=["pathloss_only", "fast_fading", "rt"],
                    choices=["pathloss_only", "fast_fading", "rt"],
                    help="channels of the default-vs-reference comparison")
    ap.add_argument("--skip", nargs="*", default=[], choices=["compare", "uma", "rt"])
    ap.add_argument("--front-end", nargs="*", default=["correlator"], choices=["correlator", "ofdm"],
                    help="the reference's time-domain receiver: 'correlator' (per-symbol "
                         "correlation, CP included) and/or 'ofdm' (CP removal + FFT, the default's "
                         "own receiver: isolates the channel's fidelity)")
    ap.add_argument("--noise", nargs="*", default=["none", "same"], choices=["none", "same"])
    args = ap.parse_args()
    opts = {"front_ends": tuple(args.front_end), "noises": tuple(n == "same" for n in args.noise)}
    if "compare" not in args.skip:
        if "pathloss_only" in args.compare:
            cir, ue = synthetic_uma(max(args.ref_points, 2), "pathloss_only", SEED)
            compare("UMa pathloss_only", cir, ue, args.ref_points, **opts)
        if "fast_fading" in args.compare:
            # ~400 paths per link: the exact reference costs ~280 s per point; decimated by 8 it
            # is exact inside the band (tests/unit/test_channel.py) and ~10x cheaper
            cir, ue = synthetic_uma(max(args.ref_points, 2), "fast_fading", SEED)
            compare("UMa fast_fading", cir, ue, args.ref_points, decimation=8, **opts)
        if args.rt_cache and "rt" in args.compare:
            cir, ue = load_rt(args.rt_cache, args.rt_scene, args.rt_points)
            compare("ray-traced", cir, ue, args.ref_points, **opts)
    if "uma" not in args.skip:
        for mode in ("pathloss_only", "fast_fading"):
            cir, ue = synthetic_uma(args.uma_points, mode, SEED)
            accuracy(f"UMa {mode}", cir, ue)
    if args.rt_cache and "rt" not in args.skip:
        cir, ue = load_rt(args.rt_cache, args.rt_scene, args.rt_points)
        accuracy("ray-traced", cir, ue)


if __name__ == "__main__":
    main()
