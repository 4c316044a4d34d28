"""Propagation sections of the config: the channel model, ray-tracing fidelity, materials,
polarization and the UE array."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import bad_value
from ..inputs import check_path
from .fields import param, section

__all__ = ["ArrayConfig", "POLARIZATIONS", "PolarizationConfig", "MaterialsConfig",
           "RayTracingConfig", "PropagationConfig"]


@dataclass(frozen=True)
class ArrayConfig:
    """The UE's uniform linear array (horizontal)."""

    num_elements: int = param(5, "number of ULA elements (at least 2: one element measures no "
                              "angle of arrival)", lo=2, hi=64)
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
    candidate_plane_distance_m: float = param(30.0, "'exhaustive' candidates reflect on planes "
                                              "within this distance of a link's end (cost "
                                              "and accuracy: docs/performance.md)",
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
        if self.cache_dir:
            check_path(self.cache_dir, f"{path}.cache_dir")
        if self.diffuse_reflection and self.materials.scattering_coefficient == 0.0:
            raise bad_value(f"{path}.diffuse_reflection", True,
                            "false while materials.scattering_coefficient is 0 (nothing is "
                            "scattered: diffuse tracing would only cost time)")


@dataclass(frozen=True)
class PropagationConfig:
    """Channel model for every link."""

    model: str = param("raytrace", "'raytrace' (Sionna RT on the scene), 'uma' (stochastic "
                       "TR 38.901 UMa: rooftop macro sites) or 'umi' (stochastic TR 38.901 "
                       "UMi - Street Canyon: street-level sites below the roofs), or a "
                       "registered plug-in model (docs/extending.md; names checked when the "
                       "run starts)")
    carrier_frequency_hz: float = param(3.5e9, "carrier frequency", lo=0.5e9, hi=100e9)
    uma_mode: str = param("fast_fading", "UMa and UMi: 'fast_fading' (clusters and rays, "
                          "TR 38.901 7.5) or 'pathloss_only' (one direct path per link, as "
                          "MATLAB-era simulators)", choices=("fast_fading", "pathloss_only"))
    stochastic_twin: str = param("auto", "the stochastic model `veriloc-rt compare` sets "
                                 "against ray tracing: 'uma', 'umi', or 'auto' (UMi when the "
                                 "BSs' median antenna height is below the scene's median roof "
                                 "height, i.e. street-level sites; UMa for rooftop sites)",
                                 choices=("auto", "uma", "umi"))
    stochastic_pathloss_offset_los_db: float = param(0.0, "added to the path loss of every "
                                                     "LoS serving link drawn by 'uma'/'umi' "
                                                     "(`compare --match-pathloss` sets it)",
                                                     lo=-100.0, hi=100.0)
    stochastic_pathloss_offset_nlos_db: float = param(0.0, "the same for the NLoS serving "
                                                      "links", lo=-100.0, hi=100.0)
    raytrace: RayTracingConfig = section(RayTracingConfig, "ray-tracing fidelity")
    ue_array: ArrayConfig = section(ArrayConfig, "UE antenna array")

