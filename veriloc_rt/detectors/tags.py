"""HMAC and digital-signature (DS) tag detectors: per-BS tag verdicts -> one point verdict.

The tag receiver (:class:`veriloc_rt.phy.receiver.tag_verifier.TagVerifier`) checks each serving BS's
tag in each received slot. This stage turns those checks into the point's verdict (paper Sec.
"Authentication Schemes Embedded in Empty PRS REs"); the same rule serves HMAC and DS, the
config names which scheme the verdict belongs to.

Rule, per point:

* a **detected** BS is *verified* iff the fraction of its checked slots whose tag verified is at
  least ``min_valid_fraction`` (default 0.5: a majority of the frame's slots; 1.0 demands every
  slot). A detected BS with no checked slot is not verified.
* an **undetected** serving BS (no correlation peak, e.g. under jamming, so no tag could be
  located) follows ``undetected``:

  - ``"invalid"`` (default, as the paper counts it): the point is invalid, because the tag of a
    serving BS could not be verified. This makes jamming a detection for HMAC/DS.
  - ``"ignore"``: undetected BSs are left out; the point still needs at least
    ``min_verified_bs`` verified BSs.

* the point is **valid** iff every detected serving BS is verified, the undetected rule allows it,
  and at least ``min_verified_bs`` BSs are verified.

Statistic (:attr:`TagVerdict.stat`, the ``hmac_stat`` / ``digsig_stat`` CSV columns): the
verified-slot fraction of the weakest BS that counts, so that the point is valid iff
``stat >= min_valid_fraction`` (exactly: the rule above and this comparison are one code path):

* the minimum over the detected serving BSs of their fraction of checked slots whose tag
  verified (a detected BS with no checked slot: 0);
* 0 when an undetected BS makes the point invalid (``undetected="invalid"``) or fewer than
  ``min_verified_bs`` BSs are detected (no fraction > 0 can make the point valid);
* 1 when no BS is detected and none is needed (``undetected="ignore"``, ``min_verified_bs=0``).

``min_valid_fraction`` lies in (0, 1], so 0 always rejects and 1 always accepts. The comparison
is exact, with no tolerance: IEEE division is correctly rounded, so a fraction k/n and a decimal
threshold are both the nearest doubles to their values and rounding keeps their order (5/10 and
0.5 are the same double).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.detectors import TagDetectorConfig

__all__ = ["TagDetectorConfig", "TagDetector", "TagVerdict"]


@dataclass(frozen=True, eq=False)
class TagVerdict:
    """valid : bool; verified : [num_bs] bool, per-BS verdict; detected : [num_bs] bool;
    stat : float, the weakest counted BS's verified-slot fraction in [0, 1] (valid iff
    ``stat >= min_valid_fraction``; module docstring)."""

    valid: bool
    verified: np.ndarray
    detected: np.ndarray
    stat: float = float("nan")


class TagDetector:
    """Stateless HMAC/DS point verdict.

    :param config: the decision rule
    """

    def __init__(self, config: TagDetectorConfig | None = None):
        self.config = config if config is not None else TagDetectorConfig()

    def __call__(self, tag_valid, detected=None) -> TagVerdict:
        """Point verdict.

        :param tag_valid: [num_bs] or [num_bs, num_slots] bool, tag verified per BS (and slot);
            a float array may carry NaN for a slot that was not checked
        :param detected: [num_bs] bool, BS detected (correlation peak found); None: all detected
        """
        tv = np.asarray(tag_valid)
        if tv.ndim == 1:
            tv = tv[:, None]
        if tv.ndim != 2 or tv.shape[0] == 0:
            raise ValueError(f"Argument `tag_valid` must have shape [num_bs] or [num_bs, num_slots], "
                             f"not {np.shape(tag_valid)}")
        num_bs = tv.shape[0]
        det = np.ones(num_bs, bool) if detected is None else np.asarray(detected, dtype=bool)
        if det.shape != (num_bs,):
            raise ValueError(f"Argument `detected` must have shape ({num_bs},), not {det.shape}")
        tvf = tv.astype(np.float64)
        checked = np.isfinite(tvf)
        num_checked = checked.sum(axis=1)
        num_ok = np.where(checked, tvf, 0.0).sum(axis=1)
        frac = np.divide(num_ok, num_checked, out=np.zeros(num_bs), where=num_checked > 0)
        th = self.config.min_valid_fraction
        verified = det & (frac >= th)   # frac is 0 without a checked slot, and th > 0
        stat = self.statistic(frac, det)
        return TagVerdict(stat >= th, verified, det, stat)

    def statistic(self, fraction: np.ndarray, detected: np.ndarray) -> float:
        """The point statistic (module docstring).

        :param fraction: [num_bs] float64, verified share of each BS's checked slots (0 if none)
        :param detected: [num_bs] bool
        """
        if self.config.undetected == "invalid" and not np.all(detected):
            return 0.0
        if int(detected.sum()) < self.config.min_verified_bs:
            return 0.0
        return float(fraction[detected].min()) if np.any(detected) else 1.0
