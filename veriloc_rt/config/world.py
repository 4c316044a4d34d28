"""World sections of the config: the scene, the BS layout and the UE and adversary paths."""

from __future__ import annotations

import importlib.util
import os
import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError, bad_value
from ..inputs import check_path
from .fields import param

__all__ = ["BUNDLED_PREFIX", "bundled_scene_names", "bundled_scene_xml", "MAX_DRIVE_M", "MAX_POINTS", "MIN_ANTENNA_HEIGHT_M", "ITU_MATERIAL_RANGES_GHZ", "itu_material_problem", "SceneConfig", "TopologyConfig",
           "TrajectoryConfig", "MIN_TRPS", "MAX_TRPS", "CELL_BS"]

#: fewest TRPs of a 2-D TDOA fix (two RSTDs for two unknowns) and the BSs of a hexagonal cell
MIN_TRPS = CELL_BS = 3
#: most TRPs per point (TR 38.857's InF evaluates 18; the PRS resources of TS 38.211 7.4.1.7
#: share one grid among up to comb x slots of them)
MAX_TRPS = 32

#: antennas sit above this height, m: TR 38.901's effective environment height h_E = 1 m (Table
#: 7.4.1-1 note 1), below which the UMa path loss and its breakpoint distance are undefined
MIN_ANTENNA_HEIGHT_M = 1.0

#: most trajectory points of one run (about 8x the paper's 1200-point drive): a run holds every
#: point's links and chain results in memory, and the geometry alone grows with the points
MAX_POINTS = 10_000
#: longest route the street generator drives, m ((num_points - 1) x dt_s x max_speed_mps): it
#: integrates the speed profile in Python every 0.25 m of route
MAX_DRIVE_M = 500e3

#: ITU-R P.2040-3 Table 3 materials Sionna RT knows (``sionna.rt.radio_materials.itu``), with
#: the frequency ranges, GHz, its fitted parameters hold for (a test checks the copy)
ITU_MATERIAL_RANGES_GHZ = {
    "concrete": ((1.0, 100.0), (110.0, 330.0)),
    "brick": ((1.0, 40.0), (110.0, 330.0)),
    "plasterboard": ((1.0, 100.0), (110.0, 330.0), (100.0, 400.0)),
    "wood": ((0.001, 100.0), (110.0, 330.0), (100.0, 400.0)),
    "glass": ((0.1, 100.0), (220.0, 450.0), (100.0, 400.0)),
    "clear_acrylic": ((110.0, 330.0),),
    "ceiling_board": ((1.0, 100.0), (220.0, 450.0), (100.0, 400.0)),
    "chipboard": ((1.0, 100.0), (100.0, 200.0)),
    "plywood": ((1.0, 40.0), (110.0, 330.0), (100.0, 400.0)),
    "marble": ((1.0, 60.0), (110.0, 330.0), (100.0, 400.0)),
    "floorboard": ((50.0, 100.0), (220.0, 300.0), (300.0, 400.0), (400.0, 450.0),
                   (100.0, 400.0)),
    "vinyl_tile": ((1.0, 40.0),),
    "carpet_tile": ((1.0, 40.0),),
    "asphalt_concrete": ((1.0, 40.0),),
    "metal": ((1.0, 100.0),),
    "very_dry_ground": ((1.0, 10.0),),
    "medium_dry_ground": ((1.0, 10.0),),
    "wet_ground": ((1.0, 10.0),),
    "vacuum": ((0.001, 100.0),),
}


def itu_material_problem(name: str, frequency_hz: float) -> str | None:
    """Why ITU material ``name`` cannot be used at ``frequency_hz`` (None: it can)."""
    ranges = ITU_MATERIAL_RANGES_GHZ.get(name)
    if ranges is None:
        return (f"unknown ITU material {name!r:.40}; Sionna RT knows "
                + ", ".join(ITU_MATERIAL_RANGES_GHZ))
    f_ghz = frequency_hz / 1e9
    if not any(lo <= f_ghz <= hi for lo, hi in ranges):
        spans = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in ranges)
        return f"ITU material {name!r} is defined for {spans} GHz, not {f_ghz:g} GHz"
    return None


#: prefix of ``scene.source`` naming a scene bundled with Sionna RT (``"sionna:munich"``)
BUNDLED_PREFIX = "sionna:"
#: the form of a registered scene source's ``scene.source``: ``<name>`` or ``<name>:<argument>``
_SOURCE_NAME = re.compile(r"[A-Za-z0-9_-]+(:.*)?")


def _bundled_scenes_dir() -> Path | None:
    """Sionna RT's bundled scene folder (``sionna/rt/scenes``), found without importing Sionna
    (importing it selects a Mitsuba variant, which :mod:`veriloc_rt.backend` must do first)."""
    spec = importlib.util.find_spec("sionna")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0]) / "rt" / "scenes"


def bundled_scene_names() -> tuple[str, ...]:
    """Names of the Sionna RT scenes bundled as ``<name>/<name>.xml`` (``sionna.rt.scene.<name>``)."""
    root = _bundled_scenes_dir()
    if root is None or not root.is_dir():
        return ()
    return tuple(sorted(d.name for d in root.iterdir() if (d / f"{d.name}.xml").is_file()))


def bundled_scene_xml(name: str, field: str = "scene.source") -> Path:
    """The XML file of bundled scene ``name``.

    :raises InputError: if Sionna RT bundles no scene of that name
    """
    names = bundled_scene_names()
    if name not in names:
        raise InputError(field, f"{BUNDLED_PREFIX}{name[:40]!r} is not a scene bundled with "
                         "Sionna RT; bundled: " + (", ".join(names) or "none (Sionna RT not found)"))
    return _bundled_scenes_dir() / name / f"{name}.xml"


@dataclass(frozen=True)
class SceneConfig:
    """Propagation scene: a procedural urban canyon or an external Mitsuba XML scene."""

    source: str = param("canyon", "'canyon' for the procedural Manhattan grid, a path to a "
                        "Sionna-compatible Mitsuba XML scene (metres, z up, flat ground at the "
                        "bottom, centred near the origin; a streets.json beside it gives the "
                        "street graph), or 'sionna:<name>' for a scene bundled with Sionna RT "
                        "(sionna:munich, sionna:etoile, sionna:florence, ...), or the name of a "
                        "registered scene-source plug-in, '<name>' or '<name>:<argument>' "
                        "(docs/extending.md)")
    building_height_m: float = param(15.0, "mean building height", lo=1.0, hi=200.0)
    height_jitter_m: float = param(0.0, "building heights uniform in mean +- jitter (seeded)",
                                   lo=0.0, hi=100.0)
    street_width_m: float = param(5.0, "street width between blocks", lo=2.0, hi=100.0)
    block_size_m: float = param(30.0, "side of the square building blocks", lo=2.0, hi=500.0)
    extent_m: float = param(450.0, "half-side of the square area the street grid covers",
                            lo=20.0, hi=5000.0)
    margin_m: float = param(300.0, "emit only buildings (canyon blocks, or a mesh scene's "
                            "building shapes) within this 2-D distance of a used BS "
                            "or of the trajectory (crop: model no more than the scene needs; "
                            "cost and accuracy of the margins: docs/performance.md)",
                            lo=0.0, hi=5000.0)
    building_material: str = param("concrete", "ITU-R P.2040 material of the buildings",
                                   choices=tuple(ITU_MATERIAL_RANGES_GHZ))
    ground_material: str = param("medium_dry_ground", "ITU-R P.2040 material of the ground",
                                 choices=("concrete", "very_dry_ground", "medium_dry_ground",
                                          "wet_ground", "marble", "metal"))
    material_thickness_m: float = param(0.3, "slab thickness of the materials", lo=0.001, hi=10.0)
    osm: str = param("", "path to a local OpenStreetMap extract (.osm XML or .osm.pbf); when set, "
                     "the run builds the scene from it (buildings extruded, ITU materials by "
                     "building type, streets.json; docs/osm-import.md) into its scene/ folder, "
                     "rebuilt only when the extract or the osm_* fields change; scene.source "
                     "stays 'canyon'")
    osm_bbox_deg: tuple[float, ...] = param((), "crop of the OSM extract: [lon_min, lat_min, "
                                            "lon_max, lat_max] in degrees (WGS84); the "
                                            "frame is centred on it; [] for none")
    osm_radius_m: float = param(0.0, "crop of the OSM extract: keep the buildings within this "
                                "distance of the frame's centre (0: none)", lo=0.0, hi=50000.0)
    osm_storey_m: float = param(3.0, "height per building:levels storey of an OSM building "
                                "without a height tag (TR 38.901 Table 7.2-1's 3 m floors)",
                                lo=1.0, hi=20.0)
    osm_default_height_m: float = param(10.0, "height of an OSM building with neither height "
                                        "nor building:levels (a convention)", lo=1.0, hi=500.0)

    @property
    def is_canyon(self) -> bool:
        return self.source == "canyon" and not self.osm

    @property
    def is_bundled(self) -> bool:
        """The source names a scene bundled with Sionna RT (``sionna:<name>``)."""
        return self.source.startswith(BUNDLED_PREFIX)

    @property
    def is_path(self) -> bool:
        """The source is a scene file's path (it ends in ``.xml`` or holds a folder separator)."""
        return not self.is_bundled and (self.source.endswith(".xml") or "/" in self.source
                                        or os.sep in self.source)

    @property
    def source_name(self) -> str:
        """The scene-source registry's name of this scene (``veriloc_rt.world.sources``):
        ``osm`` when ``osm`` is set, ``xml`` for a path, else the source up to its first ``:``
        (``canyon``, ``sionna`` of ``sionna:<name>``, a plug-in's ``<name>[:<argument>]``)."""
        if self.osm:
            return "osm"
        if self.is_path:
            return "xml"
        return self.source.split(":", 1)[0]

    @property
    def source_arg(self) -> str:
        """What follows the plug-in name and ``:`` in ``source`` ('' for none or a path)."""
        if self.is_path or ":" not in self.source:
            return ""
        return self.source.split(":", 1)[1]

    @property
    def xml_path(self) -> Path:
        """The XML file of a mesh scene (a path as given, or a bundled scene's file)."""
        if self.is_bundled:
            return bundled_scene_xml(self.source[len(BUNDLED_PREFIX):])
        return Path(self.source)

    def validate(self, path: str) -> None:
        if self.osm:
            check_path(self.osm, f"{path}.osm")
            if self.source != "canyon":
                raise bad_value(f"{path}.source", self.source, "'canyon' when scene.osm is set "
                                "(the OSM extract is the scene)")
            name = self.osm.lower()
            if not name.endswith((".osm", ".osm.xml", ".pbf")):
                raise bad_value(f"{path}.osm", self.osm, "a path ending in .osm (XML) or "
                                ".osm.pbf")
        b = self.osm_bbox_deg
        if b and (len(b) != 4 or not (-180 <= b[0] < b[2] <= 180 and -90 <= b[1] < b[3] <= 90)):
            raise bad_value(f"{path}.osm_bbox_deg", list(b), "[] or [lon_min, lat_min, lon_max, "
                            "lat_max] with -180 <= lon_min < lon_max <= 180 and -90 <= lat_min "
                            "< lat_max <= 90")
        if self.osm:
            return
        if self.is_bundled:
            bundled_scene_xml(self.source[len(BUNDLED_PREFIX):], f"{path}.source")
            return
        if self.is_path:
            check_path(self.source, f"{path}.source")
            if not self.source.endswith(".xml"):
                raise bad_value(f"{path}.source", self.source, "'canyon', 'sionna:<name>', a "
                                "path ending in .xml or a registered scene source's name")
            return
        # a registered scene source's name (the canyon's or a plug-in's), looked up when the
        # run is assembled (veriloc_rt.sim.plugins), above the registry's package
        if not _SOURCE_NAME.fullmatch(self.source):
            raise bad_value(f"{path}.source", self.source, "'canyon', 'sionna:<name>', a path "
                            "ending in .xml or a registered scene source's name "
                            "('<name>' or '<name>:<argument>')")


@dataclass(frozen=True)
class TopologyConfig:
    """Hexagonal BS layout: 3 BSs per cell at alternate vertices of its hexagon."""

    isd_m: float = param(500.0, "inter-site distance (distance between cell centres)",
                         lo=20.0, hi=20000.0)
    bs_height_m: float = param(25.0, "BS antenna height (above TR 38.901's effective "
                               "environment height h_E = 1 m, which the UMa model, and "
                               "`compare` on any config, need)", lo=MIN_ANTENNA_HEIGHT_M,
                               lo_open=True, hi=300.0)
    random_offset: bool = param(True, "random offset and rotation of the layout per Monte Carlo "
                                "iteration, drawn from the seed")
    iteration: int = param(0, "Monte Carlo iteration index (selects the layout draw)", lo=0)
    placement: str = param("auto", "BS heights: 'fixed' (every BS at bs_height_m above the "
                           "ground), 'rooftop' (each hexagonal site moved to the nearest roof of "
                           "a mesh scene, mast_height_m above its highest point there), 'auto' "
                           "(fixed on the canyon, rooftop on a mesh scene)",
                           choices=("auto", "fixed", "rooftop"))
    mast_height_m: float = param(3.0, "antenna height above the roof for rooftop placement "
                                 "(a stated default: a short rooftop mast; no standard fixes it)",
                                 lo=0.5, hi=100.0)
    sites: str = param("", "CSV of BS sites with header x,y,z[,azimuth_deg] (m, scene frame; "
                       "z above the ground) replacing the hexagonal layout; each UE point is "
                       "served by its num_trps nearest sites (selection 'traced_power': the "
                       "strongest by traced power). Empty: the hexagonal layout")
    num_trps: int = param(3, "TRPs (BS sites) whose PRS each point measures, slot 0 (the "
                          "strongest) the RSTD reference; 3 is the paper's serving set, TR 38.857 "
                          "and TR 38.855 evaluate 12-18", lo=MIN_TRPS, hi=MAX_TRPS)
    selection: str = param("auto", "which TRPs a point measures: 'power' (the num_trps strongest "
                           "by median received PRS power: every site transmits the same power "
                           "from isotropic antennas and TR 38.901's median path loss grows with "
                           "the 2-D distance at fixed heights, so the num_trps nearest sites "
                           "(also with bs_antenna 'tr38901': the choice ignores the panels); "
                           "which of them are heard is the receiver's hearability test, "
                           "receiver.hearability_db), 'cell' (the three BSs of the hexagonal "
                           "cell holding the point: the paper's serving set; num_trps 3 and the "
                           "hexagonal layout only), 'auto' ('cell' for num_trps 3 on the "
                           "hexagonal layout, else 'power'), 'traced_power' (a sites CSV "
                           "and ray tracing only: every candidate site within "
                           "candidate_radius_m of a point is traced to it, and the point "
                           "measures the num_trps with the strongest traced received PRS power, "
                           "the links' total path gain: every site transmits "
                           "channel.bs_max_power_dbm; docs/trps.md)",
                           choices=("auto", "power", "cell", "traced_power"))
    candidate_radius_m: float = param(400.0, "selection 'traced_power': the candidate sites of "
                                      "a point are those within this horizontal distance of it "
                                      "(and always its num_trps nearest); it bounds the traced "
                                      "links to the sites within the radius per point",
                                      lo=1.0, hi=20000.0)
    bs_antenna: str = param("isotropic", "BS antennas: 'isotropic' (0 dBi in every direction, "
                            "one per site: every propagation model's own links) or 'tr38901' "
                            "(topology.sectors panels per site, each a vertical column of "
                            "TR 38.901 Table 7.3-1 elements with electrical downtilt, applied "
                            "to the links' departure angles after propagation; each link gets "
                            "the site's strongest sector; docs/scenarios.md, 'BS antennas')",
                            choices=("isotropic", "tr38901"))
    sectors: int = param(3, "bs_antenna 'tr38901': sectors (panels) per site, boresights "
                         "360/sectors deg apart, the first towards the centre of a cell the "
                         "site serves (hexagonal layout), or the sites CSV's azimuth_deg, else "
                         "30 deg (TR 38.901 Table 7.8-1: 30, 150, 270 deg)", choices=(1, 3))
    bs_antenna_elements: int = param(10, "bs_antenna 'tr38901': elements M of the vertical "
                                     "column (TR 38.901 Table 7.8-1 calibration: 10)",
                                     lo=1, hi=64)
    bs_antenna_spacing_wavelengths: float = param(0.5, "bs_antenna 'tr38901': vertical "
                                                  "element spacing d_V, wavelengths (0.5 as "
                                                  "the Table 7.8-1 calibration transcriptions "
                                                  "give it; docs/scenarios.md)",
                                                  lo=0.1, hi=2.0)
    bs_antenna_tilt_deg: float = param(102.0, "bs_antenna 'tr38901': electrical downtilt as "
                                       "the zenith angle of the column's beam, deg (90: the "
                                       "horizon; TR 38.901 Table 7.8-1 UMa/UMi: 102, 12 deg "
                                       "below it)", lo=45.0, hi=135.0)

    @property
    def uses_cell(self) -> bool:
        """The hexagonal cell's three BSs serve each point (else the num_trps nearest sites)."""
        if self.selection == "auto":
            return self.num_trps == CELL_BS and not self.sites
        return self.selection == "cell"

    def validate(self, path: str) -> None:
        if self.sites:
            check_path(self.sites, f"{path}.sites")
        if self.selection == "traced_power" and not self.sites:
            raise bad_value(f"{path}.selection", self.selection,
                            "'power', 'cell' or 'auto' on the hexagonal layout: 'traced_power' "
                            "chooses among the candidate sites of topology.sites")
        if self.selection == "cell" and (self.num_trps != CELL_BS or self.sites):
            raise bad_value(f"{path}.selection", self.selection,
                            f"'power' or 'auto' unless topology.num_trps is {CELL_BS} on the "
                            "hexagonal layout (a cell has three BSs; a sites CSV has no cells)")


@dataclass(frozen=True)
class TrajectoryConfig:
    """UE path (street-following generator or CSV) and the adversary that follows it."""

    source: str = param("generator", "'generator' (on the canyon's street grid, or on a mesh "
                        "scene's street graph: streets.json beside its XML, else derived from "
                        "the free space at ue_height_m, 1 m from every wall) or a CSV path with "
                        "columns t,x,y[,z]")
    num_points: int = param(120, "number of trajectory points (the built-in default is small "
                            "enough for a few minutes; configs/paper-*.json use the paper's "
                            "1200). The maximum bounds a run's memory and time: it holds every "
                            "point's links and chain results in memory and its time grows with "
                            "the points (docs/performance.md); for more statistics use "
                            "run.realisations. A generated drive, (num_points - 1) x dt_s x "
                            "max_speed_mps, is at most 500 km (the generator integrates the "
                            "speed profile every 0.25 m of route)",
                            lo=2, hi=MAX_POINTS)
    dt_s: float = param(1.0, "time between points", lo=0.001, hi=3600.0, lo_open=True)
    ue_height_m: float = param(1.5, "UE antenna height above ground (above h_E = 1 m, as "
                               "topology.bs_height_m)", lo=MIN_ANTENNA_HEIGHT_M, lo_open=True,
                               hi=100.0)
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
        if self.source != "generator":
            check_path(self.source, f"{path}.source")
        else:
            drive_m = (self.num_points - 1) * self.dt_s * self.max_speed_mps
            if drive_m > MAX_DRIVE_M:
                raise bad_value(f"{path}.num_points", self.num_points,
                                f"a generated drive of at most {MAX_DRIVE_M / 1e3:g} km; "
                                f"(num_points - 1) x dt_s x max_speed_mps is "
                                f"{drive_m / 1e3:.4g} km (the generator integrates the speed "
                                "profile every 0.25 m of its route): fewer points, a shorter "
                                "dt_s or a lower max_speed_mps")
        if self.min_speed_mps > self.max_speed_mps:
            raise bad_value(f"{path}.min_speed_mps", self.min_speed_mps,
                            f"a value <= max_speed_mps ({self.max_speed_mps})")

