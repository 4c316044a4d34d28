"""Layer 5 (beside detectors, independent of it), attacks: what the adversary transmits.

The three threats as stages on arrays (:mod:`.fbs` false-BS selective spoofing, :mod:`.meaconing`
relay, :mod:`.jamming` wideband noise), :mod:`.threats` (the threat registry: each scenario's
threat registered by name, the three built-ins and any plug-in, docs/extending.md) and
:mod:`.adversary`, which looks the scenario's threat up and turns it into the signal a
positioning chain receives at a trajectory point.
"""

from .fbs import (FalseBaseStation, FBSPlan, fbs_delays, fbs_delays_absolute, spoofer_replicas,
                  target_position)
from .jamming import Jammer, jamming_grid, jamming_iq, prs_band_hz
from .meaconing import Meaconer, fractional_delay, meacon

__all__ = ["FalseBaseStation", "FBSPlan", "fbs_delays", "fbs_delays_absolute",
           "spoofer_replicas", "target_position", "Jammer", "jamming_grid",
           "jamming_iq", "prs_band_hz", "Meaconer", "fractional_delay", "meacon"]
