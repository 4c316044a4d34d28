"""What a point comes to: the detectors' verdicts and the positioning outcome.

The names of the five detectors (the CSV's columns, in the paper's order), the three outcomes and
the rule that maps a fix to one (paper Fig. "encrypted_PRS"), and :class:`PointRow`, one
trajectory point of one scenario as the run writes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["DETECTORS", "OUTCOMES", "PointRow", "TRP_DETECTORS", "outcome_of"]

#: the detectors, in the paper's (and the CSV's) column order
DETECTORS = ("HMAC", "DigSig", "ABSA", "Handshake", "Tracking")
#: the detectors of runs with more than three TRPs (``Config.trp_outputs``), after
#: :data:`DETECTORS`: the fix's integrity test and the per-anchor tag authentication
TRP_DETECTORS = ("Integrity", "AuthShare")
#: what a point comes to, from :func:`outcome_of`
OUTCOMES = ("success", "large_error", "service_failure")


@dataclass
class PointRow:
    """One trajectory point of one scenario (a CSV row).

    time_s : float, s; verdicts : {detector: bool} (True valid; :data:`DETECTORS`, and
    :data:`TRP_DETECTORS` in a run with more than three TRPs); attack : bool
    true_xy, est_xy : [2] float64, m (est NaN without a fix); error_m : float (NaN without a fix)
    outcome : str; the ``*_enc`` fields: the same for encrypted PRS (None when not evaluated)
    stats : {detector: float}, each detector's decision statistic
    (:mod:`veriloc_rt.detectors.statistics`; empty when not recorded)
    trps, links : the TRPs heard, used and excluded, and the per-TRP link rows (below)
    """

    index: int
    time_s: float
    attack: bool
    verdicts: dict
    true_xy: np.ndarray
    est_xy: np.ndarray
    error_m: float
    outcome: str
    est_xy_enc: np.ndarray | None = None
    error_m_enc: float | None = None
    outcome_enc: str | None = None
    stats: dict = field(default_factory=dict)
    #: (bs_heard, bs_used, bs_excluded): TRPs heard, TRPs the fix used (0 without a fix), the
    #: TRP slots the integrity test excluded ('3;7', '' none); None: not recorded
    trps: tuple | None = None
    #: per-TRP rows of the links CSV (``report.results.LINK_COLUMNS`` after ``index``); None:
    #: not recorded
    links: list | None = None
    #: [2, 2] float64, m^2, the weighted fit's covariance of the fix (None: none)
    fix_cov: np.ndarray | None = None
    #: (share of the fix's TRPs whose tags verified, [2] the fix from the TRPs whose tags
    #: verified alone, NaN without one); None: not recorded
    auth: tuple | None = None


def outcome_of(fix_ok: bool, error_m: float, threshold_m: float) -> str:
    """'success', 'large_error' or 'service_failure' (paper Fig. "encrypted_PRS")."""
    if not fix_ok:
        return "service_failure"
    return "success" if error_m <= threshold_m else "large_error"
