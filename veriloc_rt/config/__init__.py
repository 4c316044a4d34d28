"""The run configuration: nested, frozen, validated; unknown keys are rejected.

The bottom layer: pure data, imported by every layer above and importing none of them. One
module per group of sections, each a frozen dataclass of :func:`~veriloc_rt.config.fields.param`
fields: :mod:`.world` (scene, topology, trajectory), :mod:`.propagation`, :mod:`.nr`,
:mod:`.security`, :mod:`.channel` (link application and receivers), :mod:`.attacks`,
:mod:`.detectors`, :mod:`.run`; this module holds the root :class:`Config` and re-exports them.

Load with :func:`load_config` (a JSON file) or :func:`config_from_dict`. Every field has a
default, so ``{}`` is the built-in default scenario. Errors name the dotted field path.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError, bad_value
from ..inputs import MAX_JSON_BYTES, check_path, parse_json, read_text
from .attacks import FBS_MODES, FBSConfig, JammingConfig, MeaconingConfig, ThreatsConfig
from .channel import ChannelConfig, ReceiverConfig
from .detectors import (ABSAConfig, DetectorsConfig, FusionConfig, HandshakeConfig,
                        TagDetectorConfig, TrackingConfig)
from .fields import (check_value, from_dict, json_schema, param, patch_data, section, to_dict,
                     validate_on_construction)
from .nr import NRConfig
from .propagation import (POLARIZATIONS, ArrayConfig, MaterialsConfig, PolarizationConfig,
                          PropagationConfig, RayTracingConfig)
from .run import DEFAULT_SCENARIOS, RunConfig
from .security import SecurityConfig
from .world import SceneConfig, TopologyConfig, TrajectoryConfig

#: BSs that serve every point in the paper: the three of the hexagonal cell (world.topology);
#: ``topology.num_trps`` sets the number
SERVING_BS = 3


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

    def __post_init__(self) -> None:
        # per-TRP tuples shorter than topology.num_trps are completed (NRConfig.for_trps; the
        # encryption flags repeat the last one listed), so a user lists only what differs
        n = self.topology.num_trps
        if self.nr.num_bs < n:
            object.__setattr__(self, "nr", self.nr.for_trps(
                n, self.security.tag_scheme != "none"))
        enc = self.security.encrypted
        if enc and len(enc) < n:
            object.__setattr__(self, "security", dataclasses.replace(
                self.security, encrypted=enc + (enc[-1],) * (n - len(enc))))

    def validate(self, path: str) -> None:
        """Checks across sections (each section checked its own fields already)."""
        for name in ("street_width_variants_m", "height_jitter_variants_m"):
            if getattr(self.run, name) and self.scene.source != "canyon":
                raise bad_value(f"run.{name}", list(getattr(self.run, name)),
                                "[] unless scene.source is 'canyon' (the procedural scene)")
        for i, v in enumerate(self.run.height_jitter_variants_m):
            if v >= self.scene.building_height_m:
                raise bad_value(f"run.height_jitter_variants_m[{i}]", v,
                                f"a value < scene.building_height_m "
                                f"({self.scene.building_height_m:g})")
        n = self.topology.num_trps
        if self.nr.num_bs != n:
            raise bad_value("nr.comb_offsets", list(self.nr.comb_offsets),
                            f"at most {n} offsets, one per TRP (topology.num_trps; "
                            "missing ones are derived)")
        if len(self.security.encrypted) != self.nr.num_bs:
            raise bad_value("security.encrypted", list(self.security.encrypted),
                            f"at most {n} flags, one per TRP (topology.num_trps; missing ones "
                            "repeat the last)")
        slots = self.threats.fbs.spoofed_slots
        for i, k in enumerate(slots):
            if not 0 <= k < self.nr.num_bs:
                raise bad_value(f"threats.fbs.spoofed_slots[{i}]", k,
                                f"a TRP slot 0..{self.nr.num_bs - 1} (topology.num_trps)")
        if len(set(slots)) != len(slots):
            raise bad_value("threats.fbs.spoofed_slots", list(slots), "no repeated slot")
        if self.threats.fbs.mode == "bias" and len(set(slots or range(self.nr.num_bs))) == self.nr.num_bs:
            raise bad_value("threats.fbs.spoofed_slots", list(slots),
                            "with threats.fbs.mode 'bias', a subset of the serving BSs (a bias on "
                            "every BS is common and cancels in every RSTD)")

        tags = self.security.tag_scheme != "none"
        self.nr.check_resources(tags)
        _, rep = self.nr.slot_plan(tags)
        for i, s in enumerate(self.receiver.tag_slots):
            if rep < self.nr.slots_per_frame and s >= rep:
                raise bad_value(f"receiver.tag_slots[{i}]", s,
                                f"a slot 0..{rep - 1}: each of the {self.nr.num_bs} TRPs "
                                f"transmits in {rep} of the frame's PRS slots (slot groups, "
                                "docs/real-cities.md) and its tags are checked in its own")
        if self.detectors.tracking.measurement_noise == "fix_covariance" and not self.weighted_fix:
            raise bad_value("detectors.tracking.measurement_noise", "fix_covariance",
                            "'fixed' unless the fix is weighted (receiver.fix_weighting 'snr', "
                            "or 'auto' with topology.num_trps > 3): the unweighted fit has no "
                            "covariance")
        self._validate_receiver()
        self._validate_world()
        self.run.check_trajectory_length(self.trajectory.num_points, "trajectory.num_points")

    @property
    def tracking_measurement_noise(self) -> str:
        """``detectors.tracking.measurement_noise`` resolved: 'auto' is 'fix_covariance' when
        the fix is weighted (:attr:`weighted_fix`: a covariance per fix), else 'fixed'."""
        m = self.detectors.tracking.measurement_noise
        if m == "auto":
            return "fix_covariance" if self.weighted_fix else "fixed"
        return m

    @property
    def weighted_fix(self) -> bool:
        """The DL fix is the weighted fit with a covariance (``receiver.fix_weighting``)."""
        w = self.receiver.fix_weighting
        return w == "snr" or (w == "auto" and self.topology.num_trps > SERVING_BS)

    @property
    def trp_outputs(self) -> bool:
        """Rows carry the TRP and fix-covariance columns (more than three TRPs, or the
        weighted fit): a three-TRP run with the paper's fit keeps the paper's columns."""
        return self.topology.num_trps > SERVING_BS or self.weighted_fix

    def _validate_receiver(self) -> None:
        rx, nr, m = self.receiver, self.nr, self.propagation.ue_array.num_elements
        for i, s in enumerate(rx.tag_slots):
            if s >= nr.slots_per_frame:
                raise bad_value(f"receiver.tag_slots[{i}]", s, f"a PRS slot 0.."
                                f"{nr.slots_per_frame - 1} (nr.slots_per_frame)")
        # the AoA estimator smooths over subarrays of M - 1 elements (M >= 3) and resolves at
        # most one source fewer than the subarray has elements (phy.receiver.aoa)
        most = (m - 1 if m >= 3 else m) - 1
        if rx.aoa_num_sources > most:
            raise bad_value("receiver.aoa_num_sources", rx.aoa_num_sources,
                            f"at most {most} for a {m}-element array "
                            "(propagation.ue_array.num_elements), or 0 for MDL")

    def _validate_world(self) -> None:
        if self.topology.selection == "traced_power" and self.propagation.model != "raytrace":
            raise bad_value("topology.selection", "traced_power", "'power' unless "
                            "propagation.model is 'raytrace' (the received power is traced)")
        if self.scene.is_canyon and self.topology.placement == "rooftop":
            raise bad_value("topology.placement", "rooftop", "'auto' or 'fixed' on the canyon "
                            "(its BSs stand at topology.bs_height_m); rooftop needs a mesh scene")
        if (self.scene.is_canyon and self.trajectory.source == "generator"
                and self.trajectory.region_m > self.scene.extent_m):
            raise bad_value("trajectory.region_m", self.trajectory.region_m,
                            f"a value <= scene.extent_m ({self.scene.extent_m}): the street grid "
                            "ends there")

    def replace(self, **changes: Any) -> "Config":
        """Copy with top-level fields changed (``seed=...``; a section as a section object or
        as a dict of the fields to change, ``scene={"street_width_m": 8}``), validated.

        :raises InputError: naming the dotted field path, as a config file's error
        """
        whole = {k: v for k, v in changes.items() if not isinstance(v, dict)}
        parts = {f"{k}.{f}": w for k, v in changes.items() if isinstance(v, dict)
                 for f, w in v.items()}
        cfg = dataclasses.replace(self, **whole) if whole else self
        return cfg.updated(parts) if parts else cfg

    def updated(self, changes: dict) -> "Config":
        """Copy with the fields at the dotted paths of ``changes`` set
        (``cfg.updated({"scene.street_width_m": 8})``), validated as a config file is.

        :raises InputError: naming the dotted field path (unknown, wrong type, out of range)
        """
        return config_from_dict(patch_data(config_to_dict(self), changes))


validate_on_construction(Config)


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
    p = check_path(path, str(path))
    text = read_text(p, str(path), "config file", MAX_JSON_BYTES)
    data = parse_json(text, str(path))
    cfg = config_from_dict(data)
    return _resolve_paths(cfg, p.parent)


def with_overrides(cfg: Config, *, points: int | None = None, seed: int | None = None) -> Config:
    """``cfg`` with the command line's ``--points`` and ``--seed``, checked against the same
    limits as the config fields (and the config re-validated as a whole)."""
    data = config_to_dict(cfg)
    if points is not None:
        data["trajectory"]["num_points"] = check_value(TrajectoryConfig, "num_points", points,
                                                       "--points")
    if seed is not None:
        data["seed"] = check_value(Config, "seed", seed, "--seed")
    return config_from_dict(data)


def _resolve_paths(cfg: Config, base: Path) -> Config:
    scene, traj, sec, topo = cfg.scene, cfg.trajectory, cfg.security, cfg.topology
    if scene.is_path and not scene.osm and not Path(scene.source).is_absolute():
        scene = dataclasses.replace(scene, source=str((base / scene.source).resolve()))
    if scene.osm and not Path(scene.osm).is_absolute():
        scene = dataclasses.replace(scene, osm=str((base / scene.osm).resolve()))
    if topo.sites and not Path(topo.sites).is_absolute():
        topo = dataclasses.replace(topo, sites=str((base / topo.sites).resolve()))
    if traj.source != "generator" and not Path(traj.source).is_absolute():
        traj = dataclasses.replace(traj, source=str((base / traj.source).resolve()))
    if sec.keys_dir and not Path(sec.keys_dir).is_absolute():
        sec = dataclasses.replace(sec, keys_dir=str((base / sec.keys_dir).resolve()))
    return dataclasses.replace(cfg, scene=scene, trajectory=traj, security=sec, topology=topo)


def config_to_dict(cfg: Config) -> dict:
    """The resolved config as JSON-ready data."""
    return to_dict(cfg)


def config_schema() -> dict:
    """JSON schema of the config."""
    schema = json_schema(Config)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema
