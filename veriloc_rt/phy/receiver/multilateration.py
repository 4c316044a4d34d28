"""OTDOA multilateration: RSTDs to a 2-D position with known heights, and GDOP.

The UE at (x, y, h_UE) with known h_UE and BSs at known 3-D positions b_i measure
``rstd_s[i] = toa_i - toa_ref``, i.e. c rstd_i = d_i - d_ref with d_i = |p - b_i| (3-D).
The solver

1. initialises with a closed form (Chan/Fang: the range-difference equations are linear in
   (x, y, d_ref); with known heights the vertical offsets enter as constants, and the constraint
   d_ref^2 = |p - b_ref|^2 gives a quadratic in d_ref) and with the best node of a coarse grid;
2. refines every start with Levenberg-Marquardt (MINPACK's ``lmder`` through
   ``scipy.optimize.leastsq``, the routine ``least_squares(method="lm")`` calls, with the
   analytic Jacobian) on the whitened residuals (RSTD covariance sigma^2 (I + 1 1^T) for iid
   ToA noise), keeping the lowest cost;
3. checks convergence, distance from the network, and the residual: the rms range residual must
   stay below ``max_residual_m``, and with ``sigma_m`` given the whitened SSR must pass a
   chi-square(N - 3) test (RAIM-style; with 3 BSs there is no redundancy and only hyperbolas
   that do not intersect at all are caught).

A failure is a *service failure* (DoS): the result says so with a reason; no NaN, no exception
for bad geometry or inconsistent measurements. Bad arguments (shapes, types) raise ValueError.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import sqrt

import numpy as np
from scipy.special import chdtri   # chi-square inverse survival function: chi2.isf(q, k) is
                                   # chdtri(k, q) (scipy.stats computes it so), without
                                   # importing scipy.stats

from ...constants import SPEED_OF_LIGHT

#: Result status values
STATUS_OK = "ok"
STATUS_TOO_FEW = "too_few_bs"
STATUS_NO_CONVERGENCE = "no_convergence"
STATUS_DIVERGED = "diverged"
STATUS_RESIDUAL = "residual_check_failed"

#: MINPACK's termination code (``leastsq``'s ``ier``) -> ``least_squares``' ``status`` (> 0:
#: converged; 0: evaluation cap; -1: anything else) and ``least_squares``' message for it
_LM_STATUS = {1: 2, 2: 3, 3: 4, 4: 1, 5: 0}
_LM_MESSAGE = {
    0: "The maximum number of function evaluations is exceeded.",
    1: "`gtol` termination condition is satisfied.",
    2: "`ftol` termination condition is satisfied.",
    3: "`xtol` termination condition is satisfied.",
    4: "Both `ftol` and `xtol` termination conditions are satisfied.",
}


@dataclass(frozen=True, eq=False)
class MultilaterationResult:
    """Outcome of one position fix.

    position : [3] float64, m; the fix (x, y, ue_height) when ``ok``; otherwise the best finite
        iterate or the BS centroid, never NaN. Use it only when ``ok``.
    ok : bool; status : str (``STATUS_*``); reason : str (empty when ok)
    residual_rms_m : float, m, rms of c rstd - (d_i - d_ref) at the fix
    chi2 : float, whitened SSR / sigma^2 (NaN-free: 0 when sigma unknown); dof : int, N - 3
    num_bs : int, BSs used (reference included); gdop : float (inf for singular geometry)
    nfev : int, residual evaluations of the best refinement
    starts : list of [2] float64, m, the initial points tried (closed form roots, grid node)
    alternatives : list of [3] float64, m, other fixes that fit equally well (the two-intersection
        ambiguity of 3 BSs with the UE outside their hull); ``position`` is the one nearest the
        BS centroid. Non-empty means ``ambiguous``.
    """

    position: np.ndarray
    ok: bool
    status: str
    reason: str = ""
    residual_rms_m: float = 0.0
    chi2: float = 0.0
    dof: int = 0
    num_bs: int = 0
    gdop: float = float("inf")
    nfev: int = 0
    starts: list = field(default_factory=list)
    alternatives: list = field(default_factory=list)
    #: [2, 2] float64, m^2, covariance of the (x, y) fix from the weighted fit, (J^T C^-1 J)^-1
    #: with C the RSTD covariance (None: unweighted fit, or no fix)
    covariance: np.ndarray | None = None
    #: indices (into the call's ``bs_pos``) the integrity test excluded, in exclusion order
    excluded: tuple = ()
    #: indices (into the call's ``bs_pos``) of the anchors the fix used
    used: tuple = ()
    #: the weighted fit's first integrity test, before any exclusion: its chi-square statistic
    #: and degrees of freedom (0, 0: no test made, e.g. the unweighted fit)
    test_chi2: float = 0.0
    test_dof: int = 0

    @property
    def ambiguous(self) -> bool:
        return bool(self.alternatives)

    @property
    def service_failure(self) -> bool:
        return not self.ok


def gdop(bs_pos, ue_pos, ref_index: int = 0) -> float:
    """Horizontal GDOP of TDOA positioning with known UE height.

    H rows are (u_i - u_ref)[:2], u_i the unit vector BS i -> UE (3-D if the positions are 3-D);
    the RSTD covariance for iid ToA noise sigma is sigma^2 (I + 1 1^T); P = (H^T R^-1 H)^-1 and
    GDOP = sqrt(tr P). Equal to the TOA-with-clock-bias form.

    :param bs_pos: [num_bs, 2 or 3] float64, m; ue_pos: [2 or 3] float64, m
    :returns: float, dimensionless (inf when H is rank deficient or num_bs < 3)
    """
    b = np.asarray(bs_pos, dtype=float)
    u = np.asarray(ue_pos, dtype=float)
    if b.ndim != 2 or b.shape[1] not in (2, 3) or u.shape != (b.shape[1],):
        raise ValueError(f"Arguments `bs_pos`, `ue_pos` must be [N, 2|3] and [2|3], not "
                         f"{b.shape}, {u.shape}")
    if not 0 <= ref_index < b.shape[0]:
        raise ValueError(f"Argument `ref_index` must be in [0, {b.shape[0]}), not {ref_index}")
    if b.shape[0] < 3:
        return float("inf")
    d = u - b
    unit = d / np.linalg.norm(d, axis=1, keepdims=True)
    others = [i for i in range(b.shape[0]) if i != ref_index]
    h = (unit[others] - unit[ref_index])[:, :2]
    m = len(others)
    r_inv = np.eye(m) - np.ones((m, m)) / (m + 1.0)          # (I + 1 1^T)^-1
    info = h.T @ r_inv @ h
    # condition number of the symmetric 2 x 2 information matrix from its eigenvalues
    # tr/2 +- sqrt(((a - c)/2)^2 + b^2) (what numpy.linalg.cond computes by an SVD)
    (a, b), (_, c) = info.tolist()
    half_gap = sqrt(0.25 * (a - c) * (a - c) + b * b)
    lo, hi = 0.5 * (a + c) - half_gap, 0.5 * (a + c) + half_gap
    if lo <= 0.0 or hi > 1e12 * lo:
        return float("inf")
    return float(np.sqrt(np.trace(np.linalg.inv(info))))


def _bs_line(bs_pos: np.ndarray, tol_m: float = 1e-6) -> tuple[np.ndarray, np.ndarray] | None:
    """(point, unit direction) of the line through the BSs' horizontal positions when they
    are collinear within ``tol_m``, else None."""
    s = bs_pos[:, :2]
    c = s.mean(axis=0)
    _, sv, vt = np.linalg.svd(s - c)
    if sv[0] <= tol_m or (sv.size > 1 and sv[1] > tol_m):
        return None
    return c, vt[0]


def _whitened_residuals(bs: np.ndarray, rd: np.ndarray, ref: int, h2: np.ndarray,
                        w: np.ndarray):
    """The refinement's residuals f = W (d_i - d_ref - rd_i)_{i != ref} and their Jacobian in
    (x, y), d_i = sqrt(|xy - b_i|^2 + h2_i), dd_i/dxy = (xy - b_i) / d_i, in plain floats: with
    2 unknowns and 2-5 residuals numpy's per-call cost would be most of an evaluation.

    :param bs: [num_bs, 3] float64, m; rd: [num_bs] float64, m; h2: [num_bs] float64, m^2, the
        squared height differences; w: [num_bs - 1, num_bs - 1] float64, the whitening
    :returns: fun(xy) -> [num_bs - 1] list, m; jac(xy) -> [num_bs - 1][2] list
    """
    bx, by, hh = bs[:, 0].tolist(), bs[:, 1].tolist(), h2.tolist()
    others = [i for i in range(len(bx)) if i != ref]
    rdo = [float(rd[i]) for i in others]
    # rows of W as (column, weight) pairs without its zeros (W is upper triangular)
    rows = [[(k, wk) for k, wk in enumerate(row) if wk != 0.0] for row in w.tolist()]

    def offsets(xy):
        x, y = xy.tolist()
        return [(x - bxi, y - byi, sqrt((x - bxi) * (x - bxi) + (y - byi) * (y - byi) + hi))
                for bxi, byi, hi in zip(bx, by, hh)]

    def fun(xy):
        o = offsets(xy)
        dr = o[ref][2]
        r = [(o[i][2] - dr) - rdi for i, rdi in zip(others, rdo)]
        return [sum(wk * r[k] for k, wk in row) for row in rows]

    def jac(xy):
        u = [(dx / d, dy / d) if d > 0.0 else (0.0, 0.0) for dx, dy, d in offsets(xy)]
        gx = [u[i][0] - u[ref][0] for i in others]
        gy = [u[i][1] - u[ref][1] for i in others]
        return [[sum(wk * gx[k] for k, wk in row), sum(wk * gy[k] for k, wk in row)]
                for row in rows]

    return fun, jac


@dataclass(frozen=True, eq=False)
class _Refined:
    """One start's refinement: x [2] float64, m; cost 0.5 |f|^2; ``least_squares``' status and
    message; nfev, residual evaluations."""

    x: np.ndarray
    cost: float
    status: int
    message: str
    nfev: int


def chan_initialisation(bs_pos: np.ndarray, range_diff_m: np.ndarray, ref_index: int,
                        ue_height_m: float) -> list[np.ndarray]:
    """Closed-form candidates (x, y) from range differences, known heights (Chan / Fang).

    :param bs_pos: [num_bs, 3] float64, m; range_diff_m: [num_bs] float64, m (d_i - d_ref;
        the reference entry is ignored)
    :returns: list of [2] float64 candidates (empty if the geometry is degenerate or no
        positive real root exists)
    """
    others = [i for i in range(bs_pos.shape[0]) if i != ref_index]
    s = bs_pos[:, :2]
    dz = bs_pos[:, 2] - ue_height_m
    k = np.sum(s**2, axis=1) + dz**2
    r = range_diff_m[others]
    a = -2.0 * (s[others] - s[ref_index])
    b = r**2 - k[others] + k[ref_index]
    # one SVD gives the rank (numpy.linalg.matrix_rank's default tolerance) and the
    # pseudo-inverse (numpy.linalg.pinv's default cut-off and arithmetic)
    u, sv, vt = np.linalg.svd(a, full_matrices=False)
    if np.sum(sv > sv.max() * max(a.shape) * np.finfo(float).eps) < 2:
        return []
    large = sv > 1e-15 * sv.max()
    pinv = vt.T @ (np.where(large, 1.0 / np.where(large, sv, 1.0), 0.0)[:, None] * u.T)
    p = pinv @ b                    # x = p + q d_ref
    q = pinv @ (2.0 * r)
    e = p - s[ref_index]
    coef = (float(q @ q - 1.0), float(2.0 * (q @ e)), float(e @ e + dz[ref_index] ** 2))
    out = [p + q * rt for rt in _quadratic_roots(*coef) if rt > 0]
    return [c for c in out if np.all(np.isfinite(c))]


def _quadratic_roots(c2: float, c1: float, c0: float) -> list[float]:
    """Real roots of c2 t^2 + c1 t + c0 (linear when |c2| <= 1e-12), by the cancellation-free
    form t1 = q / c2, t2 = c0 / q, q = -(c1 + sign(c1) sqrt(c1^2 - 4 c2 c0)) / 2 (Numerical
    Recipes, 3rd ed., sec. 5.6). A complex pair whose imaginary part is below 1e-6 max(1, |t|)
    (a double root split by rounding) counts as its real part, twice, as ``numpy.roots``' real
    parts did."""
    if abs(c2) <= 1e-12:
        return [-c0 / c1] if c1 != 0.0 else []
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        re, im = -c1 / (2.0 * c2), sqrt(-disc) / (2.0 * abs(c2))
        return [re, re] if im < 1e-6 * max(1.0, abs(complex(re, im))) else []
    q = -0.5 * (c1 + (sqrt(disc) if c1 >= 0.0 else -sqrt(disc)))
    return [q / c2, c0 / q] if q != 0.0 else [0.0, 0.0]


class Multilaterator:
    """RSTD multilateration solver, configured once and called per measurement set.

    :param ue_height_m: float, m, known UE antenna height
    :param max_residual_m: float, m, largest accepted rms range residual
    :param sigma_m: optional float, m, ToA (range) noise std; enables the chi-square test
    :param false_alarm: float, chi-square test size
    :param max_distance_m: float, m, fixes farther than this from the BS centroid are divergence
    :param max_nfev: int, LM evaluation cap per start
    :param grid_points: int, grid nodes per axis for the coarse initialisation
    :param exclusion: with per-anchor stds (``range_std_m``), exclude anchors until the
        chi-square test passes (fault detection and exclusion), else only test
    """

    def __init__(self, ue_height_m: float = 1.5, max_residual_m: float = 10.0,
                 sigma_m: float | None = None, false_alarm: float = 1e-3,
                 max_distance_m: float = 10_000.0, max_nfev: int = 200, grid_points: int = 41,
                 exclusion: bool = True):
        for name, val in (("max_residual_m", max_residual_m), ("max_distance_m", max_distance_m)):
            if not np.isfinite(val) or val <= 0:
                raise ValueError(f"Argument `{name}` must be finite and > 0, not {val!r}")
        if sigma_m is not None and (not np.isfinite(sigma_m) or sigma_m <= 0):
            raise ValueError(f"Argument `sigma_m` must be None or > 0, not {sigma_m!r}")
        if not 0 < false_alarm < 1:
            raise ValueError(f"Argument `false_alarm` must be in (0, 1), not {false_alarm!r}")
        self.ue_height_m = float(ue_height_m)
        self.max_residual_m = float(max_residual_m)
        self.sigma_m = sigma_m
        self.false_alarm = float(false_alarm)
        self.max_distance_m = float(max_distance_m)
        self.max_nfev = int(max_nfev)
        self.grid_points = int(grid_points)
        self.exclusion = bool(exclusion)

    def __call__(self, bs_pos, rstd_s, ref_index: int = 0, valid=None,
                 range_std_m=None) -> MultilaterationResult:
        """Position fix from RSTDs.

        :param bs_pos: [num_bs, 3] float64, m
        :param rstd_s: [num_bs] float64, s, toa_i - toa_ref (reference entry ignored); non-finite
            entries count as not detected
        :param ref_index: int, index of the reference BS
        :param valid: optional [num_bs] bool, BSs detected
        :param range_std_m: optional [num_bs] float64, m, each ToA's range std (c sigma_tau):
            the fit is then weighted least squares with the RSTD covariance
            C = diag(sigma_i^2) + sigma_ref^2 1 1^T, the result carries the fix covariance,
            and with ``exclusion`` the chi-square(N - 3) test of the whitened residuals at
            ``false_alarm`` excludes anchors (:meth:`_exclude`)
        """
        bs = np.asarray(bs_pos, dtype=float)
        rstd = np.asarray(rstd_s, dtype=float)
        if bs.ndim != 2 or bs.shape[1] != 3 or not np.all(np.isfinite(bs)):
            raise ValueError(f"Argument `bs_pos` must be a finite [num_bs, 3] array, not {bs.shape}")
        if rstd.shape != (bs.shape[0],):
            raise ValueError(f"Argument `rstd_s` must have shape ({bs.shape[0]},), not {rstd.shape}")
        if not isinstance(ref_index, (int, np.integer)) or not 0 <= ref_index < bs.shape[0]:
            raise ValueError(f"Argument `ref_index` must be an index into bs_pos, not {ref_index!r}")
        use = np.isfinite(rstd)
        use[ref_index] = True
        if valid is not None:
            v = np.asarray(valid, dtype=bool)
            if v.shape != use.shape:
                raise ValueError(f"Argument `valid` must have shape {use.shape}, not {v.shape}")
            use &= v
        centroid = np.append(bs[:, :2].mean(axis=0), self.ue_height_m)
        if valid is not None and not use[ref_index]:
            return MultilaterationResult(centroid, False, STATUS_TOO_FEW,
                                         "reference BS not detected", num_bs=int(use.sum()))
        n = int(use.sum())
        if n < 3:
            return MultilaterationResult(centroid, False, STATUS_TOO_FEW,
                                         f"{n} BSs detected, 3 needed for a 2-D fix", num_bs=n)
        idx = np.flatnonzero(use)
        ref = int(np.flatnonzero(idx == ref_index)[0])
        rd = SPEED_OF_LIGHT * np.where(np.isfinite(rstd), rstd, 0.0)
        if range_std_m is None:
            return replace(self._solve(bs[idx], rd[idx], ref), used=tuple(idx.tolist()))
        sig = np.asarray(range_std_m, dtype=float)
        if sig.shape != (bs.shape[0],):
            raise ValueError(f"Argument `range_std_m` must have shape ({bs.shape[0]},), not "
                             f"{sig.shape}")
        if not np.all((sig[idx] > 0) & np.isfinite(sig[idx])):
            raise ValueError("Argument `range_std_m` must be finite and > 0 for the used BSs")
        return self._exclude(bs, rd, sig, list(idx.tolist()), int(ref_index))

    def _exclude(self, bs: np.ndarray, rd: np.ndarray, sig: np.ndarray, used: list[int],
                 ref: int) -> MultilaterationResult:
        """Weighted fix of the anchors ``used`` and fault detection and exclusion.

        The chi-square statistic of the whitened residuals, r^T C^-1 r, has N - 3 degrees of
        freedom for N anchors (N - 1 RSTDs, two unknowns) under Gaussian ToA noise of the
        given stds. When it exceeds the (1 - false_alarm) quantile and at least one degree of
        freedom would remain, every anchor is tried out in turn (the reference too: the
        remaining anchor of least std becomes the reference, the range differences re-taken
        to it) and the one whose removal leaves the least statistic is excluded; then the test
        is repeated (RAIM fault detection and exclusion as in GNSS receivers: Parkinson and
        Axelrad, "Autonomous GPS integrity monitoring using the pseudorange residual",
        Navigation 35(2), 1988; Brown, "A baseline GPS RAIM scheme", Navigation 39(3), 1992;
        references as recalled).
        Without ``exclusion`` only the test is made. A fix that still fails it is a residual
        failure naming the statistic.
        """
        excluded: list[int] = []
        first = None
        while True:
            res = self._weighted(bs, rd, sig, used, ref)
            if first is None:
                first = (float(res.chi2), int(res.dof))
            thr = chdtri(res.dof, self.false_alarm) if res.dof > 0 else np.inf
            fails = res.dof > 0 and res.chi2 > thr and res.status != STATUS_NO_CONVERGENCE
            if not fails or not self.exclusion or res.dof < 2:
                break
            best = None
            for j in used:
                rest = [i for i in used if i != j]
                r2 = ref if j != ref else min(rest, key=lambda i: sig[i])
                trial = self._weighted(bs, rd, sig, rest, r2)
                # a trial without a usable fix explains nothing
                stat = trial.chi2 if trial.status in (STATUS_OK, STATUS_RESIDUAL) else np.inf
                if best is None or stat < best[0]:
                    best = (stat, j, r2)
            if not np.isfinite(best[0]):
                break
            _, j, ref = best
            used = [i for i in used if i != j]
            excluded.append(j)
        res = replace(res, excluded=tuple(excluded), used=tuple(used), test_chi2=first[0],
                      test_dof=first[1])
        if res.ok and fails:
            return replace(res, ok=False, status=STATUS_RESIDUAL,
                           reason=f"chi-square {res.chi2:.1f} > {thr:.1f} (dof {res.dof}, "
                                  f"P_fa {self.false_alarm:g})"
                                  + (f" after excluding {len(excluded)}" if excluded else ""))
        return res

    def _weighted(self, bs: np.ndarray, rd: np.ndarray, sig: np.ndarray, used: list[int],
                  ref: int) -> MultilaterationResult:
        """Weighted fix of anchors ``used`` (indices into ``bs``) with reference ``ref``."""
        idx = np.asarray(used)
        k = int(np.flatnonzero(idx == ref)[0])
        # range differences to the reference taken afresh (rd holds them to the call's one)
        rdi = rd[idx] - rd[ref]
        s2 = sig[idx] ** 2
        others = [i for i in range(len(idx)) if i != k]
        cov = np.diag(s2[others]) + s2[k]
        res = self._solve(bs[idx], rdi, k, cov=cov)
        return res


    # -- internals ---------------------------------------------------------------------------
    def _solve(self, bs: np.ndarray, rd: np.ndarray, ref: int,
               cov: np.ndarray | None = None) -> MultilaterationResult:
        # imported on the first fix: a run that computes no chain (a resume past its last
        # point) then never loads scipy.optimize
        from scipy.optimize import leastsq

        n = bs.shape[0]
        others = np.array([i for i in range(n) if i != ref])
        m = n - 1
        # whitening of the RSTD covariance I + 1 1^T: W^T W = (I + 1 1^T)^-1 (or of ``cov``)
        w = (np.linalg.cholesky(np.eye(m) - np.ones((m, m)) / n).T if cov is None
             else np.linalg.cholesky(np.linalg.inv(cov)).T)
        h2 = (bs[:, 2] - self.ue_height_m) ** 2

        def raw(xy):
            d = np.sqrt(np.sum((bs[:, :2] - xy) ** 2, axis=1) + h2)
            return (d[others] - d[ref]) - rd[others]

        fun, jac = _whitened_residuals(bs, rd, ref, h2, w)
        centroid = bs[:, :2].mean(axis=0)
        starts = chan_initialisation(bs, rd, ref, self.ue_height_m)
        starts.append(self._grid_start(bs, rd, ref, others))
        line = _bs_line(bs)
        if line is not None:
            # collinear BSs: the fit is symmetric about their line, so the mirror image of
            # every start is an equally good one; refining both finds the twin fix, which is
            # then reported (``alternatives``, ``ambiguous``) instead of a silent coin toss
            p0, u = line
            starts += [2.0 * (p0 + u * ((x - p0) @ u)) - x for x in list(starts)]
        sols = []
        for x0 in starts:
            try:
                x, _, info, mesg, ier = leastsq(fun, x0, Dfun=jac, full_output=True,
                                                maxfev=self.max_nfev, xtol=1e-12, ftol=1e-12,
                                                gtol=1e-12)
            except (ValueError, TypeError, np.linalg.LinAlgError):   # pragma: no cover
                continue
            status = _LM_STATUS.get(ier, -1)
            res = _Refined(x, 0.5 * float(info["fvec"] @ info["fvec"]), status,
                           _LM_MESSAGE.get(status, mesg), int(info["nfev"]))
            if np.all(np.isfinite(res.x)) and np.isfinite(res.cost):
                sols.append(res)
        best = min(sols, key=lambda r: r.cost) if sols else None
        alternatives = []
        if best is not None:
            # equally good, distinct fixes (3 BSs, UE outside the hull: two hyperbola
            # intersections). Keep the one nearest the network centroid, report the others.
            rms_best = np.sqrt(np.mean(raw(best.x) ** 2))
            twins = [r for r in sols if r.status > 0
                     and np.sqrt(np.mean(raw(r.x) ** 2)) <= rms_best + 1e-6]
            twins.sort(key=lambda r: np.linalg.norm(r.x - centroid))
            for r in twins:
                if all(np.linalg.norm(r.x - a) > 1.0 for a in alternatives):
                    alternatives.append(r.x)
            if twins:
                best = twins[0]
        pos_fallback = np.append(centroid, self.ue_height_m)
        if best is None:
            return MultilaterationResult(pos_fallback, False, STATUS_NO_CONVERGENCE,
                                         "no start produced a finite solution", num_bs=n)
        pos = np.append(best.x, self.ue_height_m)
        r = raw(best.x)
        rms = float(np.sqrt(np.mean(r**2)))
        dof = n - 3
        if cov is not None:     # whitened by the full covariance: the SSR is the statistic
            stat = float(2.0 * best.cost)
        else:
            stat = float(2.0 * best.cost / self.sigma_m**2) if self.sigma_m else 0.0
        g = gdop(bs, pos, ref)
        common = dict(residual_rms_m=rms, chi2=stat, dof=dof, num_bs=n, gdop=g,
                      nfev=int(best.nfev), starts=[np.asarray(s) for s in starts],
                      alternatives=[np.append(a, self.ue_height_m) for a in alternatives[1:]])
        if cov is not None:
            jw = np.asarray(jac(best.x), dtype=float)           # W J, [N - 1, 2]
            info = jw.T @ jw
            common["covariance"] = (np.linalg.inv(info) if np.linalg.cond(info) < 1e12
                                    else np.full((2, 2), np.inf))
        if best.status <= 0:
            return MultilaterationResult(pos, False, STATUS_NO_CONVERGENCE,
                                         f"Levenberg-Marquardt stopped: {best.message}", **common)
        dist = float(np.linalg.norm(best.x - centroid))
        if dist > self.max_distance_m:
            return MultilaterationResult(pos_fallback, False, STATUS_DIVERGED,
                                         f"fix {dist:.0f} m from the network centroid "
                                         f"(> {self.max_distance_m:.0f} m)", **common)
        if rms > self.max_residual_m:
            return MultilaterationResult(pos, False, STATUS_RESIDUAL,
                                         f"rms range residual {rms:.2f} m > "
                                         f"{self.max_residual_m:.2f} m (inconsistent RSTDs)",
                                         **common)
        if self.sigma_m and dof > 0 and stat > chdtri(dof, self.false_alarm):
            return MultilaterationResult(pos, False, STATUS_RESIDUAL,
                                         f"chi-square {stat:.1f} > {chdtri(dof, self.false_alarm):.1f}"
                                         f" (dof {dof}, P_fa {self.false_alarm:g})", **common)
        return MultilaterationResult(pos, True, STATUS_OK, "", **common)

    def _grid_start(self, bs: np.ndarray, rd: np.ndarray, ref: int,
                    others: np.ndarray) -> np.ndarray:
        """Best node (least squared range-difference residual) of a coarse grid over the BS
        hull padded by its size (at least 500 m)."""
        lo, hi = bs[:, :2].min(axis=0), bs[:, :2].max(axis=0)
        pad = max(500.0, float(np.max(hi - lo)))
        gx = np.linspace(lo[0] - pad, hi[0] + pad, self.grid_points)
        gy = np.linspace(lo[1] - pad, hi[1] + pad, self.grid_points)
        # squared offsets per axis, summed by broadcasting: node (i, j) = (gx[i], gy[j])
        dx2 = (gx[:, None] - bs[None, :, 0]) ** 2                            # [G, N]
        dy2 = (gy[:, None] - bs[None, :, 1]) ** 2                            # [G, N]
        d = np.sqrt(dx2[:, None, :] + dy2[None, :, :]
                    + (bs[:, 2] - self.ue_height_m) ** 2).reshape(-1, bs.shape[0])  # [G*G, N]
        cost = np.sum((d[:, others] - d[:, ref:ref + 1] - rd[others]) ** 2, axis=1)
        i = int(np.argmin(cost))
        return np.array([gx[i // gy.size], gy[i % gy.size]])


def multilaterate(bs_pos, rstd_s, ref_index: int = 0, valid=None, **config) -> MultilaterationResult:
    """One-shot :class:`Multilaterator` (``config`` are its constructor arguments)."""
    return Multilaterator(**config)(bs_pos, rstd_s, ref_index=ref_index, valid=valid)
