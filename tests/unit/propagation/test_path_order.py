"""The order of a link's paths leaving the Sionna wrapper depends on the paths only.

Sionna RT assigns each path its slot with an atomic counter, so two calls tracing the same
link can list the same paths in different orders; every later step (merge, dedup, strongest-
path selection, CIR sums in float) must see one order.
"""

from __future__ import annotations

import numpy as np

from veriloc_rt.propagation.sionna_rt import RawPaths, canonical_order


def _paths(rng, links=4, n=9, depth=3):
    valid = rng.random((links, n)) < 0.7
    tau = np.round(rng.uniform(1e-6, 2e-6, (links, n)), 8)   # rounded: delay ties occur
    tau[:, 1] = tau[:, 0]                                     # a tie broken by angles
    ang = {f: rng.uniform(-np.pi, np.pi, (links, n)) for f in ("theta_r", "phi_r", "theta_t", "phi_t")}
    a = rng.normal(size=(links, n, 2, 2)) + 1j * rng.normal(size=(links, n, 2, 2))
    inter = rng.integers(0, 8, (links, n, depth)).astype(np.uint8)
    return RawPaths(tau=np.where(valid, tau, -1.0), a=np.where(valid[..., None, None], a, 0),
                    interactions=np.where(valid[..., None], inter, 0).astype(np.uint8),
                    valid=valid, **{f: np.where(valid, x, 0.0) for f, x in ang.items()})


def test_any_permutation_of_a_links_paths_gives_the_same_arrays():
    rng = np.random.default_rng(3)
    raw = _paths(rng)
    ref = canonical_order(raw)
    for _ in range(20):
        perm = np.argsort(rng.random(raw.tau.shape), axis=1)
        shuffled = RawPaths(**{f: np.take_along_axis(getattr(raw, f), perm.reshape(
            perm.shape + (1,) * (getattr(raw, f).ndim - 2)), axis=1) for f in RawPaths.FIELDS})
        out = canonical_order(shuffled)
        for f in RawPaths.FIELDS:
            assert np.array_equal(getattr(out, f), getattr(ref, f)), f


def test_valid_paths_come_first_in_delay_order_and_none_is_lost():
    raw = _paths(np.random.default_rng(4))
    out = canonical_order(raw)
    for i in range(raw.num_links):
        k = int(raw.valid[i].sum())
        assert out.valid[i, :k].all() and not out.valid[i, k:].any()
        assert np.all(np.diff(out.tau[i, :k]) >= 0)
        assert np.array_equal(np.sort(out.tau[i, :k]), np.sort(raw.tau[i][raw.valid[i]]))
        assert np.isclose(np.abs(out.a[i]).sum(), np.abs(raw.a[i]).sum(), rtol=1e-12)
