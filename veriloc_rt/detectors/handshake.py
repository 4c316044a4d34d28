"""DL-UL handshake detector: the UE's DL-OTDOA fix against the network's UL fix.

Paper Sec. "Downlink-Uplink Handshaking": valid iff ``||p_DL - p_UL|| <= epsilon`` (20 m).

Failures are explicit:

* **DL fix missing** (None, NaN, or the multilateration reported a service failure): the UE has
  no position to report, so the LMF cannot confirm it: *invalid* (the paper counts the DoS of
  jamming as detected by the handshake).
* **UL fix missing**: the network cannot check the report. ``ul_failure`` decides: ``"invalid"``
  (default, fail-safe: an unverifiable report is not trusted) or ``"valid"`` (trust the DL fix
  when the uplink is unavailable; only sensible if UL outages are known to be benign).

The distance is horizontal (x, y) by default, since both fixes assume the known UE height;
``horizontal=False`` uses the full 3-D distance when both fixes have 3 coordinates.

Statistic (:attr:`HandshakeVerdict.stat`, the ``handshake_stat`` CSV column, m): the distance,
``inf`` when a missing fix makes the point invalid whatever the threshold, 0 when
``ul_failure="valid"`` trusts a DL fix without UL fix; the point is valid iff
``stat <= threshold_m`` exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.detectors import HandshakeConfig

__all__ = ["HandshakeConfig", "HandshakeDetector", "HandshakeVerdict"]


@dataclass(frozen=True)
class HandshakeVerdict:
    """valid : bool; distance_m : float, m (NaN when a fix is missing); reason : str;
    stat : float, m (valid iff ``stat <= threshold_m``; module docstring)."""

    valid: bool
    distance_m: float
    reason: str = ""
    stat: float = float("nan")


def _fix(p, name: str) -> np.ndarray | None:
    if p is None:
        return None
    a = np.asarray(p, dtype=np.float64).reshape(-1)
    if a.size not in (2, 3):
        raise ValueError(f"Argument `{name}` must have 2 or 3 coordinates, not {a.size}")
    return a if np.all(np.isfinite(a)) else None


class HandshakeDetector:
    """Stateless DL-UL comparison.

    :param config: threshold and failure policy
    """

    def __init__(self, config: HandshakeConfig | None = None):
        self.config = config if config is not None else HandshakeConfig()

    def __call__(self, dl_position, ul_position) -> HandshakeVerdict:
        """Point verdict.

        :param dl_position: [2 or 3] float64, m, the UE's DL-OTDOA fix; None/NaN: no fix
        :param ul_position: [2 or 3] float64, m, the network's UL fix; None/NaN: no fix
        """
        dl, ul = _fix(dl_position, "dl_position"), _fix(ul_position, "ul_position")
        if dl is None:
            return HandshakeVerdict(False, float("nan"), "no DL fix", float("inf"))
        if ul is None:
            stat = 0.0 if self.config.ul_failure == "valid" else float("inf")
            return HandshakeVerdict(stat <= self.config.threshold_m, float("nan"), "no UL fix",
                                    stat)
        if not self.config.horizontal and dl.size != ul.size:
            raise ValueError("Arguments `dl_position` and `ul_position` need the same number of "
                             f"coordinates for a 3-D comparison, not {dl.size} and {ul.size}")
        n = 2 if self.config.horizontal else dl.size
        dist = float(np.linalg.norm(dl[:n] - ul[:n]))
        return HandshakeVerdict(dist <= self.config.threshold_m, dist, "", dist)
