"""World sections of the config: the scene, the BS layout and the UE and adversary paths."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import bad_value
from .fields import param

__all__ = ["SceneConfig", "TopologyConfig", "TrajectoryConfig"]


@dataclass(frozen=True)
class SceneConfig:
    """Propagation scene: a procedural urban canyon or an external Mitsuba XML scene."""

    source: str = param("canyon", "'canyon' for the procedural Manhattan grid, or a path to a "
                        "Sionna-compatible Mitsuba XML scene")
    building_height_m: float = param(15.0, "mean building height", lo=1.0, hi=200.0)
    height_jitter_m: float = param(0.0, "building heights uniform in mean +- jitter (seeded)",
                                   lo=0.0, hi=100.0)
    street_width_m: float = param(5.0, "street width between blocks", lo=2.0, hi=100.0)
    block_size_m: float = param(30.0, "side of the square building blocks", lo=2.0, hi=500.0)
    extent_m: float = param(450.0, "half-side of the square area the street grid covers",
                            lo=20.0, hi=5000.0)
    margin_m: float = param(150.0, "emit only buildings within this 2-D distance of a used BS "
                            "or of the trajectory (crop: model no more than the scene needs; "
                            "cost and accuracy of the margins: docs/performance.md)",
                            lo=0.0, hi=5000.0)
    building_material: str = param("concrete", "ITU-R P.2040 material of the buildings",
                                   choices=("concrete", "brick", "plasterboard", "wood",
                                            "glass", "ceiling_board", "chipboard", "floorboard",
                                            "metal", "marble", "very_dry_ground",
                                            "medium_dry_ground", "wet_ground"))
    ground_material: str = param("medium_dry_ground", "ITU-R P.2040 material of the ground",
                                 choices=("concrete", "very_dry_ground", "medium_dry_ground",
                                          "wet_ground", "marble", "metal"))
    material_thickness_m: float = param(0.3, "slab thickness of the materials", lo=0.001, hi=10.0)

    @property
    def is_canyon(self) -> bool:
        return self.source == "canyon"

    def validate(self, path: str) -> None:
        if not self.is_canyon and not self.source.endswith(".xml"):
            raise bad_value(f"{path}.source", self.source, "'canyon' or a path ending in .xml")


@dataclass(frozen=True)
class TopologyConfig:
    """Hexagonal BS layout: 3 BSs per cell at alternate vertices of its hexagon."""

    isd_m: float = param(500.0, "inter-site distance (distance between cell centres)",
                         lo=20.0, hi=20000.0)
    bs_height_m: float = param(25.0, "BS antenna height", lo=1.0, hi=300.0)
    random_offset: bool = param(True, "random offset and rotation of the layout per Monte Carlo "
                                "iteration, drawn from the seed")
    iteration: int = param(0, "Monte Carlo iteration index (selects the layout draw)", lo=0)


@dataclass(frozen=True)
class TrajectoryConfig:
    """UE path (street-following generator or CSV) and the adversary that follows it."""

    source: str = param("generator", "'generator' or a CSV path with columns t,x,y[,z]")
    num_points: int = param(120, "number of trajectory points (the built-in default is small "
                            "enough for a few minutes; configs/paper-*.json use the paper's 1200)", lo=2, hi=1_000_000)
    dt_s: float = param(1.0, "time between points", lo=0.001, hi=3600.0, lo_open=True)
    ue_height_m: float = param(1.5, "UE antenna height above ground", lo=0.1, hi=100.0)
    region_m: float = param(250.0, "half-side of the square, centred on the origin, the "
                            "generated UE drives in", lo=10.0, hi=5000.0)
    max_speed_mps: float = param(13.9, "top cruising speed", lo=0.1, hi=70.0)
    min_speed_mps: float = param(3.0, "lowest cruising speed", lo=0.0, hi=70.0)
    accel_mps2: float = param(2.0, "acceleration and braking", lo=0.1, hi=20.0)
    stop_probability: float = param(0.3, "probability of stopping at an intersection",
                                    lo=0.0, hi=1.0)
    max_stop_s: float = param(12.0, "longest stop at an intersection", lo=0.0, hi=600.0)
    turn_probability: float = param(0.4, "probability of turning at an intersection",
                                    lo=0.0, hi=1.0)
    adversary_lag_points: int = param(10, "the adversary follows the UE's path this many points "
                                      "behind", lo=0, hi=100_000)
    adversary_min_separation_m: float = param(5.0, "the adversary never gets closer than this "
                                              "along the path (it queues behind a stopped UE)",
                                              lo=0.5, hi=1000.0)

    def validate(self, path: str) -> None:
        if self.min_speed_mps > self.max_speed_mps:
            raise bad_value(f"{path}.min_speed_mps", self.min_speed_mps,
                            f"a value <= max_speed_mps ({self.max_speed_mps})")

