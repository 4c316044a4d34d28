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
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError, bad_value
from .attacks import FBS_MODES, FBSConfig, JammingConfig, MeaconingConfig, ThreatsConfig
from .channel import ChannelConfig, ReceiverConfig
from .detectors import (ABSAConfig, DetectorsConfig, HandshakeConfig, TagDetectorConfig,
                        TrackingConfig)
from .fields import from_dict, json_schema, param, section, to_dict
from .nr import NRConfig
from .propagation import (POLARIZATIONS, ArrayConfig, MaterialsConfig, PolarizationConfig,
                          PropagationConfig, RayTracingConfig)
from .run import SCENARIOS, RunConfig
from .security import SecurityConfig
from .world import SceneConfig, TopologyConfig, TrajectoryConfig


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
