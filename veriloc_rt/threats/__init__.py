"""Physical-layer threats as pure functions on arrays: FBS spoofing, meaconing, jamming."""

from .fbs import (FalseBaseStation, FBSConfig, FBSPlan, biased_fix_outcomes, fbs_delays,
                  fbs_delays_absolute, spoofer_replicas, target_position)
from .jamming import Jammer, JammingConfig, dbm_to_w, jamming_grid, jamming_iq, prs_band_hz
from .meaconing import Meaconer, MeaconingConfig, fractional_delay, meacon

__all__ = ["FalseBaseStation", "FBSConfig", "FBSPlan", "biased_fix_outcomes", "fbs_delays",
           "fbs_delays_absolute",
           "spoofer_replicas", "target_position", "Jammer", "JammingConfig", "dbm_to_w",
           "jamming_grid", "jamming_iq", "prs_band_hz", "Meaconer", "MeaconingConfig",
           "fractional_delay", "meacon"]
