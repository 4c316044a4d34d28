"""Per-link quantities for comparing two traces of the same links (fidelity against reference).

Every function works on padded per-link path arrays, whatever model produced them:

    tau : [num_links, num_paths] float64, s;  power : [num_links, num_paths] float64, |a|^2
    interactions : [num_links, num_paths, depth] uint8, ``INTERACTION_*`` codes
    valid : [num_links, num_paths] bool

A :class:`~veriloc_rt.propagation.cir.CIR` gives them with :func:`cir_link_arrays`, a
:class:`~veriloc_rt.propagation.sionna_rt.RawPaths` directly (``power = |a|^2``).

What a user of a traced channel concludes from, per link: the received power (the sum of the
path powers: the wideband power of an isotropic receiver, over which the path phases average
out; Rappaport, *Wireless Communications*, 2nd ed., Sec. 5.2.1, "Relationship between bandwidth
and received power"), which path is the strongest (the one a receiver locks to), the first
path's delay (what ranging measures) and how strong it is relative to the strongest (whether a
receiver's first-path detection finds it). Two traces of one link share a path when the paths have
the same interaction sequence and delays within a tolerance (Sionna RT refines every candidate to
the exact geometric path with the image method, so a path found by two traces has the same
geometry up to float32 rounding; its field is the same when both traces launch rays from the
same end, Sionna RT's own diffraction coefficient giving one path different powers in the two
tracing directions, and, for a path that uses every one of ``max_depth`` interactions with a
reflection after its diffraction, with the same ``max_depth``).
"""

from __future__ import annotations

import numpy as np

from .cir import INTERACTION_NONE

#: two paths of a link with the same interaction sequence are the same path when their delays
#: are this close (0.6 mm of path length). Measured on the default canyon (docs/convergence.md):
#: copies of one path found by two traces of one tracing direction agree to 3.4e-13 s (float32
#: delays of ~1 us), while distinct paths of one interaction sequence in one link come as close
#: as 1.25e-11 s; the tolerance sits between the two, a factor ~6 from each. A window of a
#: nanosecond would take one path for another: 235 same-sequence pairs of the reference's 30
#: links are within 1 ns of each other
SAME_PATH_TOL_S = 2e-12


def pad_depth(inter: np.ndarray, depth: int) -> np.ndarray:
    """Interaction sequences zero-padded (no interaction) along the last axis to ``depth``, so
    that sequences traced with different ``max_depth`` compare element by element.

    :param inter: [..., max_depth] int interaction types; depth >= its max_depth
    """
    return np.pad(inter, [(0, 0)] * (inter.ndim - 1) + [(0, depth - inter.shape[-1])])


def cir_link_arrays(cir, points: np.ndarray | None = None):
    """(tau, power, interactions, valid) of a CIR's links, flattened to [num_points * num_tx].

    The power of a path is taken at the first UE antenna element: the synthetic array applies a
    unit-magnitude phase per element (:func:`~veriloc_rt.propagation.cir.array_response`).
    """
    sel = slice(None) if points is None else np.asarray(points)
    tau, valid = cir.delays[sel], cir.valid[sel]
    power = np.abs(cir.gains[sel][:, :, 0, :]) ** 2
    inter = cir.interactions[sel]
    n = tau.shape[0] * tau.shape[1]
    return (tau.reshape(n, -1), power.reshape(n, -1),
            inter.reshape(n, inter.shape[2], inter.shape[3]), valid.reshape(n, -1))


def link_power(power: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Received power per link: the sum of the valid paths' powers. -> [num_links] float64"""
    return np.where(valid, power, 0.0).sum(axis=-1)


def power_deviation_db(p: np.ndarray, p_ref: np.ndarray) -> np.ndarray:
    """10 log10(p / p_ref) per link, dB (negative: power missing against the reference).

    A link without power in both is 0 dB (they agree); a link that lost all its paths is -inf,
    one that gained paths +inf. -> [num_links] float64
    """
    p, p_ref = np.asarray(p, float), np.asarray(p_ref, float)
    out = np.zeros(p.shape)
    both = (p > 0) & (p_ref > 0)
    out[both] = 10.0 * np.log10(p[both] / p_ref[both])
    out[(p > 0) & (p_ref <= 0)] = np.inf
    out[(p <= 0) & (p_ref > 0)] = -np.inf
    return out


def strongest_index(power: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Index of the strongest valid path per link (-1: no path). -> [num_links] int64"""
    p = np.where(valid, power, -np.inf)
    j = np.argmax(p, axis=-1)
    return np.where(valid.any(axis=-1), j, -1)


def first_index(tau: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Index of the earliest valid path per link (-1: no path). -> [num_links] int64"""
    j = np.argmin(np.where(valid, tau, np.inf), axis=-1)
    return np.where(valid.any(axis=-1), j, -1)


def _take(x: np.ndarray, j: np.ndarray, fill) -> np.ndarray:
    """x[l, j[l]] (and the trailing axes) per link; ``fill`` where j < 0."""
    idx = np.maximum(j, 0).reshape((-1, 1) + (1,) * (x.ndim - 2))
    v = np.take_along_axis(x, idx, axis=1)[:, 0]
    mask = (j < 0).reshape((-1,) + (1,) * (v.ndim - 1))
    return np.where(mask, fill, v)


def has_path(tau: np.ndarray, interactions: np.ndarray, valid: np.ndarray,
             tau_q: np.ndarray, inter_q: np.ndarray, tol_s: float = SAME_PATH_TOL_S) -> np.ndarray:
    """Whether each link has a valid path like the query path of that link.

    :param tau_q: [num_links] float64, s, the query path's delay (NaN: no query, False)
    :param inter_q: [num_links, depth_q] uint8, its interaction sequence
    :returns: [num_links] bool, a valid path with the same interaction sequence (trailing
        ``INTERACTION_NONE`` padding ignored) and ``|tau - tau_q| <= tol_s``
    """
    depth = max(interactions.shape[-1], inter_q.shape[-1])
    inter, q = pad_depth(interactions, depth), pad_depth(inter_q, depth)
    same = np.all(inter == q[:, None, :], axis=-1)
    close = np.abs(tau - np.asarray(tau_q, float)[:, None]) <= tol_s
    return np.any(valid & same & close, axis=-1)


def link_deviation(test: tuple, ref: tuple, tol_s: float = SAME_PATH_TOL_S) -> dict:
    """Per-link deviations of ``test`` from ``ref``, each a (tau, power, interactions, valid)
    tuple of the same links.

    :returns: dict of [num_links] float64 arrays:
        ``power_dev_db`` (:func:`power_deviation_db`);
        ``strongest_found`` 1.0 when ``test`` has the reference's strongest path, 0.0 when not,
        NaN when the reference has no path;
        ``first_delay_dev_s`` first-path delay of test minus the reference's (NaN unless both
        have a path);
        ``first_rel_db`` and ``first_rel_db_ref``: first-path power over the strongest path's
        power, dB (<= 0; NaN without a path), of test and of the reference
    """
    tau, power, inter, valid = test
    tau_r, power_r, inter_r, valid_r = ref
    if tau.shape[0] != tau_r.shape[0]:
        raise ValueError(f"test has {tau.shape[0]} links, the reference {tau_r.shape[0]}")
    out = {"power_dev_db": power_deviation_db(link_power(power, valid), link_power(power_r, valid_r))}
    js_r = strongest_index(power_r, valid_r)
    found = has_path(tau, inter, valid, _take(tau_r, js_r, np.nan), _take(inter_r, js_r, 0), tol_s)
    out["strongest_found"] = np.where(js_r >= 0, found.astype(float), np.nan)
    j1, j1_r = first_index(tau, valid), first_index(tau_r, valid_r)
    out["first_delay_dev_s"] = _take(tau, j1, np.nan) - _take(tau_r, j1_r, np.nan)
    for key, (t, p, v, j1x) in {"first_rel_db": (tau, power, valid, j1),
                                "first_rel_db_ref": (tau_r, power_r, valid_r, j1_r)}.items():
        js = strongest_index(p, v)
        with np.errstate(divide="ignore"):
            rel = 10.0 * np.log10(_take(p, j1x, np.nan) / _take(p, js, np.nan))
        out[key] = rel
    return out


def quantile(x: np.ndarray, q: float) -> float | None:
    """The q-th percentile of ``x`` as one of its values (no interpolation, so +-inf entries are
    kept: a lost link is infinitely wrong), NaN entries dropped; None when nothing is left."""
    x = np.asarray(x, dtype=float).ravel()
    x = x[~np.isnan(x)]
    if x.size == 0:
        return None
    return float(np.percentile(x, q, method="inverted_cdf"))


def union_paths(traces: list[tuple], tol_s: float = SAME_PATH_TOL_S) -> tuple:
    """Every distinct path found by any of several traces of the same links.

    Two paths are the same when they have the same interaction sequence and delays within
    ``tol_s``; the copy of the earliest trace in the list is kept. Every path a trace returns is
    an exact geometric path (image method), so the union is the best lower bound on the
    converged channel that the traces give.

    :param traces: (tau, power, interactions, valid) tuples with the same number of links
    :returns: (tau, power, interactions, valid, source) with source [num_links, num_paths]
        int64 the index of the trace each kept path came from (-1: padding)
    """
    n = traces[0][0].shape[0]
    depth = max(t[2].shape[-1] for t in traces)
    for s, t in enumerate(traces):
        if t[0].shape[0] != n:
            raise ValueError(f"trace {s} has {t[0].shape[0]} links, not {n}")
    padded = [(t[0], t[1], pad_depth(t[2], depth), t[3]) for t in traces]
    per_link = []
    for link in range(n):
        k_tau, k_pow = np.zeros(0), np.zeros(0)
        k_int, k_src = np.zeros((0, depth), np.uint8), np.zeros(0, np.int64)
        for s, (tau, power, inter, valid) in enumerate(padded):
            j = np.flatnonzero(valid[link])
            if j.size == 0:
                continue
            t, seq = tau[link, j], inter[link, j]
            dup = np.any((np.abs(t[:, None] - k_tau[None, :]) <= tol_s)
                         & np.all(seq[:, None, :] == k_int[None, :, :], axis=-1), axis=1)
            new = j[~dup]
            k_tau = np.concatenate([k_tau, tau[link, new]])
            k_pow = np.concatenate([k_pow, power[link, new]])
            k_int = np.concatenate([k_int, inter[link, new]])
            k_src = np.concatenate([k_src, np.full(new.size, s, np.int64)])
        per_link.append((k_tau, k_pow, k_int, k_src))
    width = max(1, max(k[0].size for k in per_link))
    tau_u = np.full((n, width), -1.0)
    pow_u = np.zeros((n, width))
    int_u = np.zeros((n, width, depth), np.uint8)
    src_u = np.full((n, width), -1, np.int64)
    for link, (k_tau, k_pow, k_int, k_src) in enumerate(per_link):
        m = k_tau.size
        tau_u[link, :m], pow_u[link, :m], int_u[link, :m], src_u[link, :m] = k_tau, k_pow, k_int, k_src
    return tau_u, pow_u, int_u, src_u >= 0, src_u


def path_class(seq: np.ndarray) -> str:
    """A path's interaction sequence as letters in path order: R specular reflection,
    D diffraction, S diffuse, T refraction; 'LoS' for none."""
    letters = {1: "R", 2: "S", 4: "T", 8: "D"}
    s = "".join(letters.get(int(c), "?") for c in seq if c != INTERACTION_NONE)
    return s or "LoS"
