"""Detector sections of the config: the five detectors' thresholds and rules (paper Sec. V)."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import bad_value
from .fields import param, section

__all__ = ["ABSAConfig", "FusionConfig", "HandshakeConfig", "TagDetectorConfig",
           "TrackingConfig"]


@dataclass(frozen=True)
class TagDetectorConfig:
    """HMAC / DS tag detector: how per-slot, per-BS tag checks make a point verdict."""

    scheme: str = param("hmac", "which tag the verdicts come from (label only)",
                        choices=("hmac", "ds"))
    min_valid_fraction: float = param(0.5, "fraction of a BS's checked slots whose tag must "
                                      "verify for the BS to count as verified", lo=0.0,
                                      lo_open=True, hi=1.0)
    undetected: str = param("invalid", "an undetected serving BS makes the point 'invalid', or "
                            "is 'ignore'd", choices=("invalid", "ignore"))
    min_verified_bs: int = param(1, "fewest verified BSs for a valid point", lo=0, hi=64)


@dataclass(frozen=True)
class ABSAConfig:
    """ABSA: angular tolerance and where the reference azimuth comes from."""

    threshold_deg: float = param(20.0, "largest accepted |AoA - reference| (paper: 20 deg)",
                                 lo=0.0, hi=180.0)
    reference: str = param("geometry", "reference azimuth: from the last validated position "
                           "('geometry'), a supplied per-BS azimuth ('scene'), or the supplied "
                           "one where finite else geometry ('scene_or_geometry')",
                           choices=("geometry", "scene", "scene_or_geometry"))
    missing_estimate: str = param("invalid", "a BS without an AoA estimate makes the point "
                                  "'invalid' or is 'ignore'd", choices=("invalid", "ignore"))
    unchecked_verdict: bool = param(False, "verdict of a point where no BS could be checked")
    min_pass: int = param(0, "k of a k-of-N rule: the point is valid when at least k TRPs' AoAs "
                          "are within threshold_deg (the statistic is the k-th smallest "
                          "deviation; missing_estimate and unchecked_verdict then do not "
                          "apply: a TRP without an estimate just does not pass); 0: every "
                          "TRP must pass (the paper's rule)", lo=0, hi=32)


@dataclass(frozen=True)
class HandshakeConfig:
    """DL-UL handshake: largest accepted distance between the DL and UL fixes."""

    threshold_m: float = param(20.0, "largest accepted |p_DL - p_UL| (paper: 20 m)", lo=0.0,
                               hi=100_000.0)
    ul_failure: str = param("invalid", "verdict when the UL fix is missing",
                            choices=("invalid", "valid"))
    horizontal: bool = param(True, "compare (x, y) only; false: 3-D distance")


@dataclass(frozen=True)
class TrackingConfig:
    """Kalman position tracking detector (paper Sec. "Position Tracking")."""

    dt_s: float = param(1.0, "time between epochs (overridable per call)", lo=0.0, lo_open=True,
                        hi=3600.0)
    accel_std_mps2: float = param(1.0, "std of the DWNA piecewise-constant acceleration "
                                  "(process noise)", lo=0.0, lo_open=True, hi=100.0)
    meas_std_m: float = param(5.0, "std of each position coordinate of a fix (R = std^2 I)",
                              lo=0.0, lo_open=True, hi=10_000.0)
    measurement_noise: str = param("auto", "R of each fix: 'fixed' (meas_std_m^2 I, the "
                                   "paper's), 'fix_covariance' (the weighted fit's "
                                   "covariance of that fix, receiver.fix_weighting; each "
                                   "variance at least 0.01 m^2) or 'auto' (fix_covariance "
                                   "when the fix is weighted, else fixed)",
                                   choices=("auto", "fixed", "fix_covariance"))
    init_velocity_std_mps: float = param(10.0, "velocity std at track initialisation",
                                         lo=0.0, lo_open=True, hi=1000.0)
    gate_probability: float = param(0.85, "chi-square(2) probability of the NIS gate "
                                    "(0.85 -> 3.7942)", lo=0.5, hi=0.999999)
    accept_m: int = param(2, "M: gate passes needed in the recovery window", lo=1, hi=100)
    window_n: int = param(2, "N: recovery window length in epochs", lo=1, hi=100)

    def validate(self, path: str = "tracking") -> None:
        p = f"{path}." if path else ""
        if self.accept_m > self.window_n:
            raise bad_value(f"{p}accept_m", self.accept_m, f"<= window_n ({self.window_n})")

    def __post_init__(self) -> None:
        self.validate("")  # from_dict names the section

@dataclass(frozen=True)
class FusionConfig:
    """Fused decisions over the five detectors (analysis.fusion): k-of-n voting and a
    Neyman-Pearson likelihood-ratio test on their statistics."""

    k: int = param(3, "k-of-n voting: a point is rejected when at least k of the 5 detectors "
                   "reject it (3: majority)", lo=1, hi=5)
    false_alarm: float = param(0.05, "Neyman-Pearson fusion: the benign false-alarm rate its "
                               "threshold is set for (on held-out benign points)", lo=0.0,
                               lo_open=True, hi=0.5)
    split_block: int = param(10, "the Neyman-Pearson fusion splits the trajectory into blocks "
                             "of this many consecutive points, dealt in a random order (from the "
                             "seed) to three parts: fit, threshold, evaluation", lo=1,
                             hi=100_000)


@dataclass(frozen=True)
class DetectorsConfig:
    """The five per-point detectors (paper Sec. "Proposed Detection and Resilience Techniques")."""

    hmac: TagDetectorConfig = section(TagDetectorConfig, "HMAC tag detector")
    digsig: TagDetectorConfig = section(lambda: TagDetectorConfig(scheme="ds"),
                                        "digital-signature (Ed25519) tag detector")
    absa: ABSAConfig = section(ABSAConfig, "angular-based source authentication")
    handshake: HandshakeConfig = section(HandshakeConfig, "DL-UL handshake")
    tracking: TrackingConfig = section(TrackingConfig, "Kalman position tracking")
    fusion: FusionConfig = section(FusionConfig, "k-of-n and Neyman-Pearson fused decisions")
    min_benign_accept: float = param(0.5, "a detector that accepts a smaller share of the benign "
                                     "run's fixes at its threshold is reported as "
                                     "'uninformative', not as detecting the attacks", lo=0.0,
                                     hi=1.0)
    min_auth_share: float = param(0.5, "runs with more than three TRPs: the AuthShare detector "
                                  "accepts a point when at least this share of its fix's TRPs "
                                  "had their tags verified", lo=0.0, hi=1.0)
    extra: tuple[str, ...] = param((), "registered plug-in detectors (docs/extending.md) "
                                   "evaluated at every point after the five built-in ones; "
                                   "each adds its verdict column and '<name in lower case>_stat' "
                                   "to the results CSVs (names checked when the run starts)")

    def validate(self, path: str = "detectors") -> None:
        if self.hmac.scheme != "hmac":
            raise bad_value(f"{path}.hmac.scheme", self.hmac.scheme, "'hmac'")
        if self.digsig.scheme != "ds":
            raise bad_value(f"{path}.digsig.scheme", self.digsig.scheme, "'ds'")
        if len(set(self.extra)) != len(self.extra):
            raise bad_value(f"{path}.extra", list(self.extra), "no repeated detector")

