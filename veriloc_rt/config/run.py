"""The run section of the config: scenarios, attack window, outcome threshold, realisations."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import InputError, bad_value
from .fields import param

__all__ = ["DEFAULT_SCENARIOS", "RunConfig"]


#: the scenarios a run evaluates by default: the benign run and the three built-in threats.
#: Every scenario but 'none' names a threat of the threat registry
#: (``veriloc_rt.attacks.threats.THREAT_REGISTRY``, above this layer: the names are checked
#: when the run starts, docs/design.md "Plug-in registries")
DEFAULT_SCENARIOS = ("none", "fbs", "meaconing", "jamming")


@dataclass(frozen=True)
class RunConfig:
    """What ``veriloc-rt run`` evaluates: scenarios, attack window, outcome threshold,
    Monte Carlo realisations."""

    scenarios: tuple[str, ...] = param(DEFAULT_SCENARIOS, "scenarios evaluated in one run, each "
                                       "over the whole trajectory: 'none' (benign) or a "
                                       "registered threat ('fbs', 'meaconing', 'jamming' or a "
                                       "plug-in, docs/extending.md; names checked when the run "
                                       "starts)")
    attack_start_fraction: float = param(0.25, "the adversary is active from point "
                                         "floor(f * num_points) (0-based; paper: point 301 of "
                                         "1200)", lo=0.0, hi=1.0)
    attack_end_fraction: float = param(0.75, "... up to, excluding, point floor(f * num_points) "
                                       "(paper: the attack ends after point 900 of 1200)",
                                       lo=0.0, hi=1.0)
    success_threshold_m: float = param(15.0, "a fix within this horizontal error is a success "
                                       "(paper: 15 m, the benign 99.9th percentile)",
                                       lo=0.0, lo_open=True, hi=1e6)
    evaluate_encrypted: bool = param(True, "also run every scenario with all serving BSs "
                                     "encrypted (outcomes_encrypted); the detectors are "
                                     "evaluated on standard PRS, as in the paper")
    digsig: str = param("separate", "'separate': the DigSig column comes from a second, DS-tagged "
                        "chain call on the same noise and adversary draws (it decodes its own "
                        "tags with the first call's timing; costs the second grid and the tag "
                        "decoding per point); 'shared': it reuses the HMAC-tagged run's tag checks "
                        "with the same verdict rule (same decoder, codeword lengths differ)",
                        choices=("separate", "shared"))
    realisations: int = param(1, "Monte Carlo realisations: complete runs, realisation r with "
                              "BS layout topology.iteration + r and its own draws (seed derived "
                              "from the seed; realisation 0 is the plain run); metrics.json then "
                              "holds the mean and 95 % confidence interval over them",
                              lo=1, hi=100_000)
    street_width_variants_m: tuple[float, ...] = param(
        (), "scene variants of a Monte Carlo (procedural canyon only): realisation r uses "
        "scene.street_width_m = this list's entry r mod its length (2..100 m each); [] keeps "
        "scene.street_width_m")
    height_jitter_variants_m: tuple[float, ...] = param(
        (), "scene variants of a Monte Carlo (procedural canyon only): realisation r uses "
        "scene.height_jitter_m = this list's entry r mod its length (0..200 m each, below "
        "scene.building_height_m; each realisation draws its own heights from its seed); [] "
        "keeps scene.height_jitter_m")

    def validate(self, path: str = "run") -> None:
        for name, lo, hi in (("street_width_variants_m", 2.0, 100.0),
                             ("height_jitter_variants_m", 0.0, 200.0)):
            for i, v in enumerate(getattr(self, name)):
                if not lo <= v <= hi:
                    raise bad_value(f"{path}.{name}[{i}]", v, f"a value >= {lo:g} and <= {hi:g}")
        if not self.scenarios:
            raise bad_value(f"{path}.scenarios", list(self.scenarios), "at least one scenario")
        if len(set(self.scenarios)) != len(self.scenarios):
            raise bad_value(f"{path}.scenarios", list(self.scenarios), "no repeated scenario")
        if self.attack_end_fraction <= self.attack_start_fraction:
            raise bad_value(f"{path}.attack_end_fraction", self.attack_end_fraction,
                            f"a value > attack_start_fraction ({self.attack_start_fraction})")

    def check_trajectory_length(self, num_points: int, where: str) -> None:
        """Raise :class:`InputError` when an attack scenario's window holds no point of a
        trajectory of ``num_points`` points (every attack metric would be empty)."""
        if not any(s != "none" for s in self.scenarios):
            return
        lo = int(self.attack_start_fraction * num_points)
        hi = int(self.attack_end_fraction * num_points)
        if hi <= lo:
            raise InputError("run.attack_end_fraction",
                             f"the attack window, points floor({self.attack_start_fraction:g} x "
                             f"{num_points}) = {lo} up to floor({self.attack_end_fraction:g} x "
                             f"{num_points}) = {hi}, is empty at {num_points} points ({where}); "
                             "widen the window or use more points")

    def attack_points(self, num_points: int):
        """[num_points] bool, the attack window of a trajectory of ``num_points`` points."""
        import numpy as np

        i = np.arange(num_points)
        lo = int(np.floor(self.attack_start_fraction * num_points))
        hi = int(np.floor(self.attack_end_fraction * num_points))
        return (i >= lo) & (i < hi)

