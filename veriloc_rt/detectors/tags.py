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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.detectors import TagDetectorConfig

__all__ = ["TagDetectorConfig", "TagDetector", "TagVerdict"]


@dataclass(frozen=True, eq=False)
class TagVerdict:
    """valid : bool; verified : [num_bs] bool, per-BS verdict; detected : [num_bs] bool."""

    valid: bool
    verified: np.ndarray
    detected: np.ndarray


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
        # tolerance for fractions like 5/10 vs 0.5 computed in floating point
        verified = det & (num_checked > 0) & (frac >= self.config.min_valid_fraction - 1e-12)
        ok = bool(np.all(verified[det]))
        if self.config.undetected == "invalid" and not np.all(det):
            ok = False
        ok = ok and int(verified.sum()) >= self.config.min_verified_bs
        return TagVerdict(ok, verified, det)
