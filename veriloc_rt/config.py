"""The run configuration: nested, frozen, validated; unknown keys are rejected.

Load with :func:`load_config` (a JSON file) or :func:`config_from_dict`. Every field has a
default, so ``{}`` is the built-in default scenario. Errors name the dotted field path.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .channel_config import ChannelConfig, ReceiverConfig
from .configtools import from_dict, json_schema, param, section, to_dict
from .detectors.absa import ABSAConfig
from .detectors.handshake import HandshakeConfig
from .detectors.tags import TagDetectorConfig
from .detectors.tracking import TrackingConfig
from .errors import InputError, bad_value
from .nr.config import NRConfig
from .security.config import SecurityConfig
from .threats.fbs import FBSConfig
from .threats.jamming import JammingConfig
from .threats.meaconing import MeaconingConfig

#: scenarios a run can evaluate (DESIGN.md, "The public contract")
SCENARIOS = ("none", "fbs", "meaconing", "jamming")


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
                            "150 m: `veriloc-rt bench` measured the same tracing cost as 20 or "
                            "60 m and fewer first paths off the reference)",
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


@dataclass(frozen=True)
class ArrayConfig:
    """The UE's uniform linear array (horizontal)."""

    num_elements: int = param(5, "number of ULA elements", lo=1, hi=64)
    spacing_wavelengths: float = param(0.5, "element spacing", lo=0.05, hi=4.0, lo_open=False)
    axis_azimuth_deg: float = param(0.0, "azimuth of the array axis (from +x, counter-clockwise)",
                                    lo=-360.0, hi=360.0)


#: single-port linear polarizations of a ray-traced antenna (TR 38.901 7.3.2 model-2 slant angles:
#: see :data:`veriloc_rt.propagation.polarization.SLANT_ANGLES`)
POLARIZATIONS = ("V", "H", "+45", "-45")


@dataclass(frozen=True)
class PolarizationConfig:
    """Polarization of the antenna at each end of the ray-traced links.

    Every antenna is one isotropic element with one port, linearly polarised along
    ``cos(zeta) theta_hat + sin(zeta) phi_hat`` (TR 38.901 7.3.2, polarization model-2): 'V' is
    theta-hat (vertical for a wave travelling horizontally), 'H' phi-hat (horizontal for every
    direction), '+45'/'-45' the slants. The tracer keeps the full 2x2 polarimetric path matrix,
    so these fields are applied after tracing and do not enter the ray-tracing cache key. The
    UMa model ignores them (single vertical polarization, uma.py).
    """

    bs: str = param("V", "the BS's PRS port (TS 38.211 7.4.1.7: one antenna port, so one "
                    "polarization)", choices=POLARIZATIONS)
    ue: str = param("V", "the UE's port, the same on every ULA element", choices=POLARIZATIONS)
    adversary: str = param("bs", "the adversary's one port, transmitting to the UE and receiving "
                           "the BSs: 'bs' = the BSs' polarization (it impersonates or relays a "
                           "BS with BS-type equipment), or an explicit one",
                           choices=("bs",) + POLARIZATIONS)

    def adversary_polarization(self) -> str:
        """The adversary's polarization with 'bs' resolved."""
        return self.bs if self.adversary == "bs" else self.adversary


@dataclass(frozen=True)
class MaterialsConfig:
    """Surface scattering and depolarization, applied to every radio material of the scene
    after it is loaded (canyon and external XML alike; the XML's own values are replaced)."""

    scattering_coefficient: float = param(0.0, "S of Sionna RT's effective-roughness model "
                                          "(Degli-Esposti 2007): the specular reflection "
                                          "coefficient is scaled by sqrt(1 - S^2) and S^2 of the "
                                          "reflected power is scattered diffusely (traced only "
                                          "with diffuse_reflection)", lo=0.0, hi=1.0)
    scattering_pattern: str = param("lambertian", "diffuse scattering pattern: 'lambertian', "
                                    "'directive' (lobe around the specular direction, width "
                                    "alpha_r) or 'backscattering' (forward lobe alpha_r, back "
                                    "lobe alpha_i, split by backscatter_fraction)",
                                    choices=("lambertian", "directive", "backscattering"))
    alpha_r: int = param(1, "width exponent of the lobe around the specular direction "
                         "(directive, backscattering; larger is narrower)", lo=1, hi=100)
    alpha_i: int = param(1, "width exponent of the lobe around the incidence direction "
                         "(backscattering)", lo=1, hi=100)
    backscatter_fraction: float = param(0.0, "share of the diffuse power in the backward lobe "
                                        "(backscattering; Sionna's 1 - Lambda)", lo=0.0, hi=1.0)
    xpr_db: float = param(8.0, "cross-polarization ratio of diffusely scattered waves, co- to "
                          "cross-polarised power (Sionna's K_x = 1 / (1 + 10^(xpr_db/10))); "
                          "default: TR 38.901 Table 7.5-6 Part-1 UMi-Street Canyon NLOS mu_XPR. "
                          "Sionna applies it to diffuse reflection only", lo=-30.0, hi=100.0)


@dataclass(frozen=True)
class RayTracingConfig:
    """Sionna RT fidelity knobs (every one trades time for accuracy)."""

    max_depth: int = param(4, "maximum number of interactions per path (4: the cheapest depth "
                           "that kept every serving link of the default canyon, `veriloc-rt "
                           "bench`)", lo=0, hi=10)
    direction: str = param("reciprocal", "'reciprocal': launch rays from the street-level end "
                           "(UE, adversary) and use reciprocity, so the nearby roof edges that "
                           "carry canyon links are densely sampled; 'forward': launch from the "
                           "transmitter (BS)", choices=("reciprocal", "forward"))
    rays_per_source: int = param(1_000, "rays launched per source (samples_per_src) for "
                                 "Sionna RT's sampled candidates (with 'exhaustive' edge "
                                 "candidates they carry the line of sight and the reflections: "
                                 "1e3 and 1e4 give the same power and outcomes, "
                                 "docs/convergence.md)",
                                 lo=100, hi=100_000_000)
    max_candidates_per_source: int = param(2000, "path-candidate buffer per source and target "
                                           "(Sionna max_num_paths_per_src / num_targets)",
                                           lo=10, hi=1_000_000)
    los: bool = param(True, "line-of-sight paths")
    specular_reflection: bool = param(True, "specular reflections")
    diffraction: bool = param(True, "first-order wedge diffraction")
    diffraction_coefficient: str = param("utd", "'utd': the Kouyoumjian-Pathak UTD (perfect "
                                         "conductors) and a reciprocal form of Luebbers' "
                                         "heuristic (lossy wedges), checked against the exact "
                                         "half-plane solution; 'sionna': Sionna RT's own "
                                         "coefficient, kept for comparison (docs/diffraction.md)",
                                         choices=("utd", "sionna"))
    edge_candidates: str = param("exhaustive", "'exhaustive': every first-order diffraction "
                                 "path that reflects on planes near its two ends ([R...] D "
                                 "[R...], every wedge of the scene) is enumerated and solved by "
                                 "Sionna's image method (veriloc_rt.propagation.street_paths; "
                                 "docs/convergence.md), Sionna RT's sampled rays give the line "
                                 "of sight and the reflections; 'both': Sionna's sampled "
                                 "diffraction as well; 'sampled': Sionna RT's candidates alone",
                                 choices=("exhaustive", "both", "sampled"))
    candidate_plane_distance_m: float = param(20.0, "'exhaustive' candidates reflect on planes "
                                              "within this distance of a link's end",
                                              lo=0.0, hi=1000.0)
    candidate_target_reflections: int = param(2, "'exhaustive' candidates: at most this many "
                                              "reflections between the edge and the Sionna "
                                              "target (the BS when tracing 'reciprocal')",
                                              lo=0, hi=10)
    diffuse_reflection: bool = param(False, "trace diffusely scattered paths (needs "
                                     "materials.scattering_coefficient > 0)")
    refraction: bool = param(False, "refraction through walls")
    max_paths_per_link: int = param(32, "keep the strongest N paths per link", lo=1, hi=4096)
    work_per_call: int = param(30_000_000, "bound on depth x rays x sources x targets per "
                               "PathSolver call (Sionna's deterministic solver allocates this "
                               "many entries, ~60 B each: bounds peak memory)", lo=100_000, hi=10**12)
    cache_dir: str = param(".veriloc-cache", "directory of the on-disk propagation cache "
                           "('' disables caching)")
    polarization: PolarizationConfig = section(PolarizationConfig, "antenna polarizations")
    materials: MaterialsConfig = section(MaterialsConfig, "surface scattering and "
                                         "depolarization of every material")

    def validate(self, path: str) -> None:
        if self.diffuse_reflection and self.materials.scattering_coefficient == 0.0:
            raise bad_value(f"{path}.diffuse_reflection", True,
                            "false while materials.scattering_coefficient is 0 (nothing is "
                            "scattered: diffuse tracing would only cost time)")


@dataclass(frozen=True)
class PropagationConfig:
    """Channel model for every link."""

    model: str = param("raytrace", "'raytrace' (Sionna RT on the scene) or 'uma' "
                       "(stochastic TR 38.901 UMa)", choices=("raytrace", "uma"))
    carrier_frequency_hz: float = param(3.5e9, "carrier frequency", lo=0.5e9, hi=100e9)
    uma_mode: str = param("fast_fading", "UMa: 'fast_fading' (clusters and rays, TR 38.901 "
                          "7.5) or 'pathloss_only' (one direct path per link, as MATLAB-era "
                          "simulators)", choices=("fast_fading", "pathloss_only"))
    raytrace: RayTracingConfig = section(RayTracingConfig, "ray-tracing fidelity")
    ue_array: ArrayConfig = section(ArrayConfig, "UE antenna array")


@dataclass(frozen=True)
class DetectorsConfig:
    """The five per-point detectors (paper Sec. "Proposed Detection and Resilience Techniques")."""

    hmac: TagDetectorConfig = section(TagDetectorConfig, "HMAC tag detector")
    digsig: TagDetectorConfig = section(lambda: TagDetectorConfig(scheme="ds"),
                                        "digital-signature (Ed25519) tag detector")
    absa: ABSAConfig = section(ABSAConfig, "angular-based source authentication")
    handshake: HandshakeConfig = section(HandshakeConfig, "DL-UL handshake")
    tracking: TrackingConfig = section(TrackingConfig, "Kalman position tracking")

    def validate(self, path: str = "detectors") -> None:
        if self.hmac.scheme != "hmac":
            raise bad_value(f"{path}.hmac.scheme", self.hmac.scheme, "'hmac'")
        if self.digsig.scheme != "ds":
            raise bad_value(f"{path}.digsig.scheme", self.digsig.scheme, "'ds'")


@dataclass(frozen=True)
class ThreatsConfig:
    """The adversary of each attack scenario (paper Sec. "Adversarial Threat Models")."""

    fbs: FBSConfig = section(FBSConfig, "selective PRS spoofing by a false BS")
    meaconing: MeaconingConfig = section(MeaconingConfig, "meaconing relay")
    jamming: JammingConfig = section(JammingConfig, "wideband jammer over the PRS band")


@dataclass(frozen=True)
class RunConfig:
    """What ``veriloc-rt run`` evaluates: scenarios, attack window, outcome threshold,
    Monte Carlo realisations."""

    scenarios: tuple[str, ...] = param(SCENARIOS, "scenarios evaluated in one run, each over the "
                                       "whole trajectory: 'none', 'fbs', 'meaconing', 'jamming'")
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

    def validate(self, path: str = "run") -> None:
        if not self.scenarios:
            raise bad_value(f"{path}.scenarios", list(self.scenarios), "at least one scenario")
        for i, s in enumerate(self.scenarios):
            if s not in SCENARIOS:
                raise bad_value(f"{path}.scenarios[{i}]", s,
                                "one of " + ", ".join(repr(c) for c in SCENARIOS))
        if len(set(self.scenarios)) != len(self.scenarios):
            raise bad_value(f"{path}.scenarios", list(self.scenarios), "no repeated scenario")
        if self.attack_end_fraction <= self.attack_start_fraction:
            raise bad_value(f"{path}.attack_end_fraction", self.attack_end_fraction,
                            f"a value > attack_start_fraction ({self.attack_start_fraction})")

    def attack_points(self, num_points: int):
        """[num_points] bool, the attack window of a trajectory of ``num_points`` points."""
        import numpy as np

        i = np.arange(num_points)
        lo = int(np.floor(self.attack_start_fraction * num_points))
        hi = int(np.floor(self.attack_end_fraction * num_points))
        return (i >= lo) & (i < hi)


@dataclass(frozen=True)
class Config:
    """veriloc-rt run configuration."""

    seed: int = param(1, "drives every random draw", lo=0, hi=2**63 - 1)
    scene: SceneConfig = section(SceneConfig, "scene")
    topology: TopologyConfig = section(TopologyConfig, "BS layout")
    trajectory: TrajectoryConfig = section(TrajectoryConfig, "UE and adversary paths")
    propagation: PropagationConfig = section(PropagationConfig, "propagation model")
    nr: NRConfig = section(NRConfig, "NR PRS waveform and OFDM sampling (TS 38.211)")
    security: SecurityConfig = section(SecurityConfig, "PRS encryption and authentication tags")
    channel: ChannelConfig = section(ChannelConfig, "link application: powers, noise, domain")
    receiver: ReceiverConfig = section(ReceiverConfig, "ToA, AoA, tags and uplink receivers")
    detectors: DetectorsConfig = section(DetectorsConfig, "the five per-point detectors")
    threats: ThreatsConfig = section(ThreatsConfig, "the adversary of each attack scenario")
    run: RunConfig = section(RunConfig, "scenarios, attack window, outcome threshold, Monte Carlo "
                             "realisations")

    def validate(self, path: str) -> None:
        if len(self.security.encrypted) != self.nr.num_bs:
            raise bad_value("security.encrypted", list(self.security.encrypted),
                            f"{self.nr.num_bs} flags, one per serving BS of nr.comb_offsets")
        slots = self.threats.fbs.spoofed_slots
        for i, k in enumerate(slots):
            if not 0 <= k < self.nr.num_bs:
                raise bad_value(f"threats.fbs.spoofed_slots[{i}]", k,
                                f"a serving-BS slot 0..{self.nr.num_bs - 1}")
        if len(set(slots)) != len(slots):
            raise bad_value("threats.fbs.spoofed_slots", list(slots), "no repeated slot")
        if self.threats.fbs.mode == "bias" and len(set(slots or range(self.nr.num_bs))) == self.nr.num_bs:
            raise bad_value("threats.fbs.spoofed_slots", list(slots),
                            "with threats.fbs.mode 'bias', a subset of the serving BSs (a bias on "
                            "every BS is common and cancels in every RSTD)")

    def replace(self, **changes: Any) -> "Config":
        """Copy with top-level fields changed (``seed=...``)."""
        return dataclasses.replace(self, **changes)


def config_from_dict(data: dict) -> Config:
    """Validated :class:`Config` from JSON data; raises :class:`InputError`."""
    return from_dict(Config, data)


def load_config(path: str | Path | None) -> Config:
    """Load a JSON config file; ``None`` gives the built-in default.

    Relative paths inside the config (scene XML, trajectory CSV) are resolved against the
    config file's folder.
    """
    if path is None:
        return Config()
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise InputError(str(path), f"cannot read config file ({exc.strerror or exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(str(path), f"not valid JSON (line {exc.lineno}: {exc.msg})") from None
    cfg = config_from_dict(data)
    return _resolve_paths(cfg, p.parent)


def _resolve_paths(cfg: Config, base: Path) -> Config:
    scene, traj, sec = cfg.scene, cfg.trajectory, cfg.security
    if not scene.is_canyon and not Path(scene.source).is_absolute():
        scene = dataclasses.replace(scene, source=str((base / scene.source).resolve()))
    if traj.source != "generator" and not Path(traj.source).is_absolute():
        traj = dataclasses.replace(traj, source=str((base / traj.source).resolve()))
    if sec.keys_dir and not Path(sec.keys_dir).is_absolute():
        sec = dataclasses.replace(sec, keys_dir=str((base / sec.keys_dir).resolve()))
    return dataclasses.replace(cfg, scene=scene, trajectory=traj, security=sec)


def config_to_dict(cfg: Config) -> dict:
    """The resolved config as JSON-ready data."""
    return to_dict(cfg)


def config_schema() -> dict:
    """JSON schema of the config."""
    schema = json_schema(Config)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema
