"""Shared checks of drawn TR 38.901 large-scale parameters (UMa and UMi statistics tests)."""

from __future__ import annotations

import numpy as np
from scipy import stats


def ring(n, rng, r_min, r_max):
    """[n, 3] UE positions uniform in radius r_min..r_max m around the origin, 1.5 m high."""
    r = rng.uniform(r_min, r_max, n)
    a = rng.uniform(0, 2 * np.pi, n)
    return np.stack([r * np.cos(a), r * np.sin(a), np.full(n, 1.5)], axis=-1)


def assert_clipped_normal(name, x, mu, sd, clip):
    """x ~ min(N(mu, sd), clip): KS on the unclipped values against the truncated normal at the
    alpha = 0.001 critical value 1.949 / sqrt(n), and the clipped count against its expectation
    within 4 Poisson standard deviations, at least 3 counts for tiny expectations (the atom at
    the clip would otherwise dominate the KS distance)."""
    mu, sd = np.broadcast_to(mu, x.shape), np.broadcast_to(sd, x.shape)
    p_clip = stats.norm.sf(clip, mu, sd)
    at = x >= clip - 1e-12
    expect = p_clip.sum()
    assert abs(at.sum() - expect) < max(4 * np.sqrt(expect), 3), name
    u = stats.norm.cdf(x[~at], mu[~at], sd[~at]) / (1 - p_clip[~at])   # PIT of the truncated law
    d = stats.kstest(u, "uniform").statistic
    assert d < 1.949 / np.sqrt(u.size), f"{name}: KS D = {d:.4f}"
