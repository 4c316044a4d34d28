"""Angular-based source authentication (ABSA): estimated AoA against a reference azimuth per BS.

Paper Sec. "Angular-Based Source Authentication": BS ``i`` passes iff
``|wrap(theta_est_i - theta_ref_i)| <= delta_th`` (20 deg), with the difference wrapped to
(-pi, pi] so that 359 deg and 1 deg are 2 deg apart.

References (``reference`` in the config):

* ``"geometry"``: the azimuth from the last validated UE position towards the BS,
  ``atan2(y_bs - y_ue, x_bs - x_ue)`` (x east, y north, azimuth from +x counter-clockwise, the
  package convention). The caller supplies the last validated position (e.g. the tracker's
  last accepted fix, or the initial fix).
* ``"scene"``: a supplied per-BS azimuth, e.g. the ray-traced scene's strongest-path AoA at the
  UE (what a perfect beam report would give; in NLOS it differs from the geometric bearing).
* ``"scene_or_geometry"``: the supplied azimuth where it is finite, else the geometry.

Missing data:

* a BS whose estimate is NaN (no AoA: BS not detected, or the estimator found no source) follows
  ``missing_estimate``: ``"invalid"`` (default; the paper counts jamming as detected) or
  ``"ignore"``.
* a BS with no reference (no last validated position and no scene azimuth) is not checked.
* a point where no BS could be checked gets ``unchecked_verdict`` (default invalid, fail-safe).

Statistic (:attr:`ABSAVerdict.stat`, the ``absa_stat`` CSV column, deg): the largest
``|wrap(theta_est_i - theta_ref_i)|`` over the checked BSs, rounded to :data:`STAT_DECIMALS`
decimals of a degree (far below any AoA accuracy; the rounding absorbs the wrap's roundoff at an
exact threshold difference), so that the point is valid iff ``stat <= threshold_deg`` exactly.
A point that ``missing_estimate="invalid"`` or ``unchecked_verdict=False`` rejects whatever the
threshold gets ``inf``; one that ``unchecked_verdict=True`` accepts gets 0 (no deviation seen).

The ULA's mirror ambiguity (az and 2 alpha - az give the same spatial frequency) must be resolved
before this stage (:func:`veriloc_rt.phy.receiver.aoa.resolve_ambiguity` against the same reference).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.detectors import ABSAConfig

#: decimals of a degree the statistic keeps: wrapping an exact threshold difference can cost a
#: few ulp, which rounding to 1e-9 deg removes (an AoA is never that accurate)
STAT_DECIMALS = 9

__all__ = ["ABSAConfig", "ABSADetector", "ABSAVerdict", "wrap_angle", "angle_difference",
           "geometric_azimuth"]


def wrap_angle(a):
    """Wrap to (-pi, pi]. a : [...] float64, rad -> [...] float64, rad."""
    w = np.mod(np.asarray(a, dtype=np.float64) + np.pi, 2.0 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def angle_difference(a, b):
    """|a - b| on the circle, in [0, pi]. a, b : [...] float64, rad -> [...] float64, rad."""
    return np.abs(wrap_angle(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)))


def geometric_azimuth(bs_pos, ue_pos):
    """Azimuth from the UE towards each BS.

    :param bs_pos: [num_bs, 2 or 3] float64, m
    :param ue_pos: [2 or 3] float64, m
    :return: az : [num_bs] float64, rad, from +x counter-clockwise, in (-pi, pi]
    """
    b = np.atleast_2d(np.asarray(bs_pos, dtype=np.float64))
    u = np.asarray(ue_pos, dtype=np.float64).reshape(-1)
    return np.arctan2(b[:, 1] - u[1], b[:, 0] - u[0])


@dataclass(frozen=True, eq=False)
class ABSAVerdict:
    """valid : bool; error : [num_bs] float64, rad, |AoA - reference| (NaN unchecked);
    reference : [num_bs] float64, rad (NaN: none); passed : [num_bs] bool;
    stat : float, deg, the largest checked deviation (valid iff ``stat <= threshold_deg``;
    module docstring)."""

    valid: bool
    error: np.ndarray
    reference: np.ndarray
    passed: np.ndarray
    stat: float = float("nan")


class ABSADetector:
    """Stateless ABSA point verdict.

    :param config: tolerance and reference source
    """

    def __init__(self, config: ABSAConfig | None = None):
        self.config = config if config is not None else ABSAConfig()
        self.threshold = math.radians(self.config.threshold_deg)

    @staticmethod
    def deviation_deg(error) -> np.ndarray:
        """[...] float64, deg: ``error`` (rad) in degrees, rounded to :data:`STAT_DECIMALS`."""
        return np.round(np.degrees(np.asarray(error, dtype=np.float64)), STAT_DECIMALS)

    def reference_azimuth(self, bs_pos, reference_position=None, reference_azimuth=None) -> np.ndarray:
        """ref : [num_bs] float64, rad, the reference per BS (NaN where there is none)."""
        b = np.atleast_2d(np.asarray(bs_pos, dtype=np.float64))
        n = b.shape[0]
        geo = np.full(n, np.nan)
        if reference_position is not None:
            p = np.asarray(reference_position, dtype=np.float64).reshape(-1)
            if p.size < 2:
                raise ValueError(f"Argument `reference_position` must hold (x, y), not {p.size} values")
            if np.all(np.isfinite(p[:2])):
                geo = geometric_azimuth(b, p)
        scene = np.full(n, np.nan)
        if reference_azimuth is not None:
            scene = np.asarray(reference_azimuth, dtype=np.float64).reshape(-1)
            if scene.shape != (n,):
                raise ValueError(f"Argument `reference_azimuth` must have shape ({n},), not {scene.shape}")
        mode = self.config.reference
        if mode == "geometry":
            return geo
        if mode == "scene":
            return scene
        return np.where(np.isfinite(scene), scene, geo)

    def __call__(self, azimuth, bs_pos, reference_position=None, reference_azimuth=None) -> ABSAVerdict:
        """Point verdict.

        :param azimuth: [num_bs] float64, rad, estimated AoA azimuth per serving BS (NaN: none)
        :param bs_pos: [num_bs, 2 or 3] float64, m
        :param reference_position: [2 or 3] float64, m, last validated UE position (None: unknown)
        :param reference_azimuth: [num_bs] float64, rad, supplied reference (NaN: unknown)
        """
        est = np.asarray(azimuth, dtype=np.float64).reshape(-1)
        b = np.atleast_2d(np.asarray(bs_pos, dtype=np.float64))
        if b.shape[0] != est.size or b.shape[1] not in (2, 3):
            raise ValueError(f"Arguments `azimuth` {est.shape} and `bs_pos` {b.shape} must be "
                             "[num_bs] and [num_bs, 2 or 3]")
        ref = self.reference_azimuth(b, reference_position, reference_azimuth)
        has_est, has_ref = np.isfinite(est), np.isfinite(ref)
        checked = has_est & has_ref
        err = np.full(est.size, np.nan)
        err[checked] = angle_difference(est[checked], ref[checked])
        dev = self.deviation_deg(err)
        th = self.config.threshold_deg
        passed = checked & (np.nan_to_num(dev, nan=np.inf) <= th)
        k = self.config.min_pass
        if k:   # k of N: the k-th smallest deviation (inf with fewer than k checked)
            d = np.sort(dev[checked])
            stat = float(d[k - 1]) if d.size >= k else math.inf
            return ABSAVerdict(stat <= th, err, ref, passed, stat)
        if self.config.missing_estimate == "invalid" and not np.all(has_est):
            stat = math.inf
        elif not np.any(checked):
            stat = 0.0 if self.config.unchecked_verdict else math.inf
        else:
            stat = float(dev[checked].max())
        return ABSAVerdict(stat <= th, err, ref, passed, stat)
