"""Position tracking detector: constant-velocity Kalman filter with NIS gating and M-of-N recovery.

Model (paper Sec. "Position Tracking"; Bar-Shalom, Li & Kirubarajan 2001, Sec. 6.3.3):

* state ``x = [px, py, vx, vy]`` (m, m/s), transition ``F = [[I, dt I], [0, I]]``;
* process noise: discrete white-noise acceleration (DWNA), a piecewise-constant acceleration of
  variance ``q = accel_std_mps2**2`` per epoch, ``Gamma = [dt^2/2, dt]^T`` per axis and
  ``Q = q Gamma Gamma^T`` per axis (x and y independent);
* measurement ``z = H x + v``, ``H = [I, 0]``, ``R = meas_std_m**2 I``;
* NIS ``eps = nu^T S^-1 nu`` with ``nu = z - H x_pred``, ``S = H P_pred H^T + R``; under the model
  it is chi-square(2). The gate is the chi-square(2) quantile at ``gate_probability``:
  ``gamma = -2 ln(1 - P)`` (3.7942 at 0.85; standards-and-limits.md "Kalman NIS gating").

Decision rule per epoch (exactly what :meth:`KalmanTracker.__call__` does):

1. **No track yet**: the first finite measurement initialises the track (position = z,
   velocity 0, covariance ``diag(R, v0^2 I)``) and is *valid*; a missing/NaN measurement before
   that is *invalid* and nothing else happens.
2. Every later epoch first predicts (``x = F x``, ``P = F P F^T + Q``).
3. **Tracking mode**: a finite measurement with ``eps <= gamma`` is accepted (Kalman update,
   Joseph form) and the epoch is *valid*. ``eps > gamma`` or a missing/NaN measurement (DoS)
   makes the epoch *invalid*, the update is skipped (coasting: prediction only, ``P`` grows) and
   the tracker enters recovery mode.
4. **Recovery mode** (M-of-N): each epoch is *consistent* iff its measurement is finite and
   passes the gate against the coasted prediction. The window holds the consistency flags of
   the last ``window_n`` epochs spent in recovery mode (epochs before the rejection that started
   it do not count; the rejected epoch itself is not in recovery). The current measurement is
   re-accepted iff the current epoch is consistent and at least ``accept_m`` of the window's
   flags are true: then the filter updates with it, the epoch is *valid* and the tracker is back
   in tracking mode. Otherwise the epoch is *invalid* and the filter keeps coasting. Measurements
   of the window other than the current one are never fused.

Statistic (:attr:`TrackVerdict.stat`, the ``tracking_stat`` CSV column, dimensionless NIS) such
that the epoch is valid iff ``stat <= gamma`` exactly:

* tracking mode: the NIS (``inf`` without a measurement);
* recovery mode: ``max(eps_k, eps_(M))``, the current NIS and the M-th smallest NIS of the
  recovery window (``inf`` for a missing measurement or a window shorter than M): both are
  <= gamma iff the current epoch passes and at least M of the window's epochs do, the M-of-N
  rule above;
* no track yet: 0 for the measurement that initialises the track, ``inf`` without one.

The filter's path depends on the gate (what it fuses, when it coasts), so sweeping a threshold
over this statistic gives the run's decisions at other thresholds *given* the configured gate's
track, not what a run with another gate would decide.

With the paper's two-epoch window (M = N = 2), recovery needs two consecutive gate passes, so
one false rejection costs at least two invalid epochs: if gate outcomes were independent with
false-rejection probability ``p = 1 - gate_probability``, the invalid rate would be
``1 - (1 - p)^2`` (0.2775 at p = 0.15; a three-state Markov chain).

They are not independent: an 85 % gate rejects good measurements preferentially when the state
error is large, the filter coasts instead of correcting, and the error grows while P says it
should not. Measured on 40 tracks x 150 epochs (R = (5 m)^2, dt = 1 s, after 20 epochs):

=============================  ==========  ==============  ============
truth / filter accel std       gate P      NIS mean        invalid rate
=============================  ==========  ==============  ============
CV (0) / 1.0 m/s^2 (default)   0.85        1.67            0.19
DWNA 1.0 / 1.0 (matched)       0.85        4.3 (track loss) 0.63
DWNA 1.0 / 2.0 (Q x4)          0.85        1.79            0.21
DWNA 1.0 / 1.0                 0.95        2.63            0.18
DWNA 1.0 / 1.0                 0.99        2.01            0.016
=============================  ==========  ==============  ============

So with the paper's 85 % gate, ``accel_std_mps2`` must over-bound the real manoeuvres (the paper
tuned its gate "empirically"); a matched filter loses the track.

Known limitations (tested in ``tests/unit/detectors/test_tracking.py``):

* coasting accumulates ``Q``: after k coasted epochs the position variance grows like
  ``q dt^4 k^3 / 3``, so a constant spoofing offset eventually falls inside the inflated gate
  and, after M-of-N passes, is re-accepted (the recovery rule delays this, it cannot prevent it);
* a slowly drifting spoof (a few m per epoch of extra displacement) stays inside the gate at
  every epoch and drags the track (per-step gating cannot see it; a windowed/cumulative NIS or
  CUSUM would be needed).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..config.detectors import TrackingConfig

__all__ = ["TrackingConfig", "TrackVerdict", "KalmanTracker", "cv_transition", "dwna_process_noise",
           "nis_gate"]

log = logging.getLogger(__name__)

MODE_INIT = "init"
MODE_TRACKING = "tracking"
MODE_RECOVERY = "recovery"


def nis_gate(probability: float, dof: int = 2) -> float:
    """Chi-square quantile: the NIS gate. Closed form for dof 2 (``-2 ln(1 - P)``)."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"Argument `probability` must be in (0, 1), not {probability!r}")
    if dof == 2:
        return -2.0 * math.log1p(-probability)
    from scipy.stats import chi2
    return float(chi2.ppf(probability, dof))


def cv_transition(dt_s: float) -> np.ndarray:
    """F : [4, 4] float64, constant-velocity transition for [px, py, vx, vy] over ``dt_s`` s."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt_s
    return f


def dwna_process_noise(dt_s: float, accel_std_mps2: float) -> np.ndarray:
    """Q : [4, 4] float64, DWNA process noise (Bar-Shalom 6.3.3), m^2, m^2/s, m^2/s^2.

    Per axis ``q [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]`` with ``q = accel_std^2``.
    """
    q = accel_std_mps2 ** 2
    g = np.array([dt_s ** 2 / 2.0, dt_s])
    block = q * np.outer(g, g)
    out = np.zeros((4, 4))
    for ax in (0, 1):
        idx = np.array([ax, ax + 2])
        out[np.ix_(idx, idx)] = block
    return out


@dataclass(frozen=True, eq=False)
class TrackVerdict:
    """Outcome of one epoch.

    valid : bool, the detector's verdict (True: no anomaly)
    accepted : bool, the measurement was fused
    nis : float, NIS of the measurement against the prediction (NaN: none computed)
    mode : str, mode *after* this epoch ('init', 'tracking', 'recovery')
    position : [2] float64, m, filtered (or coasted) position (NaN before initialisation)
    covariance : [4, 4] float64, state covariance after this epoch
    stat : float, the decision statistic (valid iff ``stat <= gate``; module docstring)
    """

    valid: bool
    accepted: bool
    nis: float
    mode: str
    position: np.ndarray
    covariance: np.ndarray
    stat: float = math.nan


#: smallest variance of a fix's covariance the tracker takes, m^2 (a weighted fit of many
#: strong TRPs can claim centimetres, which no street-level drive model follows)
MIN_R_M2 = 0.01


class KalmanTracker:
    """Stateful tracking detector; call once per trajectory point, ``reset()`` between runs.

    :param config: thresholds and noise levels
    """

    def __init__(self, config: TrackingConfig | None = None):
        self.config = config if config is not None else TrackingConfig()
        self.gate = nis_gate(self.config.gate_probability)
        self._r = self.config.meas_std_m ** 2 * np.eye(2)
        self.reset()

    def reset(self) -> None:
        """Forget the track."""
        self.x = np.full(4, np.nan)
        self.P = np.full((4, 4), np.nan)
        self.mode = MODE_INIT
        #: NIS of the epochs spent in recovery mode (inf: no measurement), the last window_n
        self._window: list[float] = []

    @property
    def position(self) -> np.ndarray:
        """[2] float64, m, current position estimate."""
        return self.x[:2].copy()

    def predict(self, dt_s: float) -> None:
        f = cv_transition(dt_s)
        self.x = f @ self.x
        self.P = f @ self.P @ f.T + dwna_process_noise(dt_s, self.config.accel_std_mps2)

    def _update(self, z: np.ndarray, nu: np.ndarray, s: np.ndarray, r: np.ndarray) -> None:
        h = np.hstack([np.eye(2), np.zeros((2, 2))])
        k = self.P @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ nu
        ikh = np.eye(4) - k @ h
        self.P = ikh @ self.P @ ikh.T + k @ r @ k.T  # Joseph form

    def __call__(self, z, dt_s: float | None = None, r=None) -> TrackVerdict:
        """Process one epoch.

        :param z: [2] float64, m, the position fix (x, y); None or any NaN: no fix (DoS)
        :param dt_s: time since the previous epoch; None: ``config.dt_s``
        :param r: [2, 2] float64, m^2, this fix's measurement covariance (None or not finite:
            ``meas_std_m^2 I``); its eigenvalues are raised to at least :data:`MIN_R_M2`
        """
        dt = self.config.dt_s if dt_s is None else float(dt_s)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"Argument `dt_s` must be finite and > 0, not {dt_s!r}")
        rr = self._r
        if r is not None:
            r = np.asarray(r, dtype=np.float64)
            if r.shape != (2, 2):
                raise ValueError(f"Argument `r` must be [2, 2], not {r.shape}")
            if np.all(np.isfinite(r)):
                w, v = np.linalg.eigh(0.5 * (r + r.T))
                rr = (v * np.maximum(w, MIN_R_M2)) @ v.T
        meas = None
        if z is not None:
            meas = np.asarray(z, dtype=np.float64).reshape(-1)
            if meas.size < 2:
                raise ValueError(f"Argument `z` must hold (x, y), not shape {np.shape(z)}")
            meas = meas[:2]
            if not np.all(np.isfinite(meas)):
                meas = None

        if self.mode == MODE_INIT:
            if meas is None:
                return self._verdict(False, math.nan, math.inf)
            v0 = self.config.init_velocity_std_mps ** 2
            self.x = np.array([meas[0], meas[1], 0.0, 0.0])
            self.P = np.diag([rr[0, 0], rr[1, 1], v0, v0])
            self.mode = MODE_TRACKING
            return self._verdict(True, math.nan, 0.0)

        self.predict(dt)
        nis = math.nan
        if meas is not None:
            nu = meas - self.x[:2]
            s = self.P[:2, :2] + rr
            nis = float(nu @ np.linalg.solve(s, nu))
        eps = nis if meas is not None else math.inf

        if self.mode == MODE_TRACKING:
            if eps <= self.gate:
                self._update(meas, nu, s, rr)
                return self._verdict(True, nis, eps)
            self.mode = MODE_RECOVERY
            self._window = []
            log.debug("tracking: rejected (nis %.3g), coasting", nis)
            return self._verdict(False, nis, eps)

        # recovery mode: M-of-N over the epochs spent in recovery
        self._window.append(eps)
        self._window = self._window[-self.config.window_n:]
        m = self.config.accept_m
        mth = sorted(self._window)[m - 1] if len(self._window) >= m else math.inf
        stat = max(eps, mth)
        if stat <= self.gate:
            self._update(meas, nu, s, rr)
            self.mode = MODE_TRACKING
            self._window = []
            log.debug("tracking: re-accepted (nis %.3g)", nis)
            return self._verdict(True, nis, stat)
        return self._verdict(False, nis, stat)

    def _verdict(self, accepted: bool, nis: float, stat: float) -> TrackVerdict:
        """An epoch's verdict: valid iff the measurement was fused (``stat <= gate`` then)."""
        return TrackVerdict(accepted, accepted, nis, self.mode, self.x[:2].copy(), self.P.copy(),
                            stat)
