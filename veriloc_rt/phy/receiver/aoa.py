"""Angle of arrival on the UE's horizontal ULA: ESPRIT and MUSIC (ABSA's direction finder).

Array model (the one of :func:`veriloc_rt.propagation.cir.array_response`): element k of an
M-element ULA along the horizontal axis at azimuth alpha sits at ``(k - (M-1)/2) d`` along the
axis; a plane wave arriving from (az, zen) gives it the phase ``exp(+j 2 pi (k - (M-1)/2) d mu)``
with the *spatial frequency* ``mu = cos(az - alpha) sin(zen)`` and d in wavelengths.

What the array measures is mu only. Hence:

* **mirror ambiguity**: az and its mirror about the array axis, 2 alpha - az, give the same mu.
  Every estimate carries both candidates ``alpha +- arccos(mu / sin zen)``; pick with a reference
  (:func:`resolve_ambiguity`, e.g. the azimuth expected from the last fix);
* **zenith**: with a known zenith the ``sin(zen)`` factor is divided out; |mu / sin zen| > 1
  (noise, wrong zenith) is clipped to 1 and flagged.

Coherent multipath (the rule in urban canyons) makes the source covariance rank-deficient;
forward-backward averaging and spatial smoothing over subarrays of ``subarray`` elements
restore it (FB + SS handles up to 2 coherent paths with M = 5, L = 4). Model order: fixed
``num_sources`` or MDL (Wax-Kailath) on the smoothed covariance with the effective number of
snapshots N (M - L + 1) (x 2 with FB), an approximation since those looks are not independent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AoAEstimate", "AoAEstimator", "esprit", "music", "resolve_ambiguity", "ula_steering",
           "sample_covariance", "forward_backward", "spatial_smoothing", "mdl_order"]


def ula_steering(num_ant: int, spacing_wavelengths: float, mu) -> np.ndarray:
    """ULA steering vectors, centred phase reference (matches ``cir.array_response``).

    :param mu: [K] float64, spatial frequency cos(az - alpha) sin(zen)
    :returns: [num_ant, K] complex128
    """
    k = np.arange(num_ant) - (num_ant - 1) / 2.0
    return np.exp(2j * np.pi * spacing_wavelengths * np.outer(k, np.atleast_1d(mu)))


def sample_covariance(snapshots: np.ndarray) -> np.ndarray:
    """R = X X^H / N. snapshots: [num_ant, num_snapshots] complex128 -> [num_ant, num_ant]."""
    return snapshots @ snapshots.conj().T / snapshots.shape[1]


def forward_backward(r: np.ndarray) -> np.ndarray:
    """(R + J R* J) / 2 with J the exchange matrix: [M, M] -> [M, M] complex128."""
    return 0.5 * (r + np.flip(r.conj(), axis=(0, 1)))


def spatial_smoothing(r: np.ndarray, subarray: int) -> np.ndarray:
    """Average of the M - L + 1 overlapping L x L diagonal blocks: [M, M] -> [L, L]."""
    m = r.shape[0]
    return sum(r[i:i + subarray, i:i + subarray] for i in range(m - subarray + 1)) / (m - subarray + 1)


def mdl_order(eigvals: np.ndarray, num_snapshots: float) -> int:
    """Minimum description length model order (Wax & Kailath 1985).

    :param eigvals: [L] float64, covariance eigenvalues (any order)
    :returns: int in [0, L - 1]
    """
    lam = np.sort(np.maximum(np.real(eigvals), 1e-300))[::-1]
    n_l = lam.size
    best, best_k = np.inf, 0
    for k in range(n_l):
        tail = lam[k:]
        ratio = np.exp(np.mean(np.log(tail))) / np.mean(tail)
        val = -num_snapshots * (n_l - k) * np.log(ratio) + 0.5 * k * (2 * n_l - k) * np.log(num_snapshots)
        if val < best:
            best, best_k = val, k
    return best_k


@dataclass(frozen=True, eq=False)
class AoAEstimate:
    """Directions found by ESPRIT or MUSIC, strongest first.

    mu : [K] float64, spatial frequency cos(az - alpha) sin(zen)
    cos_rel : [K] float64, cos(az - alpha) after dividing by sin(zen), clipped to [-1, 1]
    azimuth_candidates : [K, 2] float64, rad, (alpha + arccos(cos_rel), alpha - arccos(cos_rel)),
        wrapped to (-pi, pi]: the direction and its mirror about the array axis
    power : [K] float64, estimated source power (same unit as |snapshot|^2)
    clipped : [K] bool, |mu / sin zen| exceeded 1
    eigenvalues : [L] float64, of the (FB-averaged, smoothed) covariance, descending
    num_sources : int; method : str; array_axis_azimuth : float, rad
    """

    mu: np.ndarray
    cos_rel: np.ndarray
    azimuth_candidates: np.ndarray
    power: np.ndarray
    clipped: np.ndarray
    eigenvalues: np.ndarray
    num_sources: int
    method: str
    array_axis_azimuth: float

    def resolve(self, reference_azimuth) -> np.ndarray:
        """Candidate nearest ``reference_azimuth`` (rad, scalar or [K]) for each source: [K] rad."""
        return resolve_ambiguity(self.azimuth_candidates, reference_azimuth)


def _wrap(a):
    return np.angle(np.exp(1j * np.asarray(a)))


def resolve_ambiguity(azimuth_candidates, reference_azimuth) -> np.ndarray:
    """Pick, per source, the mirror candidate closest (wrapped) to the reference azimuth.

    :param azimuth_candidates: [K, 2] float64, rad; reference_azimuth: scalar or [K], rad
    :returns: [K] float64, rad
    """
    c = np.atleast_2d(np.asarray(azimuth_candidates, dtype=float))
    ref = np.broadcast_to(np.asarray(reference_azimuth, dtype=float), (c.shape[0],))
    err = np.abs(_wrap(c - ref[:, None]))
    return c[np.arange(c.shape[0]), np.argmin(err, axis=1)]


class AoAEstimator:
    """Subspace AoA estimator for a horizontal ULA, configured once, called per snapshot set.

    :param method: ``"esprit"`` (LS-ESPRIT) or ``"music"`` (grid search + local refinement)
    :param num_sources: fixed model order, or None for MDL
    :param spacing_wavelengths: element spacing d / lambda (<= 0.5 avoids grating ambiguity)
    :param array_axis_azimuth: float, rad, azimuth alpha of the array axis (element index grows
        along +axis, as ``cir.ula_element_positions``)
    :param forward_backward: apply FB averaging
    :param subarray: spatial-smoothing subarray size L (None: M - 1 for M >= 3, else M)
    :param grid_points: MUSIC grid size over mu in [-1, 1]
    """

    def __init__(self, method: str = "esprit", num_sources: int | None = None,
                 spacing_wavelengths: float = 0.5, array_axis_azimuth: float = 0.0,
                 forward_backward: bool = True, subarray: int | None = None,
                 grid_points: int = 2001):
        if method not in ("esprit", "music"):
            raise ValueError(f"Argument `method` must be 'esprit' or 'music', not {method!r}")
        if num_sources is not None and (not isinstance(num_sources, (int, np.integer))
                                        or num_sources < 1):
            raise ValueError(f"Argument `num_sources` must be None or an int >= 1, not {num_sources!r}")
        if not 0 < spacing_wavelengths <= 1.0:
            raise ValueError(f"Argument `spacing_wavelengths` must be in (0, 1], not "
                             f"{spacing_wavelengths!r}")
        self.method = method
        self.num_sources = num_sources
        self.spacing = float(spacing_wavelengths)
        self.alpha = float(array_axis_azimuth)
        self.fb = bool(forward_backward)
        self.subarray = subarray
        self.grid_points = int(grid_points)

    def __call__(self, snapshots, zenith: float = np.pi / 2) -> AoAEstimate:
        """Estimate the directions.

        :param snapshots: [num_ant, num_snapshots] complex128 (or [num_ant] for one snapshot),
            e.g. per-antenna correlation peaks or per-subcarrier channel estimates
        :param zenith: float, rad, known zenith of arrival (pi/2: horizontal)
        """
        x = np.asarray(snapshots)
        if x.ndim == 1:
            x = x[:, None]
        if x.ndim != 2 or x.shape[0] < 2 or not np.all(np.isfinite(x)):
            raise ValueError(f"Argument `snapshots` must be a finite [num_ant >= 2, num_snapshots] "
                             f"array, not shape {x.shape}")
        if not 0 < zenith < np.pi:
            raise ValueError(f"Argument `zenith` must be in (0, pi) rad, not {zenith!r}")
        m, n = x.shape
        sub = self.subarray if self.subarray is not None else (m - 1 if m >= 3 else m)
        if not 2 <= sub <= m:
            raise ValueError(f"Argument `subarray` must be in [2, {m}], not {sub!r}")
        r = sample_covariance(x.astype(complex))
        if self.fb:
            r = forward_backward(r)
        r = spatial_smoothing(r, sub)
        lam, vec = np.linalg.eigh(r)
        lam, vec = lam[::-1].real, vec[:, ::-1]
        if self.num_sources is None:
            n_eff = n * (m - sub + 1) * (2 if self.fb else 1)
            k = max(1, mdl_order(lam, n_eff))
        else:
            k = int(self.num_sources)
        if k > sub - 1:
            raise ValueError(f"Argument `num_sources` = {k} exceeds subarray size - 1 = {sub - 1}")
        if self.method == "esprit":
            mu = self._esprit(vec[:, :k])
        else:
            mu = self._music(vec[:, k:], k)
        power = self._powers(r, lam, k, mu, sub)
        order = np.argsort(-power, kind="stable")
        mu, power = mu[order], power[order]
        rel = mu / np.sin(zenith)
        clipped = np.abs(rel) > 1.0
        rel = np.clip(rel, -1.0, 1.0)
        off = np.arccos(rel)
        cands = _wrap(np.stack([self.alpha + off, self.alpha - off], axis=-1))
        return AoAEstimate(mu=mu, cos_rel=rel, azimuth_candidates=cands, power=power,
                           clipped=clipped, eigenvalues=lam, num_sources=k, method=self.method,
                           array_axis_azimuth=self.alpha)

    # -- internals ---------------------------------------------------------------------------
    def _esprit(self, es: np.ndarray) -> np.ndarray:
        """LS-ESPRIT: E2 = E1 Phi, eig(Phi) = exp(j 2 pi d mu)."""
        phi = np.linalg.lstsq(es[:-1], es[1:], rcond=None)[0]
        z = np.linalg.eigvals(phi)
        return np.clip(np.angle(z) / (2 * np.pi * self.spacing), -1.0, 1.0)

    def _music(self, en: np.ndarray, k: int) -> np.ndarray:
        """Highest k peaks of 1 / |E_n^H a(mu)|^2 on a mu grid, refined by a bounded search."""
        # imported here: scipy.signal pulls in scipy.stats (about a second), which a run that
        # computes no chain (a resume past its last point) never needs
        from scipy.optimize import minimize_scalar
        from scipy.signal import find_peaks

        sub = en.shape[0]
        grid = np.linspace(-1.0, 1.0, self.grid_points)

        def null(mu):
            return np.sum(np.abs(en.conj().T @ ula_steering(sub, self.spacing, mu)) ** 2, axis=0)

        spec = -np.log(null(grid) + 1e-300)
        ext = np.concatenate([[-np.inf], spec, [-np.inf]])       # edge peaks allowed
        peaks, _ = find_peaks(ext)
        peaks = peaks - 1
        peaks = peaks[np.argsort(-spec[peaks])][:k]
        step = grid[1] - grid[0]
        out = []
        for p in peaks:
            lo, hi = max(-1.0, grid[p] - step), min(1.0, grid[p] + step)
            res = minimize_scalar(lambda u: float(null(u)[0]), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-10})
            out.append(res.x)
        while len(out) < k:                                       # fewer peaks than sources
            out.append(out[-1] if out else 0.0)
        return np.asarray(out, dtype=float)

    def _powers(self, r: np.ndarray, lam: np.ndarray, k: int, mu: np.ndarray, sub: int) -> np.ndarray:
        """Least-squares source powers diag(A^+ (R - sigma^2 I) A^+H), sigma^2 = mean noise eig."""
        a = ula_steering(sub, self.spacing, mu)
        noise = float(np.mean(lam[k:])) if k < lam.size else 0.0
        ap = np.linalg.pinv(a)
        return np.maximum(np.real(np.diag(ap @ (r - noise * np.eye(sub)) @ ap.conj().T)), 0.0)


def esprit(snapshots, num_sources: int | None = None, zenith: float = np.pi / 2, **config) -> AoAEstimate:
    """One-shot ESPRIT (``config``: :class:`AoAEstimator` arguments)."""
    return AoAEstimator("esprit", num_sources, **config)(snapshots, zenith)


def music(snapshots, num_sources: int | None = None, zenith: float = np.pi / 2, **config) -> AoAEstimate:
    """One-shot MUSIC (``config``: :class:`AoAEstimator` arguments)."""
    return AoAEstimator("music", num_sources, **config)(snapshots, zenith)
