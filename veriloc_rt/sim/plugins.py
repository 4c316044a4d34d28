"""The names a config gives the plug-in families, checked against their registries.

The config sits below the packages that register threats, detectors, propagation models and
scene sources (docs/design.md, "Plug-in registries"), so it checks only a name's type (or form);
this module, above them all, looks every name up before a run computes anything
(:func:`check_plugin_names`, called by :func:`~veriloc_rt.sim.engine.run`, the Monte Carlo
driver and ``veriloc-rt config check``) and lists the registered choices of each such field
(:func:`registered_choices`, for the generated configuration reference and the live editor).
"""

from __future__ import annotations

from ..attacks.threats import BENIGN, THREAT_REGISTRY, scenario_names
from ..config import Config
from ..detectors.outcomes import DETECTORS
from ..errors import bad_value
from ..detectors.registry import DETECTOR_REGISTRY
from ..propagation.models import PROPAGATION_REGISTRY
from ..world.sources import SCENE_SOURCE_REGISTRY

__all__ = ["check_plugin_names", "registered_choices"]


def check_plugin_names(cfg: Config) -> None:
    """Raise :class:`~veriloc_rt.errors.InputError` naming the field of the first name that no
    registry holds (``run.scenarios[i]``, ``detectors.extra[i]``, ``propagation.model``)."""
    for i, s in enumerate(cfg.run.scenarios):
        if s != BENIGN:
            THREAT_REGISTRY.get(s, f"run.scenarios[{i}]")
    for i, d in enumerate(cfg.detectors.extra):
        if d in DETECTORS:
            raise bad_value(f"detectors.extra[{i}]", d, "a plug-in detector (the five "
                            "built-in ones always run)")
        DETECTOR_REGISTRY.get(d, f"detectors.extra[{i}]")
    PROPAGATION_REGISTRY.get(cfg.propagation.model, "propagation.model")
    SCENE_SOURCE_REGISTRY.get(cfg.scene.source_name, "scene.source")


def registered_choices() -> dict[str, tuple[str, ...]]:
    """``{config field: the names registered now}`` of the fields that name plug-ins
    (``detectors.extra``: the plug-in detectors only; the built-in five always run)."""
    return {"run.scenarios": scenario_names(),
            "detectors.extra": tuple(d for d in DETECTOR_REGISTRY.names() if d not in DETECTORS),
            "propagation.model": PROPAGATION_REGISTRY.names(),
            "scene.source": SCENE_SOURCE_REGISTRY.names()}
